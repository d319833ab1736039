"""Compensator designs against biodynamic feedthrough, all evaluated on the same family.

Each design is a function ``design_<name>(family, samples, **options) -> DesignResult``;
the scripts in the repository's ``designs/`` folder and ``bdft design NAME`` run them.
"""

from designs.evaluate import DesignEvaluation, evaluate_design, intended_motion

__all__ = ["DesignEvaluation", "evaluate_design", "intended_motion"]
