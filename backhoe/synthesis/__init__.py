"""The force-feedback generalized plant of the Figure 5 loop (:mod:`.forcefb`) and its
controllers in the loop's convention."""

from backhoe.synthesis.forcefb import (
    ForceFeedbackWeights,
    as_loop_controller,
    force_feedback_plant,
    synthesis_member,
)

__all__ = [
    "ForceFeedbackWeights",
    "as_loop_controller",
    "force_feedback_plant",
    "synthesis_member",
]
