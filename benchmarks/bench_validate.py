"""Benchmark: ``bdft validate`` of many members, serial against local threads and Dask.

Runs the command ``bdft validate --samples N --json`` (default family, seed 0) three ways,
each ``--repeats`` times: in one thread (``--jobs 1``, the baseline), in two threads of
the process (``--jobs 2``) and on a ``dask.distributed.LocalCluster`` of two single-threaded
worker processes (``--scheduler``; the cluster is started once, outside the timing).
Prints min/median/max wall time of each, the ratios of the medians against the serial run,
whether the three JSON outputs are the same bytes, and this process's peak resident memory
(the commands run in-process).

Run: ``python benchmarks/bench_validate.py [--samples 1000000] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import platform
import resource
import statistics
import time

from bdft import main


def _run(argv):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        t = time.perf_counter()
        rc = main(argv)
        dt = time.perf_counter() - t
    if rc != 0:
        raise SystemExit(f"bdft {' '.join(argv)} failed with exit code {rc}")
    return dt, out.getvalue()


def main_(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)
    from distributed import LocalCluster

    base = ["validate", "--samples", str(a.samples), "--json"]
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        ways = {
            "serial (--jobs 1)": base + ["--jobs", "1"],
            "local threads (--jobs 2)": base + ["--jobs", "2"],
            "Dask LocalCluster, 2 workers (--scheduler)": base
            + ["--scheduler", cluster.scheduler_address],
        }
        times, outs = {}, {}
        for _ in range(a.repeats):
            for name, argv in ways.items():
                dt, out = _run(argv)
                times.setdefault(name, []).append(dt)
                outs.setdefault(name, set()).add(out)
    cpu = platform.processor() or platform.machine()
    print(f"members: {a.samples} (default family, seed 0); {cpu}")
    serial = statistics.median(times["serial (--jobs 1)"])
    for name, ts in times.items():
        med = statistics.median(ts)
        print(
            f"{name}: min {min(ts):.2f} s, median {med:.2f} s, max {max(ts):.2f} s; "
            f"serial / this {serial / med:.2f}"
        )
    distinct = set().union(*outs.values())
    print(f"same JSON bytes on every engine and run: {'yes' if len(distinct) == 1 else 'NO'}")
    print(f"peak RSS: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main_()
