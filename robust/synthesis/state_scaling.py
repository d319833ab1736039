"""The state stage of the plant scaling: a diagonal balancing of ``A``, then the balanced
realization of the plant shifted to stability (``x = T xs``).

:class:`StateScaling` is the first of the four stages that
:class:`robust.synthesis.scaling.PlantScaling` chains; :func:`diagonal_balance` is also
what the synthesis assumptions' checks balance the plant with. Apart from the other
stages for the Gramian computations it alone needs.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg as sla

from robust.errors import ModelStructureError
from robust.synthesis.lmi import PlantBlocks
from robust.synthesis.scaling_base import _Identities

__all__ = ["BALANCE_MAX_COND", "GRAMIAN_FLOOR", "StateScaling", "diagonal_balance"]


#: largest condition number accepted for the balancing state transformation
#: (beyond it, the diagonal balancing alone is used)
BALANCE_MAX_COND = 1e8
#: Gramian eigenvalues below this fraction of the largest are raised to it (keeps T invertible)
GRAMIAN_FLOOR = 1e-14


def _sym(P):
    P = np.asarray(P, float)
    return (P + P.T) / 2


def diagonal_balance(A) -> np.ndarray:
    """Diagonal ``t`` (powers of 2) that balances ``A``: ``diag(t)^-1 A diag(t)``.

    Computed by ``scipy.linalg.matrix_balance`` without permutation.

    Parameters
    ----------
    A : numpy.ndarray, shape (n, n)
        Square matrix (``n = 0`` gives an empty ``t``).

    Returns
    -------
    numpy.ndarray, shape (n,)
    """
    if A.shape[0] == 0:
        return np.ones(0)
    _, (t, _) = sla.matrix_balance(A, permute=False, separate=True)
    return np.asarray(t, float)


def _balancing_transform(A, B, C):
    """State transformation ``x = T xs`` to a balanced realization of the shifted plant.

    Balanced realization (Moore, "Principal component analysis in linear systems:
    controllability, observability, and model reduction", IEEE TAC 26(1) (1981)
    17-32), by the square-root method of Laub, Heath, Paige & Ward,
    "Computation of system balancing transformations and other applications of
    simultaneous diagonalization algorithms", IEEE TAC 32(2) (1987) 115-122,
    applied to ``(A - alpha I, B, C)`` with ``alpha`` chosen so that the shifted
    matrix is stable (the plant itself may be unstable; the shift only selects
    a coordinate system, the plant is transformed unshifted).  In these
    coordinates the controllability and observability Gramians of the shifted
    plant are equal and diagonal, so the entries of ``B`` and ``C`` reflect the
    input-output gains rather than the arbitrary internal scales of the
    interconnected blocks (companion forms, physical units).

    Returns ``(T, Tinv)``, or ``None`` when the Gramians cannot be computed or
    ``T`` would be worse conditioned than ``BALANCE_MAX_COND``.
    """
    n = A.shape[0]
    if n == 0:
        return None
    ev = np.linalg.eigvals(A)
    rho = float(np.max(np.abs(ev)))
    if not rho > 0:
        return None
    alpha = 2.0 * max(float(ev.real.max()), 0.0) + 1e-2 * rho
    As = A - alpha * np.eye(n)
    try:
        Wc = sla.solve_continuous_lyapunov(As, -B @ B.T)
        Wo = sla.solve_continuous_lyapunov(As.T, -C.T @ C)
    except (np.linalg.LinAlgError, ValueError):
        return None
    roots = []
    for W in (Wc, Wo):
        w, V = np.linalg.eigh((W + W.T) / 2)
        if not (np.all(np.isfinite(w)) and w.max() > 0):
            return None
        roots.append(V * np.sqrt(np.maximum(w, GRAMIAN_FLOOR * w.max())))
    Lc, Lo = roots
    U, s, Vt = np.linalg.svd(Lo.T @ Lc)
    T = (Lc @ Vt.T) / np.sqrt(s)[None, :]
    if not np.all(np.isfinite(T)) or np.linalg.cond(T) > BALANCE_MAX_COND:
        return None
    Tinv = np.linalg.inv(T)
    return T, Tinv


@dataclasses.dataclass(frozen=True, eq=False)
class StateScaling(_Identities):
    """State transformation ``x = T xs`` with ``T = diag(t) Tb``.

    ``diag(t)`` balances ``A`` (:func:`diagonal_balance`); ``Tb`` then takes the
    diagonally balanced plant to a balanced realization of the plant shifted to
    stability (Moore 1981; square-root method of Laub, Heath, Paige & Ward 1987),
    and is left out when it is unavailable or worse conditioned than
    ``BALANCE_MAX_COND``.

    Maps changed: the plant (``A -> T^-1 A T``, ``B -> T^-1 B``, ``C -> C T``) and
    the certificate (the congruence ``P -> Tc' P Tc``, ``Tc = blkdiag(T, I_nk)``,
    since it contains plant states).  Controller and gamma maps are identities: the
    controller sees only u and y, and a change of state coordinates keeps the norm.

    Parameters
    ----------
    t : numpy.ndarray, shape (n,)
        Diagonal balancing factors.
    Tb : numpy.ndarray, shape (n, n), optional
        Balancing transformation after the diagonal one (``None``: none).
    Tbi : numpy.ndarray, shape (n, n), optional
        Inverse of ``Tb`` (given with it).
    kind : str
        ``"balanced"``, ``"diagonal"`` or ``"none"`` (identity), for reports.
    """

    t: np.ndarray
    Tb: np.ndarray | None = None
    Tbi: np.ndarray | None = None
    kind: str = "diagonal"

    def __post_init__(self):
        if (self.Tb is None) != (self.Tbi is None):
            raise ModelStructureError(
                "StateScaling: Tb and Tbi must be given together; got "
                f"Tb={'None' if self.Tb is None else 'an array'}, "
                f"Tbi={'None' if self.Tbi is None else 'an array'}"
            )

    @classmethod
    def fit(cls, blocks: PlantBlocks) -> StateScaling:
        """The diagonal balancing of ``A``, then the balanced realization if well conditioned.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant to scale.
        """
        t = diagonal_balance(blocks.A)
        diag = cls(t, kind="diagonal").apply(blocks)
        bal = _balancing_transform(
            diag.A, np.hstack([diag.B1, diag.B2]), np.vstack([diag.C1, diag.C2])
        )
        if bal is None:
            return cls(t, kind="diagonal")
        return cls(t, bal[0], bal[1], kind="balanced")

    @classmethod
    def identity(cls, n: int) -> StateScaling:
        """No state transformation.

        Parameters
        ----------
        n : int
            Plant order.
        """
        return cls(np.ones(n), kind="none")

    @property
    def T(self) -> np.ndarray:
        """The whole transformation ``T = diag(t) Tb`` (``x = T xs``)."""
        T = np.diag(self.t)
        return T if self.Tb is None else T @ self.Tb

    def apply(self, blocks: PlantBlocks) -> PlantBlocks:
        """``A -> T^-1 A T``, ``B -> T^-1 B``, ``C -> C T``.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in original state coordinates.
        """
        t = self.t
        A = blocks.A * (1.0 / t)[:, None] * t[None, :]
        B1, B2 = blocks.B1 / t[:, None], blocks.B2 / t[:, None]
        C1, C2 = blocks.C1 * t[None, :], blocks.C2 * t[None, :]
        if self.Tb is not None:
            Tb, Tbi = self.Tb, self.Tbi
            A, B1, B2, C1, C2 = Tbi @ A @ Tb, Tbi @ B1, Tbi @ B2, C1 @ Tb, C2 @ Tb
        return dataclasses.replace(blocks, A=A, B1=B1, B2=B2, C1=C1, C2=C2)

    def invert(self, blocks: PlantBlocks) -> PlantBlocks:
        """Inverse of :meth:`apply`: ``A -> T A T^-1``, ``B -> T B``, ``C -> C T^-1``.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in scaled state coordinates.
        """
        t = self.t
        A, B1, B2, C1, C2 = blocks.A, blocks.B1, blocks.B2, blocks.C1, blocks.C2
        if self.Tb is not None:
            Tb, Tbi = self.Tb, self.Tbi
            A, B1, B2, C1, C2 = Tb @ A @ Tbi, Tb @ B1, Tb @ B2, C1 @ Tbi, C2 @ Tbi
        A = A * t[:, None] * (1.0 / t)[None, :]
        B1, B2 = B1 * t[:, None], B2 * t[:, None]
        C1, C2 = C1 / t[None, :], C2 / t[None, :]
        return dataclasses.replace(blocks, A=A, B1=B1, B2=B2, C1=C1, C2=C2)

    def _closed_loop_T(self, P, inverse: bool) -> np.ndarray:
        n = self.t.size
        nk = P.shape[0] - n
        if P.ndim != 2 or P.shape[0] != P.shape[1] or nk < 0:
            raise ModelStructureError(
                f"P must be a square certificate of order >= {n} (plant states, then "
                f"controller states); got shape {P.shape}"
            )
        T = np.linalg.inv(self.T) if inverse else self.T
        return sla.block_diag(T, np.eye(nk))

    def apply_certificate(self, P) -> np.ndarray:
        """``P -> Tc' P Tc`` with ``Tc = blkdiag(T, I_nk)`` (a congruence).

        Parameters
        ----------
        P : numpy.ndarray, shape (n + nk, n + nk)
            Certificate of the closed loop in original coordinates.
        """
        P = np.asarray(P, float)
        Tc = self._closed_loop_T(P, inverse=False)
        return _sym(Tc.T @ _sym(P) @ Tc)

    def invert_certificate(self, P) -> np.ndarray:
        """``P -> Tc^-T P Tc^-1`` with ``Tc = blkdiag(T, I_nk)``.

        Parameters
        ----------
        P : numpy.ndarray, shape (n + nk, n + nk)
            Certificate of the closed loop in scaled state coordinates.
        """
        P = np.asarray(P, float)
        Tinv = self._closed_loop_T(P, inverse=True)
        return _sym(Tinv.T @ _sym(P) @ Tinv)
