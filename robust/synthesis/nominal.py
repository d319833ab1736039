"""Nominal H-infinity output-feedback synthesis by LMIs (cvxpy + Clarabel), verified.

:func:`hinfsyn_lmi` designs a full-order controller for one plant: the projection
(elimination) LMIs of Gahinet & Apkarian 1994 [GA94] Thm 4.3 give the optimal
gamma; the controller is rebuilt from (R, S) at a backed-off gamma by the
explicit formula of Iwasaki & Skelton 1994 [IS94].

Every returned controller has been checked independently: closed-loop
eigenvalues (stable in the sense of :mod:`robust.analysis.stability`), and the
closed loop's H-infinity norm by the Bruinsma-Steinbuch Hamiltonian iteration
(:func:`robust.analysis.norms.hinf_norm`), which must not exceed ``gamma_bound``
by more than ``verify_rtol``.  Otherwise :class:`~robust.errors.VerificationError`
is raised; nothing unverified is returned.

References: see :mod:`robust.synthesis.lmi`.
"""

from __future__ import annotations

import dataclasses
import time

import control
import cvxpy as cp
import numpy as np

from robust.analysis.norms import hinf_norm, spectral_abscissa
from robust.analysis.stability import stability_bound
from robust.errors import InfeasibleError, ParameterError, SolverError, VerificationError
from robust.synthesis.assumptions import check_hinf_assumptions
from robust.synthesis.genplant import as_generalized_plant
from robust.synthesis.lmi import PlantBlocks, projection_lmis, reconstruct_controller
from robust.synthesis.scaling import ControllerMatrices, D22Removal, PlantScaling
from robust.synthesis.solve import DEFAULT_SOLVERS, SOLVER_TOL, solve_problem

__all__ = [
    "BACKOFF_SCHEDULE",
    "DEFAULT_BACKOFF",
    "GAP_TOL_CENTRE",
    "GAP_TOL_MINIMISE",
    "MARGIN_FACTOR",
    "MU_FACTORS",
    "HinfResult",
    "LMISynthesisProblem",
    "hinfsyn_lmi",
]

#: strict LMIs are enforced as ``<= -MARGIN_FACTOR * tol * I``
#: (tol: the first solver's feasibility tolerance)
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
        Largest real part of the closed-loop poles, rad/s (below
        :func:`robust.analysis.stability.stability_bound`).
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


def _verify(gp, K, gamma_bound, verify_rtol):
    cl = gp.closed_loop(K)
    sa = spectral_abscissa(cl)
    if not sa < stability_bound():
        return None, (
            f"closed loop unstable (max real part of poles {sa:.3g} rad/s; "
            f"stable means below {stability_bound():.3g})"
        )
    g = hinf_norm(cl)
    if not g <= gamma_bound * (1.0 + verify_rtol):
        return (
            None,
            f"closed-loop norm {g:.6g} exceeds the bound {gamma_bound:.6g} "
            f"by more than {verify_rtol:g}",
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
        Transform states (balanced realization), and scale time, inputs and
        outputs before solving (:class:`robust.synthesis.scaling.PlantScaling`).
    verbose : bool
        Solver output.

    Returns
    -------
    HinfResult

    Raises
    ------
    ParameterError
        ``backoff``, ``verify_rtol`` or ``gamma_max`` out of range.
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

    1. assumption checks (:func:`robust.synthesis.assumptions.check_hinf_assumptions`):
       continuous time, (A, B2) stabilisable, (C2, A) detectable (PBH tests on
       the modes that are not stable), D12 full column rank and D21 full row
       rank.  Singular problems are refused rather than regularised: add a
       control penalty or measurement noise to the generalized plant instead,
       so the regularisation is visible in the design.  A nonzero D22 is
       removed by designing for ``y0 = y - D22 u`` and transforming the
       controller back, ``K = K0 (I + D22 K0)^-1``
       (:class:`robust.synthesis.scaling.D22Removal`).
    2. scaling (``scale=True``, :class:`robust.synthesis.scaling.PlantScaling`):
       state coordinates of a balanced realization of the plant shifted to
       stability (Moore 1981, square-root method of Laub et al. 1987; after a
       diagonal balancing of A), so that B and C reflect input-output gains
       rather than the internal scales of the interconnected blocks; time
       scaling by the spectral radius, unit-norm columns of [B2; D12] and rows
       of [C2 D21], and one scalar each for w and z (gamma rescales exactly).
       The controller does not depend on the plant's state coordinates, so
       only the time, u and y scalings are undone.
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
    6. verification of every candidate: closed-loop poles stable
       (:func:`robust.analysis.stability.stability_bound`), and the
       Bruinsma-Steinbuch norm of the closed loop at most
       ``gamma_bound * (1 + verify_rtol)``.

    Examples
    --------
    The first-order problem of Doyle, Glover, Khargonekar & Francis (1989),
    whose optimal gamma is sqrt(2):

    >>> from robust.synthesis.testing import dgkf_scalar_plant
    >>> res = hinfsyn_lmi(dgkf_scalar_plant(0.0), 1, 1)
    >>> bool(abs(res.gamma_opt - 2 ** 0.5) < 1e-4)
    True
    >>> bool(res.gamma <= res.gamma_bound * (1 + 1e-6))
    True
    """
    t_start = time.perf_counter()
    if not 0.0 < backoff < 1.0:
        raise ParameterError(f"backoff must be in (0, 1); got {backoff!r}")
    if not 0.0 < verify_rtol < 0.1:
        raise ParameterError(f"verify_rtol must be in (0, 0.1); got {verify_rtol!r}")
    if gamma_max is not None and not (np.isfinite(gamma_max) and gamma_max > 0):
        raise ParameterError(f"gamma_max must be a positive finite number; got {gamma_max!r}")
    gp = as_generalized_plant(P, nmeas, ncon)
    check_hinf_assumptions(gp)
    loop = D22Removal(gp.D22)
    b0 = PlantBlocks.from_generalized_plant(loop.apply(gp))
    if scale:
        sc = PlantScaling.fit(b0)
    else:
        sc = PlantScaling.identity(gp.nx, gp.nu, gp.ny)
    bs = sc.apply(b0)
    cap = None if gamma_max is None else sc.apply_gamma(gamma_max)
    margin = MARGIN_FACTOR * SOLVER_TOL.get(solvers[0], 1e-8)
    prob = LMISynthesisProblem(bs, margin=margin, gamma_cap=cap)
    try:
        sol = prob.solve(gamma_floor=0.0, solvers=solvers, verbose=verbose)
    except InfeasibleError as exc:
        if gamma_max is None:
            raise
        raise InfeasibleError(
            f"hinfsyn_lmi: no controller achieves gamma <= {gamma_max=:g}: the projected "
            "bounded-real LMIs of GA94 Thm 4.3 with the coupling [[R, I], [I, S]] >= 0 are "
            f"infeasible at that level. Raise gamma_max or relax the weights ({exc})"
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
                gp, loop, bs, sc, R, S, gs, verify_rtol, log, f"backoff {b:g}, {label}"
            )
            if best is None:
                continue
            K, (cl, sa, g), info = best
            return HinfResult(
                K=K,
                gamma_bound=sc.invert_gamma(gs),
                gamma=g,
                gamma_opt=sc.invert_gamma(g_opt_s),
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
        f"(optimal LMI gamma {sc.invert_gamma(g_opt_s):.6g}); attempts: " + "; ".join(log)
    )


def _best_reconstruction(gp, loop, bs, sc, R, S, gs, verify_rtol, log, label):
    """Rebuild K from (R, S) at scaled level ``gs`` for each ``MU_FACTORS``; keep the best.

    Only controllers that pass :func:`_verify` are kept; the best has the smallest
    verified closed-loop norm.
    """
    best = None
    gamma_bound = sc.invert_gamma(gs)
    for mf in MU_FACTORS:
        try:
            Ks, info = reconstruct_controller(bs, R, S, gs, mu_factor=mf)
            K0 = sc.invert_controller(ControllerMatrices(*Ks))
            cd22 = loop.loop_condition(K0.Dk)
            Km = loop.invert_controller(K0)
        except (VerificationError, np.linalg.LinAlgError) as exc:
            log.append(f"{label}, mu x{mf:g}: reconstruction failed: {exc}")
            continue
        K = control.ss(*Km, inputs=list(gp.y), outputs=list(gp.u), name="K")
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

    Attributes
    ----------
    blocks : PlantBlocks
        The plant data given.
    lmis : robust.synthesis.lmi.ProjectionLMIs
        Variables, parameter and constraints.
    problem : cvxpy.Problem
        The compiled problem (minimise gamma).
    """

    def __init__(self, blocks: PlantBlocks, *, margin: float, gamma_cap: float | None = None):
        self.blocks = blocks
        self.lmis = projection_lmis(blocks, margin=margin, gamma_cap=gamma_cap)
        self.problem = cp.Problem(self.lmis.objective, self.lmis.constraints)

    def solve(self, *, gamma_floor: float = 0.0, solvers=DEFAULT_SOLVERS, verbose: bool = False):
        """Minimise gamma subject to ``gamma >= gamma_floor``.

        Parameters
        ----------
        gamma_floor : float
            Lower bound on gamma: 0 for the optimum; a level above the optimum
            gives a point near the centre of that slice of the feasible set.
        solvers : sequence of str
            cvxpy solvers, in order.
        verbose : bool
            Solver output.

        Returns
        -------
        robust.synthesis.solve.SolveResult
        """
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
