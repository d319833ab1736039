"""The robust LMI ladder: the margin maximisation, from the start to the certified scales.

:func:`maximise_margin` runs steps 2 to 6 of :mod:`designs.robust_lmi`: the starting
controller (``_start``, or a caller's), the ladder of family scales and its bisection
(``_maximise``; each rung from :mod:`designs.robust_lmi_rung`, read from the cache or tried
beside the ladder through :mod:`designs.robust_lmi_ahead`), the pole region certified over
the scaled box of every rung reached (``_certify_rungs``), and the result,
:class:`RobustLMIDesign`.
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np

from designs.hinf_nominal import design_hinf_nominal
from designs.robust_lmi_ahead import _Ahead, _cached_rung, _keep_rung, _stored_rung
from designs.robust_lmi_rung import RobustOptions, ScaleLevel, _loop_controller
from designs.spec import Specification
from robust.analysis.reduction import balanced_truncation
from robust.engine import jobs_available, map_tasks
from robust.errors import ParameterError
from robust.synthesis.pk import certify_regions
from robust.synthesis.solve import deterministic_solvers
from uncertainty.margins import margin_lower_bound

__all__ = ["RobustLMIDesign", "maximise_margin"]


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
    family : backhoe.Family
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
