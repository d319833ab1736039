"""Uncertain parameters, the physical human model and parametric families.

Public API (import from here; module layout may change):

* physical human: :class:`PhysicalHuman`, :class:`PhysicalHumanParams`,
  :func:`physical_human_matrices`, :func:`fit_summary`, :func:`segment_masses`.
"""

from .anthropometry import NOMINAL_BODY_MASS, SEGMENT_MASS_FRACTIONS, segment_masses
from .human import PhysicalHuman, PhysicalHumanParams, fit_summary, physical_human_matrices

__all__ = [
    "NOMINAL_BODY_MASS",
    "SEGMENT_MASS_FRACTIONS",
    "segment_masses",
    "PhysicalHuman",
    "PhysicalHumanParams",
    "physical_human_matrices",
    "fit_summary",
]
