"""A mu upper bound below 1 at every frequency, with no grid trusted between frequencies.

``mu(M(jw)) < 1`` is shown at one frequency by D-G scalings (Fan, Tits & Doyle, IEEE TAC
36(1), 1991; :func:`uncertainty.mussv`). With those scalings fixed, the matrix
``F(w) = M^H D M + j (G M - M^H G) - D`` is negative definite at that frequency and stays so
on the whole interval bounded by the nearest frequencies where ``det F(w) = 0``; those are
the imaginary-axis zeros of the para-Hermitian ``Phi(s) = [M~ I] Pi [M; I]`` with
``Pi = [[D, -jG], [jG, -D]]``, found as finite eigenvalues of its Rosenbrock pencil (the
test of Ferreres & Biannic, "A mu analysis technique without frequency gridding", ACC 1998),
and the interval is backed by direct evaluations of ``F`` inside it. Frequencies are added
where the intervals leave a gap until ``[0, inf]`` (or the band asked for) is covered, or a
frequency's bound reaches 1. With real ``M`` (a real system), ``mu(M(-jw)) = mu(M(jw))``:
the non-negative frequencies suffice.

Used by :mod:`uncertainty.performance` (robust performance, a complex performance block)
and :mod:`uncertainty.margins` (robust stability, ``method="mu"``).
"""

from __future__ import annotations

import math
import time

import numpy as np
import scipy.linalg as sla

from robust.errors import ParameterError
from uncertainty.mu import (
    _balance,
    _bound_from_scalings,
    _power_iteration,
    _scalings_feasible,
    _structured,
    _upper_balanced,
    _verified_lower,
)

__all__ = ["mu_cover", "MAX_FREQUENCIES"]

#: Relative tolerance of the D-G bisection at each frequency of the certificate.
SCALING_RTOL = 1e-3
#: A generalised eigenvalue ``lambda`` of the crossing pencil counts as imaginary (a frequency
#: where ``det F = 0``) when ``|Re lambda| <= CROSSING_TOL * max(1, |lambda|)``; a looser
#: test only shortens the certified intervals.
CROSSING_TOL = 1e-6
#: Bound on each real block's G scaling relative to its D (``-G_MAX D <= G <= G_MAX D``):
#: a real parameter's mu is a spike at the frequency where its loop is real, and an
#: unbounded G, huge beside it, leaves the interval test ill-conditioned there; bounded, the
#: upper bound is continuous in frequency and still an upper bound (a smaller set of
#: scalings), like the small complex part other tools give real parameters.
G_MAX = 10.0
#: A frequency counts only when its bound is below ``1 - MU_MARGIN``: the scaled matrix is
#: then negative definite by a margin, and its crossings lie measurably away from the
#: frequency (without it the cover can creep towards a frequency where mu reaches 1, each
#: interval shorter than the last, and the last one step over it by rounding).
MU_MARGIN = 1e-6
#: Below this largest singular value of the balanced matrix no LMI is solved at a frequency:
#: the balancing's own scalings (``D = S^2``, ``G = 0``) leave ``F`` negative definite by
#: ``1 - 0.9^2`` of ``D`` at least (the family's loop at small scales: 0.05-0.3 at most
#: frequencies, where each LMI of its 30 channels takes seconds).
SINGULAR_VALUE_ENOUGH = 0.9
#: Frequencies the certificate of one scale may use before it gives up.
MAX_FREQUENCIES = 400


def _response(A, B, C, D, w: float) -> np.ndarray:
    if math.isinf(w):
        return D.astype(complex)
    n = A.shape[0]
    return D + C @ np.linalg.solve(1j * w * np.eye(n) - A, B.astype(complex))


def _crossings(A, B, C, D, Dsc, Gsc) -> np.ndarray:
    """Frequencies ``w >= 0`` (rad/s) where ``det(M^H D M + j (G M - M^H G) - D) = 0``.

    The imaginary-axis zeros of ``Phi(s) = W~(s) Pi W(s)`` with ``W = [M; I]`` and
    ``Pi = [[D, -jG], [jG, -D]]`` (normalised), as the eigenvalues of ``A_f - B_f D_f^-1 C_f``
    when ``D_f = F(inf)`` is well conditioned, else as finite eigenvalues of the Rosenbrock
    pencil.
    """
    n, m = B.shape
    # the zeros do not depend on Pi's scale; the solver's scalings can be 1e7 or more, which
    # would swamp the pencil's other entries
    s = float(np.linalg.eigvalsh(0.5 * (Dsc + Dsc.conj().T))[-1])
    Dsc, Gsc = Dsc / s, Gsc / s
    Pi = np.block([[Dsc, -1j * Gsc], [1j * Gsc, -Dsc]])
    Cw = np.vstack([C, np.zeros((m, n))]).astype(complex)
    Dw = np.vstack([D, np.eye(m)]).astype(complex)
    AH, BH = A.conj().T, B.conj().T
    Af = np.block([[A, np.zeros((n, n))], [Cw.conj().T @ Pi @ Cw, -AH]])
    Bf = np.vstack([B, Cw.conj().T @ Pi @ Dw])
    Cf = np.hstack([Dw.conj().T @ Pi @ Cw, -BH])
    Df = Dw.conj().T @ Pi @ Dw
    if np.linalg.cond(Df) < 1e8:
        # F(inf) invertible: the zeros are the eigenvalues of the Hamiltonian-like matrix
        lam = np.linalg.eigvals(Af - Bf @ np.linalg.solve(Df, Cf))
    else:
        pencil = np.block([[Af, Bf], [Cf, Df]])
        E = np.zeros_like(pencil)
        E[: 2 * n, : 2 * n] = np.eye(2 * n)
        alpha, beta = sla.eig(pencil, E, right=False, homogeneous_eigvals=True)
        finite = np.abs(beta) > 1e-12 * (np.abs(alpha) + np.abs(beta))
        lam = alpha[finite] / beta[finite]
    tol = CROSSING_TOL * np.maximum(1.0, np.abs(lam))
    # only s = j w with w >= 0: with complex scalings F(-w) is not F(w) conjugated, and
    # the certificate needs the non-negative frequencies only (mu(M(-jw)) = mu(M(jw)))
    near = (np.abs(lam.real) <= tol) & (lam.imag >= -tol)
    return np.sort(np.maximum(lam[near].imag, 0.0))


def _negative(A, B, C, D, Dsc, Gsc, w) -> bool:
    Mw = _response(A, B, C, D, w)
    MH = Mw.conj().T
    F = MH @ Dsc @ Mw + 1j * (Gsc @ Mw - MH @ Gsc) - Dsc
    return bool(np.linalg.eigvalsh(0.5 * (F + F.conj().T))[-1] < 0)


def _interval(A, B, C, D, Dsc, Gsc, w: float) -> tuple:
    """Where ``F < 0`` about ``w`` with these scalings (``F(w) < 0`` was checked):
    ``(a, b, a_included, b_included)``, an interval bounded by the nearest crossings
    (:func:`_crossings`), 0 and ``inf`` included when no crossing separates them from ``w``.

    The Hamiltonian test is backed by a direct one: ``F`` is evaluated at points inside the
    interval, and one that is not negative definite ends the interval there."""
    cross = _crossings(A, B, C, D, Dsc, Gsc)
    if math.isinf(w):
        a = float(cross.max()) if cross.size else 0.0
        b, b_in = math.inf, True
    else:
        if np.any(cross == w):  # pragma: no cover - F(w) < 0 was checked
            return w, w, True, True
        below, above = cross[cross < w], cross[cross > w]
        a = float(below.max()) if below.size else 0.0
        b = float(above.min()) if above.size else math.inf
        b_in = math.isinf(b) and _negative(A, B, C, D, Dsc, Gsc, math.inf)
    a_in = a == 0.0 and not np.any(cross == 0.0)
    # the direct check, on each side of w
    for lo, hi, side in ((a, w, "below"), (w, b, "above")):
        if not lo < hi:
            continue
        top = hi if math.isfinite(hi) else max(10.0 * max(lo, 1.0), 1e6)
        bottom = lo if lo > 0 else min(1e-6, 1e-3 * top)
        # geometric points, and the system's natural frequencies (where F moves fastest)
        natural = np.abs(np.linalg.eigvals(A)) if A.shape[0] else np.zeros(0)
        pts = np.union1d(
            np.geomspace(bottom, top, 10)[1:-1], natural[(natural > lo) & (natural < hi)]
        )
        for x in pts if side == "above" else pts[::-1]:
            if not _negative(A, B, C, D, Dsc, Gsc, float(x)):
                if side == "above":
                    b, b_in = float(x), False
                else:
                    a, a_in = float(x), False
                break
    return a, b, a_in, b_in


def _covered(x: float, intervals) -> bool:
    return any((a < x < b) or (x == a and ai) or (x == b and bi) for a, b, ai, bi in intervals)


def _first_uncovered(intervals):
    """The first point of ``[0, inf]`` the intervals leave out, or None."""
    ends = sorted({0.0, math.inf} | {e for a, b, _, _ in intervals for e in (a, b)})
    for e0, e1 in zip(ends[:-1], ends[1:]):
        if not _covered(e0, intervals):
            return e0
        mid = (
            math.sqrt(e0 * e1)
            if e0 > 0 and math.isfinite(e1)
            else (0.5 * e1 if math.isfinite(e1) else max(10.0 * e0, 1.0))
        )
        if not _covered(mid, intervals):
            return mid
    return None if _covered(math.inf, intervals) else math.inf


def _start_bound(M, blocks) -> float:
    """A cheap verified lower bound of mu: the complex blocks' power iteration (reals at 0)."""
    parts = _power_iteration(M, blocks, np.random.default_rng(0), iterations=60)
    return _verified_lower(M, blocks, _structured(blocks, parts))[0]


def mu_cover(
    A,
    B,
    C,
    D,
    blocks,
    *,
    max_frequencies: int,
    deadline: float,
    g_max: float = G_MAX,
    band: tuple[float, float] = (0.0, math.inf),
    least_bound: bool = True,
) -> dict:
    """Certificate that ``mu(M(jw)) < 1`` at every ``w`` in ``[0, inf]``, or in a band
    (module notes).

    Parameters
    ----------
    A, B, C, D : numpy.ndarray
        A stable realisation of ``M``, real or complex (square: ``C`` has as many rows as
        ``B`` columns); a complex one is covered on ``w >= 0`` only.
    blocks : list of (int, str)
        The structure, as :func:`uncertainty.mussv` takes it.
    max_frequencies : int
        Frequencies the cover may use before it gives up.
    deadline : float
        :func:`time.perf_counter` value at which it gives up.
    g_max : float
        Bound of each real block's G scaling relative to its D (:data:`G_MAX`).
    band : (float, float)
        The frequencies to cover, rad/s, ``0 <= low < high <= inf``, both ends included
        (default: all of them).
    least_bound : bool
        Where no scalings prove the bound below 1 at a frequency, bisect for the least bound
        there (its value goes into the answer: several more LMIs) or stop at once (``False``:
        the answer is the same, not certified).

    Returns
    -------
    dict
        ``certified``; ``frequencies`` (each with its mu upper bound and the interval its
        scalings cover, Hz); when not certified, ``reason`` and, where the bound reached 1,
        ``frequency_hz`` and ``mu_upper``.
    """
    lo, hi = (float(x) for x in band)
    if not (0.0 <= lo < hi):
        raise ParameterError(f"mu_cover: band must satisfy 0 <= low < high; got {band!r}")
    shown: list = []
    # what lies outside the band counts as covered (and is not shown)
    intervals: list = []
    if lo > 0:
        intervals.append((0.0, lo, True, False))
    if math.isfinite(hi):
        intervals.append((hi, math.inf, False, True))
    poles = np.linalg.eigvals(A) if A.shape[0] else np.zeros(0)
    natural = sorted({float(abs(p)) for p in poles if lo < abs(p) < hi})
    queue = [lo, hi] + natural[:: max(1, len(natural) // 6)]
    what = "[0, inf]" if lo == 0 and math.isinf(hi) else f"[{_hz(lo):.6g}, {_hz(hi):.6g}] Hz"
    while True:
        w = queue.pop(0) if queue else _first_uncovered(intervals)
        if w is None:
            return {"certified": True, "frequencies": shown}
        if _covered(w, intervals):
            continue
        if len(shown) >= max_frequencies or time.perf_counter() > deadline:
            return {
                "certified": False,
                "reason": f"budget: {len(shown)} frequencies did not cover {what}",
                "frequencies": shown,
            }
        # the realisation's channels balanced at this frequency (S M S^-1, the same mu; the
        # scalings and the interval are those of the balanced realisation: F = S F_1 S)
        s = _balance(_response(A, B, C, D, w), blocks)
        Bs, Cs, Ds = B / s[None, :], s[:, None] * C, (s[:, None] * D) / s[None, :]
        Mw = _response(A, Bs, Cs, Ds, w)
        # one LMI at the bound itself first (its scalings as negative as it can make F);
        # the bisection for the least bound only where that fails
        n_ch = Mw.shape[0]
        found = (
            (np.eye(n_ch, dtype=complex), np.zeros((n_ch, n_ch), complex))
            if np.linalg.norm(Mw, 2) < SINGULAR_VALUE_ENOUGH
            else _scalings_feasible(Mw, blocks, 1.0 - 10 * MU_MARGIN, g_max)
        )
        if found is None and not least_bound:
            return {
                "certified": False,
                "reason": f"mu upper bound >= {1.0 - 10 * MU_MARGIN:g} at {_hz(w):.6g} Hz (no "
                "D-G scalings prove it below)",
                "frequency_hz": _hz(w),
                "frequencies": shown,
            }
        if found is None:
            _, Dsc, Gsc = _upper_balanced(
                Mw, blocks, _start_bound(Mw, blocks), rtol=SCALING_RTOL, g_max=g_max
            )
        else:
            Dsc, Gsc = found
        beta = _bound_from_scalings(Mw, Dsc, Gsc)
        if beta >= 1.0 - MU_MARGIN:
            return {
                "certified": False,
                "reason": f"mu upper bound {beta:.9g} >= 1 - {MU_MARGIN:g} at {_hz(w):.6g} Hz",
                "frequency_hz": _hz(w),
                "mu_upper": float(beta),
                "frequencies": shown,
            }
        a, b, a_in, b_in = _interval(A, Bs, Cs, Ds, Dsc, Gsc, w)
        intervals.append((a, b, a_in, b_in))
        shown.append(
            {
                "frequency_hz": _hz(w),
                "mu_upper": float(beta),
                "interval_hz": [_hz(a), _hz(b)],
            }
        )


def _hz(w: float) -> float:
    return w / (2 * math.pi)
