"""The Youla parameter's basis and the Gram matrices of its maps.

:func:`lag_basis` and :func:`pole_basis` give the orthonormal bank ``phi(s)`` of strictly
proper lags (Takenaka-Malmquist functions on the region's poles) in which
:mod:`robust.synthesis.youla` writes the free parameter ``Q(s) = Theta phi(s)``;
:func:`output_gram` is the exact H2 Gram of a bank's outputs, and :func:`quadrature_grid`
with :func:`quadrature_gram` the same inner products by quadrature of frequency responses.
These are the parametrisation's building blocks, apart from the plant they are applied to.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla

from robust.errors import ParameterError

__all__ = ["lag_basis", "pole_basis", "output_gram", "quadrature_grid", "quadrature_gram"]


def lag_basis(poles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal lags with real poles ``-a_k`` (:func:`pole_basis` of ``-a``).

    The Takenaka-Malmquist functions

        phi_k(s) = sqrt(2 a_k) / (s + a_k) * prod_{j<k} (s - a_j) / (s + a_j),

    orthonormal in H2 whatever the spacing of the poles, spanning the same space as the
    ``1 / (s + a_k)`` (Ninness & Gustafsson, "A unifying construction of orthonormal bases
    for system identification", IEEE TAC 1997).

    Parameters
    ----------
    poles : sequence of float
        The poles' magnitudes ``a_k`` (> 0), rad/s.
    """
    a = np.asarray(poles, float).ravel()
    if a.size == 0 or not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ParameterError(f"lag_basis: poles must be positive and finite; got {a}")
    return pole_basis(-a)


def _balanced_allpass(p: complex):
    """Balanced realisation ``(A, B, C, D)`` of the inner section with pole ``p`` (and conj)."""
    if p.imag == 0.0:
        a = -p.real
        r = math.sqrt(2 * a)
        return np.array([[-a]]), np.array([[r]]), np.array([[-r]]), 1.0
    # ((s + p)(s + conj p)) / ((s - p)(s - conj p)) = 1 + 4 Re(p) s / den
    m2, tr = abs(p) ** 2, 2 * p.real
    A = np.array([[0.0, 1.0], [-m2, tr]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[0.0, 2 * tr]])
    P = _controllability_gramian(A, B)
    Q = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
    L = np.linalg.cholesky(0.5 * (P + P.T))
    S, U = np.linalg.eigh(L.T @ Q @ L)
    T = L @ U @ np.diag(S**-0.25)
    Ti = np.linalg.inv(T)
    return Ti @ A @ T, Ti @ B, C @ T, 1.0


def pole_basis(poles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An H2-orthonormal bank with the given stable poles: ``(A_phi, b_phi, C_phi = I)``.

    The states of a cascade of balanced inner (all-pass) sections, one per real pole and
    one per complex pair, are orthonormal in H2 and span the rational functions with those
    poles (Heuberger, Van den Hof & Bosgra, "A generalized orthonormal basis for linear
    dynamical systems", IEEE TAC 1995; Ninness & Gustafsson 1997): however clustered or
    spread the poles, the basis is perfectly conditioned. Section ``k`` is driven by
    ``u_k = w + sum_{j<k} C_j x_j`` (every section's feedthrough is 1).

    Parameters
    ----------
    poles : array_like of complex
        Poles with negative real parts; a complex pole stands for its pair (give one of
        each pair; conjugates given as well are ignored).
    """
    p = np.asarray(poles, complex).ravel()
    if p.size == 0 or not np.all(np.isfinite(p)) or np.any(p.real >= 0):
        raise ParameterError(f"pole_basis: poles must be finite with negative real parts; got {p}")
    sections = []
    for z in p:
        if abs(z.imag) <= 1e-9 * max(1.0, abs(z)):
            sections.append(_balanced_allpass(complex(z.real, 0.0)))
        elif z.imag > 0 or not np.any(np.isclose(p, np.conj(z))):
            sections.append(_balanced_allpass(complex(z.real, abs(z.imag))))
    sizes = [sec[0].shape[0] for sec in sections]
    n = sum(sizes)
    A = np.zeros((n, n))
    b = np.zeros((n, 1))
    offs = np.concatenate([[0], np.cumsum(sizes)])
    for k, (Ak, Bk, _, _) in enumerate(sections):
        ik = slice(offs[k], offs[k + 1])
        A[ik, ik] = Ak
        b[ik] = Bk
        for j in range(k):
            A[ik, offs[j] : offs[j + 1]] = Bk @ sections[j][2]
    return A, b, np.eye(n)


def _controllability_gramian(A, B):
    return sla.solve_continuous_lyapunov(A, -B @ B.T)


def output_gram(A, B, C) -> np.ndarray:
    """``C P C'`` with ``P`` the controllability Gramian of a stable ``(A, B)``: the H2 Gram.

    The states are first scaled by powers of 2 to balance ``A``
    (:func:`scipy.linalg.matrix_balance`, exact), which keeps the Lyapunov solve accurate
    when the realisation mixes very different scales (high-gain state feedback).

    Parameters
    ----------
    A, B, C : ndarray
        A stable realisation.
    """
    A = np.asarray(A, float)
    _, (sc, _) = sla.matrix_balance(A, permute=False, separate=True)
    Ab = A * (1.0 / sc)[:, None] * sc[None, :]
    Bb = np.asarray(B, float) / sc[:, None]
    Cb = np.asarray(C, float) * sc[None, :]
    P = _controllability_gramian(Ab, Bb)
    W = Cb @ P @ Cb.T
    return 0.5 * (W + W.T)


def quadrature_grid(poles, *, per_decade: int = 80):
    """A log-spaced grid and trapezoid weights for ``(1/pi) int_0^inf g(w) dw``.

    From ``1e-3`` times the smallest to ``100`` times the largest pole magnitude; the
    tails are added as ``g(w_min) w_min`` (flat below) and ``g(w_max) w_max`` (decaying
    as ``w^-2`` above, as a strictly proper map's squared magnitude does).


    Parameters
    ----------
    poles : array_like of complex
        The poles of the integrand's maps.
    per_decade : int
        Grid points per decade.

    Returns
    -------
    omega, weights : ndarray
    """
    a = np.abs(np.asarray(poles, complex))
    a = a[a > 0]
    lo, hi = 1e-3 * max(a.min(), 1e-3), 100.0 * a.max()
    k = int(math.ceil(per_decade * math.log10(hi / lo))) + 1
    w = np.geomspace(lo, hi, k)
    wt = np.zeros(k)
    d = np.diff(w)
    wt[:-1] += d / 2
    wt[1:] += d / 2
    wt[0] += w[0]
    wt[-1] += w[-1]
    return w, wt / math.pi


def quadrature_gram(resp: dict, weights, *, intent, noise=None) -> np.ndarray:
    """``W`` with ``[1, theta]' W [1, theta]`` the force variance, from :func:`force_responses`.

    ``intent`` (f,) is ``|k F(jw)|^2`` (the intent's spectrum shaping ``w``); ``noise``
    (p,) the measurement noise intensities.

    Parameters
    ----------
    resp : dict
        :func:`force_responses` on the grid.
    weights : ndarray
        Quadrature weights of the grid (:func:`quadrature_grid`).
    intent : ndarray
        ``|k F(j w)|^2`` on the grid.
    noise : array_like, optional
        Measurement noise intensities.
    """
    Vw = resp["w"] * np.sqrt(weights * intent)[:, None]
    W = (Vw.conj().T @ Vw).real
    if noise is not None and "n" in resp:
        for j, nj in enumerate(noise):
            Vn = resp["n"][:, j, :] * np.sqrt(weights * nj)[:, None]
            W += (Vn.conj().T @ Vn).real
    return 0.5 * (W + W.T)
