"""Controller order reduction by balanced truncation, with its error bound.

Square-root balanced truncation (Moore 1981; Laub, Heath, Paige & Ward 1987;
Tombs & Postlethwaite 1987) of the stable part; an unstable part is kept whole
after an additive stable/unstable split by an ordered Schur form and a Sylvester
equation (as in Varga's "modal separation"). For the stable part the classical
bound holds:

    || G - G_r ||_inf <= 2 * sum of the truncated Hankel singular values

(Glover 1984; Enns 1984). python-control's ``balred`` is SLICOT's ``ab09ad``; this
routine, with its error bound (and, on request, its states' signs fixed), is the
workbench's own, and the test suite checks it against SLICOT's.
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np
import scipy.linalg as sla

from robust.checks import NONNEGATIVE, check_abcd, check_int, check_scalar, check_state_space
from robust.errors import ModelStructureError, ParameterError

__all__ = [
    "ReducedModel",
    "balanced_truncation",
    "hankel_singular_values",
    "stable_unstable_split",
]


@dataclasses.dataclass(frozen=True)
class ReducedModel:
    """Result of :func:`balanced_truncation`.

    Attributes
    ----------
    sys : control.StateSpace
        Reduced system (same signal names as the original).
    hsv : ndarray
        Hankel singular values of the stable part, decreasing.
    error_bound : float
        ``2 * sum(truncated hsv)``: bound on the H-infinity norm of the error.
    order_before, order_after : int
        Number of states of the original and of the reduced system.
    n_unstable : int
        Number of unstable (kept) states.
    """

    sys: ct.StateSpace
    hsv: np.ndarray
    error_bound: float
    order_before: int
    order_after: int
    n_unstable: int


def stable_unstable_split(A, B, C):
    """Additive split ``G = G_s + G_u`` of a strictly proper system.

    Poles with ``Re < 0`` go to the stable part. Uses a real Schur form ordered with
    the stable eigenvalues first and the Sylvester equation ``As X - X Au + A12 = 0``
    to decouple the blocks. A feedthrough ``D`` is not involved; add it to either
    part.

    Parameters
    ----------
    A, B, C : array_like
        State-space matrices, shapes (n, n), (n, m), (p, n).

    Returns
    -------
    (As, Bs, Cs) : tuple of numpy.ndarray
        Stable part, shapes (k, k), (k, m), (p, k), with ``k`` the number of poles
        with negative real part; ``As`` is quasi-upper-triangular (real Schur).
    (Au, Bu, Cu) : tuple of numpy.ndarray
        Part with the other poles (``Re >= 0``), shapes (n - k, n - k),
        (n - k, m), (p, n - k).

    Raises
    ------
    ModelStructureError
        If a matrix is not numeric, holds NaN or inf, or the shapes do not fit (named).
    """
    A, B, C, _ = check_abcd("stable_unstable_split", A, B, C)
    T, Z, k = sla.schur(A, output="real", sort="lhp")
    n = A.shape[0]
    As, A12, Au = T[:k, :k], T[:k, k:], T[k:, k:]
    X = sla.solve_sylvester(As, -Au, -A12) if 0 < k < n else np.zeros((k, n - k))
    # new coordinates: [I X; 0 I]^-1 Z^T
    Bt = Z.T @ np.asarray(B, float)
    Ct = np.asarray(C, float) @ Z
    Bs = Bt[:k] - X @ Bt[k:]
    Bu = Bt[k:]
    Cs = Ct[:, :k]
    Cu = Ct[:, :k] @ X + Ct[:, k:]
    return (As, Bs, Cs), (Au, Bu, Cu)


def hankel_singular_values(A, B, C) -> np.ndarray:
    """Hankel singular values of a stable ``(A, B, C)``, decreasing.

    Parameters
    ----------
    A, B, C : numpy.ndarray
        State-space matrices of a stable system, shapes (n, n), (n, m), (p, n)
        (``D`` plays no part). Stability is not checked; for an unstable ``A`` the
        Lyapunov solutions are not Gramians and the values are meaningless.

    Returns
    -------
    numpy.ndarray
        The n Hankel singular values (square roots of the eigenvalues of the product
        of the Gramians), in the system's output units per input unit, decreasing.

    Raises
    ------
    ModelStructureError
        If a matrix is not numeric, holds NaN or inf, or the shapes do not fit (named).
    """
    A, B, C, _ = check_abcd("hankel_singular_values", A, B, C)
    P = sla.solve_continuous_lyapunov(A, -B @ B.T)
    Q = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
    # singular values of the product of Gramian factors (square-root method), more
    # accurate for the small values than the eigenvalues of P Q
    return np.linalg.svd(_chol_psd(Q).T @ _chol_psd(P), compute_uv=False)


def _chol_psd(M):
    M = (M + M.T) / 2
    w, V = np.linalg.eigh(M)
    return V * np.sqrt(np.clip(w, 0, None))


def _signs_fixed(A, B, C):
    """The balanced realisation with each state's sign fixed.

    A balanced realisation is unique up to the sign of each state (for distinct Hankel
    singular values); the sign is chosen so that the entry of largest magnitude in the
    state's column of ``[C; B^T]`` is positive, which makes the reduced model the same
    matrices whichever rounding the SVD's signs took.
    """
    M = np.vstack([C, B.T])
    s = np.sign(M[np.argmax(np.abs(M), axis=0), np.arange(M.shape[1])])
    s[s == 0] = 1.0
    return s[:, None] * A * s[None, :], s[:, None] * B, C * s[None, :]


def balanced_truncation(
    sys: ct.StateSpace,
    order: int | None = None,
    *,
    tol: float | None = None,
    fix_signs: bool = False,
) -> ReducedModel:
    """Reduce ``sys`` by square-root balanced truncation of its stable part.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous-time system.
    order : int, optional
        Total order wanted (unstable states count and are all kept).
    tol : float, optional
        Instead of ``order``: keep the smallest order whose error bound is <= ``tol``.
    fix_signs : bool
        Fix each balanced state's sign: the entry of largest magnitude in its column of
        ``[C; B^T]`` positive (SLICOT ab09ad's realisation up to these signs, which SLICOT
        takes from its factorisations). Off by default: the controllers tuned from a
        reduced start keep the coordinates they were tuned in.

    Returns
    -------
    ReducedModel
        The reduced system (named ``<name>_red``, same signals and ``D``), the
        Hankel singular values and the error bound. The order kept is further
        capped at the numerical rank of the stable part (Hankel singular values
        above ``1e-14`` times the largest).

    Raises
    ------
    ModelStructureError
        If ``sys`` is not a continuous-time :class:`control.StateSpace` with finite
        matrices (the message names the matrix).
    ParameterError
        If both or neither of ``order`` and ``tol`` are given, ``order`` is not an
        integer, ``tol`` is not finite and >= 0, or ``order`` is below the number of
        unstable states or above the order of ``sys``.
    """
    if not isinstance(sys, ct.StateSpace) or not sys.isctime():
        raise ModelStructureError("balanced_truncation needs a continuous-time control.StateSpace")
    check_state_space("balanced_truncation: sys", sys)
    if not isinstance(fix_signs, bool):
        raise ParameterError(
            f"balanced_truncation: fix_signs must be True or False; got {fix_signs!r}"
        )
    if (order is None) == (tol is None):
        raise ParameterError("balanced_truncation: give exactly one of order or tol")
    if order is not None:
        order = check_int("balanced_truncation: order", order)
    else:
        tol = check_scalar("balanced_truncation: tol", tol, NONNEGATIVE)
    n = sys.nstates
    (As, Bs, Cs), (Au, Bu, Cu) = stable_unstable_split(sys.A, sys.B, sys.C)
    nu = Au.shape[0]
    ns = As.shape[0]
    if ns:
        P = sla.solve_continuous_lyapunov(As, -Bs @ Bs.T)
        Q = sla.solve_continuous_lyapunov(As.T, -Cs.T @ Cs)
        Lp, Lq = _chol_psd(P), _chol_psd(Q)
        U, hsv, Vt = np.linalg.svd(Lq.T @ Lp)
    else:
        hsv = np.zeros(0)
    if tol is not None:
        tail = np.concatenate([np.cumsum(hsv[::-1])[::-1], [0.0]])  # tail[k] = sum hsv[k:]
        k = int(np.argmax(2 * tail <= tol))
    else:
        if not (nu <= order <= n):
            raise ParameterError(
                f"balanced_truncation: order must be in [{nu}, {n}] "
                f"(unstable states are kept); got {order}"
            )
        k = order - nu
    k = min(k, int(np.count_nonzero(hsv > hsv[0] * 1e-14)) if hsv.size else 0)
    if k:
        S = np.diag(hsv[:k] ** -0.5)
        Tl = S @ U[:, :k].T @ Lq.T
        Tr = Lp @ Vt[:k].T @ S
        Ar, Br, Cr = Tl @ As @ Tr, Tl @ Bs, Cs @ Tr
        if fix_signs:
            Ar, Br, Cr = _signs_fixed(Ar, Br, Cr)
    else:
        Ar, Br, Cr = np.zeros((0, 0)), np.zeros((0, sys.ninputs)), np.zeros((sys.noutputs, 0))
    A = sla.block_diag(Ar, Au)
    B = np.vstack([Br, Bu])
    C = np.hstack([Cr, Cu])
    red = ct.ss(
        A, B, C, sys.D, inputs=sys.input_labels, outputs=sys.output_labels, name=f"{sys.name}_red"
    )
    bound = float(2 * hsv[k:].sum())
    return ReducedModel(
        sys=red, hsv=hsv, error_bound=bound, order_before=n, order_after=k + nu, n_unstable=nu
    )
