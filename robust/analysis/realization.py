"""Minimal realisations by orthogonal staircase reduction.

python-control's ``minreal`` for state-space systems is SLICOT's ``tb01pd``, whose
tolerance logic the workbench does not control (the suite checks this module against
it); the BDFT loop needs a minimal realisation at run time because the paper's
Eqn 4 (a double zero at s = 0) and Eqn 5 (a double pole at s = 0) cancel exactly in
series. This module removes
uncontrollable then unobservable states with orthogonal transformations, the
staircase idea of

    P. Van Dooren, "The generalized eigenstructure problem in linear system
    theory", IEEE Trans. Automatic Control 26(1), 1981, pp. 111-129;

and A. Varga, "Minimal realization procedures based on balancing and related
techniques", in *Numerical Methods for Control*, 1991.

The system is first balanced with ``scipy.linalg.matrix_balance`` (a diagonal
similarity), so the rank decisions are made on comparable scales. The removed
modes are returned, so callers can report them instead of hiding them.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg as sla

from robust.checks import POSITIVE, check_abcd, check_scalar

__all__ = ["MinimalRealization", "minimal_realization", "controllable_part", "matrices_key"]


@dataclasses.dataclass(frozen=True)
class MinimalRealization:
    """A minimal ``(A, B, C, D)`` and the eigenvalues of the modes removed to get it.

    Parameters
    ----------
    A, B, C, D : numpy.ndarray
        Minimal state-space matrices, shapes (r, r), (r, m), (p, r), (p, m) with
        ``r`` the minimal order. The states are in
        a transformed (balanced, orthogonally reduced) basis with no physical
        meaning; ``D`` is the original feedthrough.
    removed_eigenvalues : numpy.ndarray
        Complex eigenvalues (rad/s) of the removed modes, uncontrollable ones first,
        shape (n - r,).
    n_uncontrollable : int
        Number of states removed as uncontrollable.
    n_unobservable : int
        Number of states then removed as unobservable.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    removed_eigenvalues: np.ndarray
    n_uncontrollable: int
    n_unobservable: int

    @property
    def nstates(self) -> int:
        """The minimal order ``r`` (number of rows of ``A``)."""
        return self.A.shape[0]


def _krylov_basis(A: np.ndarray, B: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis of the controllable subspace of ``(A, B)``.

    Block Krylov iteration with re-orthogonalisation; a direction counts when its
    singular value exceeds ``tol`` (absolute, on the balanced system).
    """
    n = A.shape[0]
    block = _range(B, tol)
    basis = block
    while block.shape[1] and basis.shape[1] < n:
        new = A @ block
        for _ in range(2):  # classical Gram-Schmidt twice is numerically orthogonal
            new = new - basis @ (basis.T @ new)
        block = _range(new, tol)
        basis = np.hstack([basis, block])
    return basis


def _range(M: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis of the directions of ``M`` whose singular values exceed ``tol``.

    A single column is its own singular vector (singular value its norm): normalised
    without an SVD, which a single-input system's Krylov sequence would otherwise call at
    every step.
    """
    if M.shape[1] == 1:
        s = float(np.sqrt(M[:, 0] @ M[:, 0]))
        return M / s if s > tol else M[:, :0]
    U, s, _ = np.linalg.svd(M, full_matrices=False)
    return U[:, s > tol]


def controllable_part(A, B, C, *, rtol: float = 1e-9):
    """Return ``(Ac, Bc, Cc, removed_eigs)``: the controllable part of ``(A, B, C)``.

    Parameters
    ----------
    A, B, C : array_like
        State-space matrices, shapes (n, n), (n, m), (p, n). Applied to
        ``(A.T, C.T, B.T)`` it gives the observable part instead.
    rtol : float, optional
        Relative rank tolerance. It scales with the balanced system's norm: a
        direction is controllable when its Krylov singular value exceeds
        ``rtol * max(||A||, ||B||, 1)``.

    Returns
    -------
    Ac, Bc, Cc : numpy.ndarray
        Controllable part, shapes (r, r), (r, m), (p, r), in a balanced and
        orthogonally transformed basis (balanced only, when nothing is removed).
    removed_eigs : numpy.ndarray
        Complex eigenvalues (rad/s) of the removed uncontrollable modes, shape
        (n - r,).

    Raises
    ------
    robust.errors.ModelStructureError
        If a matrix is not numeric, holds NaN or inf, or the shapes do not fit (named).
    robust.errors.ParameterError
        If ``rtol`` is not finite and positive.
    """
    rtol = check_scalar("controllable_part: rtol", rtol, POSITIVE)
    A, B, C, _ = check_abcd("controllable_part", A, B, C)
    return _controllable_part(A, B, C, rtol)


def _controllable_part(A, B, C, rtol):
    n = A.shape[0]
    if n == 0:
        return A, B, C, np.zeros(0, complex)
    Ab, T = sla.matrix_balance(A, permute=False, separate=True)
    scale = T[0]
    Bb = B / scale[:, None]
    Cb = C * scale[None, :]
    tol = rtol * max(np.linalg.norm(Ab, 2), np.linalg.norm(Bb, 2), 1.0)
    V = _krylov_basis(Ab, Bb, tol)
    r = V.shape[1]
    if r == n:
        return Ab, Bb, Cb, np.zeros(0, complex)
    full = sla.qr(V, mode="full")[0]
    Q = np.hstack([V, full[:, r:]])
    # make the complement exactly orthogonal to V
    Q[:, r:] = sla.null_space(V.T) if r else np.eye(n)
    At = Q.T @ Ab @ Q
    removed = np.linalg.eigvals(At[r:, r:])
    return At[:r, :r], (Q.T @ Bb)[:r], (Cb @ Q)[:, :r], removed


def minimal_realization(A, B, C, D, *, rtol: float = 1e-9) -> MinimalRealization:
    """Remove uncontrollable, then unobservable, states of ``(A, B, C, D)``.

    Parameters
    ----------
    A, B, C, D : array_like
        State-space matrices, shapes (n, n), (n, m), (p, n), (p, m).
    rtol : float
        Relative rank tolerance (see :func:`controllable_part`).

    Returns
    -------
    MinimalRealization
        The reduced matrices (in a transformed basis) and the removed eigenvalues.

    Raises
    ------
    robust.errors.ModelStructureError
        If a matrix is not numeric, holds NaN or inf, or the shapes do not fit (named).
    robust.errors.ParameterError
        If ``rtol`` is not finite and positive.
    """
    rtol = check_scalar("minimal_realization: rtol", rtol, POSITIVE)
    A, B, C, D = check_abcd("minimal_realization", A, B, C, D)
    Ac, Bc, Cc, rem_c = _controllable_part(A, B, C, rtol)
    Ao, Co_T, Bo_T, rem_o = _controllable_part(Ac.T, Cc.T, Bc.T, rtol)
    return MinimalRealization(
        A=Ao.T,
        B=Bo_T.T,
        C=Co_T.T,
        D=D,
        removed_eigenvalues=np.concatenate([rem_c, rem_o]),
        n_uncontrollable=len(rem_c),
        n_unobservable=len(rem_o),
    )


def matrices_key(mats) -> tuple:
    """A hashable key equal for equal matrices: each one's float64 bytes and shape.

    For caches of work on a system that callers hand over again and again (every member
    checked against one controller or one weight): a key of the contents, so that arrays
    changed in place are a new key.

    Parameters
    ----------
    mats : sequence of array_like
        The matrices (e.g. ``A, B, C, D``).

    Returns
    -------
    tuple of (bytes, tuple)

    Raises
    ------
    TypeError, ValueError
        If a matrix cannot be read as a float array (numpy's own errors).
    """
    arrs = [np.ascontiguousarray(m, float) for m in mats]
    return tuple((a.tobytes(), a.shape) for a in arrs)
