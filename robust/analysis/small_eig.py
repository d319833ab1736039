"""Eigenvalues of many small real matrices: compiled loops that run across the stack.

:func:`numpy.linalg.eigvals` on a stack of 13x13 closed loops calls LAPACK's ``dgeev``
once per matrix, 22 us each on the machine of the README's figures: 4.5 us of balancing
(``dgebal`` and its norm calls), 1.4 of Hessenberg reduction and 14.6 of ``dlahqr``'s
double-shift sweeps, whose latency (a square root and three divisions per reflector, one
reflector after the other) and short loops the processor cannot fill. Validating a
million members was mostly this loop. :func:`eigvals_stack` runs the same three
classical steps, compiled by Numba, on up to :data:`LANES` matrices side by side, with
the innermost loops running across the matrices, so that the compiler vectorises them
and one matrix's reflector overlaps another's (a stack of one matrix costs what LAPACK
does, 37 us; from eight on, the loops are 2 to 2.7 times faster):

1. balancing by powers of two (Parlett and Reinsch, "Balancing a matrix for calculation
   of eigenvalues and eigenvectors", Numer. Math. 13, 1969), without the permutations;
2. reduction to upper Hessenberg form by Householder reflections (Golub and Van Loan,
   *Matrix Computations*, 4th ed., 2013, algorithm 7.4.2);
3. Francis's implicit double-shift QR iteration, eigenvalues only, with the deflation
   and consecutive-small-subdiagonal tests and the exceptional shifts of Martin, Peters
   and Wilkinson ("The QR algorithm for real Hessenberg matrices", Numer. Math. 14,
   1970; EISPACK's ``hqr``).

Each matrix gets the operations it would get alone, so its eigenvalues do not depend on
its neighbours or on how a stack is split into chunks and tasks (tested bit for bit).
They agree with LAPACK's to rounding where the eigenvalues are well conditioned, not bit
for bit; against 40-digit references the compiled loops are the more accurate of the two on
the family's closed loops (tested). Without LAPACK's permutations, which isolate the
eigenvalues of a reducible matrix exactly, a reducible non-normal matrix (a triangular one,
one with zero rows or columns) gets only backward-stable eigenvalues: on random lower
triangular 30x30 matrices up to 3e-6 of the norm off the exact diagonal. The loops are
meant for closed loops such as the family's, whose matrices are irreducible.
A matrix whose iteration has not converged after :data:`MAX_SWEEPS` sweeps for one
eigenvalue is handed to :func:`numpy.linalg.eigvals`, and so is one with an entry of
magnitude beyond 1e100 or below 1e-100 (other than zero), whose scaling LAPACK guards,
or a non-finite one (NumPy then raises its own error). The compiled code has no fused multiply-add
and no reassociation (Numba's default), so it gives the same bits on every x86-64 CPU,
whatever vector width the compiler chose (tested against a build for a generic CPU).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["LANES", "MAX_SWEEPS", "eigvals_stack", "load_kernels"]

#: Double-shift sweeps allowed per eigenvalue (or pair) before LAPACK takes the matrix.
MAX_SWEEPS = 60
# the magnitudes a matrix's entries may have (LAPACK takes the others) and within which
# a reflector's entries are squared unscaled
_TINY = 1e-100
_HUGE = 1e100
#: Most matrices reduced side by side (the compiled loops run across them).
LANES = 64


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _balance(b, n, lanes, c, r, f, d):  # pragma: no cover - compiled
    """Balance the first ``lanes`` lanes of ``b`` by powers of two (in place; ``c``, ``r``,
    ``f``, ``d`` scratch of one value per lane).

    Parlett and Reinsch's iteration: row and column ``i`` are scaled by ``1/f`` and ``f``
    (a power of two, so exactly) when that brings their off-diagonal 1-norms within a
    factor of two and their sum down by 5 %, index after index, until a pass over the
    indices changes nothing. The lanes make their passes together; a lane whose pass
    changed nothing would change nothing in the next pass either, so each lane ends
    where it would on its own.
    """
    done = False
    while not done:
        done = True
        for i in range(n):
            # the off-diagonal 1-norms (the diagonal entry set aside for the sums)
            for m in range(lanes):
                c[m] = 0.0
                r[m] = 0.0
                d[m] = b[i, i, m]
                b[i, i, m] = 0.0
            for j in range(n):
                for m in range(lanes):
                    c[m] += abs(b[j, i, m])
                    r[m] += abs(b[i, j, m])
            changed = False
            for m in range(lanes):
                b[i, i, m] = d[m]
                cm = c[m]
                rm = r[m]
                f[m] = 1.0
                if cm == 0.0 or rm == 0.0:
                    continue
                g = rm / 2.0
                fm = 1.0
                sm = cm + rm
                while cm < g:
                    fm *= 2.0
                    cm *= 4.0
                g = rm * 2.0
                while cm > g:
                    fm /= 2.0
                    cm /= 4.0
                if (cm + rm) / fm < 0.95 * sm:
                    f[m] = fm
                    changed = True
            if not changed:
                continue
            done = False
            for m in range(lanes):
                c[m] = 1.0 / f[m]
            for j in range(n):
                for m in range(lanes):
                    b[i, j, m] *= c[m]
            for j in range(n):
                for m in range(lanes):
                    b[j, i, m] *= f[m]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _hessenberg(b, n, lanes, v, w, h):  # pragma: no cover - compiled
    """Householder reduction of the first ``lanes`` lanes of ``b`` (shape (n, n, LANES))
    to upper Hessenberg form (in place; ``v`` (n, LANES), ``w`` (n, LANES) and ``h``
    (4, LANES) scratch). The lanes run the same operations; a lane whose column is
    already zero gets the identity (its reflector's scale is zero)."""
    scale = h[0]
    hh = h[1]
    g = h[2]
    hinv = h[3]
    for k in range(n - 2):
        for m in range(lanes):
            scale[m] = 0.0
        for i in range(k + 1, n):
            for m in range(lanes):
                scale[m] += abs(b[i, k, m])
        for m in range(lanes):
            hinv[m] = 1.0 / scale[m] if scale[m] != 0.0 else 0.0
            hh[m] = 0.0
        for i in range(k + 1, n):
            for m in range(lanes):
                v[i, m] = b[i, k, m] * hinv[m]
                hh[m] += v[i, m] * v[i, m]
        for m in range(lanes):
            gm = math.sqrt(hh[m])
            if v[k + 1, m] > 0.0:
                gm = -gm
            hh[m] -= v[k + 1, m] * gm
            v[k + 1, m] -= gm
            g[m] = gm
            hinv[m] = 1.0 / hh[m] if scale[m] != 0.0 else 0.0
        # from the left, row by row: w = v' b / h, then b -= v w
        for j in range(k + 1, n):
            for m in range(lanes):
                w[j, m] = 0.0
        for i in range(k + 1, n):
            for j in range(k + 1, n):
                for m in range(lanes):
                    w[j, m] += v[i, m] * b[i, j, m]
        for j in range(k + 1, n):
            for m in range(lanes):
                w[j, m] *= hinv[m]
        for i in range(k + 1, n):
            for j in range(k + 1, n):
                for m in range(lanes):
                    b[i, j, m] -= w[j, m] * v[i, m]
        # from the right, column by column: w = b v / h, then b -= w v'
        for i in range(n):
            for m in range(lanes):
                w[i, m] = 0.0
        for j in range(k + 1, n):
            for i in range(n):
                for m in range(lanes):
                    w[i, m] += v[j, m] * b[i, j, m]
        for i in range(n):
            for m in range(lanes):
                w[i, m] *= hinv[m]
        for i in range(n):
            for j in range(k + 1, n):
                for m in range(lanes):
                    b[i, j, m] -= w[i, m] * v[j, m]
        for m in range(lanes):
            if scale[m] != 0.0:
                b[k + 1, k, m] = scale[m] * g[m]
                for i in range(k + 2, n):
                    b[i, k, m] = 0.0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _hqr(b, n, lanes, max_sweeps, lam, ok, ints, reals):  # pragma: no cover - compiled
    """Eigenvalues of the upper Hessenberg matrices of the first ``lanes`` lanes of ``b``
    (shape (n + 1, n + 1, LANES), the last row and column zero) into ``lam`` (LANES, n);
    ``ok[m]`` False where lane ``m`` did not converge. ``ints`` (4, LANES) and ``reals``
    (12, LANES) are scratch.

    Every lane runs EISPACK's ``hqr`` on its own matrix, the lanes side by side: each
    round, each lane deflates what it can (a negligible subdiagonal entry splits its
    active block; a 1x1 or 2x2 block at the bottom gives eigenvalues) and picks its shifts
    and its sweep's first row on its own; then the bulge chases of all lanes run as one
    loop over the rows, a lane outside its sweep's rows applying the identity (zero
    reflector coefficients subtract exact zeros). The row and column updates cover the
    union of the lanes' ranges, so they also change entries outside a lane's active
    block; those couple it to blocks already split off or not yet reached, which no
    eigenvalue of the block depends on, so each lane's eigenvalues are those of ``hqr``
    alone.
    """
    nn = ints[0]
    its = ints[1]
    low = ints[2]
    mst = ints[3]
    t = reals[0]
    anorm = reals[1]
    P0 = reals[2]
    Q0 = reals[3]
    R0 = reals[4]
    X = reals[5]
    Y = reals[6]
    Z = reals[7]
    Q = reals[8]
    R = reals[9]
    for m in range(lanes):
        nn[m] = n - 1
        its[m] = 0
        t[m] = 0.0
        ok[m] = True
        s = 0.0
        for i in range(n):
            for j in range(max(i - 1, 0), n):
                s += abs(b[i, j, m])
        anorm[m] = s
    while True:
        kmin = n
        kmax = -1
        lmin = n
        for m in range(lanes):
            mst[m] = n
            # deflate what the lane can: a negligible subdiagonal entry splits its block
            while nn[m] >= 0:
                e = nn[m]
                lo = e
                while lo >= 1:
                    s = abs(b[lo - 1, lo - 1, m]) + abs(b[lo, lo, m])
                    if s == 0.0:
                        s = anorm[m]
                    if abs(b[lo, lo - 1, m]) + s == s:
                        b[lo, lo - 1, m] = 0.0
                        break
                    lo -= 1
                low[m] = lo
                x = b[e, e, m]
                if lo == e:  # one real eigenvalue
                    lam[m, e] = x + t[m]
                    nn[m] = e - 1
                    its[m] = 0
                    continue
                y = b[e - 1, e - 1, m]
                w = b[e, e - 1, m] * b[e - 1, e, m]
                if lo == e - 1:  # a 2x2 block: two real eigenvalues or a conjugate pair
                    p = 0.5 * (y - x)
                    q = p * p + w
                    z = math.sqrt(abs(q))
                    x += t[m]
                    if q >= 0.0:
                        z = p + math.copysign(z, p)
                        lam[m, e - 1] = x + z
                        lam[m, e] = x - w / z if z != 0.0 else x + z
                    else:
                        lam[m, e - 1] = complex(x + p, z)
                        lam[m, e] = complex(x + p, -z)
                    nn[m] = e - 2
                    its[m] = 0
                    continue
                break
            if nn[m] < 0:
                continue
            e = nn[m]
            lo = low[m]
            if its[m] == max_sweeps:
                ok[m] = False
                nn[m] = -1
                continue
            x = b[e, e, m]
            y = b[e - 1, e - 1, m]
            w = b[e, e - 1, m] * b[e - 1, e, m]
            if its[m] == 10 or its[m] == 20:  # exceptional shift
                t[m] += x
                for i in range(e + 1):
                    b[i, i, m] -= x
                s = abs(b[e, e - 1, m]) + abs(b[e - 1, e - 2, m])
                x = 0.75 * s
                y = x
                w = -0.4375 * s * s
            its[m] += 1
            # the double shift's first column, started where two consecutive
            # subdiagonal entries are small
            k = e - 2
            while k >= lo:
                z = b[k, k, m]
                r = x - z
                s = y - z
                p = (r * s - w) / b[k + 1, k, m] + b[k, k + 1, m]
                q = b[k + 1, k + 1, m] - z - r - s
                r = b[k + 2, k + 1, m]
                s = 1.0 / (abs(p) + abs(q) + abs(r))
                p *= s
                q *= s
                r *= s
                if k == lo:
                    break
                u = abs(b[k, k - 1, m]) * (abs(q) + abs(r))
                v = abs(p) * (abs(b[k - 1, k - 1, m]) + abs(z) + abs(b[k + 1, k + 1, m]))
                if u + v == v:
                    break
                k -= 1
            for i in range(k + 2, e + 1):
                b[i, i - 2, m] = 0.0
                if i != k + 2:
                    b[i, i - 3, m] = 0.0
            mst[m] = k
            P0[m] = p
            Q0[m] = q
            R0[m] = r
            kmin = min(kmin, k)
            kmax = max(kmax, e - 1)
            lmin = min(lmin, lo)
        if kmax < 0:
            return
        # the lanes' bulge chases, row by row
        for k in range(kmin, kmax + 1):
            for m in range(lanes):
                X[m] = 0.0
                Y[m] = 0.0
                Z[m] = 0.0
                Q[m] = 0.0
                R[m] = 0.0
                if k < mst[m] or k >= nn[m]:
                    continue
                last = k == nn[m] - 1
                x = 1.0
                if k == mst[m]:
                    p = P0[m]
                    q = Q0[m]
                    r = R0[m]
                else:
                    p = b[k, k - 1, m]
                    q = b[k + 1, k - 1, m]
                    r = 0.0 if last else b[k + 2, k - 1, m]
                    x = abs(p) + abs(q) + abs(r)
                    if x == 0.0:
                        continue
                    if x < _TINY or x > _HUGE:
                        inv = 1.0 / x
                        p *= inv
                        q *= inv
                        r *= inv
                    else:
                        x = 1.0
                s = math.copysign(math.sqrt(p * p + q * q + r * r), p)
                if s == 0.0:
                    continue
                if k == mst[m]:
                    if low[m] != k:
                        b[k, k - 1, m] = -b[k, k - 1, m]
                else:
                    b[k, k - 1, m] = -s * x
                p += s
                inv = 1.0 / s
                X[m] = p * inv
                Y[m] = q * inv
                Z[m] = r * inv
                inv = 1.0 / p
                Q[m] = q * inv
                R[m] = r * inv
            for j in range(k, kmax + 2):
                for m in range(lanes):
                    p = b[k, j, m] + Q[m] * b[k + 1, j, m]
                    p += R[m] * b[k + 2, j, m]
                    b[k + 2, j, m] -= p * Z[m]
                    b[k + 1, j, m] -= p * Y[m]
                    b[k, j, m] -= p * X[m]
            top = min(kmax + 1, k + 3)
            for i in range(lmin, top + 1):
                for m in range(lanes):
                    p = X[m] * b[i, k, m] + Y[m] * b[i, k + 1, m]
                    p += Z[m] * b[i, k + 2, m]
                    b[i, k + 2, m] -= p * R[m]
                    b[i, k + 1, m] -= p * Q[m]
                    b[i, k, m] -= p


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _stack(A, max_sweeps):  # pragma: no cover - compiled
    """Eigenvalues of every matrix of the (N, n, n) stack ``A``; per matrix, whether its
    entries were in range (zero or of magnitude 1e-100 to 1e100: no overflow, underflow or
    non-finite value on the way) and the iteration converged."""
    N, n, _ = A.shape
    lam = np.zeros((N, n), np.complex128)
    ok = np.zeros(N, np.bool_)
    b = np.zeros((n + 1, n + 1, LANES))
    v = np.empty((n, LANES))
    w = np.empty((n, LANES))
    h = np.empty((4, LANES))
    finite = np.empty(LANES, np.bool_)
    lanes_lam = np.zeros((LANES, n), np.complex128)
    lanes_ok = np.empty(LANES, np.bool_)
    ints = np.empty((4, LANES), np.int64)
    reals = np.empty((12, LANES))
    for start in range(0, N, LANES):
        count = min(LANES, N - start)
        # the lanes' balanced matrices side by side (a non-finite or missing one as
        # zeros), bordered by a zero row and column
        b[:] = 0.0
        for m in range(count):
            fin = True
            for i in range(n):
                for j in range(n):
                    x = abs(A[start + m, i, j])
                    fin &= (x <= _HUGE) & ((x == 0.0) | (x >= _TINY))
            finite[m] = fin
            if fin:
                for i in range(n):
                    for j in range(n):
                        # a negative zero made positive (x + 0.0): the other lanes' identity
                        # updates may turn -0.0 into +0.0, and the sign of a zero decides
                        # the order within a pair of eigenvalues
                        b[i, j, m] = A[start + m, i, j] + 0.0
        # only the lanes in use take part (a short stack needs no more)
        _balance(b, n, count, h[0], h[1], h[2], h[3])
        _hessenberg(b, n, count, v, w, h)
        _hqr(b, n, count, max_sweeps, lanes_lam, lanes_ok, ints, reals)
        for m in range(count):
            if finite[m] and lanes_ok[m]:
                ok[start + m] = True
                for i in range(n):
                    lam[start + m, i] = lanes_lam[m, i]
    return lam, ok


def eigvals_stack(A) -> np.ndarray:
    """Eigenvalues of a stack of small real square matrices (LAPACK where it must).

    Parameters
    ----------
    A : array_like, shape (..., n, n)
        Real matrices (a complex stack goes to :func:`numpy.linalg.eigvals`).

    Returns
    -------
    ndarray of complex, shape (..., n)
        Each matrix's eigenvalues, in no particular order (conjugate pairs adjacent,
        the positive imaginary part first), equal to LAPACK's to rounding where they are
        well conditioned (see the module notes on reducible matrices).

    Raises
    ------
    numpy.linalg.LinAlgError
        As :func:`numpy.linalg.eigvals`: ``A`` is not a stack of square matrices or has a
        non-finite entry.
    """
    A = np.asarray(A)
    if A.ndim < 2 or A.shape[-1] != A.shape[-2] or A.dtype.kind not in "biuf":
        return np.linalg.eigvals(A)
    A = np.ascontiguousarray(A, dtype=float)
    if A.size == 0:
        return np.zeros(A.shape[:-1], complex)
    n = A.shape[-1]
    flat = A.reshape(-1, n, n)
    lam, ok = _stack(flat, MAX_SWEEPS)
    if not ok.all():
        # LAPACK takes what the loops did not (and raises NumPy's error on a non-finite entry)
        lam[~ok] = np.linalg.eigvals(flat[~ok])
    return lam.reshape(A.shape[:-1])


def load_kernels() -> None:
    """Compile the loops, or load them from Numba's cache, now rather than at first use.

    A process loads them in about 0.2 s at its first call (compiles them in about 4 s the
    first time after an install); a benchmark calls this to time that apart.
    """
    _stack(np.zeros((1, 1, 1)), MAX_SWEEPS)
