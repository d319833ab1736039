"""Benchmark: the achievable-limit map (``bdft limit``'s computation) and the coverage check.

Prints:

* the wall time of :func:`designs.limit.limit_map` on the default run (256 Latin-hypercube
  members plus the 2 critical members, the default sets, ``--jobs`` processes; target:
  at most 10 minutes on two cores), seconds per member and set, and the ratio against
  the one-process run of the same members when ``--serial-members`` is given (timed on
  that many members and extrapolated);
* the wall time of :func:`designs.coverage.member_verdicts` on 2000 members with the
  doubled-workspace design (the coverage certificate of ``bdft design``);
* the peak resident memory of this process (the workers' is not counted).

Run: ``python benchmarks/bench_limit.py [--samples 256] [--jobs 2] [--serial-members 8]``.
It uses every core for several minutes; run it alone, not in the test suite.
"""

from __future__ import annotations

import argparse
import platform
import resource
import time

from backhoe import default_family
from backhoe.model.device import DeviceLimits
from designs.coverage import member_verdicts
from designs.limit import DEFAULT_SETS, limit_map
from designs.registry import get_design
from uncertainty import sample


def peak_rss_mib() -> float:
    """Peak resident set size of this process, MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--serial-members", type=int, default=0)
    ap.add_argument("--coverage-members", type=int, default=2000)
    args = ap.parse_args()
    fam = default_family()
    print(f"python {platform.python_version()}, {platform.machine()}")
    t0 = time.perf_counter()
    lm = limit_map(fam, samples=args.samples, n_jobs=args.jobs)
    t_map = time.perf_counter() - t0
    n = len(lm.values)
    per = t_map * args.jobs / (n * len(DEFAULT_SETS))
    print(
        f"limit map: {n} members x {len(DEFAULT_SETS)} sets, {args.jobs} processes: "
        f"{t_map:.1f} s ({per:.3f} core-s per member and set)"
    )
    if args.serial_members:
        t0 = time.perf_counter()
        limit_map(fam, samples=args.serial_members, critical=False, n_jobs=1)
        t_ser = (time.perf_counter() - t0) / args.serial_members * n
        print(f"one process, extrapolated to {n} members: {t_ser:.1f} s; ratio {t_ser / t_map:.2f}")
    res = get_design("workspace").build(
        fam, sample(fam.parameters, 200, method="lhs", seed=0), DeviceLimits()
    )
    rows = sample(fam.parameters, args.coverage_members, method="mc", seed=2).values
    t0 = time.perf_counter()
    member_verdicts(res.family, rows, res.controller, seed=2, n_jobs=args.jobs)
    t_cov = time.perf_counter() - t0
    print(f"coverage check: {args.coverage_members} members, {args.jobs} processes: {t_cov:.1f} s")
    print(f"peak RSS (this process): {peak_rss_mib():.0f} MiB")


if __name__ == "__main__":
    main()
