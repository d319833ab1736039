"""H-infinity synthesis: the generalized plant, the force-feedback plant, assumption
checks, plant scaling, LMI synthesis (nominal and multi-model) in cvxpy, and the
solve wrapper.

Modules: :mod:`.genplant` (the plant), :mod:`.forcefb` (the force-feedback plant),
:mod:`.assumptions` (checks before any solve), :mod:`.scaling` (apply/invert pairs),
:mod:`.lmi` (LMI builders), :mod:`.solve` (the solver wrapper), :mod:`.nominal`
(:func:`hinfsyn_lmi`), :mod:`.multi` (:func:`hinfsyn_multi`: generalized plants, through
:func:`pksyn_multi`), :mod:`.region` (LMI pole regions of
:class:`robust.analysis.region.Region`, :func:`certify_region`), :mod:`.pk`
(:func:`pksyn_multi`, the P-K iteration on a family with per-member certificates),
:mod:`.tuning` (its starts: :func:`minimax_start` by linear programs, :func:`tune_members`
by nonsmooth BFGS), :mod:`.testing` (seeded test plants).
"""

from robust.synthesis.assumptions import (
    check_detectable,
    check_hinf_assumptions,
    check_regularity,
    check_stabilisable,
)
from robust.synthesis.d22 import D22Removal
from robust.synthesis.genplant import GeneralizedPlant, as_generalized_plant
from robust.synthesis.multi import MultiHinfResult, hinfsyn_multi
from robust.synthesis.nominal import HinfResult, LMISynthesisProblem, hinfsyn_lmi
from robust.synthesis.pk import MultiObjectiveResult, pksyn_multi
from robust.synthesis.pk_members import SynthesisMember
from robust.synthesis.region import certify_region
from robust.synthesis.scaling import PlantScaling
from robust.synthesis.solve import SolveResult, solve_problem
from robust.synthesis.tuning import minimax_start, region_start, slp_minimise, tune_members

__all__ = [
    "GeneralizedPlant",
    "as_generalized_plant",
    "HinfResult",
    "LMISynthesisProblem",
    "MultiHinfResult",
    "check_hinf_assumptions",
    "check_stabilisable",
    "check_detectable",
    "check_regularity",
    "hinfsyn_lmi",
    "hinfsyn_multi",
    "PlantScaling",
    "D22Removal",
    "SolveResult",
    "solve_problem",
    "SynthesisMember",
    "MultiObjectiveResult",
    "pksyn_multi",
    "certify_region",
    "tune_members",
    "minimax_start",
    "region_start",
    "slp_minimise",
]
