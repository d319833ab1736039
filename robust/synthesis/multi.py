"""Multi-model H-infinity synthesis: one controller for a set of plants, verified per member.

:func:`hinfsyn_multi` takes generalized plants, finds a controller that stabilises
every member (or takes the caller's), and runs the workbench's one sequential convex
(analysis/synthesis, "P-K") iteration, :func:`robust.synthesis.pk.pksyn_multi`, with each
member as its own H-infinity channel; it returns the controller with a bounded-real
certificate for every member, each certificate rebuilt in numpy on the member's closed
loop and each member's norm recomputed independently (Bruinsma-Steinbuch,
:func:`robust.analysis.norms.hinf_norm`) before anything is returned.

References: see :mod:`robust.synthesis.lmi`.
"""

from __future__ import annotations

import dataclasses
import time

import control
import numpy as np

from robust.analysis.norms import hinf_norm, spectral_abscissa
from robust.analysis.region import Region
from robust.analysis.stability import stability_bound
from robust.checks import POSITIVE, Spec, check_scalar
from robust.errors import (
    AssumptionError,
    InfeasibleError,
    ModelStructureError,
    ParameterError,
    SolverError,
    VerificationError,
)
from robust.synthesis.assumptions import check_hinf_assumptions
from robust.synthesis.genplant import GeneralizedPlant, as_generalized_plant
from robust.synthesis.lmi import PlantBlocks
from robust.synthesis.nominal import hinfsyn_lmi
from robust.synthesis.pk import pksyn_multi
from robust.synthesis.pk_members import SynthesisMember
from robust.synthesis.scaling import PlantScaling
from robust.synthesis.solve import DEFAULT_SOLVERS, check_solvers

__all__ = ["MultiHinfResult", "hinfsyn_multi"]


@dataclasses.dataclass(frozen=True)
class MultiHinfResult:
    """A verified multi-model design: one controller, a certificate per member.

    Attributes
    ----------
    K : control.StateSpace
        The common controller, ``u = K y``.
    gamma_bound : float
        Common bound certified by the final analysis step: every member i has a
        Lyapunov matrix ``P_i > 0`` proving ``||F_l(P_i, K)||_inf < gamma_bound`` (each
        member certified at ``1 + LEVEL_SLACK`` = 1.02 times its norm, the bound the largest
        of these).
    gammas : numpy.ndarray, shape (n_members,)
        H-infinity norm of each member's closed loop, computed independently
        (Bruinsma-Steinbuch); each ``<= gamma_bound * (1 + verify_rtol)``.
    spectral_abscissas : numpy.ndarray, shape (n_members,)
        Largest closed-loop pole real part of each member, rad/s (all below
        :func:`robust.analysis.stability.stability_bound`).
    certificates : tuple of numpy.ndarray
        The Lyapunov matrices ``P_i`` of the closed loops ``F_l(P_i, K)`` in the
        coordinates of :meth:`GeneralizedPlant.closed_loop` (plant states, then
        controller states): ``[[Acl' P + P Acl, P Bcl, Ccl'], [., -g I, Dcl'],
        [., ., -g I]] < 0`` with ``g = gamma_bound``.
    history : tuple of float
        Certified worst-member level at the initial controller and after each accepted
        step.
    iterations : int
        Number of analysis/synthesis (P/K) iterations performed.
    solve_time, wall_time : float
        Seconds in the solvers, and for the whole call.
    method : str
        Short description of the method and guarantee.
    scaling : dict
        ``w0``: the time scale of the SDPs, rad/s (that of
        :class:`robust.synthesis.scaling.PlantScaling` fitted to the mean plant); the
        channels are scaled by :func:`robust.synthesis.pk.pksyn_multi`.
    notes : tuple of str
        What went wrong on the way and the fallback taken (e.g. the final analysis
        step solved without scaling because the scaled one failed).
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
    notes: tuple = ()

    @property
    def gamma(self) -> float:
        """Worst member's verified norm."""
        return float(np.max(self.gammas))


def _cl_norms(gps, K):
    """Spectral abscissa and norm (``inf`` unless stable) of every member's closed loop."""
    out = []
    for gp in gps:
        cl = gp.closed_loop(K)
        sa = spectral_abscissa(cl)
        out.append((sa, hinf_norm(cl) if sa < stability_bound() else np.inf))
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])


def _check_options(plants, max_iter, rtol, trust, verify_rtol, solvers, verbose):
    """Validate the options of :func:`hinfsyn_multi` before any work; return the checked ones."""
    if isinstance(plants, (GeneralizedPlant, control.InputOutputSystem)):
        raise ModelStructureError(
            "hinfsyn_multi: plants must be a sequence of plants (one per member); got a single "
            f"{type(plants).__name__}: wrap it in a list"
        )
    if isinstance(plants, (str, bytes)):
        raise ModelStructureError(
            f"hinfsyn_multi: plants must be a sequence of plants; got the string {plants!r}"
        )
    try:
        plants = list(plants)
    except TypeError:
        raise ModelStructureError(
            "hinfsyn_multi: plants must be a sequence of plants (control.StateSpace or "
            f"GeneralizedPlant); got {type(plants).__name__}"
        ) from None
    if isinstance(max_iter, (bool, np.bool_)) or not (
        isinstance(max_iter, (int, np.integer)) and max_iter >= 0
    ):
        raise ParameterError(
            f"hinfsyn_multi: max_iter must be a nonnegative integer; got {max_iter!r} "
            f"({type(max_iter).__name__})"
        )
    rtol = check_scalar("rtol", rtol, Spec(0.0, 1.0, False, True), owner="hinfsyn_multi")
    trust = check_scalar("trust", trust, POSITIVE, owner="hinfsyn_multi")
    verify_rtol = check_scalar(
        "verify_rtol", verify_rtol, Spec(0.0, 0.1, True, True), owner="hinfsyn_multi"
    )
    solvers = check_solvers(solvers, name="hinfsyn_multi: solvers", sdp=True)
    if not isinstance(verbose, (bool, np.bool_)):
        raise ParameterError(f"hinfsyn_multi: verbose must be True or False; got {verbose!r}")
    return plants, int(max_iter), rtol, trust, verify_rtol, solvers


def _check_k0(K0, gp):
    """``K0`` as a continuous-time state-space controller from y to u, with finite matrices."""
    if not isinstance(K0, (control.StateSpace, control.TransferFunction)):
        raise ParameterError(
            "hinfsyn_multi: K0 must be a control.StateSpace or TransferFunction controller "
            f"from y to u; got {type(K0).__name__}"
        )
    for part in ("num", "den") if isinstance(K0, control.TransferFunction) else ():
        if not all(np.all(np.isfinite(np.asarray(c, float))) for r in getattr(K0, part) for c in r):
            raise ParameterError(f"hinfsyn_multi: K0's {part} contains NaN or inf")
    K = control.ss(K0)
    for name in ("A", "B", "C", "D"):
        if not np.all(np.isfinite(np.asarray(getattr(K, name), float))):
            raise ParameterError(f"hinfsyn_multi: K0.{name} must be finite; got NaN or inf entries")
    if not K.isctime():
        raise ModelStructureError(
            f"hinfsyn_multi: K0 must be a continuous-time controller; got dt={K.dt}"
        )
    if K.ninputs != gp.ny or K.noutputs != gp.nu:
        raise ModelStructureError(
            f"hinfsyn_multi: K0 must have {gp.ny} input(s) (y) and {gp.nu} output(s) (u); "
            f"got {K.ninputs} and {K.noutputs}"
        )
    return K


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
        stable = sa < stability_bound()
        if np.all(stable):
            if best is None or norms.max() < best[1]:
                best = (K, float(norms.max()), label)
            if label == "mean plant":
                break
        else:
            log.append(
                f"initial design on {label} leaves {int(np.sum(~stable))} member(s) unstable"
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
       nominal :func:`robust.synthesis.nominal.hinfsyn_lmi` design on the mean
       plant, else on a member);
    2. the P-K iteration of :func:`robust.synthesis.pk.pksyn_multi` with every member
       as one H-infinity channel (its pole region the open left half-plane): P-step,
       with K fixed, one bounded-real LMI per member in its own Lyapunov matrix
       ``P_i`` at 1.02 times the member's norm, in coordinates where ``P_i`` is the
       identity; K-step, with the ``P_i`` fixed, one LMI in the controller data
       ``[[Ak, Bk], [Ck, Dk]]`` ([GA94] eq. (2.5)) minimising the common level within
       a trust region; a step is kept only if the certified worst-member level
       decreases (otherwise the region is halved); stop when the relative decrease is
       below ``rtol``.

    The SDPs are solved with the time scale of the mean plant
    (:class:`robust.synthesis.scaling.PlantScaling`) and the channel scaling of
    :func:`robust.synthesis.pk.scale_members`, common to every member so that one
    controller serves them all.

    Guarantee (what is and is not claimed): the returned controller has, for
    *every listed member*, a Lyapunov certificate ``P_i > 0`` from the final
    P-step proving closed-loop stability and ``||T_zw,i||_inf < gamma_bound``,
    and each member's norm has been recomputed independently.  Nothing is
    claimed for plants between the members (members may differ in any
    matrix, so there is no common certificate over their convex hull), and the
    iteration is a local method: ``gamma_bound`` is not the optimum of the
    (non-convex) multi-model problem.  The certified worst-member level never
    increases from one accepted step to the next.

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
        Initial relative trust-region radius of the K-step
        (:func:`robust.synthesis.pk.pksyn_multi`).
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
        ``plants`` not a sequence of plants, members with different signal counts,
        discrete time, or an empty set; ``K0`` of the wrong size or discrete time.
    AssumptionError
        A member is not stabilisable/detectable, or has ``D22 != 0``.
    ParameterError
        ``max_iter`` is not a nonnegative integer, ``rtol`` not in [0, 1), ``trust``
        not positive, ``verify_rtol`` not in (0, 0.1), ``solvers`` empty, unknown or
        unable to solve SDPs, ``verbose`` not a bool, ``K0`` not a system or not finite.
    InfeasibleError
        No initial controller stabilises every member.
    VerificationError
        The final certificate or a member's independent norm check fails.
    """
    t_start = time.perf_counter()
    plants, max_iter, rtol, trust, verify_rtol, solvers = _check_options(
        plants, max_iter, rtol, trust, verify_rtol, solvers, verbose
    )
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
                f"member {i}: hinfsyn_multi requires D22 = 0; "
                f"got max |D22| = {np.abs(gp.D22).max():.3g}"
            )
    log: list[str] = []
    if K0 is None:
        init = _initial_controller(gps, solvers, log)
        if init is None:
            raise InfeasibleError(
                "hinfsyn_multi: no initial controller stabilises every member (tried nominal "
                "designs on the mean plant and on each member); pass K0 or split the family. "
                + "; ".join(log)
            )
        K = init[0]
    else:
        K = _check_k0(K0, gps[0])
    sa, norms = _cl_norms(gps, K)
    if not np.all(sa < stability_bound()):
        raise InfeasibleError(
            f"hinfsyn_multi: K0 must stabilise every member; it leaves members "
            f"{np.flatnonzero(~(sa < stability_bound())).tolist()} unstable "
            f"(spectral abscissas {sa.tolist()} rad/s)"
        )
    blocks = [PlantBlocks.from_generalized_plant(gp) for gp in gps]
    w0 = float(PlantScaling.fit(PlantBlocks.from_generalized_plant(_mean_plant(gps))).time.w0)
    members = [SynthesisMember(region=b, hinf=b, label=f"member {i}") for i, b in enumerate(blocks)]
    try:
        res = pksyn_multi(
            members,
            K,
            Region(),
            w0=w0,
            max_iter=max_iter,
            trust=trust,
            rtol=rtol,
            solvers=solvers,
        )
    except InfeasibleError as exc:
        # the initial certificates: the members are stable, so only the solver can refuse
        raise SolverError(f"hinfsyn_multi: {exc}") from None
    K = control.ss(
        res.K.A, res.K.B, res.K.C, res.K.D, inputs=list(gps[0].y), outputs=list(gps[0].u), name="K"
    )
    gamma_bound = float(res.gamma_bound)
    sa, norms = _cl_norms(gps, K)
    bad = [
        i
        for i in range(len(gps))
        if not (sa[i] < stability_bound() and norms[i] <= gamma_bound * (1.0 + verify_rtol))
    ]
    if bad:
        raise VerificationError(
            f"hinfsyn_multi: members {bad} fail the independent check against the certified "
            f"bound {gamma_bound:.6g} (norms {norms[bad]}, spectral abscissas {sa[bad]})"
        )
    # each member's bounded-real certificate (at its own level, so at the common one)
    # rebuilt in numpy on the closed loop as GeneralizedPlant.closed_loop orders its states
    certificates = tuple(c.P for c in res.certificates)
    for i, (gp, P) in enumerate(zip(gps, certificates)):
        worst = _brl_max_eig(gp.closed_loop(K), P, gamma_bound)
        if not (np.linalg.eigvalsh(P).min() > 0 and worst < 0):
            raise VerificationError(
                f"hinfsyn_multi: member {i}: the bounded-real certificate fails its re-check "
                f"(largest eigenvalue {worst:.3g})"
            )
    return MultiHinfResult(
        K=K,
        gamma_bound=gamma_bound,
        gammas=norms,
        spectral_abscissas=sa,
        certificates=certificates,
        history=tuple(float(h["gamma"]) for h in res.history),
        iterations=res.iterations,
        solve_time=float(sum(res.solve_times)),
        wall_time=time.perf_counter() - t_start,
        method=(
            "P-K iteration (El Ghaoui & Balakrishnan 1994; robust.synthesis.pk.pksyn_multi) "
            "with per-member bounded-real certificates"
        ),
        scaling={"w0": w0},
        notes=tuple(log) + tuple(res.notes),
    )


def _brl_max_eig(cl, P, g) -> float:
    """Largest eigenvalue of the bounded-real matrix of ``cl`` at level ``g`` with ``P``."""
    A, B, C, D = (np.asarray(m, float) for m in (cl.A, cl.B, cl.C, cl.D))
    M = np.block(
        [
            [A.T @ P + P @ A, P @ B, C.T],
            [B.T @ P, -g * np.eye(B.shape[1]), D.T],
            [C, D, -g * np.eye(C.shape[0])],
        ]
    )
    return float(np.linalg.eigvalsh((M + M.T) / 2).max())


def _mean_plant(gps):
    """Elementwise mean of the members' blocks (equal state dimensions), else the first member."""
    if len({gp.nx for gp in gps}) != 1:
        return gps[0]
    keys = gps[0].blocks()
    return gps[0].with_blocks(**{k: np.mean([gp.blocks()[k] for gp in gps], axis=0) for k in keys})
