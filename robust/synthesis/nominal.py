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
is raised; nothing unverified is returned.  The LMI optimum ``gamma_opt`` is reported
only when its certificate passes an independent numpy check
(:func:`robust.synthesis.lmi.projection_certificate`); otherwise it is NaN and the
result says why.  When a scaled problem fails or its optimum is not certified, other
scalings are tried (``SCALING_ATTEMPTS``) and the result records which one was used.

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
from robust.checks import POSITIVE, Spec, check_scalar
from robust.errors import (
    InfeasibleError,
    ModelStructureError,
    ParameterError,
    SolverError,
    VerificationError,
)
from robust.synthesis.assumptions import check_hinf_assumptions
from robust.synthesis.d22 import D22Removal
from robust.synthesis.genplant import as_generalized_plant
from robust.synthesis.lmi import (
    PlantBlocks,
    projection_certificate,
    projection_lmis,
    reconstruct_controller,
)
from robust.synthesis.scaling import PlantScaling
from robust.synthesis.scaling_base import ControllerMatrices
from robust.synthesis.solve import DEFAULT_SOLVERS, SOLVER_TOL, check_solvers, solve_problem

__all__ = [
    "BACKOFF_SCHEDULE",
    "CERT_GAP_RTOL",
    "CERT_PRIMAL_TOL",
    "DEFAULT_BACKOFF",
    "GAMMA_CAP_MAX",
    "GAP_TOL_CENTRE",
    "GAP_TOL_MINIMISE",
    "MARGIN_FACTOR",
    "MU_FACTORS",
    "SCALING_ATTEMPTS",
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
#: largest scaled gamma_max put into the SDP as a constraint (a looser one cannot bind)
GAMMA_CAP_MAX = 1e8
#: scalings tried in turn by ``hinfsyn_lmi(scale=True)``: the full plant scaling
#: (``PlantScaling.fit``), the state transformation only (``PlantScaling.state_only``),
#: none; the first that gives a verified controller and a certified gamma_opt is used
SCALING_ATTEMPTS = ("full", "state", "none")
#: tolerance of the primal check of gamma_opt: the normalised eigenvalues (diagonal
#: congruence, see ``robust.synthesis.lmi.projection_certificate``) of the projected LMIs
#: must be at most this, those of ``[[R, I], [I, S]]`` at least minus this
CERT_PRIMAL_TOL = 1e-6
#: relative tolerance of the dual check of gamma_opt: the weak-duality lower bound must lie
#: within this of gamma_opt, and gamma_opt may exceed the verified closed-loop norm by at most this
CERT_GAP_RTOL = 1e-3


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
        Optimal gamma of the LMI problem (before back-off): no controller achieves
        a smaller norm (to ``CERT_GAP_RTOL``).  Reported only when certified
        (``gamma_opt_certified``); NaN otherwise.  The strict LMIs are enforced
        with a margin, so this sits slightly above the true infimum (by a relative
        amount of order ``MARGIN_FACTOR * tol / gamma`` in scaled units).
    closed_loop : control.StateSpace
        ``F_l(P, K)`` from w to z.
    spectral_abscissa : float
        Largest real part of the closed-loop poles, rad/s (below
        :func:`robust.analysis.stability.stability_bound`).
    solver, status : str
        Solver and cvxpy status of the solve that produced the reconstructed point.
    iterations : int
        Solver iterations summed over all solves (all scaling attempts).
    solve_time, wall_time : float
        Seconds in the solver(s), and for the whole call.
    backoff : float
        Relative back-off used: ``gamma_bound`` over the LMI optimum of the
        attempt that produced ``K``, minus 1.
    condition : dict
        Condition numbers met during reconstruction (``cond_X``, ``cond_Phi``,
        ``cond_LPL``, ``cond_I_D22Dk``) and the bounded-real residual ``lmi_max_eig``.
    order : int
        Controller order.
    attempts : tuple of str
        Log of every scaling attempt, solve and reconstruction (what failed and
        why), each line prefixed by the scaling, e.g. ``"[full] ..."``.
    gamma_opt_certified : bool
        True when the LMI optimum passed the independent check of
        :func:`robust.synthesis.lmi.projection_certificate` (primal point feasible
        to ``CERT_PRIMAL_TOL``, dual lower bound within ``CERT_GAP_RTOL``) and does
        not exceed the verified ``gamma`` by more than ``CERT_GAP_RTOL``.
    certificate : dict
        The numbers of that check for the attempt that produced ``K``
        (:func:`robust.synthesis.lmi.projection_certificate`; ``dual_bound`` and
        ``gamma_lmi`` -- the solver's optimum, certified or not -- in original
        units), and the tolerances used.
    scaling : str
        The scaling attempt that produced ``K``: ``"full"``
        (:meth:`PlantScaling.fit <robust.synthesis.scaling.PlantScaling.fit>`),
        ``"state"`` (:meth:`~robust.synthesis.scaling.PlantScaling.state_only`) or
        ``"none"``; see ``SCALING_ATTEMPTS``.
    notes : tuple of str
        Plain-language remarks: fallbacks taken, why ``gamma_opt`` is not certified.
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
    gamma_opt_certified: bool = False
    certificate: dict = dataclasses.field(default_factory=dict)
    scaling: str = "full"
    notes: tuple = ()


def _verify(gp, K, gamma_bound, verify_rtol):
    try:
        # overflow here means a controller (or plant) too badly scaled to be checked: refuse it
        with np.errstate(over="raise", invalid="raise"):
            cl = gp.closed_loop(K)
            sa = spectral_abscissa(cl)
            if not sa < stability_bound():
                return None, (
                    f"closed loop unstable (max real part of poles {sa:.3g} rad/s; "
                    f"stable means below {stability_bound():.3g})"
                )
            g = hinf_norm(cl)
    except (FloatingPointError, np.linalg.LinAlgError, ModelStructureError) as exc:
        return None, f"closed loop could not be checked ({type(exc).__name__}: {exc})"
    if not g <= gamma_bound * (1.0 + verify_rtol):
        return (
            None,
            f"closed-loop norm {g:.6g} exceeds the bound {gamma_bound:.6g} "
            f"by more than {verify_rtol:g}",
        )
    return (cl, sa, g), ""


def _check_flag(name, value):
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(
            f"hinfsyn_lmi: {name} must be True or False; got {value!r} ({type(value).__name__})"
        )


def _check_options(backoff, verify_rtol, gamma_max, solvers, scale, verbose):
    """Validate the numeric and flag options of :func:`hinfsyn_lmi` before any work."""
    backoff = check_scalar("backoff", backoff, Spec(0.0, 1.0, True, True), owner="hinfsyn_lmi")
    verify_rtol = check_scalar(
        "verify_rtol", verify_rtol, Spec(0.0, 0.1, True, True), owner="hinfsyn_lmi"
    )
    if gamma_max is not None:
        gamma_max = check_scalar("gamma_max", gamma_max, POSITIVE, owner="hinfsyn_lmi")
    solvers = check_solvers(solvers, name="hinfsyn_lmi: solvers", sdp=True)
    _check_flag("scale", scale)
    _check_flag("verbose", verbose)
    return backoff, verify_rtol, gamma_max, solvers


def _scaling(label, b0):
    if label == "full":
        return PlantScaling.fit(b0)
    if label == "state":
        return PlantScaling.state_only(b0)
    _n, _nw, nu, _nz, ny = b0.sizes
    return PlantScaling.identity(b0.A.shape[0], nu, ny)


@dataclasses.dataclass
class _Attempt:
    """One scaling attempt of :func:`hinfsyn_lmi` (mutable bookkeeping, never returned)."""

    label: str
    sc: PlantScaling
    bs: PlantBlocks
    prob: LMISynthesisProblem | None = None
    sol: object = None
    g_opt_s: float = float("nan")
    R: np.ndarray | None = None
    S: np.ndarray | None = None
    cert: dict = dataclasses.field(default_factory=dict)
    cert_fails: list = dataclasses.field(default_factory=list)
    found: tuple | None = None
    reconstructed: bool = False

    @property
    def certified(self) -> bool:
        return self.sol is not None and not self.cert_fails


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
        Required performance (a positive finite number): the LMI problem gets
        ``gamma <= gamma_max`` and :class:`~robust.errors.InfeasibleError` is
        raised if no controller achieves it.
    verify_rtol : float
        The verified closed-loop norm may exceed ``gamma_bound`` by at most this
        relative amount (the tolerance of the independent norm computation), in (0, 0.1).
    solvers : sequence of str
        cvxpy solvers in order of preference (default Clarabel, then SCS); each
        must be one cvxpy knows and able to solve SDPs.
    scale : bool
        Transform states (balanced realization), and scale time, inputs and
        outputs before solving (:class:`robust.synthesis.scaling.PlantScaling`),
        falling back to other scalings (``SCALING_ATTEMPTS``) when that attempt
        fails; False solves the unscaled problem only.
    verbose : bool
        Solver output.

    Returns
    -------
    HinfResult

    Raises
    ------
    ParameterError
        ``backoff``, ``verify_rtol`` or ``gamma_max`` not a finite number in range,
        ``solvers`` empty, unknown or unable to solve SDPs, ``scale`` or
        ``verbose`` not a bool.
    ModelStructureError
        ``P`` not a system, non-finite plant matrices, discrete-time plant, bad
        partition sizes.
    AssumptionError
        (A, B2) not stabilisable, (C2, A) not detectable, D12 / D21 rank deficient.
    InfeasibleError
        ``gamma_max`` is below the optimal gamma (the message says which LMI
        condition could not be met).
    SolverError
        No solver returned an answer, under any scaling.
    VerificationError
        No reconstructed controller passed the independent check.

    Notes
    -----
    Steps:

    1. option checks, then assumption checks
       (:func:`robust.synthesis.assumptions.check_hinf_assumptions`):
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
    4. certification of the optimum (:func:`robust.synthesis.lmi.projection_certificate`,
       in numpy from the solver's variables): ``R > 0``, ``S > 0``, the normalised
       eigenvalues of ``[[R, I], [I, S]]`` above ``-CERT_PRIMAL_TOL`` and of the
       projected LMIs at ``gamma_opt`` below ``CERT_PRIMAL_TOL``, and a weak-duality
       lower bound from the solver's dual variables within ``CERT_GAP_RTOL`` of
       ``gamma_opt``.
    5. reconstruction at ``(1 + backoff) * gamma_opt`` from that solution by the
       explicit formula of [IS94] (:func:`robust.synthesis.lmi.reconstruct_controller`),
       for each of ``MU_FACTORS``; the best verified controller is kept.  Only
       if no reconstruction verifies: re-solve the same compiled problem with
       ``gamma_floor`` at the backed-off level (the interior-point answer is then
       centred in that slice of the feasible set) and reconstruct again; then
       larger back-offs.
    6. verification of every candidate: closed-loop poles stable
       (:func:`robust.analysis.stability.stability_bound`), and the
       Bruinsma-Steinbuch norm of the closed loop at most
       ``gamma_bound * (1 + verify_rtol)``; a certified ``gamma_opt`` must also
       not exceed that norm by more than ``CERT_GAP_RTOL``.
    7. fallbacks (``scale=True``): steps 3-6 run for each scaling of
       ``SCALING_ATTEMPTS`` in turn -- the full scaling, the state transformation
       only, no scaling -- until one gives a verified controller *and* a
       certified ``gamma_opt``.  A scaling whose solve fails or whose optimum is
       not certified (typically a solver status "optimal_inaccurate") is set
       aside without reconstruction; only if no scaling certifies are the set-aside
       solutions reconstructed, in the same order.  Among verified controllers one
       with a certified ``gamma_opt`` is preferred, then the smallest verified
       norm.  ``scaling``, ``attempts`` and ``notes`` of the result say what
       happened; an uncertified ``gamma_opt`` is reported as NaN.

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
    backoff, verify_rtol, gamma_max, solvers = _check_options(
        backoff, verify_rtol, gamma_max, solvers, scale, verbose
    )
    gp = as_generalized_plant(P, nmeas, ncon)
    if gp.nx == 0:
        raise ModelStructureError(
            "hinfsyn_lmi: P must have at least one state (the LMIs are in n x n matrices); "
            "got a static plant. A static problem needs a static gain: add the dynamics "
            "(e.g. an actuator or sensor lag) to the generalized plant"
        )
    try:
        # absurd magnitudes overflow in the rank tests and the scaling: say so, by name
        with np.errstate(over="raise", invalid="raise"):
            check_hinf_assumptions(gp)
    except (FloatingPointError, np.linalg.LinAlgError) as exc:
        raise ModelStructureError(
            "hinfsyn_lmi: P's matrices are too badly scaled to be checked (largest entry "
            f"{max(np.abs(m).max(initial=0.0) for m in gp.blocks().values()):.3g}; "
            f"{type(exc).__name__}: {exc}). Express the signals in units that bring the "
            "entries nearer 1"
        ) from None
    loop = D22Removal(gp.D22)
    b0 = PlantBlocks.from_generalized_plant(loop.apply(gp))
    margin = MARGIN_FACTOR * SOLVER_TOL.get(solvers[0], 1e-8)
    labels = SCALING_ATTEMPTS if scale else ("none",)
    stats, log, done, errors = [], [], [], []
    ctx = (gp, loop, backoff, verify_rtol, solvers, verbose, stats, log)
    # phase 1: solve and certify each scaling in turn; reconstruct only certified optima
    for label in labels:
        try:
            with np.errstate(over="raise", invalid="raise"):
                sc = _scaling(label, b0)
                att = _Attempt(label, sc, sc.apply(b0))
        except (FloatingPointError, np.linalg.LinAlgError) as exc:
            log.append(f"[{label}] scaling failed: {type(exc).__name__}: {exc}")
            errors.append((label, SolverError(f"scaling failed: {exc}")))
            continue
        try:
            _solve_attempt(att, gamma_max, margin, solvers, verbose, stats, log)
        except SolverError as exc:
            errors.append((label, exc))
            continue
        except InfeasibleError as exc:
            if gamma_max is not None:
                raise  # gamma_max is below the optimum: the same under every scaling
            errors.append((label, exc))
            continue
        done.append(att)
        if att.certified:
            _reconstruct_attempt(att, *ctx)
            if att.found is not None and att.certified:
                break
    # phase 2: nothing certified and verified -- reconstruct what was set aside
    if not any(a.found is not None and a.certified for a in done):
        for att in done:
            if not att.reconstructed:
                _reconstruct_attempt(att, *ctx)
            if att.found is not None:
                break
    found = [a for a in done if a.found is not None]
    if not found:
        _raise_no_controller(done, errors, log)
    best = min(found, key=lambda a: (not a.certified, a.found[1][2]))
    return _result(best, labels, done, errors, stats, log, t_start)


def _solve_attempt(att, gamma_max, margin, solvers, verbose, stats, log):
    """Step 3 and 4 for one scaling: solve the SDP, certify its optimum (no reconstruction)."""
    cap = None if gamma_max is None else att.sc.apply_gamma(gamma_max)
    if cap is not None and not cap <= GAMMA_CAP_MAX:
        # a requirement this loose cannot bind, and such coefficients break the solvers
        log.append(
            f"[{att.label}] gamma_max={gamma_max:g} is {cap:.3g} in scaled units, above "
            f"{GAMMA_CAP_MAX:g}: solved without the cap"
        )
        cap = None
    att.prob = LMISynthesisProblem(att.bs, margin=margin, gamma_cap=cap)
    try:
        sol = att.prob.solve(gamma_floor=0.0, solvers=solvers, verbose=verbose)
    except SolverError as exc:
        log.append(f"[{att.label}] {exc}")
        raise
    except InfeasibleError as exc:
        log.append(f"[{att.label}] {exc}")
        if gamma_max is None:
            raise
        raise InfeasibleError(
            f"hinfsyn_lmi: no controller achieves gamma <= {gamma_max=:g}: the projected "
            "bounded-real LMIs of GA94 Thm 4.3 with the coupling [[R, I], [I, S]] >= 0 are "
            f"infeasible at that level. Raise gamma_max or relax the weights ({exc})"
        ) from None
    stats.append(sol)
    lmis = att.prob.lmis
    att.sol = sol
    att.g_opt_s = float(lmis.gamma.value)
    att.R, att.S = lmis.R.value, lmis.S.value
    duals = (
        lmis.lmi_r.dual_value,
        None if lmis.lmi_s is None else lmis.lmi_s.dual_value,
    )
    cert = projection_certificate(att.bs, att.R, att.S, att.g_opt_s, duals=duals)
    att.cert_fails = _certificate_failures(cert, att.g_opt_s)
    cert = dict(cert)
    for key in ("dual_bound", "dual_bound_clipped"):
        cert[key] = float(att.sc.invert_gamma(cert[key]))
    cert.update(
        gamma_lmi=float(att.sc.invert_gamma(att.g_opt_s)),
        primal_tol=CERT_PRIMAL_TOL,
        gap_rtol=CERT_GAP_RTOL,
        solver_status=sol.status,
    )
    att.cert = cert
    verdict = "certified" if att.certified else "NOT certified: " + "; ".join(att.cert_fails)
    log.append(
        f"[{att.label}] {sol.solver} {sol.status} "
        f"(solvers: {', '.join(f'{n} {o}' for n, o in sol.attempts)}); "
        f"gamma_opt {cert['gamma_lmi']:.6g} {verdict}"
    )


def _certificate_failures(cert, g):
    """The conditions of step 4 of :func:`hinfsyn_lmi` that ``cert`` fails (scaled units)."""
    tol, rtol = CERT_PRIMAL_TOL, CERT_GAP_RTOL
    if not cert["finite"]:
        return ["the solver's R, S or gamma are not finite"]
    fails = []
    if not cert["R_min_eig"] > 0:
        fails.append(f"R > 0 fails (smallest eigenvalue {cert['R_min_eig']:.3g})")
    if not cert["S_min_eig"] > 0:
        fails.append(f"S > 0 fails (smallest eigenvalue {cert['S_min_eig']:.3g})")
    if not cert["coupling_min_eig"] >= -tol:
        fails.append(
            "[[R, I], [I, S]] >= 0 fails (smallest normalised eigenvalue "
            f"{cert['coupling_min_eig']:.3g} < -{tol:g})"
        )
    for key, what in (("lmi_r_max_eig", "R"), ("lmi_s_max_eig", "S")):
        if not cert[key] <= tol:
            fails.append(
                f"the projected LMI in {what} is not negative definite at gamma_opt "
                f"(largest normalised eigenvalue {cert[key]:.3g} > {tol:g})"
            )
    lb, lbc = cert["dual_bound"], cert["dual_bound_clipped"]
    if not np.isfinite(lb):
        fails.append("no usable dual variables, so optimality cannot be checked")
    elif not (lb >= g * (1.0 - rtol) and lbc <= g * (1.0 + rtol)):
        fails.append(
            f"the dual lower bound is {lb / g:.6g} x gamma_opt (clipped: {lbc / g:.6g}); "
            f"it must lie within {rtol:g} of it for gamma_opt to be the optimum"
        )
    return fails


def _reconstruct_attempt(att, gp, loop, backoff, verify_rtol, solvers, verbose, stats, log):
    """Steps 5 and 6 for one solved scaling: back-off schedule, centring, verification."""
    att.reconstructed = True
    sc, bs, prob, g_opt_s = att.sc, att.bs, att.prob, att.g_opt_s
    tag = f"[{att.label}] "
    for factor in BACKOFF_SCHEDULE:
        b = backoff * factor
        if b >= 1.0:
            break
        gb_s = (1.0 + b) * g_opt_s
        candidates = [("optimal-point", att.R, att.S, gb_s, att.sol)]
        sub = []
        for label, R, S, gs, s_used in _candidate_points(
            candidates, prob, gb_s, solvers, verbose, stats, sub
        ):
            best = _best_reconstruction(
                gp, loop, bs, sc, R, S, gs, verify_rtol, sub, f"backoff {b:g}, {label}"
            )
            if best is not None:
                att.found = (*best, gs, s_used)
                break
        log.extend(tag + line for line in sub)
        if att.found is not None:
            break
    if att.found is None or not att.certified:
        return
    g_opt, g_ver = sc.invert_gamma(g_opt_s), att.found[1][2]
    if not g_opt <= g_ver * (1.0 + CERT_GAP_RTOL):
        att.cert_fails.append(
            f"gamma_opt {g_opt:.6g} exceeds the verified norm {g_ver:.6g} of the rebuilt "
            f"controller by more than {CERT_GAP_RTOL:g}: it is not a lower bound"
        )
        log.append(tag + "gamma_opt NOT certified: " + att.cert_fails[-1])


def _raise_no_controller(done, errors, log):
    """The error when no scaling attempt gave a verified controller."""
    tried = ", ".join([a.label for a in done] + [lab for lab, _ in errors])
    if not done:
        if any(isinstance(e, InfeasibleError) for _, e in errors):
            raise InfeasibleError(
                f"hinfsyn_lmi: the LMI problem was declared infeasible (scalings tried: {tried}); "
                "attempts: " + "; ".join(log)
            )
        raise SolverError(
            f"hinfsyn_lmi: no scaling gave a usable solve (scalings tried: {tried}); "
            "attempts: " + "; ".join(log)
        )
    g = ", ".join(
        f"{a.label} {a.sc.invert_gamma(a.g_opt_s):.6g}"
        f" ({'certified' if a.certified else 'not certified'})"
        for a in done
    )
    raise VerificationError(
        "hinfsyn_lmi: no reconstructed controller passed the independent check "
        f"(optimal LMI gamma by scaling: {g}); attempts: " + "; ".join(log)
    )


def _result(best, labels, done, errors, stats, log, t_start):
    """The :class:`HinfResult` of the chosen attempt, with notes on fallbacks and certification."""
    K, (cl, sa, g), info, gs, s_used = best.found
    sc = best.sc
    notes = []
    if best.label != labels[0]:
        failed = [f"{lab} (solve failed: {type(e).__name__})" for lab, e in errors]
        failed += [
            f"{a.label} ({'gamma_opt not certified' if not a.certified else 'no verified K'})"
            for a in done
            if a is not best and labels.index(a.label) < labels.index(best.label)
        ]
        notes.append(
            f"fallback: the controller comes from the '{best.label}' scaling; "
            f"earlier attempts: {', '.join(failed) or 'none'}"
        )
    if best.certified:
        g_opt = sc.invert_gamma(best.g_opt_s)
    else:
        g_opt = float("nan")
        notes.append(
            f"gamma_opt is not reported (NaN): the LMI optimum {best.cert['gamma_lmi']:.6g} "
            "of this attempt failed the independent check: " + "; ".join(best.cert_fails)
        )
    return HinfResult(
        K=K,
        gamma_bound=sc.invert_gamma(gs),
        gamma=g,
        gamma_opt=g_opt,
        closed_loop=cl,
        spectral_abscissa=sa,
        solver=s_used.solver,
        status=s_used.status,
        iterations=int(sum(s.iterations or 0 for s in stats)),
        solve_time=float(sum(s.solve_time for s in stats)),
        wall_time=time.perf_counter() - t_start,
        backoff=gs / best.g_opt_s - 1.0,
        condition=info,
        order=int(K.nstates),
        attempts=tuple(log),
        gamma_opt_certified=best.certified,
        certificate=dict(best.cert, scaling=best.label),
        scaling=best.label,
        notes=tuple(notes),
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
