"""Benchmark: the operator's calibration and what it is worth to the model-based cancellation.

Prints, for ``--samples`` fresh Monte Carlo members of the default family (seed ``--seed``;
each member's record seeded ``--seed + 1000 + i``):

* how often every identified quantity lies within its error bound, and the median and
  95th-percentile relative errors of the two natural frequencies and of the damping ratios;
* the fraction of members on which the whole specification holds with the cancellation of
  the hand's motion built from the nominal human (the shipped ``cancellation`` design),
  from the identified human and from the member's own human, each with the one-sided
  Clopper-Pearson lower bound at confidence 0.999 (:mod:`uncertainty.randomized`);
* the time per member (record, identification, three specification checks) and the peak
  resident memory.

Run: ``python benchmarks/bench_calibration.py [--samples 400] [--seed 21]``.
"""

from __future__ import annotations

import argparse
import collections
import platform
import resource
import time

import numpy as np

from backhoe import default_family
from designs.calibration import (
    IDENTIFIED,
    identify_operator,
    operator_truth,
    simulate_calibration,
)
from designs.scheduled import cancellation_gap
from uncertainty import sample
from uncertainty.randomized import CoverageBound


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=400)
    ap.add_argument("--seed", type=int, default=21)
    a = ap.parse_args()
    fam = default_family()
    rows = sample(fam.parameters, a.samples, method="mc", seed=a.seed).values
    print(
        f"machine: {platform.processor() or platform.machine()}, python {platform.python_version()}"
    )
    t0 = time.perf_counter()
    errs = []
    for i, row in enumerate(rows):
        loop = fam.member(row)
        est = identify_operator(
            simulate_calibration(loop, seed=a.seed + 1000 + i), fam, loop.handle_gain
        )
        tr = operator_truth(fam, row)
        errs.append([abs(est.values[k] / tr[k] - 1) for k in IDENTIFIED])
    t_id = time.perf_counter() - t0
    errs = np.array(errs)
    t0 = time.perf_counter()
    g = cancellation_gap(fam, rows, seed=a.seed + 1000)
    t_gap = time.perf_counter() - t0
    n = len(rows)
    print(f"members: {n} (Monte Carlo, seed {a.seed})")
    print(f"every quantity within its bound: {g['inside'].mean():.3f} ({g['inside'].sum()}/{n})")
    for j, k in enumerate(IDENTIFIED):
        print(
            f"  {k:10s} relative error: median {np.median(errs[:, j]):.4f}, "
            f"95th percentile {np.percentile(errs[:, j], 95):.4f}"
        )
    print("specification holds with the cancellation built from:")
    for k in ("nominal", "identified", "exact"):
        b = CoverageBound(samples=n, failures=int(n - g[k].sum()), seed=a.seed)
        why = collections.Counter(x for ok, x in zip(g[k], g[f"binding_{k}"]) if not ok)
        print(
            f"  {k:10s} {b.fraction:.3f} (lower bound {b.lower:.3f} at 0.999); "
            f"failures by binding constraint: {dict(why)}"
        )
    print(
        f"identification: {t_id / n * 1e3:.0f} ms per member; "
        f"whole gap: {t_gap / n * 1e3:.0f} ms per member"
    )
    print(f"peak RSS: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
