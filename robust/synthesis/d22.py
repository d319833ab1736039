"""The loop shift that takes a nonzero ``D22`` out of a plant, and puts it back in the
controller.

:class:`D22Removal` synthesises on ``y0 = y - D22 u`` and maps the controller found back
(``K = K0 (I + D22 K0)^-1``, refused when ``I + Dk D22`` is conditioned worse than
:data:`D22_MAX_COND`), with the same apply/invert pattern as the scaling stages of
:mod:`robust.synthesis.scaling`. It is a change of the loop, not a scaling, and the
synthesis applies it apart from :class:`robust.synthesis.scaling.PlantScaling`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robust.errors import ModelStructureError, VerificationError
from robust.synthesis.genplant import GeneralizedPlant
from robust.synthesis.scaling_base import ControllerMatrices, _Identities

__all__ = ["D22_MAX_COND", "D22Removal"]


#: largest condition number of ``I + Dk D22`` accepted when a nonzero D22 is put back
D22_MAX_COND = 1e10


# ---------------------------------------------------------------------------------- D22
@dataclasses.dataclass(frozen=True, eq=False)
class D22Removal(_Identities):
    """Loop shift that removes ``D22``: the synthesis designs for ``y0 = y - D22 u``.

    The shifted plant has ``D22 = 0``; a controller ``K0`` designed for it is
    mapped back by ``K = K0 (I + D22 K0)^-1``.

    Maps changed: the plant (``D22 -> 0``) and the controller
    (``K0 = K (I - D22 K)^-1``, inverse as above).  Certificate and gamma maps are
    identities: the controller's states, hence the closed loop's realization, and
    so its certificates and norm, are unchanged.

    Parameters
    ----------
    D22 : numpy.ndarray, shape (ny, nu)
        Feedthrough from u to y of the original plant.
    """

    D22: np.ndarray

    def apply(self, gp: GeneralizedPlant) -> GeneralizedPlant:
        """The plant from ``(w, u)`` to ``(z, y0)``: ``D22`` set to zero.

        Parameters
        ----------
        gp : GeneralizedPlant
            Original plant (its ``D22`` must be this one's).
        """
        self._check_plant("gp", gp)
        return gp.with_blocks(D22=np.zeros_like(self.D22, dtype=float))

    def invert(self, gp: GeneralizedPlant) -> GeneralizedPlant:
        """The plant with ``D22`` put back.

        Parameters
        ----------
        gp : GeneralizedPlant
            Shifted plant (``D22 = 0``).
        """
        return gp.with_blocks(D22=self.D22)

    def _check_plant(self, name, gp):
        if gp.D22.shape != np.shape(self.D22) or not np.array_equal(gp.D22, self.D22):
            raise ModelStructureError(
                f"{name}: D22Removal was built for another D22; expected the plant's D22 to be "
                f"{np.array2string(np.asarray(self.D22), precision=3)}, got "
                f"{np.array2string(gp.D22, precision=3)}"
            )

    def loop_condition(self, Dk) -> float:
        """Condition number of ``I + Dk D22`` (1 when ``D22 = 0``).

        Parameters
        ----------
        Dk : numpy.ndarray, shape (nu, ny)
            Feedthrough of the controller designed for the shifted plant.
        """
        if not np.any(self.D22):
            return 1.0
        return float(np.linalg.cond(np.eye(Dk.shape[0]) + Dk @ self.D22))

    def apply_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """``K0 = K (I - D22 K)^-1``: the controller as seen by the shifted plant.

        Parameters
        ----------
        K : ControllerMatrices
            Controller of the original plant.

        Raises
        ------
        VerificationError
            If ``I - Dk D22`` is numerically singular (ill-posed loop).
        """
        return _shift_controller(K, -np.asarray(self.D22, float))

    def invert_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """``K = K0 (I + D22 K0)^-1``: the controller for the original plant.

        Parameters
        ----------
        K : ControllerMatrices
            Controller ``K0`` designed for the shifted plant.

        Raises
        ------
        VerificationError
            If ``I + Dk D22`` is numerically singular (ill-posed loop).
        """
        return _shift_controller(K, self.D22)


def _shift_controller(K: ControllerMatrices, D22) -> ControllerMatrices:
    """``K0 (I + D22 K0)^-1`` in state space (``D22 -> -D22`` gives the inverse map)."""
    Ak, Bk, Ck, Dk = K
    if not np.any(D22):
        return ControllerMatrices(Ak, Bk, Ck, Dk)
    M = np.eye(Dk.shape[0]) + Dk @ D22
    c = float(np.linalg.cond(M))
    if c > D22_MAX_COND:
        raise VerificationError(
            "D22 loop transformation is ill-posed: I + Dk*D22 must have condition number "
            f"at most {D22_MAX_COND:g}; got {c:.3g}"
        )
    E = np.linalg.inv(M)
    return ControllerMatrices(Ak - Bk @ D22 @ E @ Ck, Bk - Bk @ D22 @ E @ Dk, E @ Ck, E @ Dk)
