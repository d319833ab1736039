"""Benchmark: robust-margin bounds of the default family, open loop and every shipped design.

For each loop: the upper bound (worst-case search) and the certified lower bound (``auto``
by default: zero exclusion on value sets for the open loop, the verified eigenvalue
enclosures over sub-boxes for the designs; or the method named), their times, the gap and
the work (sub-boxes or value-set cells). Targets: ``bdft margin`` on the open loop with
certified / upper >= 0.9 in under 60 s; upper bound under 30 s, certified lower bound
under 5 minutes for the designs, on 2 cores.

    python benchmarks/bench_margin.py [--samples N] [--max-boxes B] [--method M]
                                      [--designs a,b,...]
"""

from __future__ import annotations

import argparse
import resource
import time

from backhoe import default_family
from designs import design_names, run_design
from uncertainty.constants import DEFAULT_BOXES, LOWER_METHODS
from uncertainty.margins import margin_lower_bound
from uncertainty.search import margin_upper_bound


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1000, help="search members per scale")
    ap.add_argument("--max-boxes", type=int, default=DEFAULT_BOXES, help="sub-boxes per scale")
    ap.add_argument("--method", default="auto", choices=LOWER_METHODS)
    ap.add_argument("--design-samples", type=int, default=500, help="design sample size")
    ap.add_argument("--designs", default=",".join(design_names()), help="comma-separated")
    args = ap.parse_args()
    fam = default_family()
    loops = [("open loop", fam, None)]
    for name in [n for n in args.designs.split(",") if n]:
        t = time.perf_counter()
        r = run_design(name, samples=args.design_samples, seed=0, held_out=100)
        print(f"# designed {name} in {time.perf_counter() - t:.1f} s", flush=True)
        loops.append((name, r.family, r.controller))
    print(f"# lower bound: {args.method}, {args.max_boxes} sub-boxes per scale")
    print(
        f"{'loop':18s} {'upper':>9s} {'t_up[s]':>8s} {'lower':>9s} {'t_low[s]':>9s} "
        f"{'gap up/low':>10s} {'low/up':>7s} {'method':>12s} {'work':>8s}"
    )
    for label, family, K in loops:
        t0 = time.perf_counter()
        up, crit, _ = margin_upper_bound(family, controller=K, samples=args.samples, seed=0)
        t1 = time.perf_counter()
        low, cert = margin_lower_bound(
            family,
            controller=K,
            k_hint=min(up, 8.0),
            max_boxes=args.max_boxes,
            method=args.method,
        )
        t2 = time.perf_counter()
        work = sum(h.get("boxes", h.get("cells", 0)) for h in cert["history"])
        gap = up / low if low > 0 else float("inf")
        print(
            f"{label:18s} {up:9.4g} {t1 - t0:8.1f} {low:9.4g} {t2 - t1:9.1f} {gap:10.3g} "
            f"{low / up:7.3f} {cert['method']:>12s} {work:8d}",
            flush=True,
        )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"process peak resident memory: {peak:.0f} MiB")


if __name__ == "__main__":
    main()
