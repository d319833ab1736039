"""Benchmark: the specification check per member, and the loop assembly it rests on.

Prints, for the default family:

1. the Figure 5 loop with a controller assembled by :func:`backhoe.model.wiring.connect`
   (the exact closed form) against the baseline, python-control's
   :func:`control.interconnect` on the same blocks (a nonlinear interconnection
   linearised by finite differences): time per assembly of each, their ratio, and the
   largest relative difference of the matrices;
2. :func:`designs.coverage.member_verdicts` (one :func:`designs.spec.check_specification`
   per member, no peak-force simulation on failing members) on ``--members`` seeded
   Monte Carlo members for the cancellation (no force) and the nominal H-infinity design
   (handle force): time per member and the fraction meeting the specification; with
   ``--artifacts DIR`` also every controller artifact of a ``bdft report``'s artifacts
   folder;
3. :func:`designs.spec.check_specification` on each of those members whose closed loop is
   stable, every constraint evaluated (the screen of 2. settles most unstable members
   without it): CPU time per member;
4. the peak resident memory of the process.

Usage::

    python benchmarks/bench_spec.py [--members 200] [--repeat 50] [--artifacts DIR]
"""

from __future__ import annotations

import argparse
import resource
import time
import warnings
from pathlib import Path

import control as ct
import numpy as np

from backhoe import default_family
from backhoe.model.wiring import connect
from designs.cancellation import cancellation_controller
from designs.coverage import member_verdicts
from designs.hinf_nominal import design_hinf_nominal
from designs.spec import Specification, check_specification
from robust.analysis.loops import closed_loop_poles
from robust.errors import ArtifactError
from robust.export import load_artifact
from uncertainty import sample


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=50)
    ap.add_argument(
        "--artifacts", default=None, help="a bdft report's artifacts folder (its *.json)"
    )
    args = ap.parse_args()
    fam = default_family()
    nominal = fam.member(fam.nominal_values())
    Kh = design_hinf_nominal(fam).controller
    Kc = cancellation_controller(nominal)

    ext = nominal.human.has_force_port
    blocks = nominal.blocks(bdft=True, controller=Kh, external_force=ext)
    ins = ["u", "f_ext"] if ext else ["u"]
    outs = ["y", "c", "h", "x", "e", "f"]
    t = time.perf_counter()
    for _ in range(args.repeat):
        ours = connect(blocks, inputs=ins, outputs=outs, name="loop")
    t_ours = (time.perf_counter() - t) / args.repeat
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(args.repeat):
            ref = ct.interconnect(blocks, inputs=ins, outputs=outs, check_unused=False)
    t_ref = (time.perf_counter() - t) / args.repeat
    diff = max(
        float(np.max(np.abs(a - b)) / max(1.0, np.max(np.abs(b))))
        for a, b in ((ours.A, ref.A), (ours.B, ref.B), (ours.C, ref.C), (ours.D, ref.D))
    )
    print(f"loop assembly ({ours.nstates} states, {args.repeat} repeats)")
    print(f"  connect (exact)              {1e3 * t_ours:8.2f} ms")
    print(f"  control.interconnect (base)  {1e3 * t_ref:8.2f} ms")
    print(f"  ratio base / connect         {t_ref / t_ours:8.1f}x")
    print(f"  largest relative difference  {diff:8.1e}")

    rows = sample(fam.parameters, args.members, method="mc", seed=5).values
    print(f"member_verdicts on {args.members} members (seed 5), one process")
    designs = [("cancellation", Kc), ("hinf-nominal", Kh)]
    if args.artifacts:
        for path in sorted(Path(args.artifacts).glob("*.json")):
            try:
                K = load_artifact(path).continuous
                designs.append((f"{path.stem} (report)", K))
            except ArtifactError:
                continue  # (a bank of controllers, not one)
    for label, K in designs:
        t = time.perf_counter()
        v = member_verdicts(fam, rows, K)
        dt = time.perf_counter() - t
        print(
            f"  {label:29s} {1e3 * dt / args.members:7.1f} ms per member, "
            f"specification holds on {v.holds.mean():.3f}"
        )
    # every member checked in full (no screen of the certainly unstable ones): the cost of
    # the check itself, on the members whose closed loop is stable
    print(f"check_specification per stable member, the same {args.members} members")
    loops = [fam.member(r) for r in rows]
    spec = Specification()
    for label, K in designs:
        stable = [m for m in loops if closed_loop_poles(m.system(bdft=True, controller=K)).stable]
        if not stable:
            print(f"  {label:29s}    none stable")
            continue
        check_specification(stable[:1], K, spec, simulate_peak=0)  # (compiled kernels)
        t = time.process_time()
        for m in stable:
            check_specification([m], K, spec, simulate_peak=0)
        dt = time.process_time() - t
        print(
            f"  {label:29s} {1e3 * dt / len(stable):7.2f} ms CPU per member ({len(stable)} stable)"
        )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {peak:.0f} MB")


if __name__ == "__main__":
    main()
