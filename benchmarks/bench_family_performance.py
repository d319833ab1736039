"""Benchmark: robust performance of a shipped design over the default family, from its LFT.

The family's closed loop with ports (:func:`backhoe.family_uss` with ``inputs="u"`` and
an output), 15 uncertain parameters, closed by a shipped handle-force design; the weighted
bound is ``||T_fu||_inf < gamma`` (handle force per intended motion) with ``gamma`` a
multiple of the nominal member's norm. Prints both bounds of the robust performance margin
(:func:`uncertainty.robust_performance`), their ratio, each bound's time, the worst member
and its norm, checked by a second algorithm (python-control's ``linfnorm``, SLICOT's
``ab13dd``), and the peak memory.

    python benchmarks/bench_family_performance.py [--design hinf-nominal] [--ratio 1.5]
        [--output f] [--json]
"""

from __future__ import annotations

import argparse
import json
import resource
import time

import control as ct
import numpy as np

from backhoe import default_family, family_uss
from designs.registry import run_design
from robust.analysis.norms import hinf_norm
from uncertainty import robust_performance


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", default="hinf-nominal")
    ap.add_argument("--output", default="f", help="the loop's output signal (default f)")
    ap.add_argument("--ratio", type=float, default=1.5, help="gamma over the nominal norm")
    ap.add_argument("--time-limit", type=float, default=300.0, help="lower bound's limit, s")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    design = run_design(a.design, samples=500, seed=0, coverage_samples=0)
    t_design = time.perf_counter() - t0
    fam = default_family()
    G = family_uss(fam, design.controller, inputs="u", outputs=a.output)
    nominal = hinf_norm(G.nominal())
    gamma = a.ratio * nominal
    t0 = time.perf_counter()
    res = robust_performance(G, gamma=gamma, time_limit_s=a.time_limit)
    t_rp = time.perf_counter() - t0
    out = {
        "design": a.design,
        "map": f"u -> {a.output}",
        "states": G.nstates,
        "parameters": len(G.parameters),
        "nominal_norm": nominal,
        "gamma": gamma,
        "lower": res.lower,
        "upper": res.upper,
        "lower_over_upper": res.lower / res.upper if res.upper > 0 else None,
        "time_design_s": t_design,
        "time_s": t_rp,
        "timings_s": res.timings_s,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    if res.worst is not None:
        w = res.worst
        member = G.at(w["parameters"])
        closed_poles = np.linalg.eigvals(member.A)
        second = float(ct.linfnorm(member)[0]) if closed_poles.real.max() < 0 else float("inf")
        # the result's norm is the weighted one, ||T / gamma||; SLICOT's is of T itself
        out["worst"] = {
            "scale": w["scale"],
            "weighted_norm": w["norm"],
            "weighted_norm_linfnorm": second / gamma,
            "frequency_hz": w.get("frequency_hz"),
        }
    if a.json:
        print(json.dumps(out, indent=2, default=float))
    else:
        print(
            f"{a.design}, {out['map']}: {out['states']} states, {out['parameters']} "
            f"uncertain parameters, gamma {a.ratio} x nominal ({gamma:.5g})"
        )
        print(
            f"margin in [{res.lower:.5g}, {res.upper:.5g}] (lower/upper "
            f"{out['lower_over_upper']:.4f}) in {t_rp:.1f} s "
            f"(upper {res.timings_s.get('upper', float('nan')):.1f} s, "
            f"lower {res.timings_s.get('lower', float('nan')):.1f} s); design {t_design:.1f} s"
        )
        if "worst" in out:
            w = out["worst"]
            print(
                f"worst member at scale {w['scale']:.5g}: ||T/gamma|| {w['weighted_norm']:.6g} "
                f"(python-control/SLICOT {w['weighted_norm_linfnorm']:.6g}) at "
                f"{w['frequency_hz']:.4g} Hz"
            )
        print(f"peak memory {out['peak_rss_mb']:.0f} MB")
    return out


if __name__ == "__main__":
    main()
