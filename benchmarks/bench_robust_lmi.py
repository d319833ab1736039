"""Benchmark: the robust LMI synthesis (P-K iteration on a family) by design-member count.

For each member count ``m``, the design members are the nominal member of the default
family and ``m - 1`` seeded corners of its box scaled to ``--scale``; the start is the
nominal LMI design truncated to ``--order`` and brought over the members by each start
of ``--starts``: ``minimax`` (:func:`robust.synthesis.tuning.minimax_start`, linear
programs) and ``bfgs`` (:func:`robust.synthesis.tuning.tune_members`, the baseline it
replaces in the designs); then :func:`robust.synthesis.pk.pksyn_multi` runs ``--steps``
K-steps. Printed per count: time of the start, of the LMI synthesis in
total, of one LMI solve (median over the solves: P-steps, K-steps and the final region
certificates), the number of solves, the certified worst H-infinity level and the peak
resident memory of the process. The baseline is the solve time per member: the K-step
holds every member's inequalities, so its cost should grow about linearly with ``m``.

Usage::

    python benchmarks/bench_robust_lmi.py                    # members 1 2 4 8
    python benchmarks/bench_robust_lmi.py --members 1 4 --steps 3 --starts minimax
    python benchmarks/bench_robust_lmi.py --ladder minimax minimax-bfgs   # whole designs

With ``--ladder`` it runs the whole default handle-force design
(:func:`designs.robust_lmi.maximise_margin`) with each start method instead and prints
its time, the scale reached, the constraint binding at the first scale not reached, the
rounds started by linear programs and by BFGS, and a hash of the controller to six
significant digits (run it under ``OPENBLAS_CORETYPE=Sandybridge`` to compare kernels).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import platform
import resource
import time

import control as ct
import numpy as np
from threadpoolctl import threadpool_info

from backhoe import default_family
from backhoe.synthesis.forcefb import synthesis_member
from designs.hinf_nominal import design_hinf_nominal
from designs.robust_lmi import START_METHODS, RobustOptions, maximise_margin
from robust.analysis.region import EVERY_FREQUENCY_HZ, Region
from robust.synthesis.pk import pksyn_multi
from robust.synthesis.tuning import minimax_start, tune_members
from uncertainty.search import scaled_bounds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--order", type=int, default=4)
    ap.add_argument("--scale", type=float, default=0.005)
    ap.add_argument("--steps", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--starts", nargs="+", choices=("minimax", "bfgs"), default=["minimax", "bfgs"])
    ap.add_argument(
        "--ladder",
        nargs="*",
        choices=START_METHODS,
        default=None,
        help="instead: the whole default design (maximise_margin) with each start method",
    )
    args = ap.parse_args()
    fam = default_family()
    if args.ladder is not None:
        ladder(fam, args.ladder or ["minimax", "minimax-bfgs"])
        return
    region = Region(0.1, 0.1, EVERY_FREQUENCY_HZ)
    K = design_hinf_nominal(fam).controller
    Kr = ct.balred(K, args.order, method="truncate")
    start = ct.ss(Kr.A, Kr.B, Kr.C, Kr.D)
    lo, hi = scaled_bounds(fam, args.scale)
    rng = np.random.default_rng(args.seed)
    corners = [np.where(rng.random(lo.size) > 0.5, hi, lo) for _ in range(max(args.members))]
    print(
        f"# robust LMI synthesis; python {platform.python_version()}, {platform.machine()}; "
        f"order {args.order}, scale {args.scale}, {args.steps} K-steps, seed {args.seed}"
    )
    print(
        f"{'members':>7} {'start':>7} {'start s':>8} {'LMI s':>8} {'solves':>6} "
        f"{'per solve s':>11} {'per member s':>12} {'gamma':>8} {'steps':>5} {'peak RSS MB':>11}"
    )
    for m in args.members:
        rows = [fam.nominal_values()] + corners[: m - 1]
        members = [synthesis_member(fam.member(r), label=f"m{i}") for i, r in enumerate(rows)]
        for how in args.starts:
            t0 = time.perf_counter()
            if how == "minimax":
                tuned = minimax_start(members, start, region, tracking_bound=0.95, h2_bound=0.75)
            else:
                tuned = tune_members(members, start, region, tracking_bound=0.95, h2_bound=0.75)
            t1 = time.perf_counter()
            res = pksyn_multi(members, tuned.K, region, h2_bound=0.8, max_iter=args.steps)
            t2 = time.perf_counter()
            per = float(np.median(res.solve_times))
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            print(
                f"{m:7d} {how:>7} {t1 - t0:8.2f} {t2 - t1:8.2f} {len(res.solve_times):6d} "
                f"{per:11.3f} {(t2 - t1) / m:12.2f} {res.gamma_bound:8.4f} {res.iterations:5d} "
                f"{rss:11.0f}"
            )


def ladder(fam, methods) -> None:
    """The default handle-force design with each start: time, scale, binding, controller hash.

    The hash is of the controller's matrices printed to 6 significant digits (what the
    design's JSON shows), so two machines' runs can be compared by eye.
    """
    print(f"# maximise_margin on the default family; BLAS {_blas()}")
    print(
        f"{'start':>13} {'time s':>7} {'scale':>6} {'binding at failure':>20} {'LP':>3} "
        f"{'BFGS':>4} {'peak RSS MB':>11} controller"
    )
    for how in methods:
        t0 = time.perf_counter()
        d = maximise_margin(fam, options=dataclasses.replace(RobustOptions(), start=how))
        dt = time.perf_counter() - t0
        K = d.controller
        text = " ".join(f"{x:.6g}" for m in (K.A, K.B, K.C, K.D) for x in np.ravel(m))
        digest = hashlib.sha256(text.encode()).hexdigest()[:12]
        lp = sum(lv.starts.get("minimax", 0) for lv in d.levels)
        bf = sum(lv.starts.get("bfgs", 0) for lv in d.levels)
        binding = d.failed.binding if d.failed else "-"
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(
            f"{how:>13} {dt:7.1f} {d.scale:6.3f} {binding:>20} {lp:3d} {bf:4d} {rss:11.0f} {digest}"
        )


def _blas() -> str:
    info = {
        (i["internal_api"], i["architecture"]) for i in threadpool_info() if i["user_api"] == "blas"
    }
    return ", ".join(sorted(f"{a} {b}" for a, b in info)) or "unknown"


if __name__ == "__main__":
    main()
