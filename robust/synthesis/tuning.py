"""Starts of the LMI iteration: fixed-order controllers tuned over several members.

The sequential LMIs of :mod:`robust.synthesis.pk` are local and need a controller
that already places every design member's poles in the region. This module supplies
it, after the stabilisation phase of HIFOO (Burke, Henrion, Lewis & Overton, IFAC
ROCOND 2006; Gumussoy, Henrion, Millstone & Overton, ROCOND 2009): the controller's
state-space entries ``Omega = [[Ak, Bk], [Ck, Dk]]`` are tuned by BFGS, which handles
such nonsmooth objectives well (Lewis & Overton, Math. Programming 141, 2013), on

    f(Omega) = tau * log mean_j exp((max(v_j, -m) + m) / tau)                (region)
             + w_t * (mean over members and frequencies of |T(jw) / g_t|^8)^(1/8)
             + w_2 * sum over members of relu(h2_i / h2_bound - 1)^2
             + prox * ||(Omega - Omega_0) / unit||^2 / size,

``v_j`` the region violations (decay and damping cone,
:meth:`robust.analysis.region.Region.violations`) of every pole of every
member's region plant, ``m`` the margin, ``T`` the member's H-infinity channel and
``h2_i`` its H2 norm. Gradients are exact: eigenvalues ``d lambda = l^H Bb dOmega Cb r /
l^H r``; frequency responses ``dT = (D12b + C R Bb) dOmega (Cb R B + D21b)`` with
``R = (jw - A)^-1``; the H2 norm through the adjoint Lyapunov equation,
``d||G||^2 = 2 trace(L dA W + ...)`` with ``A W + W A' + B B' = 0`` and
``A' L + L A + C' C = 0``.

The BFGS path depends on rounding: its inverse-Hessian estimate grows ill-conditioned at
the kinks, so the rounding differences of two BLAS kernels end at different controllers.
:func:`minimax_start` is the deterministic alternative: :func:`slp_minimise`, sequential
linear programming with a trust region (Madsen's minimax method), first on the region
violations (:func:`region_start`), then on the largest of the same utilisations that the
second phase's soft maximum weighs.
"""

from __future__ import annotations

import dataclasses

import control
import numpy as np

from robust.analysis.region import Region
from robust.checks import POSITIVE, Spec, check_int, check_scalar
from robust.errors import ModelStructureError
from robust.synthesis.minimise import SLPResult, bfgs_minimise, slp_minimise
from robust.synthesis.pk_members import SynthesisMember, from_scaled, scale_members, to_scaled
from robust.synthesis.pole_derivatives import eigen_region_rows
from robust.synthesis.region import synthesis_region
from robust.synthesis.scaling_base import ControllerMatrices
from robust.synthesis.tuning_objective import _Terms

__all__ = [
    "TuningResult",
    "tune_members",
    "region_start",
    "minimax_start",
    "slp_minimise",
    "SLPResult",
    "REGION_WEIGHT",
    "RESTARTS",
    "BARRIER_WEIGHT",
]

#: BFGS restarts per phase (each from the previous end point).
RESTARTS = 8

#: Weight of the log barrier of the region in the budget phase.
BARRIER_WEIGHT = 1e-4

#: Weight of the region term (in rad/s) against the budget terms.
REGION_WEIGHT = 100.0


@dataclasses.dataclass(frozen=True)
class TuningResult:
    """Result of :func:`tune_members`.

    Parameters
    ----------
    K : control.StateSpace
        The tuned controller.
    violation : float
        Largest region violation over the members' poles, rad/s (negative: inside).
    tracking : float
        Largest ``|T(jw)|`` over the members and the grid.
    h2 : float
        Largest H2 norm over the members (0 without H2 plants).
    response : float
        Largest ``|offset + gain T| / bound`` of the members' response bounds (0 without).
    objective : float
        Final objective value.
    iterations : int
        BFGS iterations.
    """

    K: control.StateSpace
    violation: float
    tracking: float
    h2: float
    response: float
    objective: float
    iterations: int


def _checked_start(owner: str, members, K0, region) -> tuple:
    """The members as a list, ``K0``'s matrices and the region as synthesis enforces it
    (:func:`robust.synthesis.region.synthesis_region`), checked: ``(members, K, nk,
    region)``."""
    region = synthesis_region(region, owner)
    members = list(members)
    if not members or not all(isinstance(m, SynthesisMember) for m in members):
        raise ModelStructureError(f"{owner}: members must be SynthesisMember objects")
    if not isinstance(K0, control.StateSpace):
        raise ModelStructureError(
            f"{owner}: K0 must be a control.StateSpace; got {type(K0).__name__}"
        )
    K = ControllerMatrices(*(np.asarray(M, float) for M in (K0.A, K0.B, K0.C, K0.D)))
    nk = K.Ak.shape[0]
    if K.omega().shape != (nk + members[0].nu, nk + members[0].ny):
        raise ModelStructureError(
            f"{owner}: K0 must map {members[0].ny} measurements to {members[0].nu} controls"
        )
    return members, K, nk, region


def _controller(Om_s, nk: int, w0: float, channels) -> control.StateSpace:
    """The controller ``y -> u`` of scaled controller data."""
    Oo = from_scaled(Om_s, nk, w0, channels)
    return control.ss(Oo[:nk, :nk], Oo[:nk, nk:], Oo[nk:, :nk], Oo[nk:, nk:])


def _tuning_result(terms, Om, nk: int, w0: float, channels, objective: float, iterations: int):
    """The :class:`TuningResult` of scaled controller data: its violation and budgets."""
    _, _, viol = terms.region_term(Om)
    _, _, trk = terms.tracking_term(Om)
    _, _, resp = terms.response_term(Om)
    h2 = terms.h2_term(Om)[2] * np.sqrt(w0) if terms.h2 and np.isfinite(terms.h2_bound) else 0.0
    Kt = _controller(Om, nk, w0, channels)
    return TuningResult(Kt, viol * w0, trk, float(h2), resp, objective, iterations)


def tune_members(
    members,
    K0,
    region: Region,
    *,
    tracking_bound: float = 1.0,
    h2_bound: float | None = None,
    freqs_hz=None,
    margin: float = 0.2,
    tau: float = 0.05,
    weights: tuple[float, float] = (10.0, 10.0),
    prox: float = 1e-4,
    max_iter: int = 400,
    restarts: int = RESTARTS,
    w0: float = 20.0,
) -> TuningResult:
    """Tune ``K0`` over ``members``: poles in ``region`` with a margin, budgets kept.

    See the module notes for the objective.

    Parameters
    ----------
    members : sequence of SynthesisMember
        Design members.
    K0 : control.StateSpace
        Starting controller ``y -> u`` (fixes the order).
    region : robust.analysis.region.Region
        The region; the objective stops pushing once every violation is below
        ``-margin``.
    tracking_bound : float
        Scale ``g_t`` of ``|T(jw)|`` of every member's H-infinity channel on the grid (the
        soft maximum of ``|T| / g_t`` is minimised; 1 at the specification's edge).
    h2_bound : float, optional
        Bound on every member's H2 norm (needs H2 plants).
    freqs_hz : array_like, optional
        Frequency grid of the tracking term, Hz (default 30 log-spaced, 0.05-3 Hz).
    margin : float
        Region margin, rad/s.
    tau : float
        Temperature of the log-sum-exp, rad/s.
    weights : (float, float)
        Weights of the tracking and H2 terms.
    prox : float
        Weight of the proximal term to ``K0``.
    max_iter : int
        BFGS iterations per run.
    restarts : int
        BFGS runs per phase, each from the previous end point with a fresh Hessian (the
        phase stops early when a run no longer decreases the objective).
    w0 : float
        Time scale of the tuning, rad/s (as :func:`robust.synthesis.pk.pksyn_multi`).

    Returns
    -------
    TuningResult
    """
    members, K, nk, region = _checked_start("tune_members", members, K0, region)
    for name, val in (("tracking_bound", tracking_bound), ("margin", margin), ("tau", tau)):
        check_scalar(name, val, POSITIVE, owner="tune_members")
    if h2_bound is not None:
        check_scalar("h2_bound", h2_bound, POSITIVE, owner="tune_members")
    check_scalar("prox", prox, Spec(low=0.0), owner="tune_members")
    check_int("max_iter", max_iter, low=0, owner="tune_members")
    check_int("restarts", restarts, low=1, owner="tune_members")
    check_scalar("w0", w0, POSITIVE, owner="tune_members")
    f_hz = np.geomspace(0.05, 3.0, 30) if freqs_hz is None else np.asarray(freqs_hz, float)
    channels, scaled = scale_members(members, nk, w0)
    Om0 = to_scaled(K.omega(), nk, w0, channels)
    unit = np.ones_like(Om0)
    terms = _Terms(
        scaled,
        region.scaled(w0),
        2 * np.pi * f_hz / w0,
        margin / w0,
        tau / w0,
        tracking_bound,
        (h2_bound / np.sqrt(w0)) if h2_bound is not None else np.inf,
    )
    wt, w2 = weights

    def fun(theta, budget_scale):
        Om = theta.reshape(Om0.shape) * unit
        if budget_scale < 1:
            val, grad, _ = terms.region_term(Om)
            # the region term in rad/s, weighted so that feasibility comes first
            val, grad = REGION_WEIGHT * w0 * val, REGION_WEIGHT * w0 * grad
        else:
            # phase B starts inside the region: a log barrier keeps it there smoothly
            val, grad = terms.barrier_term(Om)
            if not np.isfinite(val):
                return 1e300, np.zeros(theta.size)
            val, grad = BARRIER_WEIGHT * val, BARRIER_WEIGHT * grad
        if budget_scale < 1:
            tv, tg, _ = terms.tracking_term(Om)
            rv, rg, _ = terms.response_term(Om)
            hv, hg, _ = terms.h2_term(Om) if h2_bound is not None else (0.0, 0.0, 0.0)
            val += budget_scale * (wt * (tv + rv) + w2 * hv)
            grad = grad + budget_scale * (wt * (tg + rg) + w2 * hg)
        else:
            uv, ug, _ = terms.utilisation_term(Om)
            val, grad = val + wt * uv, grad + wt * ug
        d = (Om - Om0) / unit
        val += prox * np.sum(d * d) / d.size
        grad = grad + 2 * prox * d / d.size / unit
        return val, (grad * unit).ravel()

    # phase A: into the region (budgets nearly off); phase B: the budgets, the region kept
    # by the same (then flat) term
    x = (Om0 / unit).ravel()
    nit = 0
    for budget_scale in (1e-3, 1.0):
        xb, fb = x, fun(x, budget_scale)[0]
        # BFGS on a nonsmooth objective may stop at a kink; restarting from the last point
        # (a fresh Hessian) continues the descent
        for _ in range(restarts):
            xr, fr, it = bfgs_minimise(lambda th, bs=budget_scale: fun(th, bs), xb, max_iter)
            nit += it
            if not fr < fb - 1e-9 * max(abs(fb), 1e-12):
                break
            xb, fb = xr, fr
        if budget_scale < 1 or terms.region_term(xb.reshape(Om0.shape) * unit)[2] < 0:
            x = xb
    Om = x.reshape(Om0.shape) * unit
    return _tuning_result(terms, Om, nk, w0, channels, float(fun(x, 1.0)[0]), nit)


def _region_rows(scaled, region_s):
    def evaluate(Om):
        rows = [r for m in scaled for r in eigen_region_rows(m.region, Om, region_s)]
        v = np.array([r[0] for r in rows])
        G = np.array([r[1].ravel() for r in rows])
        return v, G, 0.0, np.zeros(Om.size)

    return evaluate


def region_start(
    members,
    K0,
    region: Region,
    *,
    margin: float = 0.05,
    max_iter: int = 60,
    trust: float = 0.1,
    prox: float = 1e-3,
    w0: float = 20.0,
) -> TuningResult:
    """Move ``K0`` the least it takes to put every member's poles in ``region`` with a margin.

    A deterministic start for :func:`robust.synthesis.pk.pksyn_multi`:
    :func:`slp_minimise` on the region violations of every member's poles (decay and
    damping cone, the first-order eigenvalue model of the K-step, ``d lambda = l^H Bb
    dOmega Cb r / l^H r``), in the scaled controller data of the P-K iteration, with a
    small L1 distance to ``K0`` (moves as few entries as the region needs). A ``K0`` that
    meets the margin already is returned unchanged.

    Parameters
    ----------
    members : sequence of SynthesisMember
        Design members.
    K0 : control.StateSpace
        Starting controller ``y -> u`` (fixes the order).
    region : robust.analysis.region.Region
        The region (its damping enforced at every frequency).
    margin : float
        Required distance inside the region, rad/s.
    max_iter : int
        Largest number of linear programs.
    trust : float
        Initial trust-region radius, relative to the root-mean-square controller entry.
    prox : float
        Weight of the L1 distance to ``K0``.
    w0 : float
        Time scale, rad/s (as :func:`robust.synthesis.pk.pksyn_multi`).

    Returns
    -------
    TuningResult
        ``tracking``, ``h2`` and ``response`` are not evaluated (0); ``violation`` and
        ``objective`` are the final largest violation in rad/s; ``iterations`` the linear
        programs solved.
    """
    members, K, nk, region = _checked_start("region_start", members, K0, region)
    for name, val in (("margin", margin), ("trust", trust), ("w0", w0)):
        check_scalar(name, val, POSITIVE, owner="region_start")
    check_scalar("prox", prox, Spec(low=0.0), owner="region_start")
    check_int("max_iter", max_iter, low=0, owner="region_start")
    channels, scaled = scale_members(members, nk, w0)
    evaluate = _region_rows(scaled, region.scaled(w0))
    Om = to_scaled(K.omega(), nk, w0, channels)
    target = -margin / w0
    if evaluate(Om)[0].max() < target:
        res = SLPResult(Om, float(evaluate(Om)[0].max()), 0.0, 0.0, 0, 0)
    else:
        unit = max(1.0, float(np.sqrt(np.mean(Om * Om))))
        # poles far inside cannot reach the boundary within the trust region (scaled time:
        # 0.5 is the K-step's ACTIVE)
        # the steps approach their level from above: aiming a tenth deeper than the
        # margin ends with the margin met
        res = slp_minimise(
            evaluate,
            Om,
            np.full(Om.shape, unit),
            target=1.1 * target,
            prox=prox,
            trust=trust,
            max_iter=max_iter,
            active=0.5,
        )
    Kt = _controller(res.x, nk, w0, channels)
    return TuningResult(Kt, res.worst * w0, 0.0, 0.0, 0.0, res.worst * w0, res.iterations)


def minimax_start(
    members,
    K0,
    region: Region,
    *,
    tracking_bound: float = 1.0,
    h2_bound: float | None = None,
    freqs_hz=None,
    margin: float = 0.05,
    max_iter: int = 100,
    trust: float = 0.05,
    prox: float = 1e-4,
    w0: float = 20.0,
    keep_region: bool = True,
) -> TuningResult:
    """A deterministic start: into the region, then the largest utilisation minimised.

    :func:`region_start` first, then :func:`slp_minimise` (a minimax method by sequential
    linear programming, Madsen, "An algorithm for minimax solution of overdetermined
    systems of non-linear equations", J. Inst. Maths Applics 16, 1975) on every
    utilisation of the specification's budgets (those of :func:`tune_members`'s second
    phase: the poles' required over achieved decay rate and damping ratio, ``|T(jw)| /
    tracking_bound`` on the grid, each member's H2 norm over ``h2_bound``, the response
    bounds), all at once: where :func:`tune_members` minimises a soft maximum by BFGS, this
    minimises the maximum itself, and its steps depend continuously on the data. Where the
    second stage ends outside the region (the budgets cannot all be met, and the minimax
    spreads the excess over the region's utilisations too), it is run again (with
    ``keep_region``) from the first stage's controller with the region kept as a
    constraint of every linear program and every accepted step; should that end outside
    too, the first stage's controller is returned.

    Parameters
    ----------
    members : sequence of SynthesisMember
        Design members.
    K0 : control.StateSpace
        Starting controller ``y -> u``.
    region : robust.analysis.region.Region
        The region (its damping enforced at every frequency).
    tracking_bound : float
        Scale of ``|T(jw)|`` (1 at the specification's edge).
    h2_bound : float, optional
        Bound on every member's H2 norm (needs H2 plants).
    freqs_hz : array_like, optional
        Frequency grid of the tracking utilisations, Hz (default 30 log-spaced, 0.05-3 Hz).
    margin : float
        Region margin of the first stage, rad/s.
    max_iter : int
        Linear programs of each stage.
    trust : float
        Initial trust-region radius of the second stage, relative to the root-mean-square
        controller entry.
    prox : float
        Weight of the L1 distance to the region stage's controller.
    w0 : float
        Time scale, rad/s.
    keep_region : bool
        Keep the region when the second stage leaves it (see above); ``False`` returns
        the second stage's controller outside the region, for a caller with another
        method to try.

    Returns
    -------
    TuningResult
    """
    first = region_start(members, K0, region, margin=margin, max_iter=max_iter, w0=w0)
    if first.violation >= 0:
        return first
    region = region.everywhere()
    check_scalar("tracking_bound", tracking_bound, POSITIVE, owner="minimax_start")
    if h2_bound is not None:
        check_scalar("h2_bound", h2_bound, POSITIVE, owner="minimax_start")
    K = first.K
    nk = K.nstates
    channels, scaled = scale_members(members, nk, w0)
    Om = to_scaled(np.block([[K.A, K.B], [K.C, K.D]]), nk, w0, channels)
    f_hz = np.geomspace(0.05, 3.0, 30) if freqs_hz is None else np.asarray(freqs_hz, float)
    terms = _Terms(
        scaled,
        region.scaled(w0),
        2 * np.pi * f_hz / w0,
        margin / w0,
        1.0,
        tracking_bound,
        (h2_bound / np.sqrt(w0)) if h2_bound is not None else np.inf,
    )

    def evaluate(x):
        u, du = terms.utilisations(x)
        return u, du.reshape(u.size, -1), 0.0, np.zeros(x.size)

    unit = max(1.0, float(np.sqrt(np.mean(Om * Om))))

    def run(constraints=None):
        res = slp_minimise(
            evaluate,
            Om,
            np.full(Om.shape, unit),
            target=0.0,
            prox=prox,
            trust=trust,
            max_iter=max_iter,
            constraints=constraints,
        )
        its = first.iterations + res.iterations
        return _tuning_result(terms, res.x, nk, w0, channels, res.merit, its)

    out = run()
    if out.violation < 0 or not keep_region:
        return out
    # the budgets' minimax left the region: its decay and damping utilisations weigh no
    # more than the budgets, so where the budgets cannot all be met it spreads the excess
    # over the region too. Again from the region stage's controller, with the region
    # kept as a constraint (a tenth of the margin inside; every iterate stays in it)
    in_region = _region_rows(scaled, region.scaled(w0))
    level = max(-0.1 * margin / w0, float(in_region(Om)[0].max()))

    def inside(x):
        v, G, _, _ = in_region(x)
        return v - level, G

    out = run(inside)
    return out if out.violation < 0 else first
