"""The backhoe with its operator: the paper's model, its parametric families and their
analyses, built on the generic uncertain-system core.

This layer is the one machine the workbench ships, written as any user's own machine would
be: it uses the generic core below it (:mod:`robust` for numerics, analysis, synthesis and
identification; :mod:`uncertainty` for uncertain reals and systems, LFTs, mu, robust
margins and performance, mu-synthesis) and nothing in the core knows it. The designs
(:mod:`designs`), the reports (:mod:`reports`) and the command line (:mod:`bdft`) build on
it.

Public API (import from here; module layout may change):

* the paper's model (:mod:`backhoe.model`): components (Eqns 3-5), the human variants, the
  Figure 5 loop, its calibration, the Omni's limits; every block written once in
  :mod:`backhoe.model.blocks`, the only module that spells the parameters' names;
* the loop's analyses (:mod:`backhoe.analysis`): poles, claims C1-C5, the BDFT ratio and
  loop gain, the critical gain, the calibration, simulation;
* the force-feedback plant (:mod:`backhoe.synthesis`);
* identification of the components from chirp data (:mod:`backhoe.sysid`);
* families (:mod:`backhoe.families`): :class:`Family`, :func:`default_family`, their batched
  matrices and validation, the loop as an uncertain system (:func:`family_uss`), interval
  enclosures, value sets, sweeps and files. A :class:`Family` is taken by
  :func:`uncertainty.robust_margin` and its relatives through its ``margin_loop`` method.
"""

from robust.lazy import lazy_exports

__all__ = [
    "DAMPING_BAND_HZ",
    "BDFTLoop",
    "CLAIM_TEXT",
    "CalibrationCandidate",
    "CalibrationResult",
    "ClaimResult",
    "DEFAULT_CALIBRATION",
    "DeviceLimits",
    "Family",
    "ForceCheck",
    "ForceFeedbackWeights",
    "HUMAN_VARIANTS",
    "HumanModel",
    "K_PSF_NOMINAL",
    "K_PSF_STABLE",
    "LiteralHuman",
    "LiteralHumanParams",
    "LoopCalibration",
    "MODEL_PARAMETERS",
    "PHYSICAL_LIMITS",
    "PIParams",
    "PhysicalHuman",
    "PhysicalHumanParams",
    "RANGES",
    "SWEEPS",
    "StructureParams",
    "SweepResult",
    "SweptSine",
    "TimeResponse",
    "ValveCylinderParams",
    "as_loop_controller",
    "batched_poles",
    "bdft_loop_gain",
    "bdft_ratio",
    "calibrate",
    "check_force",
    "closed_loop_enclosure",
    "closed_loop_matrices",
    "critical_k_psf",
    "default_family",
    "evaluate_claims",
    "family_nominals",
    "family_uss",
    "force_feedback_plant",
    "frequency_damping_sweep",
    "handle_units_per_m",
    "human_variant",
    "load_component_fit",
    "load_controller",
    "load_system",
    "loop_poles",
    "match_controller",
    "member_metrics",
    "pi_controller",
    "position_scale",
    "ratio_study",
    "simulate",
    "simulate_swept_sine",
    "structure",
    "structure_frequency_sweep",
    "valve_cylinder",
    "workspace_sweep",
]

# the names above, each imported from its module on first use (robust.lazy)
__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "backhoe.analysis": (
            "CLAIM_TEXT",
            "CalibrationCandidate",
            "CalibrationResult",
            "ClaimResult",
            "K_PSF_STABLE",
            "SweptSine",
            "TimeResponse",
            "bdft_loop_gain",
            "bdft_ratio",
            "calibrate",
            "critical_k_psf",
            "evaluate_claims",
            "loop_poles",
            "ratio_study",
            "simulate",
            "simulate_swept_sine",
        ),
        "backhoe.constants": (
            "DAMPING_BAND_HZ",
            "RANGES",
        ),
        "backhoe.families.batched": (
            "batched_poles",
            "closed_loop_matrices",
        ),
        "backhoe.families.enclosure": ("closed_loop_enclosure",),
        "backhoe.families.family": (
            "Family",
            "HUMAN_VARIANTS",
            "MODEL_PARAMETERS",
            "PHYSICAL_LIMITS",
        ),
        "backhoe.families.family_ranges": ("default_family",),
        "backhoe.families.files": (
            "family_nominals",
            "load_component_fit",
            "load_controller",
            "load_system",
            "match_controller",
        ),
        "backhoe.families.loop": ("family_uss",),
        "backhoe.families.sweeps": (
            "SWEEPS",
            "SweepResult",
            "frequency_damping_sweep",
            "structure_frequency_sweep",
            "workspace_sweep",
        ),
        "backhoe.families.validation": ("member_metrics",),
        "backhoe.model": (
            "BDFTLoop",
            "DEFAULT_CALIBRATION",
            "DeviceLimits",
            "ForceCheck",
            "HumanModel",
            "K_PSF_NOMINAL",
            "LiteralHuman",
            "LiteralHumanParams",
            "LoopCalibration",
            "PIParams",
            "PhysicalHuman",
            "PhysicalHumanParams",
            "StructureParams",
            "ValveCylinderParams",
            "check_force",
            "human_variant",
            "pi_controller",
            "position_scale",
            "structure",
            "valve_cylinder",
        ),
        "backhoe.synthesis": (
            "ForceFeedbackWeights",
            "as_loop_controller",
            "force_feedback_plant",
        ),
        "backhoe.synthesis.forcefb": ("handle_units_per_m",),
    },
)
