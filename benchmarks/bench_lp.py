"""Benchmark: the tuning's linear programs, solve_lp against scipy.optimize.linprog.

Draws ``--programs`` programs shaped as :func:`robust.synthesis.tuning.slp_minimise`'s
(``--params`` controller entries: steps, distances and a level, ``2 * params + 1``
variables; ``--rows`` linearised constraints plus the ``2 * params`` distance rows; seed
``--seed``) and times, ``--repeats`` times each in turn, :func:`robust.synthesis.lp.solve_lp`
and :func:`scipy.optimize.linprog` (``method="highs"``, the baseline). Prints min/median/max
milliseconds per program of each, the ratio of the medians, whether every answer (status,
solution, objective) is the same to the bit, and this process's peak resident memory.

Run: ``python benchmarks/bench_lp.py [--programs 300] [--params 30] [--rows 25] [--repeats 5]``.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time

from bdft.kernels import pin_numeric_kernels

pin_numeric_kernels()

import numpy as np  # noqa: E402
import scipy.optimize as so  # noqa: E402

from robust.synthesis.lp import solve_lp  # noqa: E402


def _program(rng, n, m):
    G = rng.standard_normal((m, n))
    v = rng.standard_normal(m) * 0.1
    unit = rng.random(n) + 0.5
    ref = rng.standard_normal(n) * 0.01
    c = np.concatenate([rng.standard_normal(n) * 1e-3, np.full(n, 1e-3 / n), [1.0]])
    A = np.vstack(
        [
            np.hstack([G, np.zeros((m, n)), -np.ones((m, 1))]),
            np.hstack([np.diag(1 / unit), -np.eye(n), np.zeros((n, 1))]),
            np.hstack([-np.diag(1 / unit), -np.eye(n), np.zeros((n, 1))]),
        ]
    )
    b = np.concatenate([-v, ref / unit, -ref / unit])
    bounds = [(-0.1 * u, 0.1 * u) for u in unit] + [(0.0, None)] * n + [(-0.05, None)]
    return c, A, b, bounds


def _linprog(c, A, b, bounds):
    return so.linprog(c, A_ub=A, b_ub=b, bounds=bounds, method="highs")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--programs", type=int, default=300)
    ap.add_argument("--params", type=int, default=30)
    ap.add_argument("--rows", type=int, default=25)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    programs = [_program(rng, a.params, a.rows) for _ in range(a.programs)]
    times = {"solve_lp": [], "linprog": []}
    answers = {}
    for _ in range(a.repeats):
        for name, fn in (("solve_lp", solve_lp), ("linprog", _linprog)):
            t = time.perf_counter()
            answers[name] = [fn(*p) for p in programs]
            times[name].append((time.perf_counter() - t) / len(programs) * 1e3)
    med = {k: statistics.median(v) for k, v in times.items()}
    rows, cols = programs[0][1].shape
    for name, v in times.items():
        print(
            f"{name}: min {min(v):.3f} ms, median {med[name]:.3f} ms, max {max(v):.3f} ms "
            f"per {rows} x {cols} program"
        )
    print(f"ratio linprog / solve_lp (medians): {med['linprog'] / med['solve_lp']:.2f}")
    same = all(
        int(r.status) == s.status
        and (r.x is None) == (s.x is None)
        and (r.x is None or (np.array_equal(r.x, s.x) and r.fun == s.fun))
        for s, r in zip(answers["solve_lp"], answers["linprog"])
    )
    optimal = sum(s.status == 0 for s in answers["solve_lp"])
    print(f"answers the same to the bit: {same} ({optimal} of {len(programs)} optimal)")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {peak:.0f} MiB")


if __name__ == "__main__":
    main()
