"""Robust compensators by LMI synthesis, with the certified robust margin maximised.

The design, top to bottom (the same steps serve the three designs of this module):

1. family and specification: the default family (or its doubled workspace) and the
   handle-force specification :class:`designs.spec.Specification` (device force limits
   under the realistic intended motion, pole region, tracking, feedthrough);
2. start: a fixed-order controller (the nominal LMI H-infinity design balanced-truncated
   to ``order`` for handle force; a seeded low-gain filter for the cylinder reference);
3. a ladder of family scales ``k`` (the box scaled about the nominal, as the robust margin
   scales it, :mod:`uncertainty.margins`). At each scale, rounds of:

   * design members: the nominal, then the member of the scaled box whose closed-loop
     poles break the region most (:func:`uncertainty.search.worst_member`) and the
     sampled member that binds the specification;
   * synthesis: a start placing every design member's poles in the region with the
     budgets' largest utilisation minimised, by linear programs
     (:func:`robust.synthesis.tuning.minimax_start`; where they end outside the region,
     the nonsmooth tuning :func:`robust.synthesis.tuning.tune_members`), then
     :func:`robust.synthesis.pk.pksyn_multi`, the LMI synthesis: the P-K iteration with
     a certificate per design member (bounded-real with decay rate, H2 for the RMS
     force, Chilali-Gahinet region);
   * checks: no member of the scaled box found outside the region, and the
     specification on the design members and on seeded samples of the scaled box
     (:func:`designs.spec.check_specification`);

4. bisection between the last scale reached and the first that failed;
5. the pole region certified over the whole scaled box of every scale reached, with the
   controller found there (:func:`uncertainty.margins.margin_lower_bound` at ``k``). The
   path never depends on it, so the scales are certified after the ladder, together
   (in the processes :func:`robust.engine.nested_jobs` grants);
6. result: the controller of the largest scale reached, its certificates, the largest
   scale certified, and the constraint that binds at the first scale not reached.

Within a synthesis the members' P-step SDPs are independent, and run in the processes
granted the same way; ``bdft design`` grants its ``--jobs``, a design in the report's
pool of designs none. Every split is combined in order, so the controller is the same
to the bit on any number of processes.

The force budget of the synthesis is the RMS force ``min(budget_fraction * continuous,
peak / crest_factor)``: the peak force of a realistic motion is about ``crest_factor``
times its RMS (4.2 on the 20 s simulations of the specification).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import shutil
import tempfile
import time

import control as ct
import numpy as np
from joblib.externals.loky import ProcessPoolExecutor

from designs.hinf_nominal import design_hinf_nominal
from designs.result import Design, DesignFacts, DesignResult
from designs.spec import Specification, check_specification
from robust.analysis.reduction import balanced_truncation
from robust.cache import caching, caching_enabled, lookup, store
from robust.checks import POSITIVE, Spec, check_int, validate_fields
from robust.engine import jobs_available, map_tasks
from robust.errors import BDFTError, InfeasibleError, ParameterError
from robust.synthesis.forcefb import synthesis_member
from robust.synthesis.pk import certify_regions, pksyn_multi
from robust.synthesis.solve import deterministic_solvers
from robust.synthesis.tuning import minimax_start, tune_members
from uncertainty.margins import margin_lower_bound
from uncertainty.search import scaled_bounds, worst_member

__all__ = [
    "RobustOptions",
    "ScaleLevel",
    "RobustLMIDesign",
    "RobustLMIFacts",
    "maximise_margin",
    "TradeoffPoint",
    "force_tradeoff",
    "tradeoff_tasks",
    "tradeoff_point",
    "build",
    "build_cylinder",
    "build_workspace_force",
    "DESIGN",
    "DESIGN_CYLINDER",
    "DESIGN_WORKSPACE_FORCE",
]

#: Ways of bringing a round's controller into the region (:class:`RobustOptions`).
START_METHODS = ("minimax-bfgs", "minimax", "bfgs")

#: Scales tried upwards (the box about the nominal; 1 = the whole family).
LADDER = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0)


@dataclasses.dataclass(frozen=True)
class RobustOptions:
    """Settings of the margin maximisation (every one changes the result; all are reported).

    Parameters
    ----------
    controls : tuple of str
        Controller outputs (``("f",)`` handle force, ``("r_corr",)`` cylinder reference).
    measurements : tuple of str
        Controller inputs, among ``x``, ``c``, ``y``.
    order : int
        Controller order.
    budget_fraction : float
        Fraction of the continuous-force limit the RMS force of the design members may use.
    crest_factor : float
        Assumed peak-to-RMS ratio of the force under the realistic motion.
    tracking_bound : float
        Bound of the weighted tracking channel on the design members (below 1 leaves
        room for the members between them).
    ladder : tuple of float
        Scales tried upwards.
    bisection : int
        Bisection steps between the last scale reached and the first failed.
    rounds : int
        Design-member rounds per scale (four: with three, whether a rung was reached hung
        on the BLAS kernel's rounding; see ``start``).
    pk_iterations : int
        P-K steps per round.
    start : str
        How each round's controller is brought into the region before the LMI synthesis.
        ``"minimax"``: :func:`robust.synthesis.tuning.minimax_start` alone, sequential
        linear programs into the region, then on the largest utilisation of the budgets
        with the region kept (measured on the default family,
        ``benchmarks/bench_robust_lmi.py --ladder``: scale 0.05 reached in 136 s).
        ``"minimax-bfgs"`` (default): the same linear programs, but where the budgets'
        minimax leaves the region (the budgets cannot all be met) the nonsmooth tuning
        :func:`robust.synthesis.tuning.tune_members` takes over. ``"bfgs"``: the nonsmooth
        tuning in every round. With either start the ladder's path depends on rounding:
        the linear programs' trust-region steps, the SDP solver's answers and the rounds'
        design members are decisions that a last-digit change of the data can flip, and a
        rung is reached or not by a few tenths of a rad/s of region violation in its last
        round. Measured (``minimax-bfgs``, scale reached; the README has the table): with
        three rounds per scale 0.075, 0.05 and 0.035 on the SkylakeX, Haswell and
        Sandybridge BLAS kernels; with four (``rounds``' default) 0.075 on all three.
        The ``bdft`` command fixes the kernels (:mod:`bdft.kernels`), so from the command
        line the path is the same on every x86-64 CPU with AVX2 and FMA.
    tune_iterations : int
        Iterations of the start (linear programs; BFGS iterations per run).
    tune_restarts : int
        BFGS runs per phase of the nonsmooth tuning.
    worst_samples : int
        Latin-hypercube members of the worst-member search per round.
    spec_samples : int
        Seeded members of the scaled box the specification is checked on per round.
    margin_boxes : int
        Sub-boxes of the region certificate per scale.
    seed : int
        Seed of every sample (written into the result).
    """

    controls: tuple = ("f",)
    measurements: tuple = ("x", "c")
    order: int = 4
    budget_fraction: float = 0.95
    crest_factor: float = 4.2
    tracking_bound: float = 0.95
    ladder: tuple = LADDER
    bisection: int = 1
    rounds: int = 4
    pk_iterations: int = 4
    start: str = "minimax-bfgs"
    tune_iterations: int = 100
    tune_restarts: int = 2
    worst_samples: int = 200
    spec_samples: int = 12
    margin_boxes: int = 60
    seed: int = 0

    def __post_init__(self):
        validate_fields(
            self,
            {
                "budget_fraction": Spec(0.0, 1.0, True, False),
                "crest_factor": POSITIVE,
                "tracking_bound": POSITIVE,
            },
        )
        for name, low in (
            ("order", 1),
            ("bisection", 0),
            ("rounds", 1),
            ("pk_iterations", 0),
            ("tune_iterations", 0),
            ("tune_restarts", 1),
            ("worst_samples", 10),
            ("spec_samples", 0),
            ("margin_boxes", 1),
            ("seed", 0),
        ):
            check_int(name, getattr(self, name), low=low, owner="RobustOptions")
        ladder = tuple(float(k) for k in self.ladder)
        if not ladder or any(not (0 < k <= 8) for k in ladder) or list(ladder) != sorted(ladder):
            raise ParameterError(
                f"RobustOptions.ladder must be increasing scales in (0, 8]; got {self.ladder}"
            )
        object.__setattr__(self, "ladder", ladder)
        if self.start not in START_METHODS:
            raise ParameterError(
                f"RobustOptions.start must be one of {START_METHODS}; got {self.start!r}"
            )

    def force_budget(self, spec: Specification) -> float:
        """The RMS force the synthesis allows, N."""
        return min(
            self.budget_fraction * spec.continuous_force_n, spec.peak_force_n / self.crest_factor
        )


@dataclasses.dataclass(frozen=True)
class ScaleLevel:
    """One scale tried.

    Parameters
    ----------
    scale : float
        The box scale.
    reached : bool
        Whether a controller met the checks on members at this scale: no member of the
        scaled box found outside the region, the specification on the design members and
        the seeded samples.
    members : int
        Design members at the end.
    worst_violation : float
        Largest region violation found in the scaled box, rad/s.
    certified : bool
        Whether, in addition, the region was certified over the whole scaled box.
    binding : str
        The binding constraint among :data:`LADDER_CONSTRAINTS` on the checked members.
    utilisation : float
        Its utilisation (above 1: violated).
    reason : str
        Why the scale was not reached (empty if it was).
    seconds : float
        Time spent at this scale (its certification, run after the ladder, aside).
    starts : dict
        Rounds started by each method (``minimax``: the linear programs; ``bfgs``: the
        nonsmooth tuning, run when the linear programs end outside the region).
    """

    scale: float
    reached: bool
    members: int
    worst_violation: float
    certified: bool
    binding: str
    utilisation: float
    reason: str
    seconds: float
    starts: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class RobustLMIDesign:
    """The result of :func:`maximise_margin`.

    Parameters
    ----------
    controller : control.StateSpace or None
        Loop convention (``x, c -> f`` etc.); ``None`` if not even the nominal member was
        reached.
    scale : float
        Largest scale reached: no member of the box scaled to it was found outside the
        region and the specification held on every checked member.
    certified_scale : float
        Largest scale at which the region was also certified over the whole box (with
        the controller found there; the shipped controller's own certified margin is
        computed by :func:`designs.registry.run_design`).
    levels : tuple of ScaleLevel
        Every scale tried, in order.
    synthesis : dict
        The LMI synthesis of the final controller (:meth:`MultiObjectiveResult.to_json`).
    spec : dict
        The specification check at ``scale`` (:meth:`SpecCheck.to_json`).
    design_rows : numpy.ndarray
        Parameter rows of the final design members.
    force_budget : float
        RMS force budget of the synthesis, N.
    options : RobustOptions
        The settings.
    failed : ScaleLevel or None
        The first scale not reached (what binds there), ``None`` if every scale was.
    """

    controller: object
    scale: float
    certified_scale: float
    levels: tuple
    synthesis: dict
    spec: dict
    design_rows: np.ndarray
    force_budget: float
    options: RobustOptions
    failed: ScaleLevel | None


def _loop_controller(K, options: RobustOptions, name: str) -> ct.StateSpace:
    return ct.ss(
        K.A,
        K.B,
        K.C,
        K.D,
        inputs=list(options.measurements),
        outputs=list(options.controls),
        name=name,
    )


def _start(family, options: RobustOptions, limits) -> ct.StateSpace:
    """The starting controller ``y -> u`` (plant convention, no signal names)."""
    nk = options.order
    if options.controls == ("f",) and options.measurements == ("x", "c"):
        K = design_hinf_nominal(family, limits=limits).controller
        Kr = balanced_truncation(K, nk, fix_signs=True).sys if nk < K.nstates else K
        return ct.ss(Kr.A, Kr.B, Kr.C, Kr.D)
    # a seeded, slow, low-gain filter: the entries break the symmetry of the states
    rng = np.random.default_rng(options.seed)
    ny, nu = len(options.measurements), len(options.controls)
    A = -20.0 * np.eye(nk) + rng.normal(scale=2.0, size=(nk, nk))
    return ct.ss(
        A, 1e-3 * rng.normal(size=(nk, ny)), 1e-3 * rng.normal(size=(nu, nk)), 0 * np.eye(nu, ny)
    )


def _given_start(K, options: RobustOptions) -> ct.StateSpace:
    """A caller's start in the plant convention, its signals checked against the options."""
    if not isinstance(K, ct.StateSpace):
        raise ParameterError(f"start must be a control.StateSpace; got {type(K).__name__}")
    if (
        tuple(K.input_labels) != tuple(options.measurements)
        or tuple(K.output_labels) != tuple(options.controls)
        or K.nstates != options.order
    ):
        raise ParameterError(
            f"start must map {list(options.measurements)} to {list(options.controls)} with "
            f"{options.order} states; got {list(K.input_labels)} -> {list(K.output_labels)} "
            f"with {K.nstates}"
        )
    return ct.ss(K.A, K.B, K.C, K.D)


#: The constraints of the specification a rung of the ladder must meet on its members: the
#: pole region, the device's forces and the tracking of the operator's band, which the
#: synthesis designs for. The feedthrough's reduction, the noise and the reference effort are
#: beyond what the P-K iteration targets: the specification's check reports them for the
#: design (its binding constraint and coverage), they do not stop the ladder.
LADDER_CONSTRAINTS = ("decay rate", "damping", "peak force", "continuous force", "tracking")


def _accepted(check) -> bool:
    """Whether a rung's check meets :data:`LADDER_CONSTRAINTS`."""
    return all(c.holds for c in check.constraints if c.name in LADDER_CONSTRAINTS)


#: The synthesis' own feedthrough target on its design grid: no growth of the peak over the
#: structure band. The specification asks for a 6 dB reduction at every frequency of the band
#: (``Specification.feedthrough_reduction_db``); with that target the ladder reaches no rung
#: (its first, 0.005 of the box, is infeasible: measured), so the designs keep this one and
#: the specification's check reports how far they fall short.
DESIGN_AMPLIFICATION_DB = 0.0


def _members(family, rows, options: RobustOptions, spec: Specification, limits):
    out = []
    for i, r in enumerate(rows):
        out.append(
            synthesis_member(
                family.member(r, check_bounds=False),
                controls=options.controls,
                measurements=options.measurements,
                limits=limits,
                intent_fraction=spec.intent_fraction,
                intent_bandwidth_hz=spec.intent_bandwidth_hz,
                tracking_error=spec.tracking_error,
                feedthrough_band_hz=spec.feedthrough_band_hz,
                max_amplification_db=DESIGN_AMPLIFICATION_DB,
                label=f"member {i}",
            )
        )
    return out


def _spec_rows(family, k: float, n: int, seed: int) -> np.ndarray:
    lo, hi = scaled_bounds(family, k)
    U = np.random.default_rng(seed).random((n, lo.size))
    return lo + U * (hi - lo)


def _try_scale(family, k, K, rows, spec, options, limits, progress):
    """Rounds of design members and synthesis at scale ``k``; returns the outcome."""
    # one region: the synthesis enforces its damping at every frequency (conservatively),
    # the checks of the scaled box in its band
    region = spec.region()
    budget = options.force_budget(spec)
    h2 = budget if "f" in options.controls else None
    rows = [np.asarray(r, float) for r in rows]
    t0 = time.perf_counter()
    outcome = {"reached": False, "reason": "", "K": K, "pk": None}
    check = None
    worst_v = math.nan
    starts = {"minimax": 0, "bfgs": 0}
    for rnd in range(options.rounds):
        members = _members(family, rows, options, spec, limits)
        common = dict(tracking_bound=options.tracking_bound, h2_bound=h2, margin=0.05)
        tuned = None
        if options.start != "bfgs":
            tuned = minimax_start(
                members,
                K,
                region,
                max_iter=options.tune_iterations,
                keep_region=options.start == "minimax",
                **common,
            )
            starts["minimax"] += 1
        if tuned is None or tuned.violation >= 0:
            # the nonsmooth tuning may find another basin (its path depends on rounding)
            tuned = tune_members(
                members,
                K,
                region,
                max_iter=options.tune_iterations,
                restarts=options.tune_restarts,
                **common,
            )
            starts["bfgs"] += 1
        if tuned.violation >= 0:
            outcome["reason"] = (
                f"no controller found with every design member's poles in the region "
                f"(violation {tuned.violation:.3g} rad/s)"
            )
            break
        try:
            # the region LMIs are solved for the one synthesis kept (_maximise)
            pk = pksyn_multi(
                members,
                tuned.K,
                region,
                h2_bound=h2 * 1.05 if h2 else None,
                max_iter=options.pk_iterations,
                region_certificates=False,
            )
        except (InfeasibleError, BDFTError) as exc:
            outcome["reason"] = f"LMI synthesis failed: {exc}"
            break
        K = pk.K
        KL = _loop_controller(K, options, "K")
        worst_v, row = worst_member(
            family,
            k,
            controller=KL,
            region=region,
            samples=options.worst_samples,
            seed=options.seed + rnd,
        )
        srows = _spec_rows(family, k, options.spec_samples, options.seed + 1000 + rnd)
        checked = np.vstack([rows, srows]) if len(srows) else np.asarray(rows)
        check = check_specification(
            [family.member(r, check_bounds=False) for r in checked],
            KL,
            spec,
            seed=options.seed,
            simulate_peak=3,
        )
        if progress:
            progress(
                f"scale {k:.3g}, round {rnd + 1}: {len(rows)} design members, worst region "
                f"violation {worst_v:.3g} rad/s, specification's binding {check.binding}"
            )
        outcome.update(K=K, pk=pk, check=check, members=members)
        if worst_v < 0 and _accepted(check):
            break
        # new design members: the worst one of the search, and the sampled member that
        # binds the specification (unless it is a design member already)
        n_design = len(rows)
        if worst_v >= 0:
            rows.append(row)
        if not _accepted(check):
            bad = max(
                (c for c in check.constraints if c.name in LADDER_CONSTRAINTS),
                key=lambda c: c.utilisation,
            )
            if bad.worst_member >= n_design:
                rows.append(checked[bad.worst_member])
    else:
        outcome["reason"] = outcome["reason"] or (
            f"after {options.rounds} rounds of design members: worst region violation "
            f"{worst_v:.3g} rad/s, the ladder's constraints "
            f"{'hold' if check and _accepted(check) else 'fail'}"
        )
    if check is not None and worst_v < 0 and _accepted(check):
        # whether the region holds over the whole scaled box: _maximise certifies the
        # rungs reached once the ladder is done (the path never depends on it)
        outcome["reached"] = True
    # the ladder's binding constraint: the largest utilisation among those it requires
    bad = (
        max(
            (c for c in check.constraints if c.name in LADDER_CONSTRAINTS),
            key=lambda c: c.utilisation,
        )
        if check
        else None
    )
    level = ScaleLevel(
        scale=float(k),
        reached=outcome["reached"],
        members=len(rows),
        worst_violation=float(worst_v),
        certified=False,  # filled in by _certify_rungs
        binding=bad.name if bad else "",
        utilisation=float(bad.utilisation) if bad else math.inf,
        reason="" if outcome["reached"] else outcome["reason"],
        seconds=time.perf_counter() - t0,
        starts=starts,
    )
    return level, outcome, rows


def maximise_margin(
    family,
    *,
    spec: Specification | None = None,
    options: RobustOptions | None = None,
    limits=None,
    progress=None,
    start=None,
) -> RobustLMIDesign:
    """The controller with the largest certified family scale that meets the specification.

    See the module notes for the method.

    Parameters
    ----------
    family : uncertainty.Family
        The family (physical human for handle force).
    spec : Specification, optional
        The specification (default: its defaults).
    options : RobustOptions, optional
        The settings.
    limits : DeviceLimits, optional
        Device limits (workspace of the intended motion; default: the specification's).
    progress : callable, optional
        Called with a short message after each round.
    start : control.StateSpace, optional
        The starting controller in the loop convention (inputs ``options.measurements``,
        outputs ``options.controls``, order ``options.order``); default: the module's
        start (step 2 of the module notes).

    Returns
    -------
    RobustLMIDesign

    Notes
    -----
    The BLAS and the SDP solver run on one thread here
    (:func:`robust.synthesis.solve.deterministic_solvers`), so the same seed gives the same
    controller under any ``OPENBLAS_NUM_THREADS`` and any load.
    """
    spec = spec or Specification()
    options = options or RobustOptions()
    limits = limits or spec.limits()
    # one BLAS thread and one solver thread: the nonsmooth start follows a path that rounding
    # differences (thread counts, the machine's load) would bend, and the result must not
    # depend on them
    with deterministic_solvers():
        return _maximise(family, spec, options, limits, progress, start)


def _certify_rung(task) -> bool:
    """Whether the region holds over the whole box scaled to ``k`` for a rung's controller
    (:func:`uncertainty.margins.margin_lower_bound`, ``margin_boxes`` sub-boxes); module
    level, so that the rungs can be certified in worker processes."""
    family, controller, region, k, boxes = task
    with deterministic_solvers():
        lower, _ = margin_lower_bound(
            family,
            controller=controller,
            region=region,
            k_hint=k,
            ladder=0,
            iterations=0,
            max_boxes=boxes,
        )
    return lower >= k


def _certify_rungs(family, levels, controllers, spec, options) -> tuple[list, float]:
    """The levels with ``certified`` filled in for every rung reached, and the largest
    scale certified; the rungs are independent, so they run in the processes granted by
    :func:`robust.engine.nested_jobs` (combined in order: the same answer on any number)."""
    tasks = [
        (family, controllers[i], spec.region(), levels[i].scale, options.margin_boxes)
        for i in sorted(controllers)
    ]
    jobs = min(jobs_available(), len(tasks)) if tasks else 1
    done = dict(zip(sorted(controllers), map_tasks(_certify_rung, tasks, jobs=jobs)))
    out = [dataclasses.replace(lv, certified=done.get(i, False)) for i, lv in enumerate(levels)]
    certified = max((lv.scale for lv in out if lv.certified), default=0.0)
    return out, float(certified)


class _Stale(Exception):
    """Raised in :class:`_Ahead`'s worker when the ladder no longer wants the scale it tries."""


def _wanted(path) -> str:
    """The key the ladder wants tried beside it (written by :meth:`_Ahead.guess`)."""
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except OSError:
        return ""


def _rung_inputs(family, k, K, rows, spec, options, limits) -> dict:
    """What one rung (:func:`_try_scale`) depends on besides the code, as a cache key.

    The options the ladder alone reads (``ladder``, ``bisection``, ``margin_boxes``) are left
    out, so a rung of the force trade-off (no bisection, fewer boxes) and the same rung of
    the design share one entry; the controller counts by its matrices. The key is made of
    values only: the dataclasses' ``repr`` (floats written exactly) and the arrays' bytes,
    not pickles, whose bytes depend on which equal strings are one object (a family sent
    to a worker process pickles otherwise than the same family built there).
    """
    mats = (K.A, K.B, K.C, K.D) if isinstance(K, ct.StateSpace) else tuple(K)
    opts = dataclasses.replace(options, ladder=(1.0,), bisection=0, margin_boxes=1)
    h = hashlib.sha256(repr((family, float(k), type(K).__name__, spec, opts, limits)).encode())
    for m in (*mats, rows):
        a = np.ascontiguousarray(m, dtype=float)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return {"rung": h.hexdigest()}


def _keep_rung(args, result) -> None:
    """Store a rung's result (``args`` as :func:`_try_scale`'s, ``progress`` aside) when
    :func:`robust.cache.caching` is on."""
    if caching_enabled():
        store("robust-lmi-rung", _rung_inputs(*args), result)


def _stored_rung(args):
    """The cached result of the rung ``args`` (:func:`_try_scale`'s, ``progress`` aside), or
    ``None`` (not stored, or :func:`robust.cache.caching` off)."""
    if not caching_enabled():
        return None
    found, result = lookup("robust-lmi-rung", _rung_inputs(*args))
    return result if found else None


def _cached_rung(family, k, K, rows, spec, options, limits, progress):
    """:func:`_try_scale`, or its result from the cache when :func:`robust.cache.caching` is
    on and the same rung was tried before (by the force trade-off's point at the same
    limits, or an earlier run): the same inputs give the same result to the bit."""
    args = (family, k, K, rows, spec, options, limits)
    result = _stored_rung(args)
    if result is not None:
        if progress:
            progress(f"scale {k:.3g}: tried before, taken from the cache")
        return result
    result = _try_scale(*args, progress)
    _keep_rung(args, result)
    return result


def _rung_task(task, key=None, wanted=None):
    """One scale of the ladder in a worker process (:class:`_Ahead`): ``_try_scale``'s
    arguments but ``progress``; solved on one thread, as :func:`maximise_margin` does.

    With ``wanted`` (a file holding the key the ladder wants), the task stops, raising
    :class:`_Stale`, at its start or after any round once that file names another key.
    """

    def still_wanted(_message=None):
        if wanted is not None and _wanted(wanted) != repr(key):
            raise _Stale(key)

    still_wanted()
    with deterministic_solvers():
        return _try_scale(*task, still_wanted)


class _Ahead:
    """A worker process that tries the first bisection scale while the ladder tries the next
    rung: if that rung fails, the bisection from the last scale reached is already done.

    The guess has exactly the inputs the bisection would have (the same controller, design
    members and scale), so the design is the same to the bit with or without it; a guess
    whose rung is reached is discarded. Each rung wants its own guess: one still running
    for an earlier rung stops after its current round (it reads the key wanted from a
    file), so the worker is free for the long rung, the one that fails, however long the
    short rungs before it took. The worker is terminated when the ladder is done. Used
    when :func:`robust.engine.nested_jobs` grants two processes or more.
    """

    def __init__(self):
        # loky's executor (joblib's): cloudpickle carries the controllers; a private one, so
        # that the worker can be stopped without touching joblib's pool
        self._pool = ProcessPoolExecutor(max_workers=1)
        self._dir = tempfile.mkdtemp(prefix="bdft-ahead-")
        self._file = os.path.join(self._dir, "wanted")
        self._job = None
        self._key = None

    def _want(self, text: str) -> None:
        tmp = self._file + ".tmp"
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, self._file)

    def guess(self, key, task) -> None:
        """Start ``task`` (the scale ``key``); a guess still running stops at its next round."""
        self._want(repr(key))
        self._job, self._key = self._pool.submit(_rung_task, task, key, self._file), key

    def idle(self) -> None:
        """No guess is wanted (the next scales are in the cache): one running stops."""
        self._want("")
        self._job = self._key = None

    def answer(self, key):
        """The result for the scale ``key`` if it was guessed, else ``None``."""
        return self._job.result() if self._job is not None and self._key == key else None

    def close(self) -> None:
        """Stop the worker (a guess still running is not needed)."""
        self._pool.shutdown(wait=True, kill_workers=True)
        shutil.rmtree(self._dir, ignore_errors=True)


def _maximise(family, spec, options, limits, progress, start=None) -> RobustLMIDesign:
    K = _start(family, options, limits) if start is None else _given_start(start, options)
    rows = [family.nominal_values()]
    levels = []
    controllers = {}  # level index -> the controller of a rung reached
    best = None  # (scale, outcome, rows) of the largest scale reached
    failed = None

    def record(level, outcome, new_rows):
        if level.reached:
            controllers[len(levels)] = _loop_controller(outcome["K"], options, "K")
        levels.append(level)
        return level, outcome, new_rows

    def attempt(k, K, rows):
        return record(*_cached_rung(family, k, K, rows, spec, options, limits, progress))

    ahead = _Ahead() if options.bisection and jobs_available() >= 2 else None
    try:
        # the nominal member first (scale 0), then the ladder
        for k in (0.0, *options.ladder):
            if ahead is not None and best is not None:
                mid = 0.5 * (best[0] + k)
                task = (family, mid, best[1]["K"], best[2], spec, options, limits)
                # (a rung or a bisection scale in the cache needs no guess: it is read back)
                if (
                    _stored_rung((family, k, K, rows, spec, options, limits)) is None
                    and _stored_rung(task) is None
                ):
                    ahead.guess((best[0], k), task)
                else:
                    ahead.idle()
            level, outcome, new_rows = attempt(k, K, rows)
            if not level.reached:
                failed = level
                break
            best, K, rows = (k, outcome, new_rows), outcome["K"], new_rows
        if failed is not None and best is not None and options.bisection:
            lo, hi = best[0], failed.scale
            for step in range(options.bisection):
                k = 0.5 * (lo + hi)
                stored = _stored_rung((family, k, best[1]["K"], best[2], spec, options, limits))
                guessed = (
                    ahead.answer((lo, hi))
                    if ahead is not None and step == 0 and stored is None
                    else None
                )
                if guessed is not None:
                    _keep_rung((family, k, best[1]["K"], best[2], spec, options, limits), guessed)
                    level, outcome, new_rows = record(*guessed)
                    if progress:
                        progress(
                            f"scale {k:.3g} (tried beside the ladder): "
                            f"{'reached' if level.reached else 'not reached'}, worst region "
                            f"violation {level.worst_violation:.3g} rad/s"
                        )
                else:
                    level, outcome, new_rows = attempt(k, best[1]["K"], best[2])
                if level.reached:
                    best, lo = (k, outcome, new_rows), k
                else:
                    hi = k
    finally:
        if ahead is not None:
            ahead.close()
    if progress and controllers:
        progress(f"certifying the region over the {len(controllers)} scales reached")
    levels, certified = _certify_rungs(family, levels, controllers, spec, options)
    if best is None:
        return RobustLMIDesign(
            None,
            0.0,
            0.0,
            tuple(levels),
            {},
            {},
            np.asarray(rows),
            options.force_budget(spec),
            options,
            failed,
        )
    k, outcome, rows = best
    pk = certify_regions(outcome["members"], outcome["pk"])
    return RobustLMIDesign(
        controller=_loop_controller(outcome["K"], options, "robust_lmi"),
        scale=float(k),
        certified_scale=float(certified),
        levels=tuple(levels),
        synthesis=pk.to_json(),
        spec=outcome["check"].to_json(),
        design_rows=np.asarray(rows),
        force_budget=options.force_budget(spec),
        options=options,
        failed=failed,
    )


@dataclasses.dataclass(frozen=True)
class TradeoffPoint:
    """One point of the force-budget trade-off.

    Parameters
    ----------
    continuous_force_n, peak_force_n : float
        The force limits of the specification at this point, N.
    force_budget_n : float
        The RMS force the synthesis allowed, N.
    scale : float
        Largest family scale reached (the specification on the checked members).
    certified_scale : float
        Certified robust margin of the point's controller for the specification's pole
        region (a lower bound covering the whole scaled box).
    binding : str
        The constraint that binds at the first scale not reached (empty if none failed).
    failed_scale : float
        That scale (``nan`` if none failed).
    seconds : float
        Time of the point.
    """

    continuous_force_n: float
    peak_force_n: float
    force_budget_n: float
    scale: float
    certified_scale: float
    binding: str
    failed_scale: float
    seconds: float


def tradeoff_point(task) -> TradeoffPoint:
    """One point of :func:`force_tradeoff` (a module-level function: it runs in workers).

    Parameters
    ----------
    task : tuple
        One of :func:`tradeoff_tasks`: ``(family, spec, options, margin_boxes)`` and, optionally,
        whether the ladder's rungs may be kept in and read from the cache
        (:func:`robust.cache.caching`; the design at the same limits then reuses them).
    """
    family, spec, options, margin_boxes, *rest = task
    t0 = time.perf_counter()
    with caching(bool(rest and rest[0])):
        d = maximise_margin(family, spec=spec, options=options)
    certified = 0.0
    if d.controller is not None:
        # the certified robust margin of the point's controller for the pole region
        certified, _ = margin_lower_bound(
            family,
            controller=d.controller,
            region=spec.region(),
            k_hint=max(d.scale, 1e-3),
            ladder=8,
            iterations=1,
            max_boxes=margin_boxes,
        )
    return TradeoffPoint(
        continuous_force_n=spec.continuous_force_n,
        peak_force_n=spec.peak_force_n,
        force_budget_n=d.force_budget,
        scale=d.scale,
        certified_scale=float(certified),
        binding=d.failed.binding if d.failed else "",
        failed_scale=d.failed.scale if d.failed else math.nan,
        seconds=time.perf_counter() - t0,
    )


def tradeoff_tasks(
    family,
    factors=(0.5, 1.0, 2.0, 4.0),
    *,
    spec: Specification | None = None,
    options: RobustOptions | None = None,
    margin_boxes: int = 100,
    cache: bool = False,
) -> list[tuple]:
    """The independent points of :func:`force_tradeoff`, for :func:`tradeoff_point`.

    A caller with other work to run (``bdft report``: the designs) runs them in the same
    pool of processes, so that no core waits for the slowest task of one batch.

    Parameters
    ----------
    family, factors, spec, options, margin_boxes
        As for :func:`force_tradeoff`.
    cache : bool
        Let each point keep its ladder's rungs in the cache and read them from it
        (:func:`robust.cache.caching`): ``bdft report`` runs the point at the device's own
        limits beside ``hinf-robust-lmi``, whose ladder climbs the same rungs.

    Returns
    -------
    list of tuple
        One task per factor, in order.

    Raises
    ------
    ParameterError
        If a factor is not a positive finite number.
    """
    spec = spec or Specification()
    options = options or RobustOptions(bisection=0, margin_boxes=30)
    tasks = []
    for f in factors:
        if not (math.isfinite(f) and f > 0):
            raise ParameterError(f"force_tradeoff: factors must be positive; got {f!r}")
        sp = dataclasses.replace(
            spec, peak_force_n=spec.peak_force_n * f, continuous_force_n=spec.continuous_force_n * f
        )
        tasks.append((family, sp, options, margin_boxes, bool(cache)))
    return tasks


def force_tradeoff(
    family,
    factors=(0.5, 1.0, 2.0, 4.0),
    *,
    spec: Specification | None = None,
    options: RobustOptions | None = None,
    margin_boxes: int = 100,
    jobs: int = 1,
    scheduler: str | None = None,
    progress=None,
) -> list[TradeoffPoint]:
    """Certified and reached family scale against the handle-force budget (a Pareto sweep).

    For each factor the specification's two force limits are multiplied by it (the
    device's limits at factor 1) and :func:`maximise_margin` runs with ``options``. The
    points are independent: they run in ``jobs`` local processes or on a Dask cluster
    (:func:`robust.engine.map_tasks`), each with one BLAS thread, so every engine gives the
    same points.

    Parameters
    ----------
    family : uncertainty.Family
        The family.
    factors : sequence of float
        Multipliers of the force limits (> 0).
    spec : Specification, optional
        The base specification.
    options : RobustOptions, optional
        Settings of every run (default: the design's four rounds per scale, no bisection;
        with two rounds the points were draws of the rounding, and the curve measured on
        the default family was not monotone: scales 0, 0.05, 0.1, 0.05 at force x0.5, x1,
        x2, x4, against 0, 0.05, 0.1, 0.2 with four).
    margin_boxes : int
        Sub-boxes per scale of the certified margin of each point's controller
        (:func:`uncertainty.margins.margin_lower_bound`, the specification's region, scales
        up to the one reached).
    jobs : int
        Local worker processes (1: in this process).
    scheduler : str, optional
        Address of a Dask scheduler (see :func:`robust.engine.map_tasks`).
    progress : callable, optional
        Called with a short message per point, as it finishes.

    Returns
    -------
    list of TradeoffPoint
        In the order of ``factors``.
    """
    tasks = tradeoff_tasks(family, factors, spec=spec, options=options, margin_boxes=margin_boxes)
    done = []

    def finished(i):
        done.append(i)
        if progress:
            progress(f"force x{factors[i]:g} done ({len(done)} of {len(tasks)})")

    out = map_tasks(tradeoff_point, tasks, jobs=jobs, scheduler=scheduler, progress=finished)
    if progress:
        for f, pt in zip(factors, out):
            progress(
                f"force x{f:g}: scale {pt.scale:.3g} reached, certified margin "
                f"{pt.certified_scale:.3g}"
            )
    return out


@dataclasses.dataclass(frozen=True)
class RobustLMIFacts(DesignFacts):
    """What a robust LMI design reports of itself.

    Parameters
    ----------
    design : RobustLMIDesign
        The ladder's result (scales, levels, synthesis, design members, options).
    specification : Specification
        The specification designed for.
    """

    design: RobustLMIDesign
    specification: Specification

    artifact_exclude = ("levels",)

    def to_json(self) -> dict:
        """The facts under ``bdft design --json``'s keys (no controller or member rows)."""
        d = self.design
        return {
            "scale": d.scale,
            "certified_scale": d.certified_scale,
            "force_budget_rms_n": d.force_budget,
            "levels": [dataclasses.asdict(x) for x in d.levels],
            "binding_at_failure": None if d.failed is None else dataclasses.asdict(d.failed),
            "synthesis": d.synthesis,
            "spec_at_scale": d.spec,
            "design_members": len(d.design_rows),
            "options": dataclasses.asdict(d.options),
            "specification": self.specification.to_json(),
            "seed": d.options.seed,
        }


def _result(name, description, family, d: RobustLMIDesign, spec) -> DesignResult:
    notes = []
    if d.controller is None:
        raise InfeasibleError(
            f"{name}: no controller meets the specification even on the nominal member: "
            f"{d.failed.reason if d.failed else ''}"
        )
    if d.failed is not None:
        notes.append(
            "the ladder's constraints (pole region, forces, tracking) hold on the checked "
            f"members up to family scale {d.scale:.3g}; "
            f"at scale {d.failed.scale:.3g} it fails: {d.failed.reason} (binding constraint: "
            f"{d.failed.binding}, utilisation {d.failed.utilisation:.3g})"
        )
    return DesignResult(
        name=name,
        description=description,
        family=family,
        controller=d.controller,
        order_full=d.controller.nstates,
        reduction_error_bound=0.0,
        facts=RobustLMIFacts(d, spec),
        notes=tuple(notes),
    )


def _spec_for(limits) -> Specification:
    return Specification(
        peak_force_n=limits.peak_force_n, continuous_force_n=limits.continuous_force_n
    )


def build(family, samples, limits) -> DesignResult:
    """Robust handle-force H-infinity by LMI synthesis (design (i) of the comparison).

    Parameters
    ----------
    family : uncertainty.Family
        The default family.
    samples : uncertainty.SampleSet
        Unused (the design members come from the worst-member search and seeded samples).
    limits : robust.model.device.DeviceLimits
        Device limits.
    """
    spec = Specification(
        peak_force_n=limits.peak_force_n, continuous_force_n=limits.continuous_force_n
    )
    d = maximise_margin(family, spec=spec, limits=limits)
    return _result(DESIGN_NAME, DESCRIPTION, family, d, spec)


def build_cylinder(family, samples, limits) -> DesignResult:
    """Cab-vibration control through the cylinder reference, no handle force (design (ii)).

    Parameters
    ----------
    family : uncertainty.Family
        The default family.
    samples : uncertainty.SampleSet
        Unused.
    limits : robust.model.device.DeviceLimits
        Device limits.
    """
    spec = Specification(
        peak_force_n=limits.peak_force_n, continuous_force_n=limits.continuous_force_n
    )
    options = RobustOptions(controls=("r_corr",), measurements=("c", "y"))
    d = maximise_margin(family, spec=spec, options=options, limits=limits)
    return _result(CYLINDER_NAME, CYLINDER_DESCRIPTION, family, d, spec)


def build_workspace_force(family, samples, limits) -> DesignResult:
    """The doubled workspace with robust handle-force feedback (design (iii)).

    Parameters
    ----------
    family : uncertainty.Family
        The default family (its workspace is doubled here).
    samples : uncertainty.SampleSet
        Unused.
    limits : robust.model.device.DeviceLimits
        Device limits.
    """
    spec = Specification(
        peak_force_n=limits.peak_force_n, continuous_force_n=limits.continuous_force_n
    )
    fam2 = family.with_workspace_factor(2.0)
    d = maximise_margin(fam2, spec=spec, limits=limits)
    res = _result(WORKSPACE_FORCE_NAME, WORKSPACE_FORCE_DESCRIPTION, fam2, d, spec)
    return res.replace(cost_note="a handle workspace twice the Omni's (142 mm)")


DESIGN_NAME = "hinf-robust-lmi"
DESCRIPTION = (
    "robust H-infinity handle-force feedback: P-K LMI synthesis with per-member certificates, "
    "certified family scale maximised"
)
CYLINDER_NAME = "cylinder-lmi"
CYLINDER_DESCRIPTION = (
    "cab-vibration control through the cylinder reference (no handle force), same LMI synthesis"
)
WORKSPACE_FORCE_NAME = "workspace2-hinf-lmi"
WORKSPACE_FORCE_DESCRIPTION = (
    "doubled handle workspace combined with robust handle-force feedback (same LMI synthesis)"
)
DESIGN = Design(DESIGN_NAME, DESCRIPTION, build)
DESIGN_CYLINDER = Design(CYLINDER_NAME, CYLINDER_DESCRIPTION, build_cylinder)
DESIGN_WORKSPACE_FORCE = Design(
    WORKSPACE_FORCE_NAME, WORKSPACE_FORCE_DESCRIPTION, build_workspace_force
)
