"""H-infinity and H2 norms of continuous-time LTI systems.

:func:`h2_norm` is the H2 norm from the controllability Gramian (the workbench's one
Lyapunov solver, :func:`robust.analysis.lyapunov.lyapunov`). The H-infinity norm has two
independent algorithms:

* :func:`hinf_norm` with ``method="bb"`` (default): the Hamiltonian-eigenvalue
  two-step iteration of Bruinsma & Steinbuch, "A fast algorithm to compute the
  H-infinity-norm of a transfer function matrix", Systems & Control Letters
  14 (1990) 287-293, which refines the bisection of Boyd, Balakrishnan &
  Kabamba, "A bisection method for computing the H-infinity norm of a transfer
  matrix and related problems", Math. Control Signals Systems 2 (1989) 207-219.
  Quadratically convergent; the returned value is an upper bound within
  ``rtol`` of the norm, except that near a very flat peak the imaginary-axis
  eigenvalues of the Hamiltonian are ill-conditioned and the iteration may stop
  up to about 1e-7 (relative) below the peak.  When the supremum is attributed
  to infinite frequency the result is cross-checked against the grid method.
* ``method="grid"``: a dense logarithmic frequency grid followed by a bounded
  scalar refinement of every local peak.  It never forms a Hamiltonian, so it
  is an independent check of ``"bb"``; it is a lower bound.
* ``method="slicot"``: python-control's :func:`control.norm`, which calls
  SLICOT ``ab13dd`` when slycot is installed.

Every method first checks stability: an unstable system has norm ``inf``.
Every method then rescales the states by powers of 2 so that the
system matrix ``[[A, B], [C, 0]]`` is balanced (exact, the transfer function is
unchanged): interconnections of blocks whose states carry scales over many
decades otherwise make the Hamiltonian's imaginary-axis eigenvalues too
inaccurate to be found.  The ``"bb"`` start grid's highest local maxima are
refined before the first Hamiltonian test.
"""

from __future__ import annotations

import itertools
import math

import numba
import numpy as np
import scipy.linalg as sla
import scipy.optimize as sopt

from robust.analysis.lyapunov import lyapunov
from robust.analysis.stability import stability_bound
from robust.checks import Spec, check_scalar, check_state_space, check_vector
from robust.errors import ModelStructureError, ParameterError

__all__ = ["h2_norm", "hinf_norm", "is_stable", "sigma_max", "spectral_abscissa"]

#: number of local maxima of the Bruinsma-Steinbuch start grid refined before the first
#: Hamiltonian test
N_REFINE = 5
_RTOL = Spec(low=0.0, high=0.1, low_open=True)


def _abcd(sys):
    A, B, C, D = check_state_space("sys", sys)
    isctime = getattr(sys, "isctime", None)
    if not callable(isctime):
        raise ModelStructureError(
            f"sys must be a control.StateSpace (with isctime()); got {type(sys).__name__}"
        )
    if not isctime():
        raise ModelStructureError(f"sys must be continuous-time (dt=0); got dt={sys.dt}")
    return A, B, C, D


def spectral_abscissa(sys) -> float:
    """Largest real part of the poles (eigenvalues of A), in rad/s.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous-time system (anything with ``A, B, C, D`` and ``isctime()``).

    Returns
    -------
    float
        ``max Re(eig(A))`` in rad/s; ``-inf`` for a static gain (no states).

    Raises
    ------
    ModelStructureError
        If ``sys`` is not a continuous-time state-space system with finite, conformal
        matrices (the message names the matrix).
    """
    A = _abcd(sys)[0]
    if A.shape[0] == 0:
        return -np.inf
    return float(np.max(np.linalg.eigvals(A).real))


def is_stable(sys, *, margin: float = 0.0) -> bool:
    """Whether every pole has real part below ``-margin`` (rad/s).

    The definition of :mod:`robust.analysis.stability`: with ``margin=0`` a pole is
    stable when its real part is below ``-STABILITY_TOL``.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous-time system; a static gain is stable.
    margin : float, optional
        Required decay rate, rad/s (0, the default: plain stability).

    Returns
    -------
    bool
        True when :func:`spectral_abscissa` is below ``-max(margin, STABILITY_TOL)``
        (:func:`robust.analysis.stability.stability_bound`).

    Raises
    ------
    ModelStructureError
        If ``sys`` is not a continuous-time state-space system.
    """
    return spectral_abscissa(sys) < stability_bound(margin)


def h2_norm(sys, B=None, C=None, D=None) -> float:
    """H2 norm of a continuous-time system from its controllability Gramian.

    ``sqrt(trace(C W C'))`` with ``A W + W A' + B B' = 0``: the root-mean-square output
    under unit white noise at every input (the sum of the outputs' variances).

    Parameters
    ----------
    sys : control.StateSpace or numpy.ndarray
        A continuous-time system, or its state matrix ``A`` (n, n) with ``B``, ``C`` (and
        optionally ``D``) given as well (the form of the hot paths, without a system).
    B, C : numpy.ndarray, optional
        Input (n, m) and output (p, n) matrices, with ``A``.
    D : numpy.ndarray, optional
        Feedthrough (p, m), with ``A`` (default: zero).

    Returns
    -------
    float
        The norm; ``inf`` if a pole has real part ``>= 0`` (not Hurwitz) or the
        feedthrough is nonzero (white noise passed straight through has infinite power);
        0 for a system without states and without feedthrough.

    Raises
    ------
    ModelStructureError
        If ``sys`` is not a continuous-time state-space system, or ``B``, ``C`` are
        missing with a matrix ``sys``.
    """
    if B is None and C is None and D is None:
        A, B, C, D = _abcd(sys)
    elif B is None or C is None:
        raise ModelStructureError(
            "h2_norm: give a control.StateSpace, or its matrices A, B and C (D optional)"
        )
    else:
        A, B, C = (np.asarray(M, float) for M in (sys, B, C))
    if D is not None and np.any(np.asarray(D) != 0):
        return math.inf
    if A.shape[0] == 0:
        return 0.0
    if np.linalg.eigvals(A).real.max() >= 0:
        return math.inf
    W = lyapunov(A, -B @ B.T)
    return math.sqrt(max(float(np.trace(C @ W @ C.T)), 0.0))


def sigma_max(sys, omega) -> np.ndarray:
    """Largest singular value of ``G(j*omega)`` for each frequency in ``omega``.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous-time system (any object with ``A, B, C, D`` and ``isctime()``).
        Stability is not required.
    omega : float or array_like
        Frequencies in rad/s, scalar or shape (F,).

    Returns
    -------
    numpy.ndarray
        ``sigma_max(G(j omega))``, shape (F,) (shape (1,) for a scalar), in the
        system's output units per input unit.

    Raises
    ------
    ModelStructureError
        If ``sys`` is not a continuous-time state-space system with finite, conformal
        matrices (the message names the matrix).
    ParameterError
        If ``omega`` is not a finite scalar or 1-D array.
    """
    A, B, C, D = _abcd(sys)
    omega = check_vector("sigma_max: omega", omega, min_size=0)
    return _Sigma(A, B, C, D)(omega)


class _Sigma:
    """:func:`sigma_max` of one (checked) system, at any frequencies: the Hessenberg form is
    made once. The H-infinity iteration evaluates one system at hundreds of single
    frequencies (its scalar searches), where making the form and checking the system again
    took half of each evaluation; the numbers are those of :func:`sigma_max`.

    Parameters
    ----------
    A, B, C, D : numpy.ndarray
        Finite, conformal matrices (not checked).
    """

    def __init__(self, A, B, C, D):
        self.D = D
        self.n = n = A.shape[0]
        if n:
            # Hessenberg form makes each resolvent solve cheaper and better conditioned.
            self.H, Q = sla.hessenberg(A, calc_q=True)
            self.Bq, self.Cq = Q.T @ B, C @ Q
            self.eye = np.eye(n)
            self.Bc = self.Bq.astype(complex)

    def __call__(self, omega) -> np.ndarray:
        omega = np.asarray(omega, dtype=float).reshape(-1)
        D = self.D
        out = np.empty(omega.shape)
        if self.n == 0:
            out[:] = np.linalg.norm(D, 2) if D.size else 0.0
            return out
        H, Cq, eye = self.H, self.Cq, self.eye
        if min(D.shape) == 0:
            for i, w in enumerate(omega):
                out[i] = np.linalg.norm(D + Cq @ np.linalg.solve(1j * w * eye - H, self.Bq), 2)
            return out
        # the frequencies in stacks: LAPACK solves and decomposes each matrix of a stack as
        # it does a single one, so the numbers are those of one frequency at a time
        Bc = self.Bc
        for a in range(0, omega.size, _SIGMA_STACK):
            w = omega[a : a + _SIGMA_STACK]
            X = np.linalg.solve(
                1j * w[:, None, None] * eye - H, np.broadcast_to(Bc, (w.size, *Bc.shape))
            )
            out[a : a + w.size] = np.linalg.svd(D + Cq @ X, compute_uv=False)[:, 0]
        return out


#: Frequencies per stack of :func:`sigma_max` (bounds the stack's memory).
_SIGMA_STACK = 256


def hinf_norm(sys, *, method: str = "bb", rtol: float = 1e-9, return_frequency: bool = False):
    """H-infinity norm of a continuous-time state-space system.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous-time system, any number of inputs and outputs.
    method : {"bb", "grid", "slicot"}
        ``"bb"``: Bruinsma-Steinbuch Hamiltonian iteration (upper bound within
        ``rtol``); ``"grid"``: frequency grid plus peak refinement (lower bound);
        ``"slicot"``: :func:`control.norm` (SLICOT ``ab13dd``).
    rtol : float
        Relative tolerance of the ``"bb"`` iteration, in (0, 0.1].
    return_frequency : bool
        Also return the peak frequency in rad/s (``nan`` for ``"slicot"`` or an
        unstable system; ``inf`` when the supremum is reached at infinite frequency).

    Returns
    -------
    float or (float, float)
        The norm (``inf`` if ``sys`` is unstable), and the peak frequency if asked.

    Raises
    ------
    ModelStructureError
        If ``sys`` is not a continuous-time state-space system, or a matrix contains
        NaN or inf or the shapes do not fit (the message names the matrix).
    ParameterError
        If ``method`` or ``rtol`` is invalid.
    """
    if method not in ("bb", "grid", "slicot"):
        raise ParameterError(f"method must be 'bb', 'grid' or 'slicot'; got {method!r}")
    rtol = check_scalar("hinf_norm: rtol", rtol, _RTOL)
    A, B, C, D = _abcd(sys)
    if A.shape[0] and not is_stable(sys):
        return (np.inf, np.nan) if return_frequency else np.inf
    if A.shape[0] == 0 or B.shape[1] == 0 or C.shape[0] == 0:
        val = float(np.linalg.norm(D, 2)) if D.size else 0.0
        return (val, np.inf) if return_frequency else val
    # exact (power-of-2) diagonal state scaling: the transfer function is unchanged, and
    # the Hamiltonian and the resolvents are far better conditioned for interconnections
    # whose blocks carry state scales over many decades
    A, B, C = _balance_states(A, B, C)
    if method == "slicot":
        import control

        val = float(control.norm(control.ss(A, B, C, D), "inf"))
        return (val, np.nan) if return_frequency else val
    bal = _Sigma(A, B, C, D)
    if method == "grid":
        val, w = _grid_norm(A, B, C, D, bal)
    else:
        val, w = _bb_norm(A, B, C, D, bal, rtol)
    return (val, w) if return_frequency else val


def _balance_states(A, B, C, *, max_sweeps: int = 50):
    """Diagonal state scaling by powers of 2 balancing the system matrix ``[[A, B], [C, 0]]``.

    Only the states are scaled (inputs and outputs are not), so the transfer
    function is unchanged and, the factors being powers of 2, no rounding is
    introduced.  Osborne's iteration (E.E. Osborne, "On pre-conditioning of
    matrices", J. ACM 7 (1960) 338-345) on the rows and columns of the system
    matrix, as in SLICOT TB01ID: state i is scaled so that the norm of
    column i of ``[A; C]`` and of row i of ``[A, B]`` (off-diagonal parts)
    become about equal (:func:`_osborne`, compiled).
    """
    n = A.shape[0]
    if n == 0:
        return A, B, C
    A, B, C = (np.array(M, float, order="C") for M in (A, B, C))
    _osborne(A, B, C, max_sweeps)
    return A, B, C


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _osborne(A, B, C, max_sweeps):  # pragma: no cover - compiled
    """Osborne's sweeps of :func:`_balance_states`, in place. The exponents are the only
    decisions: the norms are summed in a fixed order, and a different order could change an
    exponent only where ``0.5 log2(r / c)`` lies within rounding of a half-integer."""
    n = A.shape[0]
    for _ in range(max_sweeps):
        changed = False
        for i in range(n):
            col, row = 0.0, 0.0
            for k in range(n):
                if k != i:
                    col += A[k, i] * A[k, i]
                    row += A[i, k] * A[i, k]
            out, inp = 0.0, 0.0
            for k in range(C.shape[0]):
                out += C[k, i] * C[k, i]
            for k in range(B.shape[1]):
                inp += B[i, k] * B[i, k]
            c = math.hypot(math.sqrt(col), math.sqrt(out))
            r = math.hypot(math.sqrt(row), math.sqrt(inp))
            if c == 0.0 or r == 0.0:
                continue
            e = int(np.round(0.5 * np.log2(r / c)))
            if e == 0:
                continue
            f = 2.0**e
            for k in range(n):
                A[k, i] *= f
            for k in range(C.shape[0]):
                C[k, i] *= f
            for k in range(n):
                A[i, k] /= f
            for k in range(B.shape[1]):
                B[i, k] /= f
            changed = True
        if not changed:
            break


def _candidate_frequencies(A):
    lam = np.linalg.eigvals(A)
    absl = np.abs(lam)
    w = [0.0]
    if np.any(absl > 0):
        # Bruinsma-Steinbuch (1990) Sec. 3: the pole with the largest |Im/Re|/|lambda| ratio
        re = np.where(lam.real == 0.0, -1e-300, lam.real)
        ratio = np.abs(lam.imag / re) / np.maximum(absl, 1e-300)
        w.append(float(absl[np.argmax(ratio)]))
        w.extend(float(abs(x.imag)) for x in lam if abs(x.imag) > 0)
    return np.unique(np.asarray(w))


def _bb_norm(A, B, C, D, sigma, rtol):
    val, w = _bb_iteration(A, B, C, D, sigma, rtol)
    if np.isinf(w):
        # The supremum was attributed to infinite frequency: the Hamiltonian was then built
        # with gamma close to sigma_max(D), where D'D - gamma^2 I is nearly singular and an
        # imaginary-axis crossing can be lost to rounding.  Cross-check with a dense grid and
        # restart from its peak if it is higher.
        gval, gw = _grid_norm(A, B, C, D, sigma)
        if gval > val and np.isfinite(gw):
            val, w = _bb_iteration(A, B, C, D, sigma, rtol, start=(gval, gw))
    return val, w


def _refined_peak(sigma, w, s, *, limit: int | None = None):
    """Largest ``sigma_max`` over the local maxima of a frequency grid, each refined.

    Every local maximum ``i`` of ``s`` on the grid ``w`` (the ``limit`` highest if
    given) is refined by a bounded scalar search between its neighbours; the
    refined value is kept only where it beats the grid value. Returns
    ``(value, frequency)``, ``(-inf, nan)`` for an empty grid.
    """
    peaks = [
        i
        for i in range(len(w))
        if (i == 0 or s[i] >= s[i - 1]) and (i == len(w) - 1 or s[i] >= s[i + 1])
    ]
    peaks = sorted(peaks, key=lambda i: -s[i])[:limit]
    best, wbest = -np.inf, np.nan
    for i in peaks:
        cand, wc = float(s[i]), float(w[i])
        a, b = w[max(i - 1, 0)], w[min(i + 1, len(w) - 1)]
        if b > a:
            res = sopt.minimize_scalar(
                lambda x: -sigma([x])[0],
                bounds=(a, b),
                method="bounded",
                options={"xatol": 1e-10 * max(b, 1e-12)},
            )
            if -res.fun > cand:
                cand, wc = -float(res.fun), float(res.x)
        if cand > best:
            best, wbest = cand, wc
    return best, wbest


def _bb_iteration(A, B, C, D, sigma, rtol, start=None):
    """Bruinsma-Steinbuch (1990) two-step iteration; returns (upper bound, peak frequency)."""
    lam = np.abs(np.linalg.eigvals(A))
    lam = lam[lam > 0]
    coarse = np.geomspace(1e-2 * lam.min(), 1e2 * lam.max(), 200) if lam.size else np.zeros(0)
    wc = np.concatenate([_candidate_frequencies(A), coarse])
    order = np.argsort(wc)
    wc = wc[order]
    vals = sigma(wc)
    i = int(np.argmax(vals))
    glb, wpk = float(vals[i]), float(wc[i])
    # refine the highest local maxima of the start grid: an estimate close to the peak makes
    # the first Hamiltonian test decisive, where its imaginary-axis eigenvalues are least accurate
    pk, wk = _refined_peak(sigma, wc, vals, limit=N_REFINE)
    if pk > glb:
        glb, wpk = pk, wk
    if start is not None and start[0] > glb:
        glb, wpk = start
    sd = float(np.linalg.norm(D, 2))
    if sd > glb:
        glb, wpk = sd, np.inf
    if glb == 0.0:
        return 0.0, 0.0
    scale = max(1.0, float(lam.max()) if lam.size else 1.0)
    for _ in range(100):
        g = (1.0 + 2.0 * rtol) * glb
        imag = _imaginary_eigenvalues(A, B, C, D, g, scale)
        if imag.size == 0:
            return g, wpk
        mids = imag if imag.size == 1 else 0.5 * (imag[:-1] + imag[1:])
        sv = sigma(mids)
        j = int(np.argmax(sv))
        if sv[j] <= glb * (1.0 + rtol):
            # midpoints do not improve: maximise inside each interval between crossings
            best, wbest = _refine_intervals(sigma, imag)
            if best <= glb * (1.0 + rtol):
                return g, wpk
            glb, wpk = best, wbest
            continue
        glb, wpk = float(sv[j]), float(mids[j])
    return (1.0 + 2.0 * rtol) * glb, wpk


def _imaginary_eigenvalues(A, B, C, D, g, scale):
    """Nonnegative imaginary parts of the (numerically) imaginary eigenvalues of H(g).

    ``H(g)`` is the Hamiltonian of the Bruinsma-Steinbuch iteration at level ``g``.
    """
    R = D.T @ D - g * g * np.eye(D.shape[1])
    S = D @ D.T - g * g * np.eye(D.shape[0])
    Ri_DtC = np.linalg.solve(R, D.T @ C)
    Ri_Bt = np.linalg.solve(R, B.T)
    H = np.block(
        [
            [A - B @ Ri_DtC, -g * B @ Ri_Bt],
            [g * C.T @ np.linalg.solve(S, C), -A.T + C.T @ D @ Ri_Bt],
        ]
    )
    ev = np.linalg.eigvals(H)
    tol = 1e-7 * scale
    sel = (np.abs(ev.real) < tol + 1e-7 * np.abs(ev)) & (ev.imag >= 0)
    return np.sort(np.unique(np.round(ev[sel].imag, 12)))


def _refine_intervals(sigma, imag):
    pts = np.concatenate([[0.0], imag, [2.0 * imag[-1] + 1.0]])
    best, wbest = -np.inf, np.nan
    for a, b in itertools.pairwise(pts):
        if b <= a:
            continue
        res = sopt.minimize_scalar(
            lambda x: -sigma([x])[0],
            bounds=(a, b),
            method="bounded",
            options={"xatol": 1e-10 * b},
        )
        if -res.fun > best:
            best, wbest = -float(res.fun), float(res.x)
    return best, wbest


def _grid_norm(A, B, C, D, sigma, n_points: int = 2000):
    lam = np.abs(np.linalg.eigvals(A))
    lam = lam[lam > 0]
    lo = 1e-3 * (lam.min() if lam.size else 1.0)
    hi = 1e3 * (lam.max() if lam.size else 1.0)
    w = np.concatenate([[0.0], np.geomspace(lo, hi, n_points)])
    s = sigma(w)
    best, wbest = float(np.linalg.norm(D, 2)), np.inf
    pk, wk = _refined_peak(sigma, w, s)
    if pk > best:
        best, wbest = pk, wk
    return best, wbest
