"""The paper's model: components (Eqns 3-4), the human variants, the Figure 5 loop and the device.

Public API (import from here or from :mod:`robust`):

* components: :class:`ValveCylinderParams`, :class:`StructureParams`, :class:`PIParams`,
  :func:`valve_cylinder`, :func:`structure`, :func:`pi_controller`, :func:`position_scale`;
* humans: :class:`HumanModel`, :class:`LiteralHuman` (Eqn 5 as printed),
  :class:`PhysicalHuman` (a seated mass-spring-damper chain with a force port),
  :func:`human_variant`, anthropometry and :class:`ArmGeometry`;
* the loop: :class:`BDFTLoop`, :class:`LoopCalibration`, the signal table of
  :mod:`backhoe.model.wiring`;
* the device: :class:`DeviceLimits`, :func:`check_force`, the handle units and the
  intended-motion amplitude.

SLICOT is required, not optional: python-control realises transfer functions in state
space with SLICOT's ``td04ad`` when slycot is importable and with scipy otherwise, and the
two realisations differ. Every design tuned in state-space coordinates (the nominal LMI
design, the robust designs' starts) would then differ between installs: the nominal LMI
controller, for one, changes its frequency response by orders of magnitude at the same
H-infinity level. So the model refuses to load without it.
"""

try:
    import slycot  # noqa: F401  (see the module docstring: realisations depend on it)
except ImportError as exc:
    raise ImportError(
        "the workbench needs slycot (SLICOT): python-control's state-space realisations, "
        "and so every design, change without it; install it with 'pip install slycot'"
    ) from exc

from backhoe.model.anthropometry import NOMINAL_BODY_MASS, SEGMENT_MASS_FRACTIONS, segment_masses
from backhoe.model.arm import ArmGeometry
from backhoe.model.components import (
    K_PSF_NOMINAL,
    PIParams,
    StructureParams,
    ValveCylinderParams,
    pi_controller,
    position_scale,
    structure,
    valve_cylinder,
)
from backhoe.model.device import DeviceLimits, ForceCheck, check_force
from backhoe.model.human import HumanModel, LiteralHuman, LiteralHumanParams, human_variant
from backhoe.model.loop import (
    CONTROLLER_INPUTS,
    CONTROLLER_OUTPUTS,
    DEFAULT_CALIBRATION,
    LOOP_OUTPUTS,
    BDFTLoop,
    LoopCalibration,
)
from backhoe.model.physical import (
    PhysicalHuman,
    PhysicalHumanParams,
    fit_summary,
    physical_human_matrices,
)

__all__ = [
    "K_PSF_NOMINAL",
    "PIParams",
    "StructureParams",
    "ValveCylinderParams",
    "pi_controller",
    "position_scale",
    "structure",
    "valve_cylinder",
    "HumanModel",
    "LiteralHuman",
    "LiteralHumanParams",
    "human_variant",
    "PhysicalHuman",
    "PhysicalHumanParams",
    "fit_summary",
    "physical_human_matrices",
    "NOMINAL_BODY_MASS",
    "SEGMENT_MASS_FRACTIONS",
    "segment_masses",
    "ArmGeometry",
    "BDFTLoop",
    "LoopCalibration",
    "DEFAULT_CALIBRATION",
    "LOOP_OUTPUTS",
    "CONTROLLER_INPUTS",
    "CONTROLLER_OUTPUTS",
    "DeviceLimits",
    "ForceCheck",
    "check_force",
]
