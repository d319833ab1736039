"""The force-budget trade-off of the robust LMI design: family scale against force limits.

:func:`force_tradeoff` runs :func:`designs.robust_lmi_ladder.maximise_margin` with the
specification's two force limits multiplied by each factor, and certifies each point's
controller; :func:`tradeoff_tasks` and :func:`tradeoff_point` are its independent points,
for a caller that runs them in its own pool of processes (``bdft report``). Kept apart from
the designs (:mod:`designs.robust_lmi`): a sweep over the ladder, not a design.
"""

from __future__ import annotations

import dataclasses
import math
import time

from designs.robust_lmi_ladder import maximise_margin
from designs.robust_lmi_rung import RobustOptions
from designs.spec import Specification
from robust.cache import caching
from robust.engine import map_tasks
from robust.errors import ParameterError
from uncertainty.margins import margin_lower_bound

__all__ = ["TradeoffPoint", "tradeoff_point", "tradeoff_tasks", "force_tradeoff"]


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
    family : backhoe.Family
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
