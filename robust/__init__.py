"""Robust-control workbench for biodynamic feedthrough (BDFT) in haptic backhoe operation.

Public API, by area (import from here; module layout may change):

* the paper's model: components (Eqns 3-5), human variants, the Figure 5 loop,
  its calibration;
* analysis: minimal-realisation poles, claims C1-C5, BDFT ratio and loop gain,
  simulation;
* synthesis: the generalized plant, H-infinity by LMIs (nominal and multi-model),
  norms, the force-feedback plant;
* implementation: device limits, order reduction, discretisation and export.

Subpackages: :mod:`robust.model` (components, humans, loop, device),
:mod:`robust.analysis` (poles, claims, calibration, norms, reduction, simulation),
:mod:`robust.synthesis` (generalized plants, LMI synthesis), :mod:`robust.sysid`
(system identification); :mod:`robust.export` writes controller artifacts. This
package is the bottom layer: families live in ``uncertainty``, designs in
``designs``, reports in ``reports`` and the command line in ``bdft``, each
importing only the layers below it.
"""

from robust.analysis import (
    CLAIM_TEXT,
    K_PSF_STABLE,
    STABILITY_RTOL,
    CalibrationCandidate,
    CalibrationResult,
    ClaimResult,
    MinimalRealization,
    PoleSet,
    ReducedModel,
    SweptSine,
    TimeResponse,
    balanced_truncation,
    bdft_loop_gain,
    bdft_ratio,
    calibrate,
    closed_loop_poles,
    critical_k_psf,
    evaluate_claims,
    frequency_response,
    hankel_singular_values,
    hinf_norm,
    is_stable,
    is_unstable,
    loop_poles,
    minimal_realization,
    ratio_study,
    simulate,
    simulate_swept_sine,
    spectral_abscissa,
)
from robust.errors import (
    ArtifactError,
    AssumptionError,
    BDFTError,
    DataError,
    InfeasibleError,
    ModelStructureError,
    ParameterError,
    SolverError,
    VerificationError,
)
from robust.export import ControllerArtifact, discretize, load_artifact, write_artifact
from robust.model import (
    DEFAULT_CALIBRATION,
    K_PSF_NOMINAL,
    BDFTLoop,
    DeviceLimits,
    ForceCheck,
    HumanModel,
    LiteralHuman,
    LiteralHumanParams,
    LoopCalibration,
    PhysicalHuman,
    PhysicalHumanParams,
    PIParams,
    StructureParams,
    ValveCylinderParams,
    check_force,
    human_variant,
    pi_controller,
    position_scale,
    structure,
    valve_cylinder,
)
from robust.synthesis import (
    ForceFeedbackWeights,
    GeneralizedPlant,
    HinfResult,
    LMISynthesisProblem,
    MultiHinfResult,
    SolveResult,
    as_generalized_plant,
    as_loop_controller,
    check_hinf_assumptions,
    force_feedback_plant,
    hinfsyn_lmi,
    hinfsyn_multi,
    solve_problem,
)
from robust.synthesis.forcefb import handle_units_per_m

__version__ = "0.1.0"

__all__ = [
    # the paper's model
    "K_PSF_NOMINAL", "K_PSF_STABLE", "ValveCylinderParams", "StructureParams", "PIParams",
    "valve_cylinder", "structure", "pi_controller", "position_scale",
    "HumanModel", "LiteralHuman", "LiteralHumanParams", "PhysicalHuman", "PhysicalHumanParams",
    "human_variant",
    "BDFTLoop", "LoopCalibration", "DEFAULT_CALIBRATION",
    "calibrate", "CalibrationCandidate", "CalibrationResult",
    # analysis
    "STABILITY_RTOL", "PoleSet", "closed_loop_poles", "loop_poles", "is_unstable", "critical_k_psf",
    "frequency_response", "bdft_ratio", "bdft_loop_gain",
    "CLAIM_TEXT", "ClaimResult", "evaluate_claims", "ratio_study",
    "SweptSine", "TimeResponse", "simulate", "simulate_swept_sine",
    "MinimalRealization", "minimal_realization",
    # synthesis
    "GeneralizedPlant", "as_generalized_plant", "hinfsyn_lmi", "hinfsyn_multi", "HinfResult",
    "MultiHinfResult", "LMISynthesisProblem", "check_hinf_assumptions", "hinf_norm", "is_stable",
    "spectral_abscissa", "SolveResult", "solve_problem",
    "ForceFeedbackWeights", "force_feedback_plant", "as_loop_controller", "handle_units_per_m",
    # implementation
    "DeviceLimits", "ForceCheck", "check_force", "ReducedModel", "balanced_truncation",
    "hankel_singular_values", "ControllerArtifact", "discretize", "write_artifact", "load_artifact",
    # errors
    "BDFTError", "ParameterError", "DataError", "ModelStructureError", "AssumptionError",
    "InfeasibleError", "SolverError", "VerificationError", "ArtifactError",
    "__version__",
]
