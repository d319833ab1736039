"""Arm geometry: how the arm's fore-aft stiffness changes as the handle moves fore-aft.

The physical human (:mod:`backhoe.model.physical`) lumps the operating arm into one
fore-aft spring-damper ``k_arm, c_arm`` at the nominal handle position. Moving
the Omni fore-aft (the paper's claim C5, +-4 in) changes the arm's posture and so
that spring. This module computes the change with a planar two-link arm in the
sagittal plane (shoulder on the trunk, elbow, grip)::

    hand (x, y) relative to the shoulder, x forward, y up
    x = L1 cos q1 + L2 cos(q1 + q2),   y = L1 sin q1 + L2 sin(q1 + q2)

With joint stiffnesses ``K_q = diag(k_sh, k_el)`` (N m/rad) and the hand free to
move vertically, the fore-aft compliance at the hand is
``(J K_q^{-1} J^T)[0, 0]`` with ``J`` the Jacobian of ``(x, y)``. Joint damping
is taken proportional to joint stiffness (the same ratio at both joints), so
the fore-aft damping scales like the stiffness.

Assumptions, declared: equal shoulder and elbow stiffness (``elbow_to_shoulder =
1``); segment lengths from body height with Winter's fractions (upper arm
0.186 H, forearm 0.146 H, grip at half the hand length, hand 0.108 H); nominal
grip 0.30 m in front of and 0.35 m below the shoulder (the Omni beside the seat
at about elbow height); elbow flexed below the line from shoulder to hand.
Gravity-load (geometric) stiffness is neglected.

Reference: D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th
ed., Wiley, 2009, Table 4.1 (segment lengths / body height).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from robust.checks import POSITIVE, Spec, check_scalar, validate_fields
from robust.errors import ParameterError

__all__ = ["ArmGeometry"]


@dataclasses.dataclass(frozen=True)
class ArmGeometry:
    """Planar two-link arm that maps a handle offset to a fore-aft stiffness scale.

    Parameters
    ----------
    height : float
        Body height, m (default 1.75).
    hand_x, hand_y : float
        Nominal grip position relative to the shoulder, m (forward, up).
    elbow_to_shoulder : float
        Elbow joint stiffness / shoulder joint stiffness, > 0.
    """

    height: float = 1.75
    hand_x: float = 0.30
    hand_y: float = -0.35
    elbow_to_shoulder: float = 1.0

    def __post_init__(self):
        validate_fields(
            self,
            {"height": POSITIVE, "hand_x": Spec(), "hand_y": Spec(), "elbow_to_shoulder": POSITIVE},
        )

    @property
    def lengths(self) -> tuple[float, float]:
        """Upper-arm length and elbow-to-grip length, m (Winter's fractions of height)."""
        return 0.186 * self.height, (0.146 + 0.5 * 0.108) * self.height

    def joint_angles(self, dx: float = 0.0) -> tuple[float, float]:
        """Shoulder and elbow angles (rad) with the grip moved ``dx`` m forward of nominal.

        Parameters
        ----------
        dx : float, optional
            Fore-aft grip offset from ``(hand_x, hand_y)``, m, forward positive.

        Returns
        -------
        q1, q2 : float
            Shoulder angle from the forward horizontal and elbow flexion (positive:
            elbow below the shoulder-grip line), rad.

        Raises
        ------
        robust.errors.ParameterError
            If the grip is out of the arm's reach.
        """
        L1, L2 = self.lengths
        x, y = self.hand_x + dx, self.hand_y
        r2 = x * x + y * y
        cos_el = (r2 - L1 * L1 - L2 * L2) / (2 * L1 * L2)
        if not -1.0 < cos_el < 1.0:
            raise ParameterError(
                f"ArmGeometry: the grip at ({x:.3f}, {y:.3f}) m is out of the arm's reach "
                f"({abs(L1 - L2):.3f}-{L1 + L2:.3f} m); got dx={dx!r}"
            )
        q2 = math.acos(cos_el)  # elbow flexion, positive: elbow below the shoulder-hand line
        q1 = math.atan2(y, x) - math.atan2(L2 * math.sin(q2), L1 + L2 * math.cos(q2))
        return q1, q2

    def fore_aft_compliance(self, dx: float = 0.0) -> float:
        """Fore-aft compliance at the grip per unit shoulder compliance, m^2 (times rad/(N m)).

        Parameters
        ----------
        dx : float, optional
            Fore-aft grip offset from nominal, m, forward positive.
        """
        L1, L2 = self.lengths
        q1, q2 = self.joint_angles(dx)
        J = np.array(
            [
                [-L1 * math.sin(q1) - L2 * math.sin(q1 + q2), -L2 * math.sin(q1 + q2)],
                [L1 * math.cos(q1) + L2 * math.cos(q1 + q2), L2 * math.cos(q1 + q2)],
            ]
        )
        Kq_inv = np.diag([1.0, 1.0 / self.elbow_to_shoulder])
        return float((J @ Kq_inv @ J.T)[0, 0])

    def stiffness_scale(self, dx: float, *, from_dx: float = 0.0) -> float:
        """Fore-aft arm stiffness at offset ``dx`` over that at ``from_dx``.

        Parameters
        ----------
        dx : float
            Grip offset from nominal at which the stiffness is wanted, m, forward
            positive.
        from_dx : float, optional
            Grip offset of the reference stiffness, m; 0 (the nominal grip) by
            default.

        Returns
        -------
        float
            Dimensionless ratio; > 1 means the arm is stiffer fore-aft at ``dx``.
        """
        dx = check_scalar("dx", dx)
        from_dx = check_scalar("from_dx", from_dx)
        return self.fore_aft_compliance(from_dx) / self.fore_aft_compliance(dx)
