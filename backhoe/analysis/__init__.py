"""Analyses of the Figure 5 loop: its poles, BDFT ratio and loop gain, claims C1-C5, the
loop's calibration, the simulation and the continuous-versus-sampled-data check.
"""

from backhoe.analysis.calibration import (
    K_PSF_STABLE,
    CalibrationCandidate,
    CalibrationResult,
    calibrate,
)
from backhoe.analysis.claims import CLAIM_TEXT, ClaimResult, evaluate_claims, ratio_study
from backhoe.analysis.loops import bdft_loop_gain, bdft_ratio, critical_k_psf, loop_poles
from backhoe.analysis.sampled import SampledDataCheck, open_plant, sampled_data_check
from backhoe.analysis.simulation import SweptSine, TimeResponse, simulate, simulate_swept_sine

__all__ = [
    "K_PSF_STABLE",
    "CalibrationCandidate",
    "CalibrationResult",
    "calibrate",
    "CLAIM_TEXT",
    "ClaimResult",
    "evaluate_claims",
    "ratio_study",
    "bdft_loop_gain",
    "bdft_ratio",
    "critical_k_psf",
    "loop_poles",
    "SampledDataCheck",
    "open_plant",
    "sampled_data_check",
    "SweptSine",
    "TimeResponse",
    "simulate",
    "simulate_swept_sine",
]
