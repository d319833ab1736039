"""Analysis of LTI loops: poles and stability, the pole region, frequency responses, claims
C1-C5, calibration, H-infinity and H2 norms, minimal realisation, reduction, simulation and
the continuous-versus-sampled-data check.
"""

from robust.analysis.loops import PoleSet, closed_loop_poles, frequency_response
from robust.analysis.norms import h2_norm, hinf_norm, is_stable, sigma_max, spectral_abscissa
from robust.analysis.realization import MinimalRealization, minimal_realization
from robust.analysis.reduction import ReducedModel, balanced_truncation, hankel_singular_values
from robust.analysis.region import EVERY_FREQUENCY_HZ, Region
from robust.analysis.stability import STABILITY_TOL, poles_stable, stable_mask, unstable_mask

__all__ = [
    "PoleSet",
    "closed_loop_poles",
    "frequency_response",
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
    "STABILITY_TOL",
    "poles_stable",
    "stable_mask",
    "unstable_mask",
]
