"""The design specification's parameters: :class:`Specification` and the names of its
constraints.

What a compensator must meet, as named, checked parameters (the pole region, the
intended-motion weights and bands, the noise, the device's effort limits) and the
frequency grids that designs which optimise on frequencies use. The requirements and the
way they are checked on a family are described in :mod:`designs.spec`, which holds the
check (:func:`designs.spec.check_specification`) and re-exports these names; the
parameters are apart so that the modules that only need them (the designs, the
calibration, the coverage) do not depend on the check.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import control as ct
import numpy as np

from backhoe.constants import DAMPING_BAND_HZ
from backhoe.model.components import K_PSF_NOMINAL
from backhoe.model.device import DeviceLimits
from designs.effort import Noise
from designs.evaluate import INTENT_FRACTION, SUPPRESSION_BAND_HZ, TRACKING_BAND_HZ
from designs.response import (
    check_weight,
    default_feedthrough_weight,
    default_tracking_weight,
    weight_system,
)
from robust.checks import (
    FINITE,
    NONNEGATIVE,
    POSITIVE,
    Spec,
    check_scalar,
    check_vector,
    validate_fields,
)
from robust.errors import ParameterError
from robust.jsonio import to_jsonable
from uncertainty.region import Region

__all__ = ["CONSTRAINTS", "Specification"]


#: Names of the constraints, in the order they are reported (ties of the utilisation
#: go to the earlier one).
CONSTRAINTS = (
    "decay rate",
    "damping",
    "peak force",
    "continuous force",
    "tracking",
    "feedthrough",
    "noise",
    "reference effort",
)


#: Frequencies of the design grids below and above :attr:`Specification.split_hz` (the
#: checks are exact at every frequency; designs that optimise on frequencies use these).
N_TRACKING_FREQS = 60


N_FEEDTHROUGH_FREQS = 90


_BANDS = ("damping_band_hz", "tracking_band_hz", "feedthrough_band_hz")


@dataclasses.dataclass(frozen=True)
class Specification:
    """The handle-force design specification.

    Parameters
    ----------
    peak_force_n : float
        Largest handle force allowed, N (the Omni's peak force, 3.3).
    continuous_force_n : float
        Largest RMS handle force allowed, N (the Omni's continuous force, 0.88).
    intent_fraction : float
        Amplitude of the intended motion, as a fraction of the half-workspace, in (0, 1]
        (default :data:`designs.evaluate.INTENT_FRACTION`).
    intent_bandwidth_hz : float
        Bandwidth of the realistic intended motion (intent filter corner), Hz (2).
    decay_rate : float
        Every closed-loop pole must have real part below ``-decay_rate``, rad/s (>= 0).
    min_damping : float
        Smallest damping ratio of the poles in ``damping_band_hz``, in [0, 1).
    damping_band_hz : (float, float)
        Band of the damping requirement, Hz (poles with ``|Im p| / (2 pi)`` in it).
    tracking_error : float
        Allowed ``|Y/Y_ref - 1|`` through the operator's band (> 0): the level of the
        default tracking weight ``W_t``.
    tracking_band_hz : (float, float)
        The operator's band, Hz (default :data:`designs.evaluate.TRACKING_BAND_HZ`); its top
        is :attr:`split_hz` and places ``W_t``'s corner (an octave above).
    feedthrough_band_hz : (float, float)
        Band of the structure modes, Hz (default
        :data:`designs.evaluate.SUPPRESSION_BAND_HZ`): where the default feedthrough weight
        ``W_f`` asks for the reduction.
    max_amplification_db : float
        Far from the structure band, how much the deviation from the BDFT-free response
        may exceed the uncompensated loop's, dB (1: the compensated loop is nowhere worse
        than doing nothing, to 12 %).
    feedthrough_reduction_db : float
        Required reduction of the feedthrough over ``feedthrough_band_hz`` against the
        uncompensated loop, dB (6: half. The paper's own remedy, doubling the workspace,
        halves the BDFT loop gain; on the nominal member of the default family it lowers the
        feedthrough peak over 5-7.5 Hz from 2.28 to 0.57 of the BDFT-free response, 12 dB. A
        compensator that keeps the workspace is asked for half of that).
    tracking_floor : float
        Allowed ``|Y/Y_ref - 1|`` far above the operator's band where the feedthrough bound
        does not apply (``W_t``'s high-frequency level, 0.02).
    tracking_weight, feedthrough_weight : (num, den) or control system, optional
        The weights themselves, stable and proper rational functions with no zero on the
        imaginary axis (coefficients in descending powers of ``s``); by default
        :func:`default_tracking_weight` and :func:`default_feedthrough_weight` of the fields
        above. Stored as coefficient tuples.
    noise : designs.effort.Noise
        Sensor noise and the operator's remnant.
    noise_cylinder_mm : float
        Largest RMS cylinder position caused by the sensor noise alone, mm of cylinder travel
        (1).
    noise_force_n : float
        Largest RMS handle force caused by the sensor noise alone, N (0.1).
    correction_flow_share : float
        Share of the valve's flow and command range a reference correction may use, in
        (0, 1] (0.5: the rest is the operator's).
    peak_factor : float
        Peaks of the effort are taken as this many RMS values (3: a Gaussian signal exceeds
        it 0.27 % of the time).
    reference_k_psf : float or None
        ``K_PSF`` of the uncompensated loop the feedthrough is compared with (default the
        paper's, 0.1097: every design is judged against the machine as built, so a design
        that enlarges the workspace gets credit for the feedthrough it removes); ``None``:
        each member's own.

    Raises
    ------
    robust.errors.ParameterError
        If a field is out of range; the message names ``Specification.<field>``, the
        accepted range and the value got.
    """

    peak_force_n: float = 3.3
    continuous_force_n: float = 0.88
    intent_fraction: float = INTENT_FRACTION
    intent_bandwidth_hz: float = 2.0
    decay_rate: float = 0.1
    min_damping: float = 0.1
    damping_band_hz: tuple[float, float] = DAMPING_BAND_HZ
    tracking_error: float = 0.2
    tracking_band_hz: tuple[float, float] = TRACKING_BAND_HZ
    feedthrough_band_hz: tuple[float, float] = SUPPRESSION_BAND_HZ
    max_amplification_db: float = 1.0
    feedthrough_reduction_db: float = 6.0
    tracking_floor: float = 0.02
    tracking_weight: tuple | None = None
    feedthrough_weight: tuple | None = None
    noise: Noise = Noise()
    noise_cylinder_mm: float = 1.0
    noise_force_n: float = 0.1
    correction_flow_share: float = 0.5
    peak_factor: float = 3.0
    reference_k_psf: float | None = K_PSF_NOMINAL

    def __post_init__(self):
        validate_fields(
            self,
            {
                "peak_force_n": POSITIVE,
                "continuous_force_n": POSITIVE,
                "intent_fraction": Spec(low=0.0, high=1.0, low_open=True),
                "intent_bandwidth_hz": POSITIVE,
                "decay_rate": NONNEGATIVE,
                "min_damping": Spec(low=0.0, high=1.0, high_open=True),
                "tracking_error": POSITIVE,
                "max_amplification_db": FINITE,
                "feedthrough_reduction_db": FINITE,
                "tracking_floor": POSITIVE,
                "noise_cylinder_mm": POSITIVE,
                "noise_force_n": POSITIVE,
                "correction_flow_share": Spec(low=0.0, high=1.0, low_open=True),
                "peak_factor": POSITIVE,
            },
        )
        if self.reference_k_psf is not None:
            object.__setattr__(
                self,
                "reference_k_psf",
                check_scalar("Specification.reference_k_psf", self.reference_k_psf, POSITIVE),
            )
        if not isinstance(self.noise, Noise):
            raise ParameterError(
                "Specification.noise must be a designs.effort.Noise; "
                f"got {type(self.noise).__name__}"
            )
        for name in _BANDS:
            object.__setattr__(self, name, _band(name, getattr(self, name)))
        if self.tracking_weight is None:
            w = default_tracking_weight(
                self.tracking_error, self.tracking_floor, self.tracking_band_hz[1]
            )
        else:
            w = check_weight("tracking_weight", self.tracking_weight)
        object.__setattr__(self, "tracking_weight", w)
        if self.feedthrough_weight is None:
            w = default_feedthrough_weight(
                self.feedthrough_band_hz, self.feedthrough_reduction_db, self.max_amplification_db
            )
        else:
            w = check_weight("feedthrough_weight", self.feedthrough_weight)
        object.__setattr__(self, "feedthrough_weight", w)
        if not self.tracking_band_hz[1] < self.feedthrough_band_hz[0]:
            raise ParameterError(
                "Specification.tracking_band_hz must lie below feedthrough_band_hz (the two "
                f"checks split the axis between them); got {self.tracking_band_hz} and "
                f"{self.feedthrough_band_hz}"
            )

    @property
    def split_hz(self) -> float:
        """Frequency that splits the intent-response bound between the ``"tracking"`` check
        (up to it) and the ``"feedthrough"`` check (above), Hz: the top of
        ``tracking_band_hz``, the operator's band."""
        return self.tracking_band_hz[1]

    def weight_systems(self) -> tuple[ct.StateSpace, ct.StateSpace]:
        """``(W_t, W_f)`` as python-control state-space systems (module notes)."""
        return weight_system(self.tracking_weight), weight_system(self.feedthrough_weight)

    def deviation_bound(self, omega, r0) -> np.ndarray:
        """The bound on ``|R(jw)|`` at ``omega``: ``|W_t|`` up to :attr:`split_hz`,
        ``max(|W_t|, |W_f R0|)`` above it.

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.
        r0 : array_like of complex
            The uncompensated deviation ``R0(jw) = Y_0/Y_ref - 1`` at ``omega``
            (broadcast against ``omega``'s last axis).
        """
        s = 1j * np.asarray(omega, float)
        wt = np.abs(np.polyval(self.tracking_weight[0], s) / np.polyval(self.tracking_weight[1], s))
        wf = np.abs(
            np.polyval(self.feedthrough_weight[0], s) / np.polyval(self.feedthrough_weight[1], s)
        )
        above = np.asarray(omega, float) > 2 * math.pi * self.split_hz
        # (r0: the deviation of the uncompensated loop at reference_k_psf)
        return np.where(above, np.maximum(wt, wf * np.abs(r0)), wt)

    def region(self) -> Region:
        """The pole region: ``Region(decay_rate, min_damping, damping_band_hz)``."""
        return Region(self.decay_rate, self.min_damping, self.damping_band_hz)

    def limits(self) -> DeviceLimits:
        """Device limits with this specification's two force limits (the others default)."""
        return DeviceLimits(
            peak_force_n=self.peak_force_n, continuous_force_n=self.continuous_force_n
        )

    def check_frequencies_hz(self) -> np.ndarray:
        """The design grid of the intent-response bounds, Hz.

        For designs that optimise or choose on frequencies (the limit map, the scheduled
        damper); the checks themselves (:func:`deviation_checks`) hold at every frequency.

        Returns
        -------
        numpy.ndarray
            :data:`N_TRACKING_FREQS` from 0 Hz, then log-spaced from 0.01 Hz (or a fifth
            of the tracking band's bottom) up to :attr:`split_hz`, then
            :data:`N_FEEDTHROUGH_FREQS` from :attr:`split_hz` up to :data:`GRID_TOP_HZ`,
            log-spaced, with a third of them
            linearly spaced over ``feedthrough_band_hz``; read-only, made once per pair of
            bands.
        """
        return _check_grid(tuple(self.tracking_band_hz), tuple(self.feedthrough_band_hz))

    def to_json(self) -> dict:
        """Every field, JSON-ready (bands as lists)."""
        return to_jsonable(self)


def _band(name: str, value) -> tuple[float, float]:
    label = f"Specification.{name}"
    if isinstance(value, (str, bytes)):
        raise ParameterError(f"{label} must be a pair (low, high) in Hz; got {value!r}")
    arr = check_vector(label, value, POSITIVE, min_size=2, increasing=True)
    if arr.size != 2:
        raise ParameterError(f"{label} must be a pair (low, high) in Hz; got {value!r}")
    return float(arr[0]), float(arr[1])


#: Top of the design grids, Hz (the checks themselves have no top).
GRID_TOP_HZ = 1000.0


@functools.lru_cache(maxsize=16)
def _check_grid(tracking_band_hz: tuple, feedthrough_band_hz: tuple) -> np.ndarray:
    """:meth:`Specification.check_frequencies_hz` of a pair of bands."""
    split = tracking_band_hz[1]
    # from DC (where the deviation of a loop with integral action is decided) up to the split
    lo = min(0.01, tracking_band_hz[0] / 5)
    ft = np.concatenate([[0.0], np.geomspace(lo, split, N_TRACKING_FREQS - 1, endpoint=False)])
    n_band = N_FEEDTHROUGH_FREQS // 3
    fb = np.sort(
        np.concatenate(
            [
                np.geomspace(split, GRID_TOP_HZ, N_FEEDTHROUGH_FREQS - n_band),
                np.linspace(*feedthrough_band_hz, n_band),
            ]
        )
    )
    grid = np.concatenate([ft, fb])
    grid.setflags(write=False)
    return grid
