"""The haptic device (Phantom Omni) and its limits, as named parameters.

Defaults are the commonly published figures for the SensAble Phantom Omni
(BRIEF section 6): fore-aft workspace about 70 mm (the paper's 71 mm), peak force
3.3 N, continuous force 0.88 N, position resolution 0.055 mm, servo rate 1 kHz. A
compensator whose force exceeds these limits on the family's worst member is not a
valid design.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robust.checks import POSITIVE, Spec, check_scalar, validate_fields
from robust.errors import ParameterError

__all__ = ["DeviceLimits", "ForceCheck", "check_force"]


@dataclasses.dataclass(frozen=True)
class DeviceLimits:
    """Limits of the haptic handle.

    Parameters
    ----------
    peak_force_n : float
        Largest force the device can render, N (default 3.3).
    continuous_force_n : float
        Force it can hold continuously, N; compared with the RMS force (default 0.88).
    workspace_mm : float
        Fore-aft workspace, mm (default 71, the paper's value).
    resolution_mm : float
        Encoder position resolution, mm (default 0.055).
    servo_rate_hz : float
        Servo (sample) rate, Hz (default 1000).
    """

    peak_force_n: float = 3.3
    continuous_force_n: float = 0.88
    workspace_mm: float = 71.0
    resolution_mm: float = 0.055
    servo_rate_hz: float = 1000.0

    def __post_init__(self):
        validate_fields(self, {f.name: POSITIVE for f in dataclasses.fields(self)})

    @property
    def sample_time_s(self) -> float:
        """Servo period, s."""
        return 1.0 / self.servo_rate_hz

    def intended_amplitude_m(self, fraction: float, *, workspace_factor: float = 1.0) -> float:
        """Amplitude of the operator's intended handle motion, m.

        ``fraction`` of half the handle's fore-aft travel, the travel being the
        workspace times ``workspace_factor`` (the loop's ``K_PSF_NOMINAL / K_PSF``).
        The one definition of the intended-motion amplitude: loops convert it to
        handle units with :meth:`backhoe.model.loop.BDFTLoop.intended_amplitude`.

        Parameters
        ----------
        fraction : float
            Fraction of the half-travel, in (0, 1].
        workspace_factor : float
            Workspace scaling of the loop (> 0).
        """
        frac = check_scalar("fraction", fraction, Spec(low=0.0, high=1.0, low_open=True))
        factor = check_scalar("workspace_factor", workspace_factor, POSITIVE)
        return frac * (self.workspace_mm * factor / 2.0) * 1e-3


@dataclasses.dataclass(frozen=True)
class ForceCheck:
    """Peak and RMS force of a force history against the device limits.

    Parameters
    ----------
    peak_force_n : float
        Largest absolute force of the history, N.
    rms_force_n : float
        Root-mean-square force, N.
    peak_limit_n : float
        The device's peak force, N.
    continuous_limit_n : float
        The device's continuous force, N (compared with the RMS).
    """

    peak_force_n: float
    rms_force_n: float
    peak_limit_n: float
    continuous_limit_n: float

    @property
    def within_limits(self) -> bool:
        """Peak and RMS both within their limits."""
        return (
            self.peak_force_n <= self.peak_limit_n and self.rms_force_n <= self.continuous_limit_n
        )

    def describe(self) -> str:
        """One sentence: peak, RMS, limits and the verdict."""
        verdict = "within limits" if self.within_limits else "OVER the device limits"
        return (
            f"peak {self.peak_force_n:.3g} N (limit {self.peak_limit_n:g}), "
            f"RMS {self.rms_force_n:.3g} N "
            f"(continuous limit {self.continuous_limit_n:g}): {verdict}"
        )


def check_force(force_n: np.ndarray, limits: DeviceLimits | None = None) -> ForceCheck:
    """Peak and RMS of a force history ``force_n`` (N) against ``limits``.

    Parameters
    ----------
    force_n : array_like
        Force samples, N (a non-finite sample makes both figures infinite).
    limits : DeviceLimits, optional
        Device limits (default: the Omni's).

    Raises
    ------
    robust.errors.ParameterError
        If ``force_n`` is not numeric or ``limits`` is not a :class:`DeviceLimits`.
    """
    if limits is not None and not isinstance(limits, DeviceLimits):
        raise ParameterError(
            f"check_force: limits must be DeviceLimits or None; got {type(limits).__name__}"
        )
    limits = limits or DeviceLimits()
    try:
        f = np.asarray(force_n, float)
    except (TypeError, ValueError):
        raise ParameterError(
            f"check_force: force_n must be a numeric array of forces in N; "
            f"got {type(force_n).__name__}"
        ) from None
    if f.size == 0:
        peak = rms = 0.0
    elif not np.all(np.isfinite(f)):
        peak = rms = float("inf")
    else:
        peak, rms = float(np.max(np.abs(f))), float(np.sqrt(np.mean(f**2)))
    return ForceCheck(peak, rms, limits.peak_force_n, limits.continuous_force_n)
