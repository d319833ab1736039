"""Frequency responses of a single-input, single-output loop and their controller derivatives,
through one Hessenberg form, in compiled loops.

For a state matrix ``A`` (``n x n``) and frequencies ``w_f`` the resolvent is
``R_f = (j w_f I - A)^-1``. The P-K synthesis and its nonsmooth start
(:mod:`robust.synthesis.pk`, :mod:`robust.synthesis.tuning`) need, at every frequency,
``c R b`` (the response), ``c R Bb`` and ``Cb R b`` (the response's derivative in the
controller data): two solves with one matrix, not a factorisation per right-hand side.

Method (Laub, "Efficient multivariable frequency response computations", IEEE TAC 26(2),
1981; the approach of SLICOT's ``TB05AD``): ``A`` is balanced once by exact power-of-two
scalings ``D^-1 A D`` (Parlett & Reinsch, Numer. Math. 13, 1969: the loops' states span
many decades, and without it the orthogonal reduction below loses two to three digits
that LU with pivoting keeps), then ``D^-1 A D = Q H Q'`` (Householder reflections,
Golub & Van Loan, *Matrix Computations*, 4th ed., Alg. 7.4.2), so that
``R_f = D Q (j w_f I - H)^-1 Q' D^-1`` with ``H`` upper Hessenberg. Each frequency then costs an
``O(n^2)`` elimination of ``j w_f I - H`` with partial pivoting between adjacent rows (the
only rows that can exchange), one solve for ``z = (j w_f I - H)^-1 Q' b`` and one transposed
solve for ``y' = c Q (j w_f I - H)^-1``: ``c R b = (c Q) z``, ``Cb R b = (Cb Q) z`` and
``c R Bb = y' (Q' Bb)``. A batched LU of every ``j w_f I - A`` costs ``O(n^3)`` per frequency.

Arithmetic: plain multiplications and additions in a fixed order (no fused multiply-add,
no reassociation), so the bits do not depend on the CPU or the BLAS. The first call in a
process loads the compiled loop from Numba's cache (or compiles it once after an install).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["resolvent_solve", "siso_responses"]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _hessenberg_q(A, H, Q, v):  # pragma: no cover - compiled
    """``H = Q' A Q`` upper Hessenberg, ``Q`` orthogonal (Householder reflections)."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            H[i, j] = A[i, j]
            Q[i, j] = 0.0
        Q[i, i] = 1.0
    for k in range(n - 2):
        below = 0.0
        for i in range(k + 2, n):
            below += H[i, k] * H[i, k]
        if below == 0.0:
            continue  # the column is already reduced
        x0 = H[k + 1, k]
        alpha = math.sqrt(below + x0 * x0)
        if x0 > 0.0:
            alpha = -alpha
        v[k + 1] = x0 - alpha
        vv = v[k + 1] * v[k + 1]
        for i in range(k + 2, n):
            v[i] = H[i, k]
            vv += v[i] * v[i]
        beta = 2.0 / vv
        # H <- (I - beta v v') H: rows k+1.., columns k..
        for j in range(k, n):
            s = 0.0
            for i in range(k + 1, n):
                s += v[i] * H[i, j]
            s *= beta
            for i in range(k + 1, n):
                H[i, j] -= s * v[i]
        # H <- H (I - beta v v') and Q <- Q (I - beta v v'): columns k+1..
        for i in range(n):
            s = 0.0
            t = 0.0
            for j in range(k + 1, n):
                s += H[i, j] * v[j]
                t += Q[i, j] * v[j]
            s *= beta
            t *= beta
            for j in range(k + 1, n):
                H[i, j] -= s * v[j]
                Q[i, j] -= t * v[j]
        H[k + 1, k] = alpha
        for i in range(k + 2, n):
            H[i, k] = 0.0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _balance(A, d):  # pragma: no cover - compiled
    """Scale ``A`` in place to ``D^-1 A D``, ``d = diag(D)`` powers of two, so that each
    state's row and column have comparable norms (Parlett & Reinsch 1969, LAPACK ``dgebal``
    without permutations); the scaling is exact."""
    n = A.shape[0]
    for i in range(n):
        d[i] = 1.0
    done = False
    while not done:
        done = True
        for i in range(n):
            c = 0.0
            r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(A[j, i])
                    r += abs(A[i, j])
            if c == 0.0 or r == 0.0:
                continue
            s = c + r
            f = 1.0
            g = r / 2.0
            while c < g:
                f *= 2.0
                c *= 4.0
            g = r * 2.0
            while c >= g:
                f /= 2.0
                c /= 4.0
            if (c + r) / f < 0.95 * s:
                done = False
                d[i] *= f
                for j in range(n):
                    A[i, j] /= f
                    A[j, i] *= f


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _balanced_hessenberg(A):  # pragma: no cover - compiled
    """``(H, Q, d)``: ``D^-1 A D = Q H Q'`` with ``d = diag(D)`` (:func:`_balance`) and ``H``
    upper Hessenberg (:func:`_hessenberg_q`); ``A`` is left as it is."""
    n = A.shape[0]
    Ab = A.copy()
    d = np.empty(n)
    _balance(Ab, d)
    H = np.empty((n, n))
    Q = np.empty((n, n))
    v = np.zeros(n)
    _hessenberg_q(Ab, H, Q, v)
    return H, Q, d


@numba.njit(cache=True, nogil=True)
def _finite(a):  # pragma: no cover - compiled
    for x in a.flat:
        if not np.isfinite(x):
            return False
    return True


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _factor(H, wf, U, mult, swap, rd):  # pragma: no cover - compiled
    """Factor ``j wf I - H`` (``H`` upper Hessenberg) as ``E^-1 U``: the subdiagonal is
    eliminated (row i+1 -= l_i row i, after swapping the two rows when the lower one has
    the larger pivot; ``mult``, ``swap``), ``U`` upper triangular, ``rd`` the reciprocals of
    its diagonal. False when a pivot is zero (``j wf`` an eigenvalue of ``H``)."""
    n = H.shape[0]
    for i in range(n):
        lo = i - 1 if i > 0 else 0
        for j in range(lo, n):
            U[i, j] = -H[i, j]
        U[i, i] = complex(-H[i, i], wf)
    for i in range(n - 1):
        a = U[i, i]
        e = U[i + 1, i]
        swap[i] = abs(e.real) + abs(e.imag) > abs(a.real) + abs(a.imag)
        if swap[i]:
            for j in range(i, n):
                t = U[i, j]
                U[i, j] = U[i + 1, j]
                U[i + 1, j] = t
        piv = U[i, i]
        if piv == 0.0:
            return False
        li = U[i + 1, i] / piv
        mult[i] = li
        for j in range(i + 1, n):
            U[i + 1, j] -= li * U[i, j]
    if U[n - 1, n - 1] == 0.0:
        return False
    for i in range(n):
        rd[i] = 1.0 / U[i, i]
    return True


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _solve(U, mult, swap, rd, z):  # pragma: no cover - compiled
    """``z <- (j wf I - H)^-1 z`` for the factors of :func:`_factor`: the row operations,
    then back substitution."""
    n = z.shape[0]
    for i in range(n - 1):
        if swap[i]:
            t = z[i]
            z[i] = z[i + 1]
            z[i + 1] = t
        z[i + 1] -= mult[i] * z[i]
    for i in range(n - 1, -1, -1):
        s = z[i]
        for j in range(i + 1, n):
            s -= U[i, j] * z[j]
        z[i] = s * rd[i]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _scaled_inputs(Q, d, B):  # pragma: no cover - compiled
    """``Q' D^-1 B`` (``D = diag(d)``, the balancing), summed in one fixed order."""
    n, k = Q.shape[0], B.shape[1]
    out = np.zeros((n, k))
    for i in range(n):
        for j in range(k):
            s = 0.0
            for r in range(n):
                s += Q[r, i] * (B[r, j] / d[r])
            out[i, j] = s
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _responses(A, b, c, Bb, Cb, w, crb, cRBb, CbRb):  # pragma: no cover - compiled
    """Fill ``crb[f] = c R_f b``, ``cRBb[f] = c R_f Bb``, ``CbRb[f] = Cb R_f b``; return the
    index of the first frequency where ``j w I - A`` is singular, -1 when none is, or
    ``-2 - k`` when the ``k``-th input (``A, b, c, Bb, Cb, w``) has an entry not finite."""
    if not _finite(A):
        return -2
    if not _finite(b):
        return -3
    if not _finite(c):
        return -4
    if not _finite(Bb):
        return -5
    if not _finite(Cb):
        return -6
    if not _finite(w):
        return -7
    n = A.shape[0]
    m = Bb.shape[1]
    p = Cb.shape[0]
    # balance: R = D (j w I - D^-1 A D)^-1 D^-1, so the inputs are scaled by D^-1, the
    # outputs by D (exact: powers of two)
    H, Q, d = _balanced_hessenberg(A)
    # Q' D^-1 b, c D Q, Q' D^-1 Bb, Cb D Q
    qb = np.zeros(n)
    cq = np.zeros(n)
    qB = _scaled_inputs(Q, d, Bb)
    Cq = np.zeros((p, n))
    for i in range(n):
        for k in range(n):
            qb[i] += Q[k, i] * (b[k] / d[k])
            cq[i] += (c[k] * d[k]) * Q[k, i]
        for r in range(p):
            s = 0.0
            for k in range(n):
                s += (Cb[r, k] * d[k]) * Q[k, i]
            Cq[r, i] = s
    U = np.empty((n, n), np.complex128)
    mult = np.empty(n, np.complex128)
    swap = np.zeros(n, np.bool_)
    z = np.empty(n, np.complex128)
    y = np.empty(n, np.complex128)
    rd = np.empty(n, np.complex128)  # reciprocals of U's diagonal
    for f in range(w.shape[0]):
        if not _factor(H, w[f], U, mult, swap, rd):
            return f
        for i in range(n):
            z[i] = qb[i]
        _solve(U, mult, swap, rd, z)
        s = 0.0j
        for i in range(n):
            s += cq[i] * z[i]
        crb[f] = s
        for r in range(p):
            s = 0.0j
            for i in range(n):
                s += Cq[r, i] * z[i]
            CbRb[f, r] = s
        if m == 0:
            continue
        # y' (j w I - H) = c Q: U' u = (c Q)' forward, then y' = u' E with
        # E = G_{n-2} ... G_0, G_i = (I - l_i e_{i+1} e_i') S_i
        for i in range(n):
            s = complex(cq[i], 0.0)
            for j in range(i):
                s -= U[j, i] * y[j]
            y[i] = s * rd[i]
        for i in range(n - 2, -1, -1):
            y[i] -= mult[i] * y[i + 1]
            if swap[i]:
                t = y[i]
                y[i] = y[i + 1]
                y[i + 1] = t
        for j in range(m):
            s = 0.0j
            for i in range(n):
                s += y[i] * qB[i, j]
            cRBb[f, j] = s
    return -1


def siso_responses(A, b, c, Bb, Cb, w) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``c R b``, ``c R Bb`` and ``Cb R b`` with ``R = (j w I - A)^-1`` at every frequency.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Real state matrix.
    b : array_like, shape (n,)
        Input vector.
    c : array_like, shape (n,)
        Output vector.
    Bb : array_like, shape (n, m)
        Further input directions (the controller data's, :mod:`robust.synthesis.pk`).
    Cb : array_like, shape (p, n)
        Further output directions.
    w : array_like, shape (n_w,)
        Angular frequencies (in the time unit of ``A``).

    Returns
    -------
    crb : numpy.ndarray of complex, shape (n_w,)
    cRBb : numpy.ndarray of complex, shape (n_w, m)
    CbRb : numpy.ndarray of complex, shape (n_w, p)

    Raises
    ------
    ValueError
        If the shapes do not match or an entry is not finite.
    numpy.linalg.LinAlgError
        If ``j w I - A`` is singular at a frequency (an eigenvalue of ``A`` on it).
    """
    A = np.ascontiguousarray(A, dtype=float)
    b = np.ascontiguousarray(b, dtype=float).reshape(-1)
    c = np.ascontiguousarray(c, dtype=float).reshape(-1)
    Bb = np.ascontiguousarray(Bb, dtype=float)
    Cb = np.ascontiguousarray(Cb, dtype=float)
    w = np.ascontiguousarray(w, dtype=float).reshape(-1)
    n = A.shape[0] if A.ndim == 2 else -1
    if A.shape != (n, n) or b.size != n or c.size != n:
        raise ValueError(
            f"siso_responses: A must be square with b and c of its size; got A {A.shape}, "
            f"b {b.shape}, c {c.shape}"
        )
    if Bb.ndim != 2 or Bb.shape[0] != n or Cb.ndim != 2 or Cb.shape[1] != n:
        raise ValueError(
            f"siso_responses: Bb must have {n} rows and Cb {n} columns; got Bb {Bb.shape}, "
            f"Cb {Cb.shape}"
        )
    crb = np.empty(w.size, complex)
    cRBb = np.empty((w.size, Bb.shape[1]), complex)
    CbRb = np.empty((w.size, Cb.shape[0]), complex)
    if n == 0:
        crb[:] = 0.0
        cRBb[:] = 0.0
        CbRb[:] = 0.0
        return crb, cRBb, CbRb
    bad = _responses(A, b, c, Bb, Cb, w, crb, cRBb, CbRb)
    if bad < -1:
        name = ("A", "b", "c", "Bb", "Cb", "w")[-2 - bad]
        raise ValueError(f"siso_responses: {name} has an entry that is not finite")
    if bad >= 0:
        raise np.linalg.LinAlgError(
            f"siso_responses: j w I - A is singular at w = {float(w[bad])!r} (an eigenvalue of A)"
        )
    return crb, cRBb, CbRb


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _resolvent_solve(A, B, w, X):  # pragma: no cover - compiled
    """Fill ``X[f] = (j w_f I - A)^-1 B``; return as :func:`_responses` (inputs ``A, B, w``)."""
    if not _finite(A):
        return -2
    if not _finite(B):
        return -3
    if not _finite(w):
        return -4
    n = A.shape[0]
    k = B.shape[1]
    H, Q, d = _balanced_hessenberg(A)
    # Q' D^-1 B, and D Q for the way back
    qB = _scaled_inputs(Q, d, B)
    DQ = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            DQ[i, j] = d[i] * Q[i, j]
    U = np.empty((n, n), np.complex128)
    mult = np.empty(n, np.complex128)
    swap = np.zeros(n, np.bool_)
    rd = np.empty(n, np.complex128)
    z = np.empty(n, np.complex128)
    for f in range(w.shape[0]):
        if not _factor(H, w[f], U, mult, swap, rd):
            return f
        for j in range(k):
            for i in range(n):
                z[i] = qB[i, j]
            _solve(U, mult, swap, rd, z)
            for i in range(n):
                s = 0.0j
                for r in range(n):
                    s += DQ[i, r] * z[r]
                X[f, i, j] = s
    return -1


def resolvent_solve(A, w, B) -> np.ndarray:
    """``(j w_f I - A)^-1 B`` at every frequency ``w_f``, through one Hessenberg form.

    The method of :func:`siso_responses` (module notes) for a block of right-hand sides:
    per frequency an ``O(n^2)`` elimination and, per column of ``B``, an ``O(n^2)`` solve
    and the way back to the original coordinates, where a batched LU costs ``O(n^3)``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Real state matrix.
    w : array_like, shape (n_w,)
        Angular frequencies (in the time unit of ``A``).
    B : array_like, shape (n, k)
        Real right-hand sides.

    Returns
    -------
    numpy.ndarray of complex, shape (n_w, n, k)

    Raises
    ------
    ValueError
        If the shapes do not match or an entry is not finite.
    numpy.linalg.LinAlgError
        If ``j w I - A`` is singular at a frequency (an eigenvalue of ``A`` on it).
    """
    A = np.ascontiguousarray(A, dtype=float)
    B = np.ascontiguousarray(B, dtype=float)
    w = np.ascontiguousarray(w, dtype=float).reshape(-1)
    n = A.shape[0] if A.ndim == 2 else -1
    if A.shape != (n, n) or B.ndim != 2 or B.shape[0] != n:
        raise ValueError(
            f"resolvent_solve: A must be square and B have its rows; got A {A.shape}, B {B.shape}"
        )
    X = np.zeros((w.size, n, B.shape[1]), complex)
    if n == 0 or X.size == 0:
        return X
    bad = _resolvent_solve(A, B, w, X)
    if bad < -1:
        name = ("A", "B", "w")[-2 - bad]
        raise ValueError(f"resolvent_solve: {name} has an entry that is not finite")
    if bad >= 0:
        raise np.linalg.LinAlgError(
            f"resolvent_solve: j w I - A is singular at w = {float(w[bad])!r} (an eigenvalue of A)"
        )
    return X
