"""The responses the calibration fits, in closed form and as compiled residuals.

:func:`human_response` (the hand's response to the cab, the seated chain in closed form)
and :func:`cab_response` (the structure's gain and two modes), with their derivatives in
the fit's logarithmic coordinates (:func:`human_log_derivatives`,
:func:`cab_log_derivatives`); and the same closed forms as Numba-compiled loops over the
frequencies that give the fits' residuals and Jacobians (tested equal to rounding, step 3
of :mod:`designs.calibration`). Apart from the fits, which only evaluate them.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["human_response", "human_log_derivatives", "cab_response", "cab_log_derivatives"]


def human_response(
    family, theta: np.ndarray, f_hz: np.ndarray, handle_gain: float, mass_ratio=None
) -> np.ndarray:
    """The hand's response to the cab ``x / c`` for rows of modal parameters.

    In closed form: the seated chain's transfer function from seat acceleration to hand
    motion is ``-c_u g (s^2 + d_3 s + R (w_a^2 + w_t^2)) / D(s)``, ``D`` its characteristic
    quartic with ``d_3 = R (s_a + s_t)``, ``d_2 = R (w_a^2 + w_t^2 + s_a s_t)``, ``d_1 = R
    (s_a w_t^2 + s_t w_a^2)``, ``d_0 = R w_a^2 w_t^2`` (``s_i = 2 zeta_i w_i``, ``R = 1 +``
    the mass ratio; :mod:`backhoe.families.valueset`), equal to the state-space model of
    :func:`backhoe.model.physical.physical_human_matrices` to rounding (tested) and a tenth
    of its cost.

    Parameters
    ----------
    family : backhoe.Family
        Gives the nominal masses (their ratio is held), ``h_gain`` and ``c_unit``.
    theta : ndarray, shape (N, 4)
        Rows of (f_arm_hz, zeta_arm, f_trunk_hz, zeta_trunk).
    mass_ratio : float, optional
        Arm-endpoint over upper-body mass (default: the family's nominal).
    f_hz : ndarray, shape (F,)
        Frequencies, Hz.
    handle_gain : float
        ``sigma * kappa`` of the loop (handle units per unit of ``h``).

    Returns
    -------
    ndarray of complex, shape (N, F)
    """
    th = np.atleast_2d(np.asarray(theta, float))
    p = family.physical
    big_r = 1.0 + (p.m_arm / p.m_trunk if mass_ratio is None else float(mass_ratio))
    wa, wt = 2 * np.pi * th[:, 0:1], 2 * np.pi * th[:, 2:3]
    sa, st = 2 * th[:, 1:2] * wa, 2 * th[:, 3:4] * wt
    wa2, wt2 = wa * wa, wt * wt
    d3 = big_r * (sa + st)
    d2 = big_r * (wa2 + wt2 + sa * st)
    d1 = big_r * (sa * wt2 + st * wa2)
    d0 = big_r * wa2 * wt2
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    den = (((s + d3) * s + d2) * s + d1) * s + d0
    num = (s + d3) * s + big_r * (wa2 + wt2)
    return (-handle_gain * p.c_unit * p.h_gain) * num / den


def human_log_derivatives(family, theta: np.ndarray, f_hz: np.ndarray) -> np.ndarray:
    """Derivatives of ``log`` :func:`human_response` in its modal parameters, analytically.

    With ``num`` and ``D`` as in :func:`human_response`, ``d log(x/c) = d num / num - dD / D``;
    the coefficients ``d_3 ... d_0`` and ``num``'s constant are polynomials in ``w_a, s_a,
    w_t, s_t`` (``s_i = 2 zeta_i w_i``), differentiated term by term. The gain and the held
    mass ratio do not depend on the parameters.

    Parameters
    ----------
    family : backhoe.Family
        Gives the nominal mass ratio (held).
    theta : ndarray, shape (N, 4)
        Rows of (f_arm_hz, zeta_arm, f_trunk_hz, zeta_trunk).
    f_hz : ndarray, shape (F,)
        Frequencies, Hz.

    Returns
    -------
    ndarray of complex, shape (N, F, 4)
        ``d log(x/c) / d theta_k`` (per Hz for the frequencies).
    """
    th = np.atleast_2d(np.asarray(theta, float))
    p = family.physical
    big_r = 1.0 + p.m_arm / p.m_trunk
    wa, wt = 2 * np.pi * th[:, 0:1], 2 * np.pi * th[:, 2:3]
    sa, st = 2 * th[:, 1:2] * wa, 2 * th[:, 3:4] * wt
    wa2, wt2 = wa * wa, wt * wt
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    d3 = big_r * (sa + st)
    num = (s + d3) * s + big_r * (wa2 + wt2)
    den = (((s + d3) * s + big_r * (wa2 + wt2 + sa * st)) * s + big_r * (sa * wt2 + st * wa2)) * s
    den = den + big_r * wa2 * wt2

    def dlog(e3, e2, e1, e0, ec):
        # the log-derivative for coefficient derivatives (d3, d2, d1, d0, num's constant)
        return (e3 * s + ec) / num - (((e3 * s + e2) * s + e1) * s + e0) / den

    zero = np.zeros_like(wa)
    # per primitive variable: w_a, s_a, w_t, s_t
    d_wa = dlog(zero, 2 * big_r * wa, 2 * big_r * st * wa, 2 * big_r * wa * wt2, 2 * big_r * wa)
    d_sa = dlog(big_r + zero, big_r * st, big_r * wt2, zero, zero)
    d_wt = dlog(zero, 2 * big_r * wt, 2 * big_r * sa * wt, 2 * big_r * wt * wa2, 2 * big_r * wt)
    d_st = dlog(big_r + zero, big_r * sa, big_r * wa2, zero, zero)
    za, zt = th[:, 1:2], th[:, 3:4]
    return np.stack(
        [
            2 * np.pi * (d_wa + 2 * za * d_sa),  # d/d f_arm_hz (s_a moves with w_a)
            2 * wa * d_sa,
            2 * np.pi * (d_wt + 2 * zt * d_st),
            2 * wt * d_st,
        ],
        axis=-1,
    )


def cab_response(theta: np.ndarray, f_hz: np.ndarray) -> np.ndarray:
    """The cab's acceleration per cylinder position (Eqn 4) for rows of cab parameters.

    ``C/Y = K_s s^2 prod_i (2 zeta_i w_i s + w_i^2) / (s^2 + 2 zeta_i w_i s + w_i^2)``
    (:func:`backhoe.model.components.structure`): a product, so symmetric in its two modes.

    Parameters
    ----------
    theta : ndarray, shape (N, 5)
        Rows of (k_s, f_a_hz, zeta_a, f_b_hz, zeta_b).
    f_hz : ndarray, shape (F,)
        Frequencies, Hz.

    Returns
    -------
    ndarray of complex, shape (N, F)
    """
    th = np.atleast_2d(np.asarray(theta, float))
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    out = th[:, [0]] * s**2
    for fi, zi in ((1, 2), (3, 4)):
        w, z = 2 * np.pi * th[:, [fi]], th[:, [zi]]
        out = out * (2 * z * w * s + w**2) / (s**2 + 2 * z * w * s + w**2)
    return out


def cab_log_derivatives(theta: np.ndarray, f_hz: np.ndarray) -> np.ndarray:
    """Derivatives of ``log`` :func:`cab_response` in its parameters, analytically.

    ``log(C/Y) = log K_s + 2 log s + sum_i [log(2 zeta_i w_i s + w_i^2) - log(s^2 + 2 zeta_i
    w_i s + w_i^2)]``, differentiated term by term.

    Parameters
    ----------
    theta : ndarray, shape (N, 5)
        Rows of (k_s, f_a_hz, zeta_a, f_b_hz, zeta_b).
    f_hz : ndarray, shape (F,)
        Frequencies, Hz.

    Returns
    -------
    ndarray of complex, shape (N, F, 5)
        ``d log(C/Y) / d theta_k``.
    """
    th = np.atleast_2d(np.asarray(theta, float))
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    out = [np.broadcast_to(1.0 / th[:, [0]], (th.shape[0], s.shape[1])).astype(complex)]
    for fi, zi in ((1, 2), (3, 4)):
        w, z = 2 * np.pi * th[:, [fi]], th[:, [zi]]
        num, den = 2 * z * w * s + w**2, s**2 + 2 * z * w * s + w**2
        out.append(2 * np.pi * (2 * z * s + 2 * w) * (1.0 / num - 1.0 / den))
        out.append(2 * w * s * (1.0 / num - 1.0 / den))
    return np.stack(out, axis=-1)


_kernel = numba.njit(cache=True, nogil=True, error_model="numpy")


@_kernel
def _human_parts(z, big_r):
    """The modal quantities at ``z`` and the seated chain's coefficients (``d3 .. d0`` and
    the numerator's constant, as in :func:`human_response`)."""
    fa, za, ft, zt = math.exp(z[0]), z[1], math.exp(z[2]), z[3]
    wa, wt = 2 * math.pi * fa, 2 * math.pi * ft
    sa, st = 2 * za * wa, 2 * zt * wt
    wa2, wt2 = wa * wa, wt * wt
    # the quartic's coefficients d3 .. d0 and the numerator's constant
    coef = np.array(
        [
            big_r * (sa + st),
            big_r * (wa2 + wt2 + sa * st),
            big_r * (sa * wt2 + st * wa2),
            big_r * wa2 * wt2,
            big_r * (wa2 + wt2),
        ]
    )
    prim = np.array([fa, za, ft, zt, wa, wt, sa, st, wa2, wt2])
    return prim, coef


@_kernel
def _human_residual(z, f, H, w, big_r, gain):
    """The weighted log residual of :func:`human_response` at the fit coordinates ``z``
    (:data:`LOG_AXES`), compiled: real parts then phases, shape ``(2 F,)``."""
    d3, d2, d1, d0, c0 = _human_parts(z, big_r)[1]
    n = f.size
    out = np.empty(2 * n)
    for k in range(n):
        s = 2j * math.pi * f[k]
        num = (s + d3) * s + c0
        den = (((s + d3) * s + d2) * s + d1) * s + d0
        r = np.log(gain * num / den / H[k])
        out[k] = r.real * w[k]
        out[n + k] = r.imag * w[k]  # the principal log's phase: in (-pi, pi]
    return out


@_kernel
def _human_jacobian(z, f, w, big_r):
    """The Jacobian of :func:`_human_residual` in ``z`` (:func:`human_log_derivatives`
    through the log axes), compiled, shape ``(2 F, 4)``."""
    prim, coef = _human_parts(z, big_r)
    fa, za, ft, zt, wa, wt, sa, st, wa2, wt2 = prim
    d3, d2, d1, d0, c0 = coef
    r = big_r
    n = f.size
    out = np.empty((2 * n, 4))
    # per primitive variable (w_a, s_a, w_t, s_t): the derivatives of d3, d2, d1, d0, c0
    e = np.array(
        [
            [0.0, 2 * r * wa, 2 * r * st * wa, 2 * r * wa * wt2, 2 * r * wa],
            [r, r * st, r * wt2, 0.0, 0.0],
            [0.0, 2 * r * wt, 2 * r * sa * wt, 2 * r * wt * wa2, 2 * r * wt],
            [r, r * sa, r * wa2, 0.0, 0.0],
        ]
    )
    dl = np.empty(4, np.complex128)
    for k in range(n):
        s = 2j * math.pi * f[k]
        num = (s + d3) * s + c0
        den = (((s + d3) * s + d2) * s + d1) * s + d0
        for j in range(4):
            dl[j] = (e[j, 0] * s + e[j, 4]) / num - (
                ((e[j, 0] * s + e[j, 1]) * s + e[j, 2]) * s + e[j, 3]
            ) / den
        cols = (
            2 * math.pi * (dl[0] + 2 * za * dl[1]) * fa,  # d/d log f_arm
            2 * wa * dl[1],
            2 * math.pi * (dl[2] + 2 * zt * dl[3]) * ft,
            2 * wt * dl[3],
        )
        for j in range(4):
            out[k, j] = cols[j].real * w[k]
            out[n + k, j] = cols[j].imag * w[k]
    return out


@_kernel
def _cab_residual(z, f, H, w):
    """The weighted log residual of :func:`cab_response` at the fit coordinates ``z``
    (:data:`CAB_LOG_AXES`), compiled, shape ``(2 F,)``."""
    ks = math.exp(z[0])
    w1, z1, w2, z2 = 2 * math.pi * math.exp(z[1]), z[2], 2 * math.pi * math.exp(z[3]), z[4]
    n = f.size
    out = np.empty(2 * n)
    for k in range(n):
        s = 2j * math.pi * f[k]
        v = ks * s * s
        v = v * (2 * z1 * w1 * s + w1 * w1) / (s * s + 2 * z1 * w1 * s + w1 * w1)
        v = v * (2 * z2 * w2 * s + w2 * w2) / (s * s + 2 * z2 * w2 * s + w2 * w2)
        r = np.log(v / H[k])
        out[k] = r.real * w[k]
        out[n + k] = r.imag * w[k]  # the principal log's phase: in (-pi, pi]
    return out


@_kernel
def _cab_jacobian(z, f, w):
    """The Jacobian of :func:`_cab_residual` in ``z`` (:func:`cab_log_derivatives` through
    the log axes), compiled, shape ``(2 F, 5)``."""
    n = f.size
    out = np.empty((2 * n, 5))
    cols = np.empty(5, np.complex128)
    for k in range(n):
        s = 2j * math.pi * f[k]
        cols[0] = 1.0  # d log K_s / d log K_s
        for m in range(2):
            fi = math.exp(z[1 + 2 * m])
            wi, zi = 2 * math.pi * fi, z[2 + 2 * m]
            num = 2 * zi * wi * s + wi * wi
            den = s * s + 2 * zi * wi * s + wi * wi
            q = 1.0 / num - 1.0 / den
            cols[1 + 2 * m] = 2 * math.pi * (2 * zi * s + 2 * wi) * q * fi
            cols[2 + 2 * m] = 2 * wi * s * q
        for j in range(5):
            out[k, j] = cols[j].real * w[k]
            out[n + k, j] = cols[j].imag * w[k]
    return out
