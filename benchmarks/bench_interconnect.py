"""Benchmark: the family's closed loops assembled by compiled loops against NumPy.

Builds the blocks of ``--members`` members of the default (physical) family once, then
times ``uncertainty.closeloops.close_loops`` (compiled; the baseline is excluded from its
first call, which loads or compiles the loops) against the same closed loops assembled
with NumPy as the workbench did before: padded block-diagonal stacks, ``einsum`` products
and the series of ``(D M)^k``. Prints min/median/max microseconds per member over
``--repeats`` runs, the ratio of the medians, and whether the two give the same bits.

Run: ``python benchmarks/bench_interconnect.py [--members 20000] [--repeats 5]``.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import bdft  # noqa: F401 - fixes the numerical kernels before NumPy is used
from backhoe import default_family
from backhoe.families.batched import interconnection, loop_blocks
from uncertainty import sample
from uncertainty.closeloops import close_loops


def numpy_close(blocks, M) -> np.ndarray:
    """The closed loops by padded stacks and batched NumPy products (no algebraic cycle)."""
    N = max(b.A.shape[0] for b in blocks)
    n = sum(b.A.shape[-1] for b in blocks)
    m = sum(b.B.shape[-1] for b in blocks)
    p = sum(b.C.shape[-2] for b in blocks)
    A, B = np.zeros((N, n, n)), np.zeros((N, n, m))
    C, D = np.zeros((N, p, n)), np.zeros((N, p, m))
    x = u = y = 0
    for b in blocks:
        k, i, o = b.A.shape[-1], b.B.shape[-1], b.C.shape[-2]
        A[:, x : x + k, x : x + k] = b.A
        B[:, x : x + k, u : u + i] = b.B
        C[:, y : y + o, x : x + k] = b.C
        D[:, y : y + o, u : u + i] = b.D
        x, u, y = x + k, u + i, y + o
    DM = np.einsum("nom,mq->noq", D, M, optimize=True)
    Z, term = C.copy(), C
    for _ in range(p - 1):
        term = np.einsum("nop,npj->noj", DM, term, optimize=True)
        if not term.any():
            break
        Z += term
    BM = np.einsum("nim,mq->niq", B, M, optimize=True)
    A += np.einsum("niq,nqj->nij", BM, Z, optimize=True)
    return A


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", type=int, default=20_000)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args(argv)
    fam = default_family("physical")
    values = np.asarray(sample(fam.parameters, a.members, seed=2).values)
    blocks = loop_blocks(fam, values)
    M = interconnection(fam, blocks)
    groups = [[getattr(b, x) for b in blocks] for x in "ABCD"]
    t = time.perf_counter()
    close_loops(*groups, M)
    print(f"first call (load or compile): {time.perf_counter() - t:.2f} s")
    times = {"compiled loops": [], "NumPy (einsum)": []}
    for _ in range(a.repeats):
        t = time.perf_counter()
        new = close_loops(*groups, M)
        times["compiled loops"].append((time.perf_counter() - t) / a.members * 1e6)
        t = time.perf_counter()
        old = numpy_close(blocks, M)
        times["NumPy (einsum)"].append((time.perf_counter() - t) / a.members * 1e6)
    for name, ts in times.items():
        print(
            f"{name}: min {min(ts):.2f} us, median {statistics.median(ts):.2f} us, "
            f"max {max(ts):.2f} us per member"
        )
    ratio = statistics.median(times["NumPy (einsum)"]) / statistics.median(times["compiled loops"])
    print(f"ratio NumPy / compiled (medians): {ratio:.2f}")
    print(f"same bits: {'yes' if np.array_equal(new, old) else 'NO'} ({a.members} members)")


if __name__ == "__main__":
    main()
