"""Robust-control workbench for biodynamic feedthrough (BDFT) in haptic backhoe operation.

Public API, by area. Import from here; module layout may change.
"""

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

__version__ = "0.1.0"
