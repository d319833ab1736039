"""Seeded random generalized plants for tests and benchmarks of H-infinity synthesis."""

from __future__ import annotations

import control
import numpy as np
import scipy.linalg as sla
import scipy.optimize as sopt

from robust.checks import NONNEGATIVE, check_scalar

__all__ = ["dgkf_scalar_gamma_opt", "dgkf_scalar_plant", "random_generalized_plant"]


def random_generalized_plant(
    n: int,
    *,
    seed: int,
    nw: int = 4,
    nz: int = 4,
    nu: int = 2,
    ny: int = 2,
    n_unstable: int = 2,
    d11: bool = False,
    d22: bool = False,
) -> control.StateSpace:
    """A random stabilisable, detectable, regular generalized plant of order ``n``.

    A is built in modal form (real poles and lightly or well damped pairs)
    and rotated by a random orthogonal matrix: ``n_unstable`` poles have real
    part in [0.1, 1] rad/s, the others in [-4, -0.2] rad/s, imaginary parts in
    [0.5, 5] rad/s.  B1, B2, C1, C2, D12, D21 are standard normal (so generically
    stabilisable, detectable, D12 of full column rank, D21 of full row rank).

    Parameters
    ----------
    n : int
        Plant order (>= 1).
    seed : int
        Seed of :func:`numpy.random.default_rng`; the same seed gives the same plant.
    nw, nz, nu, ny : int
        Numbers of exogenous inputs, performance outputs, controls and
        measurements (``nz >= nu``, ``nw >= ny``).
    n_unstable : int
        Number of open-loop poles in the right half plane.
    d11, d22 : bool
        Give D11 (and D22) random nonzero entries (scaled by 0.3).

    Returns
    -------
    control.StateSpace
        Inputs ``w0.., u0..``, outputs ``z0.., y0..``; use with ``nmeas=ny, ncon=nu``.
    """
    check_scalar("n", n, NONNEGATIVE)
    rng = np.random.default_rng(seed)
    blocks, k = [], 0
    while k < n:
        r = rng.uniform(0.1, 1.0) if k < n_unstable else -rng.uniform(0.2, 4.0)
        if n - k >= 2 and rng.random() < 0.5:
            w = rng.uniform(0.5, 5.0)
            blocks.append(np.array([[r, w], [-w, r]]))
            k += 2
        else:
            blocks.append(np.array([[r]]))
            k += 1
    L = sla.block_diag(*blocks)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    A = Q @ L @ Q.T
    B1, B2 = rng.standard_normal((n, nw)), rng.standard_normal((n, nu))
    C1, C2 = rng.standard_normal((nz, n)), rng.standard_normal((ny, n))
    D11 = 0.3 * rng.standard_normal((nz, nw)) if d11 else np.zeros((nz, nw))
    D12, D21 = rng.standard_normal((nz, nu)), rng.standard_normal((ny, nw))
    D22 = 0.3 * rng.standard_normal((ny, nu)) if d22 else np.zeros((ny, nu))
    return control.ss(
        A,
        np.hstack([B1, B2]),
        np.vstack([C1, C2]),
        np.block([[D11, D12], [D21, D22]]),
        inputs=[f"w{i}" for i in range(nw)] + [f"u{i}" for i in range(nu)],
        outputs=[f"z{i}" for i in range(nz)] + [f"y{i}" for i in range(ny)],
        name=f"random_plant_n{n}_seed{seed}",
    )


def dgkf_scalar_plant(a: float) -> control.StateSpace:
    """The first-order normalised problem ``x' = a x + w1 + u``, ``z = [x; u]``, ``y = x + w2``.

    It satisfies the normalisations of Doyle, Glover, Khargonekar & Francis,
    "State-space solutions to standard H2 and H-infinity control problems",
    IEEE TAC 34(8) (1989) 831-847 (D12' [C1 D12] = [0 1], D21 [B1' D21'] = [0 1],
    D11 = 0), so its optimal gamma follows from their Theorem 3; see
    :func:`dgkf_scalar_gamma_opt`.

    Parameters
    ----------
    a : float
        The open-loop pole, rad/s (unstable for ``a > 0``).

    Returns
    -------
    control.StateSpace
        Inputs ``w1, w2, u``, outputs ``z1, z2, y``; use with ``nmeas=1, ncon=1``.
    """
    return control.ss(
        [[a]],
        [[1.0, 0.0, 1.0]],
        [[1.0], [0.0], [1.0]],
        [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
        inputs=["w1", "w2", "u"],
        outputs=["z1", "z2", "y"],
        name="dgkf_scalar",
    )


def dgkf_scalar_gamma_opt(a: float) -> float:
    """Optimal gamma of :func:`dgkf_scalar_plant` from DGKF (1989) Theorem 3.

    Both Riccati equations reduce to ``2 a X + (g^-2 - 1) X^2 + 1 = 0`` with the
    stabilising root ``X(g) = (a + sqrt(a^2 + 1 - g^-2)) / (1 - g^-2)`` (g > 1),
    and X = Y by symmetry, so the coupling condition ``rho(X Y) < g^2`` is
    ``X(g) < g``; the optimum solves ``X(g) = g``.  For ``a = 0`` this gives
    ``g^2 = 2``, i.e. ``gamma_opt = sqrt(2)``.

    Parameters
    ----------
    a : float
        The open-loop pole of :func:`dgkf_scalar_plant`, rad/s.
    """

    def f(g):
        e = 1.0 - g**-2
        return (a + np.sqrt(a * a + e)) / e - g

    return float(sopt.brentq(f, 1.0 + 1e-12, 1e6, xtol=1e-14, rtol=1e-14))
