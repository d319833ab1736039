"""Analysis of LTI loops: poles and stability, the pole region, frequency responses, claims
C1-C5, calibration, H-infinity and H2 norms, minimal realisation, reduction, simulation and
the continuous-versus-sampled-data check.
"""

from robust.analysis.calibration import (
    K_PSF_STABLE,
    CalibrationCandidate,
    CalibrationResult,
    calibrate,
)
from robust.analysis.claims import CLAIM_TEXT, ClaimResult, evaluate_claims, ratio_study
from robust.analysis.loops import (
    PoleSet,
    bdft_loop_gain,
    bdft_ratio,
    closed_loop_poles,
    critical_k_psf,
    frequency_response,
    loop_poles,
)
from robust.analysis.norms import h2_norm, hinf_norm, is_stable, sigma_max, spectral_abscissa
from robust.analysis.realization import MinimalRealization, minimal_realization
from robust.analysis.reduction import ReducedModel, balanced_truncation, hankel_singular_values
from robust.analysis.region import EVERY_FREQUENCY_HZ, Region
from robust.analysis.sampled import SampledDataCheck, open_plant, sampled_data_check
from robust.analysis.simulation import SweptSine, TimeResponse, simulate, simulate_swept_sine
from robust.analysis.stability import STABILITY_TOL, poles_stable, stable_mask, unstable_mask

__all__ = [
    "K_PSF_STABLE",
    "CalibrationCandidate",
    "CalibrationResult",
    "calibrate",
    "CLAIM_TEXT",
    "ClaimResult",
    "evaluate_claims",
    "ratio_study",
    "PoleSet",
    "bdft_loop_gain",
    "bdft_ratio",
    "closed_loop_poles",
    "critical_k_psf",
    "frequency_response",
    "loop_poles",
    "h2_norm",
    "hinf_norm",
    "is_stable",
    "sigma_max",
    "spectral_abscissa",
    "EVERY_FREQUENCY_HZ",
    "Region",
    "MinimalRealization",
    "minimal_realization",
    "ReducedModel",
    "balanced_truncation",
    "hankel_singular_values",
    "SampledDataCheck",
    "open_plant",
    "sampled_data_check",
    "STABILITY_TOL",
    "poles_stable",
    "stable_mask",
    "unstable_mask",
    "SweptSine",
    "TimeResponse",
    "simulate",
    "simulate_swept_sine",
]
