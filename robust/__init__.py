"""Robust-control workbench for biodynamic feedthrough (BDFT) in haptic backhoe operation.

Public API, by area. Import from here; module layout may change.
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
from .human import HumanModel, LiteralHuman, LiteralHumanParams, human_variant
from .loop import DEFAULT_CALIBRATION, BDFTLoop, LoopCalibration
from .realization import MinimalRealization, minimal_realization
from .simulation import SweptSine, TimeResponse, simulate, simulate_swept_sine

__version__ = "0.1.0"

# --- H-infinity synthesis ---
from .genplant import GeneralizedPlant, as_generalized_plant
from .hinfsyn import HinfResult, LMISynthesisProblem, MultiHinfResult, check_hinf_assumptions, hinfsyn_lmi, hinfsyn_multi
from .norms import hinf_norm, is_stable, spectral_abscissa
from .solve import SolveResult, solve_problem
# --- end H-infinity synthesis ---
