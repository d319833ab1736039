"""Closed-loop state matrices of a stack of interconnected block systems, in compiled loops.

Blocks ``k = 1..K``, each with a leading member axis (length ``N``, or 1 for a block the
same for every member), are wired by a constant matrix ``M`` from the block outputs to the
block inputs::

    x_k' = A_k x_k + B_k u_k,   y_k = C_k x_k + D_k u_k,   u = M y
    =>  A_cl = blkdiag(A_k) + B M (I - D M)^{-1} C

with ``B``, ``C``, ``D`` the block-diagonal stacks of the blocks' matrices. When the
feedthroughs form no algebraic cycle (``D M`` structurally nilpotent: the pattern's graph
has no cycle), the inverse is the finite series ``I + DM + (DM)^2 + ...``, exact, and
:func:`close_loops` builds every member's matrix in one compiled pass, reading each block
where it lies (no padded copies, no batched matrix products). A loop with an algebraic
cycle is solved by LAPACK (:func:`numpy.linalg.solve`) instead.

Arithmetic: plain multiplications and additions in a fixed order (no fused multiply-add,
no reassociation; products with a zero entry of ``M`` or ``D M`` are skipped, which can
only turn a ``-0.0`` into ``+0.0``), so the bits do not depend on the CPU, the BLAS or its
threads. The first call in a process loads the compiled loops from Numba's cache (or
compiles them once after an install, once per number of blocks).
"""

from __future__ import annotations

import numba
import numpy as np

from robust.errors import ModelStructureError

__all__ = ["close_loops", "algebraic_cycle"]


def algebraic_cycle(pattern: np.ndarray) -> bool:
    """Whether a square sparsity pattern's graph has a cycle (some matrix with it is not
    nilpotent).

    Parameters
    ----------
    pattern : ndarray of bool, shape (p, p)
        Where ``D M`` can be nonzero.

    Returns
    -------
    bool
        False when every matrix with this pattern is nilpotent.
    """
    P = np.asarray(pattern, bool).astype(np.int64)
    Q = P.copy()
    for _ in range(P.shape[0]):
        if not Q.any():
            return False
        Q = np.minimum(Q @ P, 1)
    return bool(Q.any())


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _close(As, Bs, Cs, Ds, M, xs, us, ys, out):  # pragma: no cover - compiled
    """``out[j] = blkdiag(A) + B M Z`` with ``Z = sum_k (D M)^k C`` for every member ``j``."""
    N, n, _ = out.shape
    m, p = M.shape
    nb = len(As)
    G = np.zeros((n, p))
    DM = np.zeros((p, p))
    Z = np.zeros((p, n))
    T = np.zeros((p, n))
    T2 = np.zeros((p, n))
    qs = np.zeros(p, np.int64)
    for j in range(N):
        G[:] = 0.0
        DM[:] = 0.0
        Z[:] = 0.0
        for k in range(nb):
            A = As[k]
            B = Bs[k]
            C = Cs[k]
            D = Ds[k]
            ja = j if A.shape[0] > 1 else 0
            jb = j if B.shape[0] > 1 else 0
            jc = j if C.shape[0] > 1 else 0
            jd = j if D.shape[0] > 1 else 0
            x0 = xs[k]
            u0 = us[k]
            y0 = ys[k]
            nk = A.shape[1]
            for r in range(nk):
                for c in range(nk):
                    out[j, x0 + r, x0 + c] = A[ja, r, c]
            # the block's rows of B M and of D M (summed over the block's inputs in order)
            for c in range(B.shape[2]):
                for q in range(p):
                    w = M[u0 + c, q]
                    if w != 0.0:
                        for r in range(nk):
                            G[x0 + r, q] += B[jb, r, c] * w
                        for r in range(D.shape[1]):
                            DM[y0 + r, q] += D[jd, r, c] * w
            for r in range(C.shape[1]):
                for c in range(nk):
                    Z[y0 + r, x0 + c] = C[jc, r, c]
        # Z = C + DM C + DM^2 C + ... (DM nilpotent: the terms end within p - 1 steps)
        for r in range(p):
            for c in range(n):
                T[r, c] = Z[r, c]
        for _ in range(p - 1):
            for r in range(p):
                for c in range(n):
                    T2[r, c] = 0.0
                for s in range(p):
                    w = DM[r, s]
                    if w != 0.0:
                        for c in range(n):
                            T2[r, c] += w * T[s, c]
            nonzero = False
            for r in range(p):
                for c in range(n):
                    T[r, c] = T2[r, c]
                    nonzero |= T2[r, c] != 0.0
            if not nonzero:  # the series has ended
                break
            for r in range(p):
                for c in range(n):
                    Z[r, c] += T[r, c]
        # A_cl = A + (B M) Z, each row's sum over the nonzero entries of B M in order
        for i in range(n):
            cnt = 0
            for q in range(p):
                if G[i, q] != 0.0:
                    qs[cnt] = q
                    cnt += 1
            if cnt == 0:
                continue
            for c in range(n):
                s = 0.0
                for t in range(cnt):
                    s += G[i, qs[t]] * Z[qs[t], c]
                out[j, i, c] += s


def close_loops(As, Bs, Cs, Ds, M) -> np.ndarray:
    """Closed-loop state matrices of ``N`` members of a loop of blocks.

    Parameters
    ----------
    As, Bs, Cs, Ds : sequence of ndarray
        Per block ``k``: ``A_k`` of shape ``(N or 1, n_k, n_k)``, ``B_k`` ``(N or 1, n_k,
        m_k)``, ``C_k`` ``(N or 1, p_k, n_k)``, ``D_k`` ``(N or 1, p_k, m_k)`` (a leading
        length 1 broadcasts: the block is the same for every member).
    M : ndarray, shape (m, p)
        ``u = M y``: the blocks' stacked inputs (``m = sum m_k``) from their stacked outputs
        (``p = sum p_k``).

    Returns
    -------
    ndarray, shape (N, n, n)
        ``blkdiag(A_k) + B M (I - D M)^{-1} C`` per member, ``n = sum n_k``.

    Raises
    ------
    ModelStructureError
        If the shapes do not fit together, or ``I - D M`` is singular for a member (an
        ill-posed loop).
    """
    arrays = [[np.ascontiguousarray(x, dtype=float) for x in group] for group in (As, Bs, Cs, Ds)]
    M = np.ascontiguousarray(M, dtype=float)
    K = len(arrays[0])
    if K == 0 or any(len(g) != K for g in arrays) or M.ndim != 2:
        raise ModelStructureError(
            "close_loops: expected as many A, B, C and D arrays (at least one block) and a "
            f"2-D M; got {[len(g) for g in arrays]} and M of shape {M.shape}"
        )
    sizes = set()
    for k, (A, B, C, D) in enumerate(zip(*arrays)):
        nk, mk, pk = A.shape[-1], B.shape[-1], C.shape[-2]
        want = {"A": (nk, nk), "B": (nk, mk), "C": (pk, nk), "D": (pk, mk)}
        for name, x in zip("ABCD", (A, B, C, D)):
            if x.ndim != 3 or x.shape[1:] != want[name]:
                raise ModelStructureError(
                    f"close_loops: block {k}'s {name} must have shape (N or 1, "
                    f"{want[name][0]}, {want[name][1]}); got {x.shape}"
                )
            if x.shape[0] != 1:
                sizes.add(x.shape[0])
    if len(sizes) > 1:
        raise ModelStructureError(
            f"close_loops: the blocks' member counts differ: {sorted(sizes)} (1 broadcasts)"
        )
    N = sizes.pop() if sizes else 1
    xs = np.cumsum([0] + [A.shape[-1] for A in arrays[0]])
    us = np.cumsum([0] + [B.shape[-1] for B in arrays[1]])
    ys = np.cumsum([0] + [C.shape[-2] for C in arrays[2]])
    n, m, p = int(xs[-1]), int(us[-1]), int(ys[-1])
    if M.shape != (m, p):
        raise ModelStructureError(
            f"close_loops: M must have shape ({m}, {p}) (block inputs x block outputs); "
            f"got {M.shape}"
        )
    pattern = np.zeros((p, p), bool)
    for k, D in enumerate(arrays[3]):
        used = np.any(D != 0.0, axis=0).astype(float)  # (p_k, m_k): nonzero for some member
        pattern[ys[k] : ys[k + 1]] |= (used @ (M[us[k] : us[k + 1]] != 0.0)) > 0
    if algebraic_cycle(pattern):
        return _solved(arrays, M, xs, us, ys, N, n, m, p)
    out = np.zeros((N, n, n))
    if N:
        blocks, offsets = _padded(arrays, (xs, us, ys))
        _close(*blocks, M, *offsets, out)
    return out


#: Blocks per call of the compiled loop: fewer are padded with empty blocks. A tuple's
#: length is part of its type, so each block count was a compilation of its own (3 s).
TUPLE_BLOCKS = 8


def _padded(arrays, offsets):
    """Each group of block arrays as a tuple of :data:`TUPLE_BLOCKS`, and the state, input
    and output offsets to match: empty blocks after the loop's own (no states, inputs or
    outputs, each at the end of the last real block), which the compiled loop passes by."""
    pad = max(TUPLE_BLOCKS - len(arrays[0]), 0)
    empty = np.zeros((1, 0, 0))
    blocks = [tuple(g) + (empty,) * pad for g in arrays]
    return blocks, [np.concatenate([v, np.full(pad, v[-1], dtype=v.dtype)]) for v in offsets]


def _solved(arrays, M, xs, us, ys, N, n, m, p) -> np.ndarray:
    """:func:`close_loops` of a loop with an algebraic cycle: ``(I - D M)^{-1}`` by LAPACK."""
    A = np.zeros((N, n, n))
    B = np.zeros((N, n, m))
    C = np.zeros((N, p, n))
    D = np.zeros((N, p, m))
    for k, blocks in enumerate(zip(*arrays)):
        rows = (slice(xs[k], xs[k + 1]), slice(us[k], us[k + 1]), slice(ys[k], ys[k + 1]))
        x, u, y = rows
        for target, block, (r, c) in zip((A, B, C, D), blocks, ((x, x), (x, u), (y, x), (y, u))):
            target[:, r, c] = block
    try:
        Z = np.linalg.solve(np.eye(p)[None] - D @ M, C)
    except np.linalg.LinAlgError:
        raise ModelStructureError(
            "the loop is ill-posed (I - D M singular) for at least one member; "
            "check the controller's feedthrough D"
        ) from None
    return A + (B @ M) @ Z
