"""The workbench's numerical core: LTI analysis, H-infinity synthesis, identification and export.

The bottom layer of the workbench, generic over any LTI plant: nothing here knows the
backhoe (:mod:`backhoe` builds the machine on it, as a user's own machine would).

Public API, by area (import from here; module layout may change):

* analysis: minimal-realisation poles (hidden modes kept), stability, frequency
  responses, H-infinity and H2 norms;
* synthesis: the generalized plant, H-infinity by LMIs (nominal and multi-model), the
  solve wrapper;
* implementation: order reduction, discretisation and export;
* the workbench's errors.

Subpackages: :mod:`robust.analysis` (poles, norms, realisation, reduction, pole regions,
interval arithmetic, eigenvalue enclosures), :mod:`robust.synthesis` (generalized
plants, LMI synthesis, Youla parametrisation, tuning), :mod:`robust.sysid` (spectra and
rational fits of frequency responses); :mod:`robust.export` writes controller artifacts.
Above it: uncertain systems in ``uncertainty``, the machine in ``backhoe``, designs in
``designs``, reports in ``reports`` and the command line in ``bdft``, each importing only
the layers below it.
"""

from robust.lazy import lazy_exports
from robust.version import __version__

__all__ = [
    # analysis
    "STABILITY_TOL",
    "PoleSet",
    "closed_loop_poles",
    "poles_stable",
    "frequency_response",
    "MinimalRealization",
    "minimal_realization",
    # synthesis
    "GeneralizedPlant",
    "as_generalized_plant",
    "hinfsyn_lmi",
    "hinfsyn_multi",
    "HinfResult",
    "MultiHinfResult",
    "LMISynthesisProblem",
    "check_hinf_assumptions",
    "hinf_norm",
    "is_stable",
    "spectral_abscissa",
    "SolveResult",
    "solve_problem",
    # implementation
    "ReducedModel",
    "balanced_truncation",
    "hankel_singular_values",
    "ControllerArtifact",
    "discretize",
    "write_artifact",
    "load_artifact",
    # errors
    "BDFTError",
    "ParameterError",
    "DataError",
    "ModelStructureError",
    "AssumptionError",
    "InfeasibleError",
    "SolverError",
    "VerificationError",
    "ArtifactError",
    "__version__",
]

# the names above but __version__ (light, imported at once), each imported from its module on
# first use (robust.lazy)
__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "robust.analysis": (
            "MinimalRealization",
            "PoleSet",
            "ReducedModel",
            "STABILITY_TOL",
            "balanced_truncation",
            "closed_loop_poles",
            "frequency_response",
            "hankel_singular_values",
            "hinf_norm",
            "is_stable",
            "minimal_realization",
            "poles_stable",
            "spectral_abscissa",
        ),
        "robust.errors": (
            "ArtifactError",
            "AssumptionError",
            "BDFTError",
            "DataError",
            "InfeasibleError",
            "ModelStructureError",
            "ParameterError",
            "SolverError",
            "VerificationError",
        ),
        "robust.export": (
            "ControllerArtifact",
            "discretize",
            "load_artifact",
            "write_artifact",
        ),
        "robust.synthesis": (
            "GeneralizedPlant",
            "HinfResult",
            "LMISynthesisProblem",
            "MultiHinfResult",
            "SolveResult",
            "as_generalized_plant",
            "check_hinf_assumptions",
            "hinfsyn_lmi",
            "hinfsyn_multi",
            "solve_problem",
        ),
    },
)
