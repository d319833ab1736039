"""Benchmark: the mu certificates on hand-derived cases, bounds against exact, and their time.

Robust performance (:func:`uncertainty.robust_performance`) on the four cases of
``tests/test_robust_performance.py`` and robust stability by mu
(``robust_margin(method="mu")``) beside the eigenvalue enclosures on the decay-rate case of
``tests/test_uss_margin.py`` and an observer-based noncollocated two-mass loop (its exact
margin from a root of the closed loop's spectral abscissa). Prints, per case, the exact
margin, both bounds and their ratios to it, and the wall time; then the time of one D-G
scaling LMI of :func:`uncertainty.mussv` (built numerically), and of one LMI of 8, 12, 20
and 30 channels (seeded random matrices, 2 x 2 repeated real blocks, the family's loop has
30 channels) by each solver, CVXOPT and Clarabel (:data:`uncertainty.mu.CVXOPT_FROM_CHANNELS`
picks between them). Targets (issue
"robust stability and performance of any loop"): lower >= 0.9 exact, upper <= 1.01 exact,
each case under a minute on two cores.

    python benchmarks/bench_mu.py [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import time

import control as ct
import numpy as np
from scipy.optimize import brentq

from uncertainty import Region, robust_margin, robust_performance, ureal, uss
from uncertainty.mu import _scaling_problem, _scalings_feasible, _solve_clarabel, _solve_cvxopt


def _performance_cases():
    a = ureal("a", 2.0, 0.5, 3.5)
    lag = uss([[-a]], [[1.0]], [[1.0]], [[0.0]])
    c = ureal("c", 1.0, 0.2, 1.8)
    res = uss([[0, 1], [-1, -c]], [[0], [1]], [[1, 0]], [[0]])
    a2, b2 = ureal("a", 1.0, 0.5, 1.5), ureal("b", 2.0, 1.0, 3.0)
    loop = uss([[-a2]], [[b2]], [[1.0]], [[0.0]])
    return [
        ("lag 1/(s+a)", dict(system=lag), 2.0 / 3.0),
        ("resonance, gamma 2", dict(system=res, gamma=2.0), (1 - 2 * math.sin(math.pi / 12)) / 0.8),
        (
            "loop b/(s+a+b), 0.75",
            dict(system=loop, controller=ct.ss([], [], [], 1.0), gamma=0.75),
            0.4,
        ),
        ("weighted lag, 1.5", dict(system=lag, output_weight=1.5), 1.0 / 3.0),
    ]


def _two_mass():
    k = ureal("k", 1.0, 0.5, 2.0)
    c = 0.01
    A = [[0, 0, 1, 0], [0, 0, 0, 1], [-k, k, -c, c], [k, -k, c, -c]]
    S = uss(A, [[0], [0], [1], [0]], [[0, 1, 0, 0]], [[0]])
    P0 = S.nominal()
    Kc, _, _ = ct.lqr(P0.A, P0.B, np.diag([1, 1, 0.1, 0.1]), [[1.0]])
    L, _, _ = ct.lqe(P0.A, np.eye(4), P0.C, np.eye(4) * 0.1, [[0.01]])
    K = ct.ss(P0.A - P0.B @ Kc - L @ P0.C, L, Kc, [[0.0]])
    closed = S.feedback(K)
    up = brentq(lambda x: np.linalg.eigvals(closed.at({"k": x}).A).real.max(), 1.0 + 1e-6, 2.0)
    return S, K, up - 1.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    rows = []
    for name, kw, exact in _performance_cases():
        t = time.perf_counter()
        r = robust_performance(**kw)
        rows.append(("performance", name, exact, r.lower, r.upper, time.perf_counter() - t))
    c = ureal("c", 1.0, 0.2, 3.0)
    G = uss([[0, 1], [-4, -c]], [[0], [1]], [[1, 0]], [[0]])
    S, K, exact2 = _two_mass()
    for name, system, ctrl, region, exact in (
        ("decay 0.3, s^2+cs+4", G, None, Region(decay_rate=0.3), 0.5),
        ("LQG two-mass, noncollocated", S, K, Region(), exact2),
    ):
        for method in ("mu", "eigenvalues"):
            t = time.perf_counter()
            r = robust_margin(system, controller=ctrl, region=region, method=method)
            rows.append(
                (f"stability ({method})", name, exact, r.lower, r.upper, time.perf_counter() - t)
            )
    M = np.random.default_rng(0).standard_normal((6, 6)) + 1j * np.random.default_rng(
        1
    ).standard_normal((6, 6))
    blocks = [(2, "real"), (2, "real"), (2, "complex")]
    t = time.perf_counter()
    for _ in range(10):
        _scalings_feasible(M, blocks, 3.0)
    lmi_s = (time.perf_counter() - t) / 10
    solvers = []
    rng = np.random.default_rng(0)
    for n in (8, 12, 20, 30):
        Mn = rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n))
        Mn /= np.linalg.norm(Mn, 2)
        nv, _, _, psd, lin = _scaling_problem(Mn, [(2, "real")] * (n // 2), 0.9, 10.0)
        row = {"channels": n}
        for name, solve in (("cvxopt", _solve_cvxopt), ("clarabel", _solve_clarabel)):
            t = time.perf_counter()
            for _ in range(3):
                solve(nv, psd, lin)
            row[f"{name}_seconds"] = (time.perf_counter() - t) / 3
        solvers.append(row)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    if args.json:
        print(
            json.dumps(
                {
                    "cases": [
                        dict(zip(("bound", "case", "exact", "lower", "upper", "seconds"), r))
                        for r in rows
                    ],
                    "dg_lmi_seconds": lmi_s,
                    "lmi_solvers": solvers,
                    "peak_rss_mib": peak,
                }
            )
        )
        return
    print(
        f"{'bound':24s} {'case':30s} {'exact':>7s} {'lower':>7s} {'upper':>7s} "
        f"{'low/ex':>7s} {'up/ex':>7s} {'time[s]':>8s}"
    )
    for kind, name, exact, lo, up, secs in rows:
        print(
            f"{kind:24s} {name:30s} {exact:7.4f} {lo:7.4f} {up:7.4f} "
            f"{lo / exact:7.4f} {up / exact:7.4f} {secs:8.1f}"
        )
    print(
        f"one D-G scaling LMI (6 x 6, two repeated reals and a complex block): {lmi_s * 1e3:.1f} ms"
    )
    for row in solvers:
        print(
            f"one LMI of {row['channels']:2d} channels: CVXOPT {row['cvxopt_seconds']:6.3f} s, "
            f"Clarabel {row['clarabel_seconds']:6.3f} s"
        )
    print(f"process peak resident memory: {peak:.0f} MiB")


if __name__ == "__main__":
    main()
