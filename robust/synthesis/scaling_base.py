"""What every stage of the plant scaling shares: the controller's matrices and the identity
maps a stage inherits.

:class:`ControllerMatrices` is the ``(Ak, Bk, Ck, Dk)`` of a controller ``u = K y`` that the
syntheses return and the stages map; ``_Identities`` gives each stage (and the ``D22``
loop shift) the identity maps of controllers, certificates and gamma, so that a stage
writes out only the maps it changes. The conventions are described in
:mod:`robust.synthesis.scaling`; this module is apart from the stages so that each stage's
module builds on it alone.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["ControllerMatrices"]


class ControllerMatrices(NamedTuple):
    """State-space matrices of a controller ``u = K y`` (positive feedback).

    Parameters
    ----------
    Ak : numpy.ndarray, shape (nk, nk)
        State matrix.
    Bk : numpy.ndarray, shape (nk, ny)
        Input matrix (from the measurements y).
    Ck : numpy.ndarray, shape (nu, nk)
        Output matrix (to the controls u).
    Dk : numpy.ndarray, shape (nu, ny)
        Feedthrough.
    """

    Ak: np.ndarray
    Bk: np.ndarray
    Ck: np.ndarray
    Dk: np.ndarray

    @classmethod
    def from_statespace(cls, K) -> ControllerMatrices:
        """The matrices of a python-control state-space controller, as 2-D float arrays.

        Parameters
        ----------
        K : control.StateSpace
            Controller; a static gain (no states) gives empty ``Ak``, ``Bk``, ``Ck``.
        """
        nk = K.nstates
        Ak = np.asarray(K.A, float).reshape(nk, nk)
        Bk = np.asarray(K.B, float).reshape(nk, -1) if nk else np.zeros((0, K.ninputs))
        Ck = np.asarray(K.C, float).reshape(-1, nk) if nk else np.zeros((K.noutputs, 0))
        Dk = np.asarray(K.D, float).reshape(K.noutputs, K.ninputs)
        return cls(Ak, Bk, Ck, Dk)

    @classmethod
    def from_omega(cls, Omega, nk: int) -> ControllerMatrices:
        """Split the controller data ``Omega = [[Ak, Bk], [Ck, Dk]]``.

        Parameters
        ----------
        Omega : array_like, shape (nk + nu, nk + ny)
            Controller data as in [GA94] eq. (2.5) (see :mod:`robust.synthesis.lmi`).
        nk : int
            Controller order.
        """
        Om = np.asarray(Omega, float)
        return cls(Om[:nk, :nk], Om[:nk, nk:], Om[nk:, :nk], Om[nk:, nk:])

    def omega(self) -> np.ndarray:
        """The controller data ``[[Ak, Bk], [Ck, Dk]]`` as one array."""
        return np.block([[self.Ak, self.Bk], [self.Ck, self.Dk]])


# ------------------------------------------------------------------------- the stages' base
class _Identities:
    """Identity maps of controllers, certificates and gamma, for the stages to override.

    Every stage (and :class:`D22Removal`) inherits from this class and writes out
    only the maps it really changes; the others are these identities.  ``apply``
    and ``invert`` (the plant maps) are each stage's own.
    """

    def apply_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """Identity: ``K`` itself (the stage leaves controllers unchanged).

        Parameters
        ----------
        K : ControllerMatrices
            Controller.
        """
        return K

    def invert_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """Identity: ``K`` itself (see :meth:`apply_controller`).

        Parameters
        ----------
        K : ControllerMatrices
            Controller.
        """
        return K

    def apply_certificate(self, P) -> np.ndarray:
        """Identity: ``P`` as a float array (the stage leaves certificates unchanged).

        Parameters
        ----------
        P : numpy.ndarray
            Certificate.
        """
        return np.asarray(P, float)

    def invert_certificate(self, P) -> np.ndarray:
        """Identity: ``P`` as a float array (see :meth:`apply_certificate`).

        Parameters
        ----------
        P : numpy.ndarray
            Certificate.
        """
        return np.asarray(P, float)

    def apply_gamma(self, gamma: float) -> float:
        """Identity: ``gamma`` itself (the stage leaves the H-infinity norm unchanged).

        Parameters
        ----------
        gamma : float
            H-infinity bound.
        """
        return gamma

    def invert_gamma(self, gamma: float) -> float:
        """Identity: ``gamma`` itself (see :meth:`apply_gamma`).

        Parameters
        ----------
        gamma : float
            H-infinity bound.
        """
        return gamma
