"""Bounds of the structured singular value (mu) of a complex matrix.

``mu_Delta(M) = 1 / min{ sigma_max(Delta) : Delta in the structure, det(I - M Delta) = 0 }``
(0 when no such ``Delta`` exists). The structure is a block-diagonal ``Delta``; each block
is given as ``(size, kind)``:

* ``(r, "real")``: a repeated real scalar ``delta I_r`` (``delta`` real); the form a real
  parameter takes in a linear fractional transformation (LFT);
* ``(s, "complex")``: a full complex ``s x s`` block (unmodelled dynamics, a performance
  channel).

:func:`mussv` brackets ``mu`` between two numbers, each checked by an independent
computation before it is returned:

* **upper bound** (Fan, Tits & Doyle, IEEE TAC 36(1), 1991; Young, Newlin & Doyle, IJRNC
  1995): ``mu(M) <= beta`` when scalings ``D = D^H > 0`` and ``G = G^H`` commuting with the
  structure (``D`` a positive multiple of the identity on a full complex block, any
  Hermitian positive-definite matrix on a repeated real scalar; ``G`` zero on complex
  blocks, any Hermitian matrix on real ones) satisfy
  ``M^H D M + j (G M - M^H G) - beta^2 D <= 0``. For a fixed ``beta`` this is a linear
  matrix inequality in ``(D, G)``; ``beta`` is bisected, each LMI solved by Clarabel or,
  from :data:`CVXOPT_FROM_CHANNELS` channels, CVXOPT, and the bound returned is
  recomputed from the scalings found: the largest generalised eigenvalue of
  ``(M^H D M + j (G M - M^H G), D)``, exact for those scalings whatever the solver's
  tolerance. The LMI is solved for ``S M S^-1``, ``S`` a positive diagonal that commutes
  with the structure and balances the matrix (Osborne's iteration, :func:`_balance`), and
  its scalings are mapped back (``D = S D_1 S``, ``G = S G_1 S``): an LFT whose channels
  differ by decades (a family's loop, with gains from 1e-3 to 1e4) otherwise leaves the
  solver without a feasible point, and the bound at the largest singular value;
* **lower bound**: ``1 / sigma_max(Delta)`` of a ``Delta`` in the structure with
  ``det(I - M Delta) = 0``, found by the power iteration of Packard & Doyle (Automatica
  29(1), 1993) for the complex blocks and, with real blocks, a search over their signs
  and the complex blocks' common phase for a real eigenvalue of ``Q M`` (a simpler
  route than the mixed power iteration of Young & Doyle, CDC 1990; on seeded 3x3-4x4
  mixed cases within 0.85-0.99 of the upper bound). The ``Delta`` is returned, and the bound
  is the spectral radius of ``Q M`` checked with ``numpy.linalg.eigvals`` (an eigenvalue
  whose phase the real blocks can carry).
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import clarabel
import cvxopt
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from robust.errors import ParameterError, SolverError

__all__ = ["MuBounds", "mussv"]

#: Relative width at which the bisection of the upper bound stops.
BISECTION_RTOL = 1e-5
#: Largest ratio between two channel scales of the balancing (:func:`_balance`): a channel
#: that the others barely reach would otherwise be scaled without end.
BALANCE_RANGE = 1e8
#: Sweeps of the balancing's iteration.
BALANCE_SWEEPS = 30
#: Channels from which the scaling LMI goes to CVXOPT first (:func:`_scalings_feasible`):
#: where it overtakes Clarabel on one LMI of random 2 x 2 repeated real blocks
#: (``benchmarks/bench_mu.py`` prints both solvers' times from 8 to 30 channels).
CVXOPT_FROM_CHANNELS = 12


@dataclasses.dataclass(frozen=True)
class MuBounds:
    """Lower and upper bounds of the structured singular value.

    Parameters
    ----------
    lower, upper : float
        ``lower <= mu(M) <= upper``.
    delta : numpy.ndarray
        A structured perturbation with ``det(I - M delta) = 0`` and
        ``sigma_max(delta) = 1 / lower`` (zeros when ``lower`` is 0).
    D, G : numpy.ndarray
        The scalings that certify ``upper``.
    blocks : tuple of (int, str)
        The structure.
    """

    lower: float
    upper: float
    delta: np.ndarray
    D: np.ndarray
    G: np.ndarray
    blocks: tuple

    def to_json(self) -> dict:
        """``lower``, ``upper`` and the structure."""
        return {"lower": self.lower, "upper": self.upper, "blocks": [list(b) for b in self.blocks]}


def _check(M, blocks) -> tuple[np.ndarray, tuple]:
    where = "mussv"
    try:
        M = np.asarray(M, dtype=complex)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{where}: M must be a complex matrix; got {type(M).__name__}"
        ) from None
    if M.ndim != 2 or M.shape[0] != M.shape[1] or M.shape[0] == 0:
        raise ParameterError(f"{where}: M must be a square, non-empty matrix; got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ParameterError(f"{where}: M must be finite; got NaN or inf entries")
    out = []
    for i, b in enumerate(blocks):
        ok = isinstance(b, (tuple, list)) and len(b) == 2
        size, kind = (b[0], b[1]) if ok else (None, None)
        if (
            not ok
            or not isinstance(size, (int, np.integer))
            or size < 1
            or kind
            not in (
                "real",
                "complex",
            )
        ):
            raise ParameterError(
                f"{where}: blocks[{i}] must be (size >= 1, 'real' or 'complex'); got {b!r}"
            )
        out.append((int(size), str(kind)))
    n = sum(s for s, _ in out)
    if n != M.shape[0]:
        raise ParameterError(
            f"{where}: the block sizes must add up to M's size {M.shape[0]}; got {n} from {out}"
        )
    return M, tuple(out)


def _slices(blocks) -> list[slice]:
    out, k = [], 0
    for s, _ in blocks:
        out.append(slice(k, k + s))
        k += s
    return out


def _bound_from_scalings(M, D, G) -> float:
    """``sqrt`` of the largest eigenvalue of ``(M^H D M + j (G M - M^H G), D)``."""
    MH = M.conj().T
    A = MH @ D @ M + 1j * (G @ M - MH @ G)
    A = 0.5 * (A + A.conj().T)
    Dh = 0.5 * (D + D.conj().T)
    lam = sla.eigh(A, Dh, eigvals_only=True)
    return math.sqrt(max(float(lam[-1]), 0.0))


def _svec_index(n: int):
    """Rows, columns and weights of Clarabel's triangle vectorisation of an ``n x n``
    symmetric matrix (upper triangle by columns, off-diagonal entries times sqrt 2)."""
    r, c = np.tril_indices(n)
    w = np.where(r == c, 1.0, math.sqrt(2.0))
    return c, r, w


def _embed(H: np.ndarray) -> np.ndarray:
    """The real symmetric form ``[[Re H, -Im H], [Im H, Re H]]`` of a Hermitian matrix
    (negative semidefinite exactly when ``H`` is)."""
    return np.block([[H.real, -H.imag], [H.imag, H.real]])


def _hermitian_basis(s: int) -> list:
    """A real basis of the Hermitian ``s x s`` matrices."""
    out = []
    for i in range(s):
        E = np.zeros((s, s), complex)
        E[i, i] = 1.0
        out.append(E)
        for j in range(i + 1, s):
            E = np.zeros((s, s), complex)
            E[i, j] = E[j, i] = 1.0
            out.append(E)
            E = np.zeros((s, s), complex)
            E[i, j], E[j, i] = 1j, -1j
            out.append(E)
    return out


def _scalings_feasible(M, blocks, beta: float, g_max: float | None = None):
    """``(D, G)`` with ``M^H D M + j (G M - M^H G) - beta^2 D <= 0``, ``D >= I``; or None.

    A semidefinite programme (:func:`_scaling_problem`): minimise ``t`` subject to
    ``LMI <= t I``, ``D >= I`` and ``t >= -1``; the scalings are returned when ``t < 0``.
    It has few variables (a few per block) and one large matrix inequality, the shape for
    which an interior-point method that eliminates the matrix variable (the Schur
    complement of the variables, CVXOPT's ``sdp``: Vandenberghe, "The CVXOPT linear and
    quadratic cone program solvers", 2010) is fastest: on the family's loop (15 parameters,
    30 channels, the LMI 60 x 60 in real form) several times faster than Clarabel, which
    factors the whole cone's KKT system (``benchmarks/bench_mu.py``). Below
    :data:`CVXOPT_FROM_CHANNELS` channels Clarabel is the faster (CVXOPT's Python
    overhead), and it solves the problem wherever CVXOPT stops without an answer.
    Whatever the solver's accuracy, the bound used is recomputed from the scalings
    (:func:`_bound_from_scalings`).

    ``g_max`` bounds each real block's ``G`` by ``-g_max D <= G <= g_max D``: a smaller set
    of scalings, so still an upper bound, and one that varies continuously with ``M``
    where a real parameter's mu is a spike at one frequency (the bound over an interval of
    frequencies needs it, :mod:`uncertainty.mucover`).
    """
    n = M.shape[0]
    nv, d_parts, g_parts, psd, lin = _scaling_problem(M, blocks, beta, g_max)
    x = _solve_cvxopt(nv, psd, lin) if n >= CVXOPT_FROM_CHANNELS else None
    if x is None:
        x = _solve_clarabel(nv, psd, lin)
    if x is None or not x[-1] < 0:
        return None
    D = np.zeros((n, n), complex)
    G = np.zeros((n, n), complex)
    for v, sl, Bb in d_parts:
        D[sl, sl] += x[v] * Bb
    for v, sl, Bb in g_parts:
        G[sl, sl] += x[v] * Bb
    if np.linalg.eigvalsh(0.5 * (D + D.conj().T))[0] <= 0:
        return None
    return D, G


def _scaling_problem(M, blocks, beta: float, g_max: float | None):
    """The LMI of :func:`_scalings_feasible` as data both solvers read.

    Variables ``x``: the coefficients of ``D`` and ``G`` in a real basis of each block's
    scalings, then ``t``. Returns ``nv``, the ``D`` and ``G`` pieces ``(variable, slice,
    basis matrix)``, the matrix inequalities ``F_0 + sum_v x_v F_v >= 0`` as ``(F_0, F)``
    (``F`` of shape ``(m, m, nv)``, real symmetric: a Hermitian ``H <= 0`` exactly when
    its real form :func:`_embed` is) and the linear ones ``l_0 + r . x >= 0`` as
    ``(l_0, r)``; the objective is ``t``, the last variable.
    """
    n = M.shape[0]
    MH = M.conj().T
    lmi, d_parts, g_parts, d_cones = [], [], [], []
    k = 0
    for (size, kind), sl in zip(blocks, _slices(blocks)):
        basis = [np.eye(size, dtype=complex)] if kind == "complex" else _hermitian_basis(size)
        idx, g_idx = [], []
        for Bb in basis:
            E = np.zeros((n, n), complex)
            E[sl, sl] = Bb
            lmi.append(MH @ E @ M - beta**2 * E)
            d_parts.append((k, sl, Bb))
            idx.append(k)
            k += 1
        if kind == "real":
            for Bb in basis:
                E = np.zeros((n, n), complex)
                E[sl, sl] = Bb
                lmi.append(1j * (E @ M - MH @ E))
                g_parts.append((k, sl, Bb))
                g_idx.append(k)
                k += 1
        d_cones.append((size, kind, idx, basis, g_idx))
    nv = k + 1  # and t
    # t I - LMI >= 0
    F = np.zeros((2 * n, 2 * n, nv))
    for v, H in enumerate(lmi):
        F[:, :, v] = -_embed(0.5 * (H + H.conj().T))
    F[:, :, -1] = np.eye(2 * n)
    psd = [(np.zeros((2 * n, 2 * n)), F)]
    lin = []
    for size, kind, idx, basis, g_idx in d_cones:
        if kind == "complex":  # d >= 1
            r = np.zeros(nv)
            r[idx[0]] = 1.0
            lin.append((-1.0, r))
            continue
        m = 2 * size
        F = np.zeros((m, m, nv))  # D - I >= 0
        for v, Bb in zip(idx, basis):
            F[:, :, v] = _embed(Bb)
        psd.append((-np.eye(m), F))
        if g_max is not None:
            for sign in (-1.0, 1.0):  # g_max D + sign G >= 0
                F = np.zeros((m, m, nv))
                for v, Bb in zip(idx, basis):
                    F[:, :, v] = g_max * _embed(Bb)
                for v, Bb in zip(g_idx, basis):
                    F[:, :, v] = sign * _embed(Bb)
                psd.append((np.zeros((m, m)), F))
    r = np.zeros(nv)  # t >= -1
    r[-1] = 1.0
    lin.append((1.0, r))
    return nv, d_parts, g_parts, psd, lin


def _solve_cvxopt(nv: int, psd, lin):
    """``x`` minimising ``t`` by CVXOPT's ``sdp`` (``G x + s = h``), or None where it
    stops short of the optimum (then Clarabel solves the problem: an optimum with
    ``t >= 0`` is an answer, the LMI infeasible at this ``beta``)."""
    c = np.zeros(nv)
    c[-1] = 1.0
    Gs = [cvxopt.matrix(-F.reshape(-1, nv, order="F")) for _, F in psd]
    hs = [cvxopt.matrix(F0) for F0, _ in psd]
    Gl = cvxopt.matrix(-np.array([r for _, r in lin]))
    hl = cvxopt.matrix(np.array([l0 for l0, _ in lin], float))
    try:
        sol = cvxopt.solvers.sdp(
            cvxopt.matrix(c), Gl=Gl, hl=hl, Gs=Gs, hs=hs, options={"show_progress": False}
        )
    except (ArithmeticError, ValueError):
        return None
    if sol["status"] != "optimal" or sol["x"] is None:
        return None
    x = np.asarray(sol["x"], float).ravel()
    return x if np.all(np.isfinite(x)) else None


def _solve_clarabel(nv: int, psd, lin):
    """``x`` minimising ``t`` by Clarabel (``A x + s = b``, the triangle vectorisation of
    each matrix cone), or None."""
    rows_A, b_parts, cones = [], [], []
    for F0, F in psd:
        ci, ri, wi = _svec_index(F0.shape[0])
        rows_A.append(-F[ci, ri, :] * wi[:, None])
        b_parts.append(F0[ci, ri] * wi)
        cones.append(clarabel.PSDTriangleConeT(F0.shape[0]))
    for l0, r in lin:
        rows_A.append(-r[None, :])
        b_parts.append(np.array([l0]))
        cones.append(clarabel.NonnegativeConeT(1))
    q = np.zeros(nv)
    q[-1] = 1.0
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    A = sp.csc_matrix(np.vstack(rows_A))
    b = np.concatenate(b_parts)
    sol = clarabel.DefaultSolver(sp.csc_matrix((nv, nv)), q, A, b, cones, settings).solve()
    if str(sol.status) not in ("Solved", "AlmostSolved"):
        return None
    return np.asarray(sol.x)


def _balance(M, blocks) -> np.ndarray:
    """Positive channel scales ``s``, equal on each full complex block, that balance
    ``S M S^-1`` (``S = diag(s)``).

    Osborne's iteration ("On pre-conditioning of matrices", J. ACM 7(4), 1960) on ``|M|``
    with the structure's groups (each channel of a repeated real scalar on its own: any
    positive-definite ``D`` commutes with ``delta I``; a full complex block as one group):
    each group's scale moves to the geometric mean of its off-diagonal column and row norms,
    for :data:`BALANCE_SWEEPS` sweeps, the scales kept within :data:`BALANCE_RANGE`. ``S^2``
    is itself a D scaling, so ``sigma_max(S M S^-1)`` bounds mu (Packard & Doyle,
    Automatica 29(1), 1993, sec. 9), and the LMI on the balanced matrix is well scaled.
    """
    n = M.shape[0]
    groups = []
    for (_, kind), sl in zip(blocks, _slices(blocks)):
        idx = np.arange(sl.start, sl.stop)
        groups += [idx] if kind == "complex" else [idx[i : i + 1] for i in range(idx.size)]
    if len(groups) < 2:
        return np.ones(n)
    A = np.abs(M)
    logs = np.zeros(n)
    for _ in range(BALANCE_SWEEPS):
        for g in groups:
            out = np.ones(n, bool)
            out[g] = False
            r = np.linalg.norm(A[np.ix_(g, out)])
            c = np.linalg.norm(A[np.ix_(out, g)])
            if r > 0 and c > 0:
                f = math.sqrt(c / r)
                A[g, :] *= f
                A[:, g] /= f
                logs[g] += math.log(f)
    half = 0.5 * math.log(BALANCE_RANGE)
    return np.exp(np.clip(logs - np.median(logs), -half, half))


def _upper(M, blocks, lo: float, rtol: float = BISECTION_RTOL, g_max: float | None = None):
    """Bisection of the D-G bound between ``lo`` and ``sigma_max(S M S^-1)``, to ``rtol``.

    ``S`` balances ``M`` (:func:`_balance`); the LMI is solved for the balanced matrix and
    its scalings are returned for ``M`` (``S D_1 S``, ``S G_1 S``). The bound kept is always
    one recomputed from scalings (:func:`_bound_from_scalings`); the bisection only steers
    which ``beta`` the LMI is asked for.
    """
    s = _balance(M, blocks)
    b, D1, G1 = _upper_balanced((s[:, None] * M) / s[None, :], blocks, lo, rtol, g_max)
    return b, s[:, None] * D1 * s[None, :], s[:, None] * G1 * s[None, :]


def _upper_balanced(M, blocks, lo: float, rtol: float, g_max: float | None):
    """:func:`_upper` of a matrix as it is (the scalings for ``M`` itself)."""
    n = M.shape[0]
    hi = float(np.linalg.norm(M, 2))
    best = (hi, np.eye(n, dtype=complex), np.zeros((n, n), complex))
    if hi == 0.0:
        return best
    lo = min(max(lo, 0.0), hi)
    floor = 1e-9 * hi  # below it, mu is reported as this small bound (e.g. mu = 0)
    while hi - lo > rtol * best[0] and hi > floor:
        mid = 0.5 * (lo + hi)
        found = _scalings_feasible(M, blocks, mid, g_max)
        if found is None:
            lo = mid
            continue
        bound = _bound_from_scalings(M, *found)
        hi = min(mid, bound)
        if bound < best[0]:
            best = (bound, *found)
    return best


def _structured(blocks, parts) -> np.ndarray:
    n = sum(s for s, _ in blocks)
    Q = np.zeros((n, n), complex)
    for sl, P in zip(_slices(blocks), parts):
        Q[sl, sl] = P
    return Q


def _verified_lower(M, blocks, Q) -> tuple[float, complex]:
    """The largest ``|lambda|`` of ``Q M`` that ``Q / lambda`` keeps in the structure.

    ``det(I - M Q / lambda) = 0`` for an eigenvalue ``lambda`` of ``Q M`` (that of
    ``M Q``); returns ``(|lambda|, lambda)``, ``(0, 0)`` without one.
    """
    lam = np.linalg.eigvals(Q @ M)
    # Delta = Q / lambda: the complex blocks take any phase; the real blocks need a real
    # lambda (unless Q is zero on them)
    real_used = any(
        kind == "real" and np.any(Q[sl, sl] != 0) for (_, kind), sl in zip(blocks, _slices(blocks))
    )
    best = (0.0, 0j)
    for v in lam:
        a = abs(v)
        if a > best[0] and not (real_used and abs(v.imag) > 1e-9 * a):
            best = (a, complex(v.real, 0.0) if real_used else complex(v))
    return best


def _rescaled(v, ref, idx, sls) -> np.ndarray:
    """Per complex block ``i`` in ``idx``: ``v_i`` scaled to the norm of ``ref_i`` (else 0)."""
    out = np.zeros_like(v)
    for i in idx:
        vi, ri = v[sls[i]], ref[sls[i]]
        out[sls[i]] = np.linalg.norm(ri) / max(np.linalg.norm(vi), 1e-300) * vi
    return out


def _power_iteration(M, blocks, rng, iterations: int = 200):
    """Packard-Doyle power iteration on the complex blocks (real blocks held at zero)."""
    n = M.shape[0]
    sls = _slices(blocks)
    cplx = [i for i, (_, k) in enumerate(blocks) if k == "complex"]
    a = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    w = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    for i, (_, k) in enumerate(blocks):
        if k == "real":
            a[sls[i]] = 0
    a /= np.linalg.norm(a) or 1.0
    w /= np.linalg.norm(w) or 1.0
    MH = M.conj().T
    for _ in range(iterations):
        b = M @ a
        nb = np.linalg.norm(b)
        if nb == 0:
            break
        b /= nb
        w = MH @ _rescaled(b, w, cplx, sls)
        nw = np.linalg.norm(w)
        if nw == 0:
            break
        w /= nw
        a_new = _rescaled(w, b, cplx, sls)
        na = np.linalg.norm(a_new)
        if na == 0:
            break
        a = a_new / na
    b = M @ a
    parts = []
    for i, (s, k) in enumerate(blocks):
        if k == "real":
            parts.append(np.zeros((s, s)))
            continue
        ai, bi = a[sls[i]], b[sls[i]]
        na, nb = np.linalg.norm(ai), np.linalg.norm(bi)
        parts.append(np.outer(ai, bi.conj()) / (na * nb) if na > 0 and nb > 0 else np.zeros((s, s)))
    return parts


def _phase_roots(M, blocks, q, parts, grid: int = 180):
    """Phases ``theta`` at which ``Q(theta) M`` has a real eigenvalue, and that ``Q``.

    ``Q(theta)`` holds the real blocks at ``q`` and the complex ones at
    ``exp(j theta)`` times ``parts``; an eigenvalue's imaginary part is followed along a
    grid of phases (nearest neighbours) and each sign change refined by bisection.
    """
    reals = [i for i, (_, k) in enumerate(blocks) if k == "real"]

    def Q_at(theta):
        p = [
            (q[reals.index(i)] * np.eye(s)) if k == "real" else parts[i] * np.exp(1j * theta)
            for i, (s, k) in enumerate(blocks)
        ]
        return _structured(blocks, p)

    thetas = np.linspace(0.0, 2 * math.pi, grid + 1)
    lams = [np.linalg.eigvals(Q_at(t) @ M) for t in thetas]
    out = []
    for j in range(grid):
        a, b = lams[j], lams[j + 1]
        for v in a:
            w = b[np.argmin(np.abs(b - v))]
            if v.imag == 0.0 or np.sign(v.imag) != np.sign(w.imag):
                lo, hi, vlo = thetas[j], thetas[j + 1], v
                for _ in range(60):
                    mid = 0.5 * (lo + hi)
                    ev = np.linalg.eigvals(Q_at(mid) @ M)
                    vm = ev[np.argmin(np.abs(ev - vlo))]
                    if np.sign(vm.imag) == np.sign(vlo.imag):
                        lo, vlo = mid, vm
                    else:
                        hi = mid
                out.append(Q_at(0.5 * (lo + hi)))
    return out


def _lower(M, blocks, seed: int, restarts: int):
    """The best verified lower bound of power iterations and a sign/phase search.

    With real and complex blocks, the real ones at sign patterns (all of them up to 16,
    random ones beyond) and the complex ones at the power iteration's directions rotated
    by a common phase: a phase where ``Q M`` has a real eigenvalue gives a perturbation
    in the structure (:func:`_phase_roots`).
    """
    rng = np.random.default_rng(seed)
    best_val, best_Q, best_lam = 0.0, np.zeros_like(M), 0j
    reals = [i for i, (_, k) in enumerate(blocks) if k == "real"]
    mixed = bool(reals) and len(reals) < len(blocks)
    if len(reals) <= 4:
        patterns = [np.array(p, float) for p in itertools.product((-1.0, 1.0), repeat=len(reals))]
    else:
        patterns = [rng.choice([-1.0, 1.0], size=len(reals)) for _ in range(16)]
    for r in range(restarts):
        parts = _power_iteration(M, blocks, rng)
        candidates = [_structured(blocks, parts)]
        if reals and not mixed:
            candidates += [
                _structured(
                    blocks, [q[reals.index(i)] * np.eye(s) for i, (s, _) in enumerate(blocks)]
                )
                for q in patterns
            ]
        if mixed and r < 2:  # the phase search from the first two starts
            for q in patterns:
                candidates += _phase_roots(M, blocks, q, parts)
        for Q in candidates:
            v, lam = _verified_lower(M, blocks, Q)
            if v > best_val:
                best_val, best_Q, best_lam = v, Q, lam
    return best_val, best_Q, best_lam


def mussv(M, blocks, *, seed: int = 0, restarts: int = 8) -> MuBounds:
    """Lower and upper bounds of the structured singular value of ``M``.

    Parameters
    ----------
    M : array_like, shape (n, n)
        A complex matrix (for example ``M(j omega)`` of an LFT).
    blocks : sequence of (int, str)
        The structure, in ``M``'s order: ``(r, "real")`` a repeated real scalar
        ``delta I_r``, ``(s, "complex")`` a full complex ``s x s`` block; the sizes add up
        to ``n``.
    seed : int
        Seed of the lower bound's random starts.
    restarts : int
        Random starts of the power iteration.

    Returns
    -------
    MuBounds
        ``lower <= mu <= upper``, the perturbation behind ``lower`` and the scalings behind
        ``upper`` (module notes).

    Raises
    ------
    robust.errors.ParameterError
        If ``M`` is not a finite square matrix or ``blocks`` does not describe it.

    Examples
    --------
    A full complex block: mu is the largest singular value.

    >>> import numpy as np
    >>> from uncertainty import mussv
    >>> M = np.array([[1.0, 2.0], [0.0, 1.0]])
    >>> b = mussv(M, [(2, "complex")])
    >>> round(b.lower, 4), round(b.upper, 4)
    (2.4142, 2.4142)
    """
    M, blocks = _check(M, blocks)
    if not isinstance(restarts, int) or restarts < 1:
        raise ParameterError(f"mussv: restarts must be an integer >= 1; got {restarts!r}")
    lower, Q, lam = _lower(M, blocks, seed, restarts)
    upper, D, G = _upper(M, blocks, lower)
    if lower > upper * (1 + 1e-9):  # pragma: no cover - both are verified; a bug if met
        raise SolverError(f"mussv: lower bound {lower} above upper bound {upper}")
    delta = Q / lam if lower > 0 else np.zeros_like(M)
    return MuBounds(
        lower=float(lower), upper=float(max(upper, lower)), delta=delta, D=D, G=G, blocks=blocks
    )
