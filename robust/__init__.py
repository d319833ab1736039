"""Robust-control workbench for biodynamic feedthrough (BDFT) in haptic backhoe operation.

Public API, by area (import from here; module layout may change):

* the paper's model: components (Eqns 3-5), human variants, the Figure 5 loop,
  its calibration;
* analysis: minimal-realisation poles, claims C1-C5, BDFT ratio and loop gain,
  simulation;
* synthesis: the generalized plant, H-infinity by LMIs (nominal and multi-model),
  norms, the force-feedback plant;
* implementation: device limits, order reduction, discretisation and export.

System identification lives in :mod:`robust.sysid`, designs in :mod:`robust.designs`,
reports in :mod:`robust.report`; families and batched validation in the
``uncertainty`` package.
"""

from .analysis import (
    STABILITY_RTOL,
    PoleSet,
    bdft_loop_gain,
    bdft_ratio,
    closed_loop_poles,
    critical_k_psf,
    frequency_response,
    is_unstable,
    loop_poles,
)
from .calibration import K_PSF_STABLE, CalibrationCandidate, CalibrationResult, calibrate
from .claims import CLAIM_TEXT, ClaimResult, evaluate_claims, ratio_study
from .components import (
    K_PSF_NOMINAL,
    PIParams,
    StructureParams,
    ValveCylinderParams,
    pi_controller,
    position_scale,
    structure,
    valve_cylinder,
)
from .device import DeviceLimits, ForceCheck, check_force
from .errors import (
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
from .export import ControllerArtifact, discretize, load_artifact, write_artifact
from .forcefb import ForceFeedbackWeights, as_loop_controller, force_feedback_plant, handle_units_per_m
from .genplant import GeneralizedPlant, as_generalized_plant
from .hinfsyn import (
    HinfResult,
    LMISynthesisProblem,
    MultiHinfResult,
    check_hinf_assumptions,
    hinfsyn_lmi,
    hinfsyn_multi,
)
from .human import HumanModel, LiteralHuman, LiteralHumanParams, human_variant
from .loop import DEFAULT_CALIBRATION, BDFTLoop, LoopCalibration
from .norms import hinf_norm, is_stable, spectral_abscissa
from .realization import MinimalRealization, minimal_realization
from .reduction import ReducedModel, balanced_truncation, hankel_singular_values
from .simulation import SweptSine, TimeResponse, simulate, simulate_swept_sine
from .solve import SolveResult, solve_problem

__version__ = "0.1.0"

__all__ = [
    # the paper's model
    "K_PSF_NOMINAL", "K_PSF_STABLE", "ValveCylinderParams", "StructureParams", "PIParams",
    "valve_cylinder", "structure", "pi_controller", "position_scale",
    "HumanModel", "LiteralHuman", "LiteralHumanParams", "human_variant",
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
