"""Compensator designs against biodynamic feedthrough, all evaluated on the same family.

One module per design, readable top to bottom as that design's script (family,
weights, synthesis; validation and export through the common pipeline):
:mod:`designs.workspace`, :mod:`designs.virtual_damping`, :mod:`designs.cancellation`,
:mod:`designs.hinf_nominal`, :mod:`designs.hinf_robust`, :mod:`designs.hinf_robust_corr`.
Each defines ``DESIGN`` (a :class:`Design`) whose ``build`` returns a
:class:`DesignResult`; :mod:`designs.registry` lists them and
:func:`run_design` runs one end to end. :mod:`designs.evaluate` holds the numbers
every design reports, :mod:`designs.multimodel` the multi-model tuning,
:mod:`designs.coverage` the coverage certificates, :mod:`designs.limit` the
achievable-limit map, :mod:`designs.calibration` the operator's calibration and
:mod:`designs.scheduled` the per-operator scheduled bank (``bdft design scheduled``, run
outside the registry's pipeline: it is a bank, not one controller).

Builds on :mod:`robust` and :mod:`uncertainty`; the reports and the command line build on it.
"""

from robust.lazy import lazy_exports

__all__ = [
    "DESIGNS",
    "Design",
    "DesignEvaluation",
    "DesignFacts",
    "DesignResult",
    "design_names",
    "evaluate_design",
    "get_design",
    "intended_motion",
    "run_design",
]

# the names above, each imported from its module on first use (robust.lazy)
__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "designs.evaluate": (
            "DesignEvaluation",
            "evaluate_design",
            "intended_motion",
        ),
        "designs.registry": (
            "DESIGNS",
            "design_names",
            "get_design",
            "run_design",
        ),
        "designs.result": (
            "Design",
            "DesignFacts",
            "DesignResult",
        ),
    },
)
