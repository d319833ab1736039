"""Where independent pieces of work run: in this process, in local processes, or on a cluster.

One function, :func:`map_tasks`, applies a function to a list of arguments and returns
the results in the arguments' order, whichever engine runs them:

* serially in this process (``jobs=1``, no scheduler);
* in ``jobs`` local worker processes through joblib's loky backend, or, for work that
  releases the GIL (``threads=True``: compiled loops), in ``jobs`` threads of this process;
* on a Dask distributed cluster (``scheduler="tcp://host:8786"``, or the address in the
  ``DASK_SCHEDULER_ADDRESS`` environment variable, Dask's own convention), its workers
  wherever they run; ``scheduler="local:N"`` starts a local Dask cluster of ``N``
  single-threaded worker processes for the call.

The engine changes where the work runs, never what it computes: each task is a pure
function of its arguments (seeds included), and the results come back in order, so the
caller combines them the same way; the same inputs give the same bytes on every engine
(tested with a ``dask.distributed.LocalCluster``). Dask is an optional dependency
(``pip install ".[distributed]"``); asking for a scheduler without it is an error that
says so.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed

from robust.errors import BDFTError, ParameterError

__all__ = [
    "map_tasks",
    "run_calls",
    "scheduler_address",
    "SCHEDULER_ENV",
    "jobs_available",
    "nested_jobs",
    "stop_workers",
]


def _check_jobs(where: str, jobs) -> None:
    """``jobs`` must be a positive integer (a bool is not one)."""
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ParameterError(f"{where}: jobs must be a positive integer; got {jobs!r}")


#: Environment variable that names a Dask scheduler when no address is given (Dask's own).
SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"
#: Seconds to wait for the scheduler before giving up.
CONNECT_TIMEOUT_S = 20.0

#: Whether this process has started joblib's local worker processes (:func:`stop_workers`).
_POOL = {"started": False}

#: Local processes the work inside a block may use (:func:`nested_jobs`); 1 outside.
_NESTED: contextvars.ContextVar[int] = contextvars.ContextVar("bdft_nested_jobs", default=1)


@contextlib.contextmanager
def nested_jobs(jobs: int):
    """Within the block, work that can split itself (a design's independent solves) may use
    ``jobs`` local processes (:func:`jobs_available`).

    A command that runs one design at a time grants its ``--jobs``; a design running in a
    pool's worker is granted nothing (the pool already fills the cores). What is computed
    never depends on it: the split work is combined in order.

    Parameters
    ----------
    jobs : int
        Local processes, >= 1.
    """
    _check_jobs("nested_jobs", jobs)
    token = _NESTED.set(jobs)
    try:
        yield
    finally:
        _NESTED.reset(token)


def jobs_available() -> int:
    """Local processes granted by the innermost :func:`nested_jobs` block (1 outside one)."""
    return _NESTED.get()


def scheduler_address(address: str | None = None) -> str | None:
    """The Dask scheduler to use: ``address``, else ``$DASK_SCHEDULER_ADDRESS``, else None.

    Parameters
    ----------
    address : str, optional
        An explicit address (``tcp://host:port``), or ``local:N`` (a local cluster of
        ``N`` workers started for the call).
    """
    if address:
        return str(address)
    env = os.environ.get(SCHEDULER_ENV, "").strip()
    return env or None


@contextlib.contextmanager
def _client(address: str):
    try:
        from distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - depends on the installation
        raise ParameterError(
            f"scheduler {address!r}: Dask distributed is not installed; "
            'pip install ".[distributed]" (or run without a scheduler)'
        ) from None
    if address.startswith("local:"):
        try:
            n = int(address[len("local:") :])
        except ValueError:
            n = 0
        if not 1 <= n <= 256:
            raise ParameterError(
                f"scheduler: expected local:N with 1 <= N <= 256 workers; got {address!r}"
            )
        with (
            LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0"
            ) as cluster,
            Client(cluster) as client,
        ):
            yield client
        return
    try:
        client = Client(address, timeout=f"{CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError) as exc:
        raise BDFTError(
            f"scheduler {address!r}: cannot connect to the Dask scheduler: {exc}"
        ) from None
    with client:
        yield client


def stop_workers() -> bool:
    """End the local worker processes that :func:`map_tasks` started.

    joblib keeps its worker processes for the next call and, when the program exits, asks
    each to finish and waits while it tears its interpreter down (about 0.6 s for two
    workers that imported the numerical libraries). A command calls this once its work is
    done: the workers are idle then, and are ended at once. A later :func:`map_tasks`
    starts new ones. Nothing that was computed depends on it.

    Returns
    -------
    bool
        Whether there were workers to end.
    """
    if not _POOL["started"]:
        return False
    from joblib.externals.loky import get_reusable_executor

    _POOL["started"] = False
    # reuse=True: the pool joblib made, whatever its settings (no new one is started)
    get_reusable_executor(reuse=True).shutdown(wait=True, kill_workers=True)
    return True


def _map_threads(fn: Callable, args: list, jobs: int, step: Callable[[int], None]) -> list:
    """:func:`map_tasks` in ``jobs`` threads of this process (results in the order of ``args``)."""
    out: list = [None] * len(args)
    pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="bdft-task")
    try:
        futures = {pool.submit(fn, a): i for i, a in enumerate(args)}
        for fut in as_completed(futures):
            i = futures[fut]
            out[i] = fut.result()
            step(i)
    except BaseException:
        # a failed task or an interrupt: the tasks not yet started are dropped
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return out


def map_tasks(
    fn: Callable,
    args: Sequence,
    *,
    jobs: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int], None] | None = None,
    threads: bool = False,
) -> list:
    """``[fn(a) for a in args]``, run serially, in local processes or threads, or on a Dask cluster.

    Parameters
    ----------
    fn : callable
        A function of one argument, importable by name (a module-level function or a
        :func:`functools.partial` of one) so that other processes can run it.
    args : sequence
        One argument per task.
    jobs : int
        Local worker processes (joblib/loky) when no scheduler is used; 1 runs in this
        process.
    scheduler : str, optional
        Address of a Dask scheduler (see :func:`scheduler_address`; the environment
        variable is read when this is None).
    progress : callable, optional
        Called with a task's index when it finishes (in completion order).
    threads : bool
        Run the local jobs as ``jobs`` threads of this process instead of processes: for a
        function that spends its time in code that releases the GIL (compiled loops such as
        Numba's ``nogil`` ones, LAPACK), no process starts, imports or receives copies of the
        arguments. A Dask scheduler, when one is given, is used all the same.

    Returns
    -------
    list
        The results, in the order of ``args``.

    Raises
    ------
    ParameterError
        If ``jobs`` is not a positive integer, or a scheduler is asked for without Dask.
    BDFTError
        If the scheduler cannot be reached. A task's own exception is raised as it is.
    """
    _check_jobs("map_tasks", jobs)
    args = list(args)
    step = progress or (lambda i: None)
    address = scheduler_address(scheduler)
    if address is not None:
        from distributed import as_completed

        with _client(address) as client:
            futures = client.map(fn, args, pure=False)
            index = {f.key: i for i, f in enumerate(futures)}
            out: list = [None] * len(args)
            for fut in as_completed(futures):
                i = index[fut.key]
                out[i] = fut.result()
                step(i)
            return out
    if jobs == 1 or len(args) <= 1:
        out = []
        for i, a in enumerate(args):
            out.append(fn(a))
            step(i)
        return out
    if threads:
        return _map_threads(fn, args, jobs, step)
    from joblib import Parallel, delayed

    _POOL["started"] = True
    out = []
    for i, r in enumerate(
        Parallel(n_jobs=jobs, return_as="generator")(delayed(fn)(a) for a in args)
    ):
        out.append(r)
        step(i)
    return out


def _call(task: Callable):
    return task()


def run_calls(
    calls: Sequence[Callable], *, jobs: int = 1, progress: Callable[[int], None] | None = None
) -> list:
    """``[c() for c in calls]`` on :func:`map_tasks`' engines, in order.

    For tasks that are different functions or take several arguments: each call a
    :func:`functools.partial` of a module-level function. One call (or ``jobs=1``) runs in
    this process: no worker process is started for it.

    Parameters
    ----------
    calls : sequence of callable
        Functions of no argument, importable by name.
    jobs : int
        Local worker processes, as :func:`map_tasks`.
    progress : callable, optional
        Called with a call's index when it finishes.
    """
    return map_tasks(_call, calls, jobs=jobs, progress=progress)
