"""Benchmark: eigenvalues of the family's 13x13 closed loops, compiled loops against LAPACK.

Builds the closed-loop matrices of ``--members`` members of the default physical family
(Latin hypercube, seed 0) and times, ``--repeats`` times each in turn,
:func:`robust.analysis.small_eig.eigvals_stack` (the compiled loops validation uses) and
:func:`numpy.linalg.eigvals` (LAPACK's ``dgeev``, one call per matrix, the baseline). Prints
min/median/max microseconds per matrix of each, the ratio of the medians, the largest
difference between the two (relative to each member's largest eigenvalue) and this
process's peak resident memory. The first call, which loads the compiled code from
Numba's cache (or compiles it), is timed apart.

Run: ``python benchmarks/bench_small_eig.py [--members 20000] [--repeats 5]``.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time

from bdft.kernels import pin_numeric_kernels

pin_numeric_kernels()

import numpy as np  # noqa: E402

from backhoe import closed_loop_matrices, default_family  # noqa: E402
from robust.analysis.small_eig import eigvals_stack, load_kernels  # noqa: E402
from uncertainty import sample  # noqa: E402


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", type=int, default=20_000)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args(argv)
    fam = default_family("physical")
    A = closed_loop_matrices(fam, sample(fam.parameters, a.members, method="lhs", seed=0).values)
    t = time.perf_counter()
    load_kernels()
    print(f"first call (load or compile): {time.perf_counter() - t:.2f} s")
    times = {"compiled loops": [], "LAPACK dgeev": []}
    for _ in range(a.repeats):
        for name, fn in (("compiled loops", eigvals_stack), ("LAPACK dgeev", np.linalg.eigvals)):
            t = time.perf_counter()
            lam = fn(A)
            times[name].append((time.perf_counter() - t) / len(A) * 1e6)
            if name == "compiled loops":
                ours = lam
            else:
                ref = lam
    med = {k: statistics.median(v) for k, v in times.items()}
    for name, v in times.items():
        print(
            f"{name}: min {min(v):.2f} us, median {med[name]:.2f} us, max {max(v):.2f} us "
            f"per {A.shape[1]}x{A.shape[2]} matrix"
        )
    print(f"ratio LAPACK / compiled (medians): {med['LAPACK dgeev'] / med['compiled loops']:.2f}")
    gap = np.abs(np.sort_complex(ours) - np.sort_complex(ref)).max(axis=1)
    print(
        f"largest difference: {np.max(gap / np.abs(ref).max(axis=1)):.2e} of the member's "
        f"largest eigenvalue ({a.members} members)"
    )
    print(f"peak RSS: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
