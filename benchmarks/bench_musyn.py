"""Benchmark: mu-synthesis (uncertainty.musyn) on the two problems of tests/test_musyn.py.

Per problem and method: the time of each iteration, the total, the grid and the certified
peak mu; on the complex problem also dkpy's D-K iteration on the same LFT plant and grid
(its K-step SLICOT sb10ad by bisection, as in the test), its peak mu judged by the same
dense-grid mussv upper bound as ours, and the ratio of the times.

    python benchmarks/bench_musyn.py [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_musyn import (  # noqa: E402
    LD_GRID,
    MSD_GRID,
    _closed_loop_lft,
    _dense_peak,
    _dkpy_dk,
    _lightly_damped,
    _mass_spring_damper,
)

from uncertainty import musyn  # noqa: E402


def _run(name, P, method, grid, max_iter):
    t0 = time.perf_counter()
    res = musyn(P, 1, 1, method=method, max_iter=max_iter, frequencies=grid)
    total = time.perf_counter() - t0
    return {
        "problem": name,
        "method": res.method,
        "seconds_total": total,
        "seconds_per_iteration": [h["seconds"] for h in res.history],
        "seconds_certificate": res.certificate["seconds"],
        "mu_peak_grid": res.mu_peak_grid,
        "mu_peak_certified": res.mu_peak_certified,
        "controller_order": res.controller.nstates,
        "history_mu_peak_grid": [h["mu_peak_grid"] for h in res.history],
        "result": res,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    rows = [
        _run("lightly damped, complex input uncertainty", _lightly_damped(), "dk", LD_GRID, 5),
        _run("mass-spring-damper, real k and c", _mass_spring_damper(), "dgk", MSD_GRID, 3),
        _run("mass-spring-damper, real k and c", _mass_spring_damper(), "dk", MSD_GRID, 3),
    ]
    P = _lightly_damped()
    t0 = time.perf_counter()
    K = _dkpy_dk(P)
    t_dkpy = time.perf_counter() - t0
    dense = np.logspace(-3, 3, 121)
    blocks = [(1, "complex"), (2, "complex")]
    theirs = _dense_peak(_closed_loop_lft(P, K)[0], blocks, dense)
    ours = _dense_peak(_closed_loop_lft(P, rows[0]["result"].controller)[0], blocks, dense)
    dkpy = {
        "seconds_total": t_dkpy,
        "mu_peak_dense_dkpy": theirs,
        "mu_peak_dense_ours": ours,
        "time_ratio_dkpy_over_ours": t_dkpy / rows[0]["seconds_total"],
        "controller_order": K.nstates,
    }
    for r in rows:
        r.pop("result")
    if args.json:
        print(json.dumps({"musyn": rows, "dkpy": dkpy}, indent=2))
        return
    for r in rows:
        per = ", ".join(f"{s:.1f}" for s in r["seconds_per_iteration"])
        print(f"{r['problem']} [{r['method']}]")
        print(f"  iterations (s): {per}; certificate {r['seconds_certificate']:.1f} s")
        print(
            f"  total {r['seconds_total']:.1f} s; peak mu grid {r['mu_peak_grid']:.4f}, "
            f"certified {r['mu_peak_certified']:.4f}; controller order {r['controller_order']}"
        )
        peaks = ", ".join(f"{m:.4f}" for m in r["history_mu_peak_grid"])
        print(f"  grid peak by iteration: {peaks}")
    print("dkpy D-K on the lightly damped problem (same LFT plant and grid)")
    print(
        f"  total {dkpy['seconds_total']:.1f} s "
        f"(dkpy / ours {dkpy['time_ratio_dkpy_over_ours']:.2f}); "
        f"dense-grid peak mu (complex structure): dkpy {dkpy['mu_peak_dense_dkpy']:.4f}, "
        f"ours {dkpy['mu_peak_dense_ours']:.4f}; dkpy controller order {dkpy['controller_order']}"
    )


if __name__ == "__main__":
    main()
