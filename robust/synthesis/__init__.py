"""H-infinity synthesis: the generalized plant, the force-feedback plant, LMI synthesis
(nominal and multi-model) in cvxpy, and the solve wrapper.
"""

from robust.synthesis.forcefb import ForceFeedbackWeights, as_loop_controller, force_feedback_plant
from robust.synthesis.genplant import GeneralizedPlant, as_generalized_plant
from robust.synthesis.hinfsyn import (
    HinfResult,
    LMISynthesisProblem,
    MultiHinfResult,
    check_hinf_assumptions,
    hinfsyn_lmi,
    hinfsyn_multi,
)
from robust.synthesis.solve import SolveResult, solve_problem

__all__ = [
    "ForceFeedbackWeights",
    "as_loop_controller",
    "force_feedback_plant",
    "GeneralizedPlant",
    "as_generalized_plant",
    "HinfResult",
    "LMISynthesisProblem",
    "MultiHinfResult",
    "check_hinf_assumptions",
    "hinfsyn_lmi",
    "hinfsyn_multi",
    "SolveResult",
    "solve_problem",
]
