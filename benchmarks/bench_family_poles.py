"""Benchmark: closed-loop poles of a family, batched vs python-control per member vs bare eigvals.

Prints, for 1e4, 1e5 and 1e6 members of the default physical family:

* members/s of :func:`uncertainty.validate_family` (batched assembly, eigenvalues
  and metrics, chunked);
* (a) members/s of building each member with python-control
  (``BDFTLoop(...).system()``, an ``interconnect``) and calling
  ``control.poles``, timed on a subset and extrapolated;
* (b) members/s of bare :func:`numpy.linalg.eigvals` on pre-built closed-loop
  matrices of the same size and number (built chunk by chunk, only the
  eigenvalue call timed);
* the ratios (targets: >= 200x faster than (a), within 3x of (b)) and the peak
  resident memory of the process (``resource.getrusage``).

Run: ``python benchmarks/bench_family_poles.py [--sizes 10000 100000 1000000] [--subset 100]``.
It uses all the CPU it can for a few minutes; run it once, not in the test suite.
"""

from __future__ import annotations

import argparse
import platform
import resource
import sys
import time

import control as ct
import numpy as np

from backhoe import closed_loop_matrices, default_family
from uncertainty import DEFAULT_CHUNK, sample, validate_family


def peak_rss_mib() -> float:
    """Peak resident set size of this process, MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def time_python_control(family, values, subset: int) -> float:
    """Seconds per member for python-control: build the loop and take its poles."""
    t0 = time.perf_counter()
    for row in values[:subset]:
        ct.poles(family.member(row).system())
    return (time.perf_counter() - t0) / subset


def time_bare_eigvals(family, values, chunk: int) -> float:
    """Seconds for numpy.linalg.eigvals alone on the members' pre-built matrices."""
    total = 0.0
    for start in range(0, len(values), chunk):
        A = closed_loop_matrices(family, values[start : start + chunk])
        t0 = time.perf_counter()
        np.linalg.eigvals(A)
        total += time.perf_counter() - t0
        del A
    return total


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument(
        "--subset", type=int, default=100, help="members timed for python-control (a)"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--chunk", type=int, default=DEFAULT_CHUNK)
    args = parser.parse_args(argv)

    family = default_family("physical")
    print(
        f"python {platform.python_version()}, numpy {np.__version__}, control {ct.__version__}, "
        f"{platform.machine()}, chunk {args.chunk}, seed {args.seed}"
    )
    probe = sample(family.parameters, args.subset, method="mc", seed=args.seed)
    per_member_a = time_python_control(family, probe.values, args.subset)
    rate_a = 1.0 / per_member_a
    print(
        "(a) python-control per member (BDFTLoop.system + control.poles), "
        f"{args.subset} members timed: "
        f"{per_member_a * 1e3:.2f} ms/member = {rate_a:,.0f} members/s"
    )
    print(
        f"{'members':>9} {'sample s':>9} {'validate s':>11} {'members/s':>11} {'(a) est. s':>11} "
        f"{'x vs (a)':>9} {'(b) eig s':>10} {'(b) m/s':>11} {'vs (b)':>7} {'peak RSS MiB':>13}"
    )
    for n in args.sizes:
        t0 = time.perf_counter()
        S = sample(family.parameters, n, method="lhs", seed=args.seed)
        t_sample = time.perf_counter() - t0
        t0 = time.perf_counter()
        res = validate_family(family, S, chunk=args.chunk)
        t_val = time.perf_counter() - t0
        rss = peak_rss_mib()
        t_b = time_bare_eigvals(family, S.values, args.chunk)
        rate = n / t_val
        print(
            f"{n:>9d} {t_sample:>9.2f} {t_val:>11.2f} {rate:>11,.0f} {n * per_member_a:>11.0f} "
            f"{rate / rate_a:>9.0f} {t_b:>10.2f} {n / t_b:>11,.0f} {t_val / t_b:>7.2f} "
            f"{rss:>13.0f}",
            flush=True,
        )
        del S, res
    print(f"peak resident memory of the run: {peak_rss_mib():.0f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
