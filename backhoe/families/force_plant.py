"""The force-feedback generalized plant over a whole family, as an uncertain system.

:func:`backhoe.synthesis.forcefb.force_feedback_plant` poses handle-force feedback on one
member; :func:`force_feedback_uss` poses the same problem (the same weights, noise models
and partition) on the family's Figure 5 loop as an uncertain system
(:func:`backhoe.families.loop.family_uss`), what :func:`uncertainty.musyn` designs on.
"""

from __future__ import annotations

import control as ct

from backhoe.families.loop import family_uss
from backhoe.model.device import DeviceLimits
from backhoe.synthesis.forcefb import ForceFeedbackWeights, weighting_blocks
from robust.errors import ModelStructureError
from uncertainty import interconnect

__all__ = ["force_feedback_uss"]


def force_feedback_uss(family, weights: ForceFeedbackWeights | None = None, limits=None):
    """The generalized plant of :func:`force_feedback_plant` over a whole family.

    The same weights, noise models and partition, around the family's Figure 5 loop as an
    uncertain system (:func:`backhoe.families.loop.family_uss`: the family's parameters
    as uncertain reals over their ranges) instead of one member's; what
    :func:`uncertainty.musyn` takes. The BDFT-free reference ``y_ref`` and the units
    (intended-motion amplitude, encoder noise) are the nominal member's.

    Parameters
    ----------
    family : backhoe.Family
        A family of the physical human (the handle force acts on the hand).
    weights : ForceFeedbackWeights, optional
        Weights (default: the documented defaults); ``bdft_weight`` must be 0 (the
        human's command is not a port of the family's uncertain loop).
    limits : DeviceLimits, optional
        Device limits (default: the Omni's).

    Returns
    -------
    uncertainty.USS
        Inputs ``w_u, n_x, n_c, f``, outputs ``z_e, z_f, x_m, c_m`` (two measurements, one
        control, in :func:`uncertainty.musyn`'s order).

    Raises
    ------
    ModelStructureError
        If the family's human has no force port, or ``bdft_weight`` is not 0.
    """
    wts = weights or ForceFeedbackWeights()
    lim = limits or DeviceLimits()
    nominal = family.member(family.nominal_values())
    if not nominal.human.has_force_port:
        raise ModelStructureError(
            f"force feedback needs a human with a force port; {nominal.human.variant!r} has none"
        )
    if wts.bdft_weight > 0:
        raise ModelStructureError(
            "force_feedback_uss: bdft_weight must be 0 (the human's command h_cmd is not an "
            f"output of the family's uncertain loop); got {wts.bdft_weight}"
        )
    amp = nominal.intended_amplitude(lim, wts.intent_fraction)
    G = family_uss(family, inputs=["u", "f_ext"], outputs=["y", "x", "c"])
    weighting, w, u, z, y = weighting_blocks(nominal, wts, lim, amp, False)
    # the controller's force is the loop's external hand force
    port = ct.ss([], [], [], [[1.0]], inputs="f", outputs="f_ext", name="force_port")
    return interconnect([G, port, *weighting], inputs=w + u, outputs=z + y)
