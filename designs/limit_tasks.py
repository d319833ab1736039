"""The limit map's work on worker processes: one task per member, run in order.

``_member_task`` computes every set's limit of one member on one BLAS and solver thread
(the same bytes in this process or a worker); ``_run`` runs such tasks in this process, in
worker processes or on a Dask cluster through :func:`robust.engine.map_tasks`, reporting
progress. Kept apart from the map (:func:`designs.limit.limit_map`,
:func:`designs.limit.basis_check`) as the scheduling of its work.
"""

from __future__ import annotations

from designs.limit_member import member_limit
from designs.limit_sets import split_set
from robust.engine import map_tasks
from robust.synthesis.solve import deterministic_solvers

#: Nothing public: :mod:`designs.limit`'s own.
__all__: list[str] = []


def _member_task(family, row, sets, spec, seed, basis_poles, duration_s):
    # one BLAS and one solver thread: the same member gives the same bytes in this process
    # or a worker, whatever OPENBLAS_NUM_THREADS says
    with deterministic_solvers():
        return _member_limits(family, row, sets, spec, seed, basis_poles, duration_s)


def _member_limits(family, row, sets, spec, seed, basis_poles, duration_s):
    loop = family.member(row)
    out = []
    for name in sets:
        a, s_ = split_set(name)
        out.append(
            member_limit(
                loop,
                a,
                spec,
                sensors=s_,
                seed=seed,
                basis_poles=basis_poles,
                duration_s=duration_s,
            )
        )
    return out


def _call(task):
    fn, args, kw = task
    return tuple(fn(*args, **kw))


def _run(tasks, n_jobs: int, progress=None, total: int | None = None, scheduler=None) -> list:
    """Run joblib-style tasks in order: in this process (``n_jobs`` 1), in ``n_jobs``
    processes or on a Dask cluster (:func:`robust.engine.map_tasks`)."""
    done = [0]

    def step(_i):
        done[0] += 1
        if progress:
            progress(done[0], total or len(tasks))

    return map_tasks(_call, list(tasks), jobs=n_jobs, scheduler=scheduler, progress=step)
