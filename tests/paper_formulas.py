"""The paper's printed formulas evaluated directly with complex arithmetic.

These are the hand computations the tests compare the python-control systems
against: no python-control, no realisation, only Eqns 3-5 as printed.
"""

import numpy as np

TWO_PI = 2 * np.pi


def valve(s, k_vc=36.0, p1=314.0, wn_hz=5.0, zeta=0.45):
    wn = TWO_PI * wn_hz
    return k_vc * p1 / (s * (s + p1)) * wn**2 / (s**2 + 2 * zeta * wn * s + wn**2)


def structure(s, k_s=200.0, z1=0.126, z2=0.223, f1=6.3, f2=6.5):
    w1, w2 = TWO_PI * f1, TWO_PI * f2
    return (
        k_s
        * s**2
        * (2 * z1 * w1 * s + w1**2)
        / (s**2 + 2 * z1 * w1 * s + w1**2)
        * (2 * z2 * w2 * s + w2**2)
        / (s**2 + 2 * z2 * w2 * s + w2**2)
    )


def human(s, k_h=5.0, z1=50.3, p1=1.57):
    return k_h * (s + z1) ** 2 / (s**2 * (s + p1) ** 2)


def pi(s, kp, ki):
    return kp + ki / s


def loop_u_to_y(s, k_psf, kp, ki, kappa, sign, bdft=True):
    """Y/U of the Figure 5 loop from the block formulas: x = u + sign*kappa*h, r = K x."""
    L = pi(s, kp, ki) * valve(s)
    t_in = L / (1 + L)
    if not bdft:
        return k_psf * t_in
    return k_psf * t_in / (1 - sign * kappa * k_psf * human(s) * structure(s) * t_in)


def characteristic_roots(k_psf, kp, ki, kappa, sign):
    """Roots of the loop's characteristic polynomial built with numpy polynomials.

    The s^2 of Eqn 4's numerator and of Eqn 5's denominator are cancelled by hand.
    """
    P = np.polynomial.Polynomial
    wn = TWO_PI * 5.0
    nv = P([36.0 * 314.0 * wn**2])
    dv = P([0, 314.0, 1]) * P([wn**2, 2 * 0.45 * wn, 1])
    npi, dpi = P([ki, kp]), P([0, 1])
    w1, w2 = TWO_PI * 6.3, TWO_PI * 6.5
    ns = 200.0 * P([w1**2, 2 * 0.126 * w1]) * P([w2**2, 2 * 0.223 * w2])
    ds = P([w1**2, 2 * 0.126 * w1, 1]) * P([w2**2, 2 * 0.223 * w2, 1])
    nh = 5.0 * P([50.3, 1]) ** 2
    dh = P([1.57, 1]) ** 2
    char = (dpi * dv + npi * nv) * ds * dh - sign * kappa * k_psf * npi * nv * ns * nh
    return char.roots()
