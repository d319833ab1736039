"""Running the report's designs: every design, and the report's other long tasks, in one pool
of processes.

:func:`run_designs_with` puts the designs (the minutes-long robust syntheses first) and
the caller's extra tasks in one :func:`robust.engine.map_tasks` pool and keeps a design
that fails with its error; :func:`run_all_designs` is the same without extra tasks. The
scheduling of the work is kept here, apart from the page that
:mod:`reports.designs` writes from the results.
"""

from __future__ import annotations

from designs import run_design
from designs.registry import report_design_names
from robust.engine import map_tasks
from robust.errors import BDFTError

__all__ = ["run_all_designs", "run_designs_with"]


#: The designs that take minutes (robust synthesis), started first when designs run in
#: parallel.
_LONG_DESIGNS = (
    "musyn",
    "hinf-robust-lmi",
    "workspace2-hinf-lmi",
    "cylinder-lmi",
    "hinf-robust-corr",
    "hinf-robust",
)


def run_all_designs(**kwargs):
    """Run every design (or ``names``); a design that fails is kept with its error, not dropped.

    :func:`run_designs_with` without other tasks; the keywords are its.

    Parameters
    ----------
    **kwargs
        As for :func:`run_designs_with` (``extra_tasks`` aside).

    Returns
    -------
    dict
        Design name to its evaluated :class:`designs.DesignResult`, or to the
        :class:`robust.errors.BDFTError` it raised.
    """
    return run_designs_with(**kwargs)[0]


def _pool_task(item):
    """One task of :func:`run_designs_with`'s pool: a design, or another ``(fn, arg)``."""
    kind, payload = item
    if kind == "design":
        return _design_task(payload)
    fn, arg = payload
    return fn(arg)


def run_designs_with(
    *,
    samples: int = 2000,
    seed: int = 0,
    out_dir=None,
    names=None,
    progress=None,
    margin_boxes: int = 0,
    coverage_samples: int = 0,
    n_jobs: int = 1,
    member_progress=None,
    cache: bool = False,
    design_jobs: int = 1,
    scheduler: str | None = None,
    extra_tasks=(),
):
    """Run every design (or ``names``) and other long tasks in one pool of processes.

    Each design runs through :func:`designs.run_design` on the default family; a design
    that fails is kept with its error, not dropped. With ``design_jobs`` above 1 (or a
    Dask ``scheduler``) the designs themselves run in parallel processes
    (:func:`robust.engine.map_tasks`), each with its coverage checks in one process; every
    design is deterministic in its process (the robust designs run their BLAS on one
    thread), so the results are those of the serial run. ``extra_tasks`` (``bdft report``:
    the points of the force trade-off) run in the same pool, ahead of the designs, so that
    no core waits for the slowest task of one batch before the next batch starts.

    Parameters
    ----------
    samples : int
        Members of the design and validation sample (the same for every design).
    seed : int
        Sampling seed.
    out_dir : path-like, optional
        Folder for the designs' artifacts; ``None`` writes none.
    names : sequence of str, optional
        Designs to run (default: every registered design, in report order).
    progress : callable, optional
        Called with each design's name before it runs.
    margin_boxes : int
        Sub-boxes per scale of each design's certified robust margin (0: not computed).
    coverage_samples : int
        Independent members of each design's coverage certificate (0: not computed).
    n_jobs : int
        Parallel processes of the coverage checks.
    member_progress : callable, optional
        ``member_progress(done, total)`` during each coverage check.
    cache : bool
        Use the result cache (see :func:`designs.run_design`).
    design_jobs : int
        Designs run at once in local processes (1: one after the other in this process,
        with ``n_jobs`` processes for each coverage check).
    scheduler : str, optional
        Address of a Dask scheduler to run the designs on instead of local processes.
    extra_tasks : sequence of (str, callable, object)
        Other tasks: a label (for ``progress``), a module-level function and its one
        argument. Run after the designs when ``design_jobs`` is 1.

    Returns
    -------
    runs : dict
        Design name to its evaluated :class:`designs.DesignResult`, or to the
        :class:`robust.errors.BDFTError` it raised.
    extra : list
        The results of ``extra_tasks``, in order (an exception they raise is raised).
    """
    names = list(names or report_design_names())
    extra_tasks = list(extra_tasks)
    options = dict(
        samples=samples,
        seed=seed,
        out_dir=out_dir,
        margin_boxes=margin_boxes,
        coverage_samples=coverage_samples,
        cache=cache,
    )
    if design_jobs == 1 and scheduler is None:
        runs = {}
        for name in names:
            if progress:
                progress(name)
            runs[name] = _design_task(
                (name, dict(options, n_jobs=n_jobs, progress=member_progress))
            )
        extra = []
        for label, fn, arg in extra_tasks:
            extra.append(fn(arg))
            if progress:
                progress(f"{label} done")
        return runs, extra
    # the other tasks and the longest designs first, so that the last to start is short
    rank = {n: i for i, n in enumerate(_LONG_DESIGNS)}
    order = sorted(names, key=lambda n: (rank.get(n, len(rank)), names.index(n)))
    items = [("task", (fn, arg)) for _, fn, arg in extra_tasks]
    items += [("design", (n, dict(options, n_jobs=1))) for n in order]
    labels = [label for label, _, _ in extra_tasks] + list(order)

    def finished(i):
        if progress:
            progress(f"{labels[i]} done")

    results = map_tasks(_pool_task, items, jobs=design_jobs, scheduler=scheduler, progress=finished)
    k = len(extra_tasks)
    by_name = dict(zip(order, results[k:]))
    return {n: by_name[n] for n in names}, list(results[:k])


def _design_task(task):
    """One design's :func:`designs.run_design`, or the :class:`BDFTError` it raised."""
    name, options = task
    try:
        return run_design(name, **options)
    except BDFTError as exc:
        return exc
