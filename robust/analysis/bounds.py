"""Frequency-wise magnitude bounds, checked at every frequency.

A closed-loop requirement such as "the cylinder never deviates from its BDFT-free
response by more than the larger of 20 % and the uncompensated loop's deviation" is a
bound ``|G(jw)| <= max_k |B_k(jw)|`` for every ``w`` in a band, with ``G`` and every
``B_k`` rational. :func:`bound_ratio` computes

    rho = sup over w in the band of |G(jw)| / max_k |B_k(jw)|

so that the bound holds exactly when ``rho <= 1``, and names the frequency where the
supremum is reached. A grid cannot decide this (a bound violated between two grid
points passes); the test here is exact in the sense of the Hamiltonian methods of
H-infinity norm computation (Boyd, Balakrishnan & Kabamba 1989; Bruinsma & Steinbuch
1990), of which it is the generalisation to a frequency-dependent level:

* the frequencies where ``|G(jw)| = gamma |B_k(jw)|`` are the imaginary-axis zeros of
  the para-Hermitian function ``Phi_k(s) = G(-s) G(s) - gamma^2 B_k(-s) B_k(s)``,
  computed as generalized eigenvalues of the Rosenbrock pencil of a realisation of
  ``Phi_k`` (order ``2 (n_G + n_Bk)``);
* between two consecutive such frequencies (of every ``k``) no sign of
  ``|G| - gamma |B_k|`` changes, so one evaluation inside each interval decides whether
  ``|G| <= gamma max_k |B_k|`` holds on all of it.

The supremum is first estimated on a logarithmic grid whose local maxima are refined,
then confirmed by the exact test at ``gamma = rho (1 + rtol)``; an interval the test finds
violated is searched for its maximum and the test repeated (the two-step scheme of
Bruinsma & Steinbuch). Eigenvalues whose real part is small relative to their modulus are
all taken as crossings: a spurious partition point costs one more evaluation, a missed one
could hide a violation.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numba
import numpy as np
import scipy.linalg as sla

from robust.analysis.norms import _balance_states
from robust.analysis.realization import matrices_key
from robust.checks import check_abcd, check_state_space
from robust.errors import ModelStructureError, ParameterError

__all__ = ["BoundRatio", "bound_ratio", "crossing_frequencies", "siso_response"]

#: Points of the estimating grid per band.
N_GRID = 240
#: Local maxima of the estimating grid refined before the exact test (a higher peak the
#: refinement passes over is found by the test, which then refines its interval).
N_REFINED = 3
#: Relative real part below which a zero of ``Phi`` counts as an imaginary-axis crossing.
CROSSING_RTOL = 1e-4


def _siso(name, sys):
    if isinstance(sys, tuple) and len(sys) == 4:
        A, B, C, D = check_abcd(name, *sys)
    else:
        A, B, C, D = check_state_space(name, sys)
    if B.shape[1] != 1 or C.shape[0] != 1:
        raise ModelStructureError(
            f"{name} must be single-input single-output; got {C.shape[0]} outputs and "
            f"{B.shape[1]} inputs"
        )
    A, B, C = (np.array(m, float) for m in (A, B, C))
    if A.shape[0]:
        A, B, C = _balance_states(A, B, C)
    return A, B, C, np.array(D, float).reshape(1, 1)


#: Largest condition number of ``A``'s eigenvector matrix for which responses are evaluated
#: in modal form (relative error about this times the rounding unit, 2e-10, far below any
#: tolerance of the checks); above it, the complex Schur form.
MODAL_COND = 1e6


class _Response:
    """``C (j w I - A)^-1 B + D`` of one SISO system at any frequencies.

    In modal form, ``sum_i c_i b_i / (j w - lambda_i)``, when ``A``'s eigenvectors are well
    conditioned (:data:`MODAL_COND`): one vectorised expression for every frequency.
    Otherwise through the complex Schur form of ``A`` (made once; back substitution over a
    vector of frequencies), which needs no eigenvector basis.
    """

    def __init__(self, abcd):
        A, B, C, D = abcd
        self.d = complex(D[0, 0])
        self.n = A.shape[0]
        self.modal = False
        if not self.n:
            self.poles = np.zeros(0, complex)
            return
        lam, V = np.linalg.eig(A)
        if np.all(np.isfinite(lam)) and np.linalg.cond(V) < MODAL_COND:
            self.modal = True
            self.poles = lam
            self.r = np.ascontiguousarray((C[0] @ V) * np.linalg.solve(V, B[:, 0]))
            return
        T, Z = sla.schur(A.astype(complex), output="complex")
        self.T = np.ascontiguousarray(T)
        self.b = np.ascontiguousarray(Z.conj().T @ B[:, 0])
        self.c = np.ascontiguousarray(C[0] @ Z + 0j)
        self.poles = np.diag(T).copy()

    def __call__(self, w) -> np.ndarray:
        s = 1j * np.asarray(w, float).reshape(-1)
        out = np.full(s.shape, self.d)
        if not self.n:
            return out
        if self.modal:
            return _modal_sum(self.r, self.poles, self.d, s)
        return _back_substitution(self.T, self.b, self.c, self.d, s)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _modal_sum(r, poles, d, s):  # pragma: no cover - compiled
    """``d + sum_i r_i / (s_j - poles_i)`` for every ``s_j`` (sums in the order of ``i``)."""
    out = np.empty(s.size, np.complex128)
    for j in range(s.size):
        acc = d
        for i in range(r.size):
            acc += r[i] / (s[j] - poles[i])
        out[j] = acc
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _back_substitution(T, b, c, d, s):  # pragma: no cover - compiled
    """``d + c (s_j I - T)^-1 b`` for upper triangular ``T``, for every ``s_j`` (back
    substitution, sums in a fixed order: no BLAS, so no thread pool on small systems)."""
    n = b.size
    out = np.empty(s.size, np.complex128)
    x = np.empty(n, np.complex128)
    for j in range(s.size):
        sj = s[j]
        acc = d
        for k in range(n - 1, -1, -1):
            v = b[k]
            for m in range(k + 1, n):
                v += T[k, m] * x[m]
            x[k] = v / (sj - T[k, k])
            acc += c[k] * x[k]
        out[j] = acc
    return out


def siso_response(sys, omega) -> np.ndarray:
    """Complex frequency response of a SISO system at ``omega`` (rad/s).

    Parameters
    ----------
    sys : control.StateSpace or tuple (A, B, C, D)
        Continuous-time, one input and one output.
    omega : array_like
        Frequencies, rad/s.

    Returns
    -------
    numpy.ndarray of complex
    """
    return _Response(_siso("sys", sys))(omega)


def _phi_pencil(g, b, gamma):
    """Rosenbrock pencil ``(M, N)`` of ``Phi(s) = G(-s) G(s) - gamma^2 B(-s) B(s)``.

    ``H = [G; gamma B]`` (block-diagonal states), ``Phi = H~ J H`` with ``J = diag(1, -1)``
    and ``H~(s) = H(-s)^T``; the series connection of ``J H`` and ``H~``.
    """
    Ag, Bg, Cg, Dg = g
    Ab, Bb, Cb, Db = b
    ng, nb = Ag.shape[0], Ab.shape[0]
    n = ng + nb
    A = np.zeros((n, n))
    A[:ng, :ng], A[ng:, ng:] = Ag, Ab
    B = np.vstack([Bg, Bb])
    C = np.zeros((2, n))
    C[0, :ng], C[1, ng:] = Cg[0], gamma * Cb[0]
    D = np.array([[Dg[0, 0]], [gamma * Db[0, 0]]])
    J = np.diag([1.0, -1.0])
    Ap = np.block([[A, np.zeros((n, n))], [-C.T @ J @ C, -A.T]])
    Bp = np.vstack([B, -C.T @ J @ D])
    Cp = np.hstack([D.T @ J @ C, B.T])
    Dp = D.T @ J @ D
    M = np.block([[Ap, Bp], [Cp, Dp]])
    N = np.zeros_like(M)
    N[: 2 * n, : 2 * n] = np.eye(2 * n)
    return M, N


def _crossings(g, b, gamma) -> np.ndarray:
    """Nonnegative frequencies (rad/s) where ``|G(jw)| = gamma |B(jw)|``, sorted (a superset:
    near-imaginary zeros are included)."""
    M, N = _phi_pencil(g, b, gamma)
    if M.shape[0] == 1:
        return np.zeros(0)
    with np.errstate(all="ignore"):
        ev = sla.eigvals(M, N)
    ev = ev[np.isfinite(ev)]
    if ev.size == 0:
        return np.zeros(0)
    sel = np.abs(ev.real) <= CROSSING_RTOL * np.abs(ev) + 1e-14
    return np.unique(np.abs(ev[sel].imag))


def crossing_frequencies(G, B, gamma: float = 1.0) -> np.ndarray:
    """Frequencies (rad/s, ascending) where ``|G(jw)| = gamma |B(jw)|``.

    The imaginary-axis zeros of ``G(-s) G(s) - gamma^2 B(-s) B(s)`` (module notes); the set
    may hold a few extra frequencies where the two magnitudes come close without crossing.

    Parameters
    ----------
    G, B : control.StateSpace or tuple (A, B, C, D)
        SISO continuous-time systems without poles on the imaginary axis.
    gamma : float
        Level (> 0).

    Returns
    -------
    numpy.ndarray
    """
    if not (math.isfinite(gamma) and gamma > 0):
        raise ParameterError(f"crossing_frequencies: gamma must be finite and > 0; got {gamma!r}")
    return _crossings(_siso("G", G), _siso("B", B), float(gamma))


@dataclasses.dataclass(frozen=True)
class BoundRatio:
    """The worst ratio of a magnitude to its bound over a band.

    Parameters
    ----------
    value : float
        ``sup |G(jw)| / max_k |B_k(jw)|`` over the band, attained at ``frequency_hz`` (a
        lower bound of the supremum within ``rtol``; ``inf`` where a bound is 0 and ``G``
        is not).
    upper : float
        An upper bound of the supremum certified by the crossing test (``value (1 + rtol)``),
        or ``nan`` when the test was not run (``value`` already above the level asked for).
    frequency_hz : float
        Where ``value`` is attained, Hz (``inf`` for the limit at infinite frequency).
    """

    value: float
    upper: float
    frequency_hz: float

    @property
    def holds(self) -> bool:
        """Whether the bound holds at every frequency of the band (``upper <= 1``)."""
        return bool(self.upper <= 1.0)


@functools.lru_cache(maxsize=64)
def _prepared_by_key(name: str, key: tuple) -> tuple:
    mats = tuple(np.frombuffer(b, float).reshape(shape) for b, shape in key)
    abcd = _siso(name, mats)
    return abcd, _Response(abcd)


def _prepared(name: str, sys) -> tuple:
    """``(A, B, C, D)`` of a checked, balanced SISO system and its :class:`_Response`, made
    once for equal matrices given as a tuple (:func:`matrices_key`): a check evaluates one map
    against several bounds and bands, and every member against the same weights. A
    python-control system is checked as one each time."""
    if isinstance(sys, tuple) and len(sys) == 4:
        try:
            key = matrices_key(sys)
        except (TypeError, ValueError):
            key = None  # (checked below, where the error names the matrix)
        if key is not None:
            return _prepared_by_key(name, key)
    abcd = _siso(name, sys)
    return abcd, _Response(abcd)


class _Ratio:
    def __init__(self, g, bounds):
        self.g = g
        self.bs = list(bounds)

    def __call__(self, w) -> np.ndarray:
        w = np.asarray(w, float).reshape(-1)
        num = np.abs(self.g(w))
        den = np.max(np.vstack([np.abs(b(w)) for b in self.bs]), axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = num / den
        return np.where(num == 0.0, 0.0, r)


def _ratio_at_infinity(g, bounds) -> float:
    num = abs(g[3][0, 0])
    den = max(abs(b[3][0, 0]) for b in bounds)
    if num == 0.0:
        return 0.0
    return num / den if den > 0 else math.inf


def _refine(ratio, a, b, w0=None, *, points: int = 25, stages: int = 3):
    """Largest ratio on ``[a, b]`` by nested grids (``(value, w)``): each stage evaluates
    ``points`` frequencies at once (log-spaced where ``a > 0``) and narrows the bracket to the
    best one's neighbours, so the bracket shrinks about ``points / 2`` times a stage."""
    if not b > a:
        x = a if w0 is None else w0
        return float(ratio([x])[0]), float(x)
    best, wbest = -math.inf, math.nan
    for _ in range(stages):
        x = np.geomspace(a, b, points) if a > 0 else np.linspace(a, b, points)
        r = ratio(x)
        i = int(np.argmax(r))
        if r[i] > best:
            best, wbest = float(r[i]), float(x[i])
        a, b = x[max(i - 1, 0)], x[min(i + 1, points - 1)]
        if not b > a:
            break
    if 0 < i < points - 1 and a > 0:
        # the vertex of the parabola through the best point and its neighbours (in log w):
        # a smooth peak's maximum to the cube of the last stage's spacing
        u = np.log(x[i - 1 : i + 2])
        f = r[i - 1 : i + 2]
        den = (u[1] - u[0]) * (f[1] - f[2]) - (u[1] - u[2]) * (f[1] - f[0])
        if den != 0.0:
            num = (u[1] - u[0]) ** 2 * (f[1] - f[2]) - (u[1] - u[2]) ** 2 * (f[1] - f[0])
            v = u[1] - 0.5 * num / den
            if u[0] < v < u[2]:
                xv = float(np.exp(v))
                rv = float(ratio([xv])[0])
                if rv > best:
                    best, wbest = rv, xv
    return best, wbest


def bound_ratio(
    G,
    bounds,
    *,
    band_hz: tuple[float, float] = (0.0, math.inf),
    rtol: float = 1e-6,
    stop_above: float = math.inf,
    grid_hz=None,
) -> BoundRatio:
    """``sup |G(jw)| / max_k |B_k(jw)|`` over a band, confirmed at every frequency.

    The estimate of a logarithmic grid (refined at its local maxima) is confirmed by the
    exact crossing test of the module notes at ``gamma = value (1 + rtol)``; intervals that
    test finds violated are searched and the test repeated.

    Parameters
    ----------
    G : control.StateSpace or tuple (A, B, C, D)
        The SISO map, continuous-time, no poles on the imaginary axis.
    bounds : sequence of control.StateSpace or tuples
        The SISO bounds ``B_k`` (at least one; no poles on the imaginary axis; they need
        not be stable).
    band_hz : (float, float)
        The band, Hz, ``0 <= low < high <= inf``.
    rtol : float
        Relative accuracy of the supremum (in (0, 0.1]).
    stop_above : float
        When the grid's estimate already exceeds this level, return it without the exact
        test (``upper`` is then ``nan``): a bound found violated needs no certificate.
    grid_hz : array_like, optional
        Extra frequencies of the estimating grid, Hz (those of the band are used).

    Returns
    -------
    BoundRatio

    Raises
    ------
    robust.errors.ModelStructureError
        If a system is not SISO or not finite.
    robust.errors.ParameterError
        If ``band_hz``, ``rtol`` or ``bounds`` is out of range.
    """
    lo, hi = (float(x) for x in band_hz)
    if not (0.0 <= lo < hi) or math.isnan(hi):
        raise ParameterError(f"bound_ratio: band_hz must satisfy 0 <= low < high; got {band_hz!r}")
    if not (0.0 < rtol <= 0.1):
        raise ParameterError(f"bound_ratio: rtol must be in (0, 0.1]; got {rtol!r}")
    g, g_response = _prepared("G", G)
    prepared = [_prepared(f"bounds[{i}]", b) for i, b in enumerate(bounds)]
    if not prepared:
        raise ParameterError("bound_ratio: bounds must hold at least one system; got none")
    bs = [abcd for abcd, _ in prepared]
    ratio = _Ratio(g_response, [r for _, r in prepared])
    wlo, whi = 2 * math.pi * lo, 2 * math.pi * hi
    poles = np.concatenate([ratio.g.poles] + [b.poles for b in ratio.bs])
    mags = np.abs(poles[np.abs(poles) > 0])
    glo = wlo if wlo > 0 else (1e-3 * mags.min() if mags.size else 1e-3)
    ghi = whi if math.isfinite(whi) else (1e3 * mags.max() if mags.size else 1e3)
    glo = min(glo, ghi / 10) if wlo == 0 else glo
    w = np.geomspace(glo, ghi, N_GRID)
    extra = [np.abs(poles.imag)]
    if grid_hz is not None:
        extra.append(2 * math.pi * np.asarray(grid_hz, float))
    w = np.concatenate([[wlo], w] + extra + ([[whi]] if math.isfinite(whi) else []))
    w = np.unique(w[(w >= wlo) & (w <= whi)])
    r = ratio(w)
    best, wbest = -math.inf, math.nan
    # the highest local maxima, refined between their neighbours
    peaks = [
        i
        for i in range(len(w))
        if (i == 0 or r[i] >= r[i - 1]) and (i == len(w) - 1 or r[i] >= r[i + 1])
    ]
    for i in sorted(peaks, key=lambda i: -r[i])[:N_REFINED]:
        a, b = w[max(i - 1, 0)], w[min(i + 1, len(w) - 1)]
        v, x = _refine(ratio, a, b, w[i])
        if r[i] >= v:
            v, x = float(r[i]), float(w[i])
        if v > best:
            best, wbest = v, x
    if not math.isfinite(whi):
        vinf = _ratio_at_infinity(g, bs)
        if vinf > best:
            best, wbest = vinf, math.inf
    if best > stop_above or not math.isfinite(best):
        return BoundRatio(best, math.nan, wbest / (2 * math.pi))
    for _ in range(20):
        gamma = max(best, 1e-300) * (1.0 + rtol)
        pts = [wlo] + [x for b in bs for x in _crossings(g, b, gamma) if wlo < x < whi]
        pts = np.unique(np.asarray(pts))
        top = [pts[-1] * 2.0 + 1.0] if not math.isfinite(whi) else [whi]
        edges = np.concatenate([pts, top])
        mids = 0.5 * (edges[:-1] + edges[1:])
        rm = ratio(mids)
        bad = np.flatnonzero(rm > gamma)
        if not bad.size:
            return BoundRatio(best, gamma, wbest / (2 * math.pi))
        for j in bad:
            a, b = edges[j], edges[j + 1]
            v, x = _refine(ratio, a, b, mids[j])
            if rm[j] >= v:
                v, x = float(rm[j]), float(mids[j])
            if v > best:
                best, wbest = v, x
        if best > stop_above:
            return BoundRatio(best, math.nan, wbest / (2 * math.pi))
    return BoundRatio(best, math.nan, wbest / (2 * math.pi))
