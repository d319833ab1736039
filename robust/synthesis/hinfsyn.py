"""H-infinity output-feedback synthesis by LMIs (cvxpy + Clarabel), every answer verified.

* :func:`hinfsyn_lmi` -- one plant, full-order controller: the projection
  (elimination) LMIs of Gahinet & Apkarian 1994 [GA94] Thm 4.3 give the
  optimal gamma; the controller is rebuilt from (R, S) at a backed-off gamma by
  the explicit formula of Iwasaki & Skelton 1994 [IS94].
* :func:`hinfsyn_multi` -- one controller for a set of plants, by a sequential
  convex method with a per-member certificate (see its docstring).

Every returned controller has been checked independently: closed-loop
eigenvalues, and the closed loop's H-infinity norm by the Bruinsma-Steinbuch
Hamiltonian iteration (:func:`robust.analysis.norms.hinf_norm`), which must not exceed
``gamma_bound`` by more than ``verify_rtol``.  Otherwise
:class:`~robust.errors.VerificationError` is raised; nothing unverified is
returned.

References: see :mod:`robust.synthesis.lmi`.
"""

from __future__ import annotations

import dataclasses
import time

import control
import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from robust.analysis.norms import hinf_norm, spectral_abscissa
from robust.errors import (
    AssumptionError,
    InfeasibleError,
    ModelStructureError,
    ParameterError,
    SolverError,
    VerificationError,
)
from robust.synthesis.genplant import GeneralizedPlant, as_generalized_plant
from robust.synthesis.lmi import (
    PlantBlocks,
    bounded_real_lmi,
    check_regularity,
    closed_loop_matrices,
    projection_lmis,
    reconstruct_controller,
)
from robust.synthesis.solve import DEFAULT_SOLVERS, SOLVER_TOL, solve_problem

__all__ = [
    "HinfResult",
    "LMISynthesisProblem",
    "MultiHinfResult",
    "check_hinf_assumptions",
    "hinfsyn_lmi",
    "hinfsyn_multi",
]

#: strict LMIs are enforced as ``<= -MARGIN_FACTOR * tol * I`` (tol: the first solver's feasibility tolerance)
MARGIN_FACTOR = 10.0
#: Clarabel duality-gap tolerance of the gamma minimisation (relative accuracy of gamma_opt)
GAP_TOL_MINIMISE = 1e-6
#: gap tolerance of the centring solve (it only has to return an interior point)
GAP_TOL_CENTRE = 1e-5
#: multiples of the smallest admissible mu tried in the explicit reconstruction formula
MU_FACTORS = (2.0, 1.1, 10.0)
#: default relative back-off from the optimal gamma before reconstruction
DEFAULT_BACKOFF = 0.003
#: further back-off factors tried, relative to ``backoff``, if a reconstruction fails verification
BACKOFF_SCHEDULE = (1.0, 3.0, 10.0, 30.0)


@dataclasses.dataclass(frozen=True)
class HinfResult:
    """A verified H-infinity design.

    Attributes
    ----------
    K : control.StateSpace
        Controller, ``u = K y`` (positive feedback, as :func:`control.hinfsyn`).
    gamma_bound : float
        Bound certified by the LMI at the backed-off level used for reconstruction.
    gamma : float
        H-infinity norm of the closed loop, computed afterwards by the
        Bruinsma-Steinbuch iteration; ``gamma <= gamma_bound * (1 + verify_rtol)``.
    gamma_opt : float
        Optimal gamma of the LMI problem (before back-off).  The strict LMIs are
        enforced with a margin, so this sits slightly above the true infimum
        (by a relative amount of order ``MARGIN_FACTOR * tol / gamma`` in scaled units).
    closed_loop : control.StateSpace
        ``F_l(P, K)`` from w to z.
    spectral_abscissa : float
        Largest real part of the closed-loop poles, rad/s (negative).
    solver, status : str
        Solver and cvxpy status of the solve that produced the reconstructed point.
    iterations : int
        Solver iterations summed over all solves.
    solve_time, wall_time : float
        Seconds in the solver(s), and for the whole call.
    backoff : float
        Relative back-off used: ``gamma_bound / gamma_opt - 1``.
    condition : dict
        Condition numbers met during reconstruction (``cond_X``, ``cond_Phi``,
        ``cond_LPL``, ``cond_I_D22Dk``) and the bounded-real residual ``lmi_max_eig``.
    order : int
        Controller order.
    attempts : tuple of str
        Log of the reconstruction attempts (what failed and why).
    """

    K: control.StateSpace
    gamma_bound: float
    gamma: float
    gamma_opt: float
    closed_loop: control.StateSpace
    spectral_abscissa: float
    solver: str
    status: str
    iterations: int
    solve_time: float
    wall_time: float
    backoff: float
    condition: dict
    order: int
    attempts: tuple


# ---------------------------------------------------------------------------------- checks
def _pbh_fails(A, M, *, side: str, tol: float, rank_rtol: float = 1e-9):
    """Eigenvalues with Re >= -tol*max(1, |lambda|) at which the PBH rank test fails.

    ``A`` is first balanced by a diagonal similarity (``scipy.linalg.matrix_balance``,
    transforming ``M`` with it), and the columns (``side="right"``: ``M = B2``) or
    rows (``side="left"``: ``M = C2``) of ``M`` are normalised to unit length, so
    the signals' units do not matter; rank is decided relative to the largest
    singular value of ``[A - lambda I, M]`` (or its transposed form).  Call it in
    well-scaled state coordinates (:func:`check_hinf_assumptions` uses those of
    :func:`_scale`): a rank decision is only as good as the coordinates.
    """
    n = A.shape[0]
    if n == 0:
        return []
    t = _diagonal_balance(A)
    A = A * (1.0 / t)[:, None] * t[None, :]
    if side == "right":
        M = M / t[:, None]
        M = M / np.maximum(np.linalg.norm(M, axis=0), 1e-300)[None, :]
    else:
        M = M * t[None, :]
        M = M / np.maximum(np.linalg.norm(M, axis=1), 1e-300)[:, None]
    bad = []
    for lam in np.linalg.eigvals(A):
        if lam.real < -tol * max(1.0, abs(lam)):
            continue
        E = A - lam * np.eye(n)
        T = np.hstack([E, M]) if side == "right" else np.vstack([E, M])
        s = np.linalg.svd(T, compute_uv=False)
        if s[n - 1] <= rank_rtol * s[0]:
            bad.append(lam)
    return bad


def check_hinf_assumptions(gp: GeneralizedPlant, *, require_regular: bool = True) -> None:
    """Check the standing assumptions of H-infinity output-feedback synthesis.

    Raises
    ------
    ModelStructureError
        If the plant is discrete-time (only continuous time is implemented).
    AssumptionError
        Naming the failed condition: (A, B2) not stabilisable, (C2, A) not
        detectable, D12 without full column rank or D21 without full row rank.
    """
    if not gp.sys.isctime():
        raise ModelStructureError(
            f"hinfsyn_lmi: only continuous-time plants are supported; got dt={gp.dt}. "
            "Design in continuous time and discretise the controller"
        )
    # rank decisions in the coordinates the LMIs are solved in (balanced realization, unit
    # control and measurement channels): independent of how the plant's states are scaled
    bs, sc = _scale(_blocks(gp))
    A = bs.A
    bad = _pbh_fails(A, bs.B2, side="right", tol=1e-12)
    if bad:
        raise AssumptionError(
            f"(A, B2) is not stabilisable: the mode(s) {np.round(np.multiply(bad, sc.w0), 6).tolist()} are unstable and "
            "uncontrollable from u; no controller can stabilise this plant"
        )
    bad = _pbh_fails(A, bs.C2, side="left", tol=1e-12)
    if bad:
        raise AssumptionError(
            f"(C2, A) is not detectable: the mode(s) {np.round(np.multiply(bad, sc.w0), 6).tolist()} are unstable and "
            "unobservable from y; no controller can stabilise this plant"
        )
    if require_regular:
        check_regularity(_blocks(gp))


def _blocks(gp: GeneralizedPlant) -> PlantBlocks:
    return PlantBlocks(gp.A, gp.B1, gp.B2, gp.C1, gp.C2, gp.D11, gp.D12, gp.D21)


# ---------------------------------------------------------------------------------- scaling
@dataclasses.dataclass(frozen=True)
class _Scaling:
    T: np.ndarray  # x = T xs (n-by-n)
    w0: float  # time scale: tau = w0 t
    su: np.ndarray  # u = diag(su) us
    sy: np.ndarray  # ys = y / sy
    sw: float  # w = sw ws
    sz: float  # zs = z / sz
    state_scaling: str = "none"  # "balanced" or "diagonal"


#: largest condition number accepted for the balancing state transformation (else diagonal balancing only)
BALANCE_MAX_COND = 1e8
#: Gramian eigenvalues below this fraction of the largest are raised to it (keeps T invertible)
GRAMIAN_FLOOR = 1e-14


def _diagonal_balance(A):
    """Diagonal ``t`` (powers of 2) balancing ``A`` (``scipy.linalg.matrix_balance``, no permutation)."""
    if A.shape[0] == 0:
        return np.ones(0)
    _, (t, _) = sla.matrix_balance(A, permute=False, separate=True)
    return np.asarray(t, float)


def _balancing_transform(A, B, C):
    """State transformation ``x = T xs`` to a balanced realization of the shifted plant.

    Balanced realization (Moore, "Principal component analysis in linear systems:
    controllability, observability, and model reduction", IEEE TAC 26(1) (1981)
    17-32), by the square-root method of Laub, Heath, Paige & Ward,
    "Computation of system balancing transformations and other applications of
    simultaneous diagonalization algorithms", IEEE TAC 32(2) (1987) 115-122,
    applied to ``(A - alpha I, B, C)`` with ``alpha`` chosen so that the shifted
    matrix is stable (the plant itself may be unstable; the shift only selects
    a coordinate system, the plant is transformed unshifted).  In these
    coordinates the controllability and observability Gramians of the shifted
    plant are equal and diagonal, so the entries of ``B`` and ``C`` reflect the
    input-output gains rather than the arbitrary internal scales of the
    interconnected blocks (companion forms, physical units).

    Returns ``(T, Tinv)``, or ``None`` when the Gramians cannot be computed or
    ``T`` would be worse conditioned than ``BALANCE_MAX_COND``.
    """
    n = A.shape[0]
    if n == 0:
        return None
    ev = np.linalg.eigvals(A)
    rho = float(np.max(np.abs(ev)))
    if not rho > 0:
        return None
    alpha = 2.0 * max(float(ev.real.max()), 0.0) + 1e-2 * rho
    As = A - alpha * np.eye(n)
    try:
        Wc = sla.solve_continuous_lyapunov(As, -B @ B.T)
        Wo = sla.solve_continuous_lyapunov(As.T, -C.T @ C)
    except (np.linalg.LinAlgError, ValueError):
        return None
    roots = []
    for W in (Wc, Wo):
        w, V = np.linalg.eigh((W + W.T) / 2)
        if not (np.all(np.isfinite(w)) and w.max() > 0):
            return None
        roots.append(V * np.sqrt(np.maximum(w, GRAMIAN_FLOOR * w.max())))
    Lc, Lo = roots
    U, s, Vt = np.linalg.svd(Lo.T @ Lc)
    T = (Lc @ Vt.T) / np.sqrt(s)[None, :]
    if not np.all(np.isfinite(T)) or np.linalg.cond(T) > BALANCE_MAX_COND:
        return None
    Tinv = np.linalg.inv(T)
    return T, Tinv


def _scale(b: PlantBlocks, common: _Scaling | None = None) -> tuple[PlantBlocks, _Scaling]:
    """State, time, input and output scaling that leaves the problem equivalent.

    State coordinates: a diagonal balancing of ``A``, then the balanced
    realization of the (shifted) plant with all inputs and outputs
    (:func:`_balancing_transform`); if that transformation is unavailable or
    ill-conditioned, the diagonal balancing alone.  Then u and y are scaled
    channel by channel (the controller absorbs it); w and z only by one scalar
    each (gamma scales by ``sz / sw``); time scaling keeps the H-infinity norm.
    With ``common`` (multi-model design) the time, u, y, w and z scalings are
    taken from it, so that one controller serves every member; only the state
    transformation is per plant.
    """
    n = b.A.shape[0]
    t = _diagonal_balance(b.A)
    A = b.A * (1.0 / t)[:, None] * t[None, :]
    B1, B2 = b.B1 / t[:, None], b.B2 / t[:, None]
    C1, C2 = b.C1 * t[None, :], b.C2 * t[None, :]
    T, how = np.diag(t), "diagonal"
    bal = _balancing_transform(A, np.hstack([B1, B2]), np.vstack([C1, C2]))
    if bal is not None:
        Tb, Tbi = bal
        A, B1, B2, C1, C2 = Tbi @ A @ Tb, Tbi @ B1, Tbi @ B2, C1 @ Tb, C2 @ Tb
        T, how = T @ Tb, "balanced"
    if common is None:
        # time scale: the spectral radius, or a fraction of |A| when A is (nearly) nilpotent
        rho = float(np.max(np.abs(np.linalg.eigvals(A)))) if n else 0.0
        w0 = max(rho, 1e-2 * float(np.linalg.norm(A, 2)) if n else 0.0)
        w0 = w0 if w0 > 1e-12 else 1.0
    else:
        w0 = common.w0
    A, B1, B2 = A / w0, B1 / w0, B2 / w0
    if common is None:
        su = 1.0 / np.maximum(np.linalg.norm(np.vstack([B2, b.D12]), axis=0), 1e-300)
        sy = np.maximum(np.linalg.norm(np.hstack([C2, b.D21]), axis=1), 1e-300)
    else:
        su, sy = common.su, common.sy
    B2, D12 = B2 * su[None, :], b.D12 * su[None, :]
    C2, D21 = C2 / sy[:, None], b.D21 / sy[:, None]
    if common is None:
        sw = 1.0 / max(np.linalg.norm(np.vstack([B1, D21]), 2), 1e-300)
    else:
        sw = common.sw
    B1, D21 = B1 * sw, D21 * sw
    D11 = b.D11 * sw
    if common is None:
        sz = max(np.linalg.norm(np.hstack([C1, D11, D12]), 2), 1e-300)
    else:
        sz = common.sz
    C1, D11, D12 = C1 / sz, D11 / sz, D12 / sz
    return PlantBlocks(A, B1, B2, C1, C2, D11, D12, D21), _Scaling(T, w0, su, sy, sw, sz, how)


def _scale_controller(Ak, Bk, Ck, Dk, sc: _Scaling):
    """Inverse of :func:`_unscale_controller`."""
    return (
        Ak / sc.w0,
        (Bk / sc.w0) * sc.sy[None, :],
        Ck / sc.su[:, None],
        Dk * sc.sy[None, :] / sc.su[:, None],
    )


def _unscale_controller(Ak, Bk, Ck, Dk, sc: _Scaling):
    return (
        Ak * sc.w0,
        (Bk * sc.w0) / sc.sy[None, :],
        sc.su[:, None] * Ck,
        sc.su[:, None] * Dk / sc.sy[None, :],
    )


def _gamma_unscale(g: float, sc: _Scaling) -> float:
    return g * sc.sz / sc.sw


def _remove_d22(Ak, Bk, Ck, Dk, D22):
    """Controller for the plant with D22 from one designed for ``y0 = y - D22 u``."""
    if not np.any(D22):
        return (Ak, Bk, Ck, Dk), 1.0
    M = np.eye(Dk.shape[0]) + Dk @ D22
    c = float(np.linalg.cond(M))
    if c > 1e10:
        raise VerificationError(
            f"D22 loop transformation is ill-posed: I + Dk*D22 has condition number {c:.3g}"
        )
    E = np.linalg.inv(M)
    return (Ak - Bk @ D22 @ E @ Ck, Bk - Bk @ D22 @ E @ Dk, E @ Ck, E @ Dk), c


# ---------------------------------------------------------------------------------- nominal
def _verify(gp, K, gamma_bound, verify_rtol):
    cl = gp.closed_loop(K)
    sa = spectral_abscissa(cl)
    if not sa < 0:
        return None, f"closed loop unstable (max real part of poles {sa:.3g})"
    g = hinf_norm(cl)
    if not g <= gamma_bound * (1.0 + verify_rtol):
        return (
            None,
            f"closed-loop norm {g:.6g} exceeds the bound {gamma_bound:.6g} by more than {verify_rtol:g}",
        )
    return (cl, sa, g), ""


def hinfsyn_lmi(
    P,
    nmeas: int | None = None,
    ncon: int | None = None,
    *,
    backoff: float = DEFAULT_BACKOFF,
    gamma_max: float | None = None,
    verify_rtol: float = 1e-6,
    solvers=DEFAULT_SOLVERS,
    scale: bool = True,
    verbose: bool = False,
) -> HinfResult:
    """H-infinity-optimal output feedback by LMIs, verified.

    Same calling convention as :func:`control.hinfsyn`: ``u = K y`` and the
    closed loop is the lower LFT ``F_l(P, K)``.

    Parameters
    ----------
    P : control.StateSpace or GeneralizedPlant
        Continuous-time generalized plant.  For a plain system the last
        ``nmeas`` outputs are measurements and the last ``ncon`` inputs controls.
    nmeas, ncon : int, optional
        Numbers of measurements and controls (not needed for a GeneralizedPlant).
    backoff : float
        Relative back-off from the optimal gamma before the controller is rebuilt,
        in (0, 1); ``gamma_bound = (1 + backoff) * gamma_opt``.  Near the optimum
        the closed-loop Lyapunov matrix is nearly singular and the rebuilt
        controller ill-conditioned; a small back-off fixes it.  If verification
        fails, larger back-offs ``backoff * BACKOFF_SCHEDULE`` are tried in turn.
    gamma_max : float, optional
        Required performance: the LMI problem gets ``gamma <= gamma_max`` and
        :class:`~robust.errors.InfeasibleError` is raised if no controller achieves it.
    verify_rtol : float
        The verified closed-loop norm may exceed ``gamma_bound`` by at most this
        relative amount (the tolerance of the independent norm computation).
    solvers : sequence of str
        cvxpy solvers in order of preference (default Clarabel, then SCS).
    scale : bool
        Transform states (balanced realization, see :func:`_scale`), and scale
        time, inputs and outputs before solving.
    verbose : bool
        Solver output.

    Returns
    -------
    HinfResult

    Raises
    ------
    ModelStructureError
        Discrete-time plant, bad partition sizes.
    AssumptionError
        (A, B2) not stabilisable, (C2, A) not detectable, D12 / D21 rank deficient.
    InfeasibleError
        ``gamma_max`` is below the optimal gamma (the message says which LMI
        condition could not be met).
    SolverError
        No solver returned an answer.
    VerificationError
        No reconstructed controller passed the independent check.

    Notes
    -----
    Steps:

    1. assumption checks (:func:`check_hinf_assumptions`): continuous time,
       (A, B2) stabilisable, (C2, A) detectable (PBH tests on the closed
       right-half-plane modes), D12 full column rank and D21 full row rank.
       Singular problems are refused rather than regularised: add a control
       penalty or measurement noise to the generalized plant instead, so the
       regularisation is visible in the design.  A nonzero D22 is removed by
       designing for ``y0 = y - D22 u`` and transforming the controller back,
       ``K = K0 (I + D22 K0)^-1``.
    2. scaling (``scale=True``): state coordinates of a balanced realization
       of the plant shifted to stability (Moore 1981, square-root method of
       Laub et al. 1987; after a diagonal balancing of A), so that B and C
       reflect input-output gains rather than the internal scales of the
       interconnected blocks; time scaling by the spectral radius, unit-norm
       columns of [B2; D12] and rows of [C2 D21], and one scalar each for w
       and z (gamma rescales exactly).  The controller does not depend on the
       plant's state coordinates, so only the time, u and y scalings are undone.
    3. one SDP (:class:`LMISynthesisProblem`): minimise gamma subject to the
       [GA94] Thm 4.3 LMIs, strict inequalities enforced with a margin of
       ``MARGIN_FACTOR`` times the solver's feasibility tolerance; Clarabel
       first, SCS if Clarabel fails (:func:`robust.synthesis.solve.solve_problem`).
    4. reconstruction at ``(1 + backoff) * gamma_opt`` from that solution by the
       explicit formula of [IS94] (:func:`robust.synthesis.lmi.reconstruct_controller`),
       for each of ``MU_FACTORS``; the best verified controller is kept.
    5. only if no reconstruction verifies: re-solve the same compiled problem
       with ``gamma_floor`` at the backed-off level (the interior-point answer
       is then centred in that slice of the feasible set) and reconstruct
       again; then larger back-offs.
    6. verification of every candidate: closed-loop poles in the open left
       half plane, and the Bruinsma-Steinbuch norm of the closed loop at most
       ``gamma_bound * (1 + verify_rtol)``.

    Examples
    --------
    The first-order problem of Doyle, Glover, Khargonekar & Francis (1989),
    whose optimal gamma is sqrt(2):

    >>> from robust.synthesis.testing import dgkf_scalar_plant
    >>> res = hinfsyn_lmi(dgkf_scalar_plant(0.0), 1, 1)
    >>> bool(abs(res.gamma_opt - 2 ** 0.5) < 1e-4), bool(res.gamma <= res.gamma_bound * (1 + 1e-6))
    (True, True)
    """
    t_start = time.perf_counter()
    if not 0.0 < backoff < 1.0:
        raise ParameterError(f"{backoff=} must be in (0, 1)")
    if not 0.0 < verify_rtol < 0.1:
        raise ParameterError(f"{verify_rtol=} must be in (0, 0.1)")
    gp = as_generalized_plant(P, nmeas, ncon)
    check_hinf_assumptions(gp)
    b0 = _blocks(gp)
    if scale:
        bs, sc = _scale(b0)
    else:
        bs, sc = b0, _Scaling(np.eye(gp.nx), 1.0, np.ones(gp.nu), np.ones(gp.ny), 1.0, 1.0)
    if gamma_max is not None and not (np.isfinite(gamma_max) and gamma_max > 0):
        raise ParameterError(f"{gamma_max=} must be a positive finite number")
    cap = None if gamma_max is None else gamma_max * sc.sw / sc.sz
    margin = MARGIN_FACTOR * SOLVER_TOL.get(solvers[0], 1e-8)
    prob = LMISynthesisProblem(bs, margin=margin, gamma_cap=cap)
    try:
        sol = prob.solve(gamma_floor=0.0, solvers=solvers, verbose=verbose)
    except InfeasibleError as exc:
        if gamma_max is None:
            raise
        raise InfeasibleError(
            f"hinfsyn_lmi: no controller achieves gamma <= {gamma_max=:g}: the projected bounded-real LMIs "
            "of GA94 Thm 4.3 with the coupling [[R, I], [I, S]] >= 0 are infeasible at that level. "
            f"Raise gamma_max or relax the weights ({exc})"
        ) from None
    lmis = prob.lmis
    g_opt_s = float(lmis.gamma.value)
    R1, S1 = lmis.R.value, lmis.S.value
    stats = [sol]
    log = []
    for factor in BACKOFF_SCHEDULE:
        b = backoff * factor
        if b >= 1.0:
            break
        gb_s = (1.0 + b) * g_opt_s
        candidates = [("optimal-point", R1, S1, gb_s, sol)]
        for label, R, S, gs, s_used in _candidate_points(
            candidates, prob, gb_s, solvers, verbose, stats, log
        ):
            best = _best_reconstruction(
                gp, bs, sc, R, S, gs, verify_rtol, log, f"backoff {b:g}, {label}"
            )
            if best is None:
                continue
            K, (cl, sa, g), info = best
            return HinfResult(
                K=K,
                gamma_bound=_gamma_unscale(gs, sc),
                gamma=g,
                gamma_opt=_gamma_unscale(g_opt_s, sc),
                closed_loop=cl,
                spectral_abscissa=sa,
                solver=s_used.solver,
                status=s_used.status,
                iterations=int(sum(s.iterations or 0 for s in stats)),
                solve_time=float(sum(s.solve_time for s in stats)),
                wall_time=time.perf_counter() - t_start,
                backoff=gs / g_opt_s - 1.0,
                condition=info,
                order=int(K.nstates),
                attempts=tuple(log),
            )
    raise VerificationError(
        "hinfsyn_lmi: no reconstructed controller passed the independent check "
        f"(optimal LMI gamma {_gamma_unscale(g_opt_s, sc):.6g}); attempts: " + "; ".join(log)
    )


def _best_reconstruction(gp, bs, sc, R, S, gs, verify_rtol, log, label):
    """Rebuild K from (R, S) at scaled level ``gs`` for each ``MU_FACTORS``; keep the best verified one."""
    best = None
    gamma_bound = _gamma_unscale(gs, sc)
    for mf in MU_FACTORS:
        try:
            (Ak, Bk, Ck, Dk), info = reconstruct_controller(bs, R, S, gs, mu_factor=mf)
            Ak, Bk, Ck, Dk = _unscale_controller(Ak, Bk, Ck, Dk, sc)
            (Ak, Bk, Ck, Dk), cd22 = _remove_d22(Ak, Bk, Ck, Dk, gp.D22)
        except (VerificationError, np.linalg.LinAlgError) as exc:
            log.append(f"{label}, mu x{mf:g}: reconstruction failed: {exc}")
            continue
        K = control.ss(Ak, Bk, Ck, Dk, inputs=list(gp.y), outputs=list(gp.u), name="K")
        ok, why = _verify(gp, K, gamma_bound, verify_rtol)
        if ok is None:
            log.append(f"{label}, mu x{mf:g}: {why}")
            continue
        log.append(f"{label}, mu x{mf:g}: verified, gamma {ok[2]:.6g}")
        if best is None or ok[2] < best[1][2]:
            best = (K, ok, dict(info, cond_I_D22Dk=cd22, mu_factor=mf))
    return best


class LMISynthesisProblem:
    """The [GA94] Thm 4.3 problem for one (scaled) plant, compiled once and re-solved.

    The cvxpy problem is built once; ``gamma_floor`` is a cvxpy Parameter, so
    solving again at another gamma level (a gamma sweep, the centring solve
    of :func:`hinfsyn_lmi`) reuses cvxpy's compiled problem data instead of
    canonicalising the LMIs again.  (Changing the plant matrices changes the
    problem: DPP does not allow plant data as parameters here, because they
    multiply the matrix variables on both sides after projection.)

    Parameters
    ----------
    blocks : PlantBlocks
        Plant data (``D22 = 0``).
    margin : float
        Strictness margin of the LMIs.
    gamma_cap : float, optional
        Upper bound on gamma.
    """

    def __init__(self, blocks: PlantBlocks, *, margin: float, gamma_cap: float | None = None):
        self.blocks = blocks
        self.lmis = projection_lmis(blocks, margin=margin, gamma_cap=gamma_cap)
        self.problem = cp.Problem(self.lmis.objective, self.lmis.constraints)

    def solve(self, *, gamma_floor: float = 0.0, solvers=DEFAULT_SOLVERS, verbose: bool = False):
        """Minimise gamma subject to ``gamma >= gamma_floor``; returns a :class:`robust.synthesis.solve.SolveResult`."""
        self.lmis.gamma_floor.value = float(gamma_floor)
        if gamma_floor == 0:
            what, gap = "gamma minimisation (GA94 Thm 4.3)", GAP_TOL_MINIMISE
        else:
            # only an interior point is needed here: the answer is verified afterwards
            what, gap = f"centring at gamma={gamma_floor:.6g}", GAP_TOL_CENTRE
        return solve_problem(
            self.problem, step=f"hinfsyn_lmi: {what}", solvers=solvers, gap_tol=gap, verbose=verbose
        )


def _candidate_points(candidates, prob, gb_s, solvers, verbose, stats, log):
    """Yield (label, R, S, gamma, solve) to reconstruct from at one back-off level.

    First the optimal point itself (cheap: no solve); then the same compiled
    problem re-solved with ``gamma_floor = gb`` (a parameter change only, so
    cvxpy reuses its compilation), whose interior-point answer sits inside
    the feasible slice at that gamma, away from the singular boundary.
    """
    yield from candidates
    try:
        s2 = prob.solve(gamma_floor=gb_s, solvers=solvers, verbose=verbose)
    except (SolverError, InfeasibleError) as exc:
        log.append(f"centring solve failed: {exc}")
        return
    stats.append(s2)
    lmis = prob.lmis
    yield ("centred", lmis.R.value, lmis.S.value, max(float(lmis.gamma.value), gb_s), s2)


# ---------------------------------------------------------------------------------- multi-model
@dataclasses.dataclass(frozen=True)
class MultiHinfResult:
    """A verified multi-model design: one controller, a certificate per member.

    Attributes
    ----------
    K : control.StateSpace
        The common controller, ``u = K y``.
    gamma_bound : float
        Common bound certified by the final analysis step: every member i has a
        Lyapunov matrix ``P_i > 0`` proving ``||F_l(P_i, K)||_inf < gamma_bound``.
    gammas : numpy.ndarray, shape (n_members,)
        H-infinity norm of each member's closed loop, computed independently
        (Bruinsma-Steinbuch); each ``<= gamma_bound * (1 + verify_rtol)``.
    spectral_abscissas : numpy.ndarray, shape (n_members,)
        Largest closed-loop pole real part of each member, rad/s (all negative).
    certificates : tuple of numpy.ndarray
        The Lyapunov matrices ``P_i`` of the closed loops ``F_l(P_i, K)`` in the
        coordinates of :meth:`GeneralizedPlant.closed_loop` (plant states, then
        controller states): ``[[Acl' P + P Acl, P Bcl, Ccl'], [., -g I, Dcl'],
        [., ., -g I]] < 0`` with ``g = gamma_bound``.
    scaling : dict
        The common scaling used: time scale ``w0`` (rad/s), scalars ``sw``, ``sz``
        (gamma_scaled = gamma * sw / sz) and per-channel ``su``, ``sy``.
    history : tuple of float
        Worst-member norm after the initial controller and after each accepted iteration.
    iterations : int
        Number of analysis/synthesis (P/K) iterations performed.
    solve_time, wall_time : float
        Seconds in the solvers, and for the whole call.
    method : str
        Short description of the method and guarantee.
    """

    K: control.StateSpace
    gamma_bound: float
    gammas: np.ndarray
    spectral_abscissas: np.ndarray
    certificates: tuple
    history: tuple
    iterations: int
    solve_time: float
    wall_time: float
    method: str
    scaling: dict

    @property
    def gamma(self) -> float:
        """Worst member's verified norm."""
        return float(np.max(self.gammas))


def _cl_norms(gps, K):
    out = []
    for gp in gps:
        cl = gp.closed_loop(K)
        sa = spectral_abscissa(cl)
        out.append((sa, hinf_norm(cl) if sa < 0 else np.inf))
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])


def _p_step(blocks, Om, nk, margin, solvers, verbose):
    """Analysis: min gamma s.t. a BRL certificate P_i for every member with K fixed."""
    g = cp.Variable(name="gamma")
    Ps, cons = [], []
    for b in blocks:
        Acl, Bcl, Ccl, Dcl = closed_loop_matrices(b, Om, nk)
        P = cp.Variable((Acl.shape[0], Acl.shape[0]), symmetric=True)
        Ps.append(P)
        cons += [
            P >> margin * np.eye(Acl.shape[0]),
            bounded_real_lmi(Acl, Bcl, Ccl, Dcl, P, g, margin=margin),
        ]
    prob = cp.Problem(cp.Minimize(g), cons)
    sol = solve_problem(
        prob, step="hinfsyn_multi: analysis (P) step", solvers=solvers, verbose=verbose
    )
    return float(g.value), [P.value for P in Ps], sol


def _k_step(blocks, Ps, Om0, nk, margin, trust, solvers, verbose):
    """Synthesis: min gamma over the controller data with every member's P_i fixed."""
    g = cp.Variable(name="gamma")
    Om = cp.Variable(Om0.shape, name="Omega")
    cons = [cp.norm(Om - Om0, "fro") <= trust * max(1.0, float(np.linalg.norm(Om0)))]
    for b, P in zip(blocks, Ps):
        Acl, Bcl, Ccl, Dcl = closed_loop_matrices(b, Om, nk)
        cons.append(bounded_real_lmi(Acl, Bcl, Ccl, Dcl, _sym_np(P), g, margin=margin))
    prob = cp.Problem(cp.Minimize(g), cons)
    sol = solve_problem(
        prob, step="hinfsyn_multi: synthesis (K) step", solvers=solvers, verbose=verbose
    )
    return float(g.value), Om.value, sol


def _sym_np(P):
    return (np.asarray(P) + np.asarray(P).T) / 2


def _initial_controller(gps, solvers, log):
    """Nominal design on the mean plant, then on each member, until one stabilises every member."""
    mean = _mean_plant(gps)
    tried = [("mean plant", mean)] + [(f"member {i}", gp) for i, gp in enumerate(gps)]
    best = None
    for label, gp in tried:
        try:
            K = hinfsyn_lmi(gp, solvers=solvers).K
        except (InfeasibleError, SolverError, VerificationError, AssumptionError) as exc:
            log.append(f"initial design on {label} failed: {exc}")
            continue
        sa, norms = _cl_norms(gps, K)
        if np.all(sa < 0):
            if best is None or norms.max() < best[1]:
                best = (K, float(norms.max()), label)
            if label == "mean plant":
                break
        else:
            log.append(
                f"initial design on {label} leaves {int(np.sum(sa >= 0))} member(s) unstable"
            )
        if best is not None:
            break
    return best


def hinfsyn_multi(
    plants,
    nmeas: int | None = None,
    ncon: int | None = None,
    *,
    K0=None,
    max_iter: int = 20,
    rtol: float = 1e-3,
    trust: float = 0.5,
    verify_rtol: float = 1e-6,
    solvers=DEFAULT_SOLVERS,
    verbose: bool = False,
) -> MultiHinfResult:
    """One controller for a set of plants, with a per-member H-infinity certificate.

    Method: a sequential convex (analysis/synthesis, "P-K") iteration on the
    bilinear matrix inequalities of the multi-model problem, as in
    El Ghaoui & Balakrishnan, "Synthesis of fixed-structure controllers via
    numerical optimization", Proc. 33rd IEEE CDC (1994) 2678-2683, and the
    survey of Goh, Safonov & Ly, "Robust synthesis via bilinear matrix
    inequalities", Int. J. Robust Nonlinear Control 6 (1996) 1079-1095:

    1. start from a controller that stabilises every member (``K0``, or a
       nominal :func:`hinfsyn_lmi` design on the mean plant, else on a member);
    2. P-step: with K fixed, the bounded-real LMI of every member is linear in
       its own Lyapunov matrix ``P_i``; minimise the common gamma (one SDP);
    3. K-step: with all ``P_i`` fixed, every member's bounded-real LMI is linear
       in the controller data ``[[Ak, Bk], [Ck, Dk]]`` ([GA94] eq. (2.5));
       minimise gamma within a trust region around the current controller;
    4. accept the new controller only if its verified worst-member norm
       decreased; stop when the relative decrease is below ``rtol``.

    Guarantee (what is and is not claimed): the returned controller has, for
    *every listed member*, a Lyapunov certificate ``P_i > 0`` from the final
    P-step proving closed-loop stability and ``||T_zw,i||_inf < gamma_bound``,
    and each member's norm has been recomputed independently.  Nothing is
    claimed for plants between the members (members may differ in any
    matrix, so there is no common certificate over their convex hull), and the
    iteration is a local method: ``gamma_bound`` is not the optimum of the
    (non-convex) multi-model problem.  The worst-member norm never increases
    from one accepted iteration to the next.

    Parameters
    ----------
    plants : sequence of control.StateSpace or GeneralizedPlant
        Members, all with the same numbers of w, u, z, y (states may differ),
        continuous time, ``D22 = 0``.
    nmeas, ncon : int, optional
        Partition counts for plain systems.
    K0 : control.StateSpace, optional
        Initial controller (must stabilise every member).
    max_iter : int
        Maximum number of P-K iterations.
    rtol : float
        Stop when the worst-member norm decreases by less than this fraction.
    trust : float
        Trust-region radius of the K-step, relative to ``max(1, ||Omega||_F)``.
    verify_rtol : float
        Allowed excess of each verified member norm over ``gamma_bound``.
    solvers : sequence of str
        cvxpy solvers, in order.
    verbose : bool
        Solver output.

    Returns
    -------
    MultiHinfResult

    Raises
    ------
    ModelStructureError
        Members with different signal counts, discrete time, or an empty set.
    AssumptionError
        A member is not stabilisable/detectable, or has ``D22 != 0``.
    InfeasibleError
        No initial controller stabilises every member.
    VerificationError
        The final certificate or a member's independent norm check fails.
    """
    t_start = time.perf_counter()
    gps = [as_generalized_plant(P, nmeas, ncon) for P in plants]
    if not gps:
        raise ModelStructureError("plants must contain at least one member; got an empty sequence")
    sizes = {(gp.nw, gp.nu, gp.nz, gp.ny) for gp in gps}
    if len(sizes) != 1:
        raise ModelStructureError(
            f"all members must have the same (nw, nu, nz, ny); got {sorted(sizes)}"
        )
    for i, gp in enumerate(gps):
        try:
            check_hinf_assumptions(gp, require_regular=False)
        except AssumptionError as exc:
            raise AssumptionError(f"member {i}: {exc}") from None
        if np.any(gp.D22):
            raise AssumptionError(
                f"member {i}: hinfsyn_multi requires D22 = 0; got max |D22| = {np.abs(gp.D22).max():.3g}"
            )
    if not (isinstance(max_iter, (int, np.integer)) and max_iter >= 0):
        raise ParameterError(f"{max_iter=} must be a nonnegative integer")
    log: list[str] = []
    if K0 is None:
        init = _initial_controller(gps, solvers, log)
        if init is None:
            raise InfeasibleError(
                "hinfsyn_multi: no initial controller stabilises every member (tried nominal designs on the "
                "mean plant and on each member); pass K0 or split the family. " + "; ".join(log)
            )
        K = init[0]
    else:
        K = control.ss(K0)
    sa, norms = _cl_norms(gps, K)
    if not np.all(sa < 0):
        raise InfeasibleError(
            f"hinfsyn_multi: K0 leaves members {np.flatnonzero(sa >= 0).tolist()} unstable"
        )
    _, sc = _scale(_blocks(_mean_plant(gps)))
    scaled = [_scale(_blocks(gp), common=sc) for gp in gps]
    blocks = [b for b, _ in scaled]
    margin = MARGIN_FACTOR * SOLVER_TOL.get(solvers[0], 1e-8)
    nk = K.nstates
    Om = _omega_scaled(K, sc)
    best = float(norms.max())
    history = [best]
    solve_time, it = 0.0, 0
    for it in range(1, max_iter + 1):
        try:
            _, Ps, s1 = _p_step(blocks, Om, nk, margin, solvers, verbose)
            _, Om_new, s2 = _k_step(blocks, Ps, Om, nk, margin, trust, solvers, verbose)
        except (SolverError, InfeasibleError) as exc:
            log.append(f"iteration {it}: {exc}")
            break
        solve_time += s1.solve_time + s2.solve_time
        K_new = _controller_from_omega(Om_new, nk, gps[0], sc)
        sa_new, norms_new = _cl_norms(gps, K_new)
        if not np.all(sa_new < 0) or norms_new.max() >= best:
            log.append(
                f"iteration {it}: no verified improvement (worst norm {norms_new.max():.6g} vs {best:.6g})"
            )
            break
        improvement = (best - norms_new.max()) / best
        Om, K, best = Om_new, K_new, float(norms_new.max())
        history.append(best)
        if improvement < rtol:
            break
    gamma_bound_s, Ps, s3 = _p_step(blocks, Om, nk, margin, solvers, verbose)
    gamma_bound = _gamma_unscale(gamma_bound_s, sc)
    solve_time += s3.solve_time
    sa, norms = _cl_norms(gps, K)
    bad = [
        i
        for i in range(len(gps))
        if not (sa[i] < 0 and norms[i] <= gamma_bound * (1.0 + verify_rtol))
    ]
    if bad:
        raise VerificationError(
            f"hinfsyn_multi: members {bad} fail the independent check against the certified bound "
            f"{gamma_bound:.6g} (norms {norms[bad]}, spectral abscissas {sa[bad]})"
        )
    return MultiHinfResult(
        K=K,
        gamma_bound=gamma_bound,
        gammas=norms,
        spectral_abscissas=sa,
        certificates=tuple(
            _certificate_unscaled(P, msc, nk, sc) for P, (_, msc) in zip(Ps, scaled)
        ),
        history=tuple(history),
        iterations=it,
        solve_time=solve_time,
        wall_time=time.perf_counter() - t_start,
        method="P-K iteration (El Ghaoui & Balakrishnan 1994) with per-member bounded-real certificates",
        scaling={"w0": sc.w0, "sw": sc.sw, "sz": sc.sz, "su": sc.su.copy(), "sy": sc.sy.copy()},
    )


def _controller_from_omega(Om, nk, gp, sc):
    Om = np.asarray(Om, float)
    Ak, Bk, Ck, Dk = _unscale_controller(Om[:nk, :nk], Om[:nk, nk:], Om[nk:, :nk], Om[nk:, nk:], sc)
    return control.ss(Ak, Bk, Ck, Dk, inputs=list(gp.y), outputs=list(gp.u), name="K")


def _omega_scaled(K, sc):
    nk = K.nstates
    Ak = np.asarray(K.A, float).reshape(nk, nk)
    Bk = np.asarray(K.B, float).reshape(nk, -1) if nk else np.zeros((0, K.ninputs))
    Ck = np.asarray(K.C, float).reshape(-1, nk) if nk else np.zeros((K.noutputs, 0))
    Dk = np.asarray(K.D, float).reshape(K.noutputs, K.ninputs)
    Ak, Bk, Ck, Dk = _scale_controller(Ak, Bk, Ck, Dk, sc)
    return np.block([[Ak, Bk], [Ck, Dk]])


def _certificate_unscaled(P, msc, nk, sc):
    """Map a bounded-real certificate of the scaled closed loop back to original coordinates.

    With time scaled by w0, w by sw and z by 1/sz, ``P_orig = (sz sw / w0) T^-T P T^-1``
    where ``x = T x_scaled`` (T = blkdiag(T_plant, I_nk)); a congruence of the scaled inequality.
    """
    Tinv = sla.block_diag(np.linalg.inv(msc.T), np.eye(nk))
    P = _sym_np(Tinv.T @ _sym_np(P) @ Tinv)
    return P * (sc.sz * sc.sw / sc.w0)


def _mean_plant(gps):
    """Elementwise mean of the members' blocks (equal state dimensions), else the first member."""
    if len({gp.nx for gp in gps}) != 1:
        return gps[0]
    keys = gps[0].blocks()
    return gps[0].with_blocks(**{k: np.mean([gp.blocks()[k] for gp in gps], axis=0) for k in keys})
