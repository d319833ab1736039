"""The calibration record: how it is taken, what it holds, and its simulation.

:class:`CalibrationProtocol` (how the rig shakes the cab and records),
:class:`CalibrationRecord` (the excitation, the encoder's handle position and the
accelerometer's cab acceleration), :class:`OperatorEstimate` (what a fit returns, with its
error bound of :data:`BOUND_SIGMAS` standard deviations), :func:`simulate_calibration`
(step 1 of :mod:`designs.calibration`) and :func:`excitation_responses`, the frequency
responses estimated through the excitation (step 2). The operator's and the cab's fits
both start from these, apart from the models they fit.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import scipy.signal as sig

from backhoe.analysis.simulation import lifted_response
from backhoe.model.wiring import connect
from designs.limit_plant import ACCEL_NOISE_RMS, ENCODER_MM
from designs.specification import Specification
from robust.checks import POSITIVE, Spec, validate_fields
from robust.errors import DataError, ParameterError
from robust.sysid.spectral import estimate_frequency_responses

__all__ = [
    "BOUND_SIGMAS",
    "CalibrationProtocol",
    "CalibrationRecord",
    "OperatorEstimate",
    "simulate_calibration",
    "excitation_responses",
]


#: Standard deviations of the error bound.
BOUND_SIGMAS = 3.0


@dataclasses.dataclass(frozen=True)
class CalibrationProtocol:
    """How the calibration record is taken (every field changes the estimate; all reported).

    Parameters
    ----------
    duration_s : float
        Length of the record, s (a calibration an operator sits through: 30-60 s).
    fs_hz : float
        Sampling rate (the servo rate), Hz.
    excitation_band_hz : tuple of float
        Pass band of the excitation added to the cylinder reference, Hz.
    excitation_fraction : float
        RMS of the excitation as a fraction of the realistic intended motion's RMS
        (``A / sqrt(2)``, ``A`` the specification's intended amplitude), in reference units
        (times ``K_PSF``): the stick moves about this much less than in operation.
    remnant_fraction : float
        RMS of the operator's involuntary motion while holding, as a fraction of the
        intended motion's RMS (an assumption: a relaxed grip on a still handle).
    band_hz : tuple of float
        Band of the fit, Hz.
    nperseg : int
        Segment length of the spectral estimates, samples (16384: 0.06 Hz resolution, six
        Hann segments with half overlap in 60 s; halving it doubles the frequencies' error
        through the leakage at the lightly damped modes, and the cancellation built from the
        estimate then covers 63 % instead of 74 % of 150 members).
    encoder_mm : float
        Encoder resolution, mm.
    accel_rms : float
        Accelerometer noise RMS (the paper's units of ``c``).
    """

    duration_s: float = 60.0
    fs_hz: float = 1000.0
    excitation_band_hz: tuple = (0.3, 15.0)
    excitation_fraction: float = 0.5
    remnant_fraction: float = 0.05
    band_hz: tuple = (0.5, 12.0)
    nperseg: int = 16384
    encoder_mm: float = ENCODER_MM
    accel_rms: float = ACCEL_NOISE_RMS

    def __post_init__(self):
        validate_fields(
            self,
            {
                "duration_s": POSITIVE,
                "fs_hz": POSITIVE,
                "excitation_fraction": POSITIVE,
                "remnant_fraction": Spec(0.0, math.inf, False, False),
                "encoder_mm": Spec(0.0, math.inf, False, False),
                "accel_rms": Spec(0.0, math.inf, False, False),
            },
        )
        check_record_timing(self)


def check_record_timing(protocol) -> None:
    """Check a record protocol's bands and segment length, naming the protocol's class.

    ``excitation_band_hz`` and ``band_hz`` must satisfy ``0 < low < high < fs/2`` (stored
    back as float pairs); ``nperseg`` must be an integer leaving at least two segments in
    ``duration_s * fs_hz`` samples.

    Raises
    ------
    robust.errors.ParameterError
        Naming the field, what was expected and what was got.
    """
    owner = type(protocol).__name__
    for name in ("excitation_band_hz", "band_hz"):
        lo, hi = (float(v) for v in getattr(protocol, name))
        if not (0 < lo < hi < protocol.fs_hz / 2):
            raise ParameterError(
                f"{owner}.{name} must be 0 < low < high < fs/2 = "
                f"{protocol.fs_hz / 2:g} Hz; got {getattr(protocol, name)!r}"
            )
        object.__setattr__(protocol, name, (lo, hi))
    n = int(round(protocol.duration_s * protocol.fs_hz))
    if isinstance(protocol.nperseg, bool) or not 64 <= int(protocol.nperseg) <= n // 2:
        raise ParameterError(
            f"{owner}.nperseg must be an integer in [64, {n // 2}] (at least two segments in "
            f"the record); got {protocol.nperseg!r}"
        )


@dataclasses.dataclass(frozen=True)
class CalibrationRecord:
    """One simulated calibration record (what the rig would store).

    Parameters
    ----------
    r : numpy.ndarray
        Excitation added to the cylinder reference (known exactly).
    x : numpy.ndarray
        Handle position through the encoder, handle units.
    c : numpy.ndarray
        Cab acceleration through the accelerometer, the paper's units.
    fs_hz : float
        Sampling rate, Hz.
    seed : int
        Seed of the excitation, the remnant and the accelerometer noise.
    """

    r: np.ndarray
    x: np.ndarray
    c: np.ndarray
    fs_hz: float
    seed: int


@dataclasses.dataclass(frozen=True)
class OperatorEstimate:
    """What the calibration tells of the operator.

    Parameters
    ----------
    values : dict
        :data:`IDENTIFIED` -> estimate.
    bounds : dict
        :data:`IDENTIFIED` -> ``(low, high)``: the error bound (:data:`BOUND_SIGMAS`
        standard deviations; relative for the positive parameters).
    sigma : dict
        :data:`IDENTIFIED` -> standard deviation in the fit coordinate (of the logarithm
        for the positive parameters, so a relative error).
    residual_rms : float
        RMS of the weighted residual at the solution (about 1 when the model explains the
        estimate to within its noise).
    f_hz : numpy.ndarray
        Frequencies of the fit, Hz.
    measured : numpy.ndarray of complex
        The estimate ``x / c`` at ``f_hz``.
    fitted : numpy.ndarray of complex
        The fitted model at ``f_hz``.
    coherence : numpy.ndarray
        The smaller of the two coherences at ``f_hz``.
    covariance : numpy.ndarray, optional
        Covariance of the estimate in the fit coordinates (logarithms of the positive
        parameters), the quantities' order: the joint error region
        (:func:`confidence_points`).
    weights : numpy.ndarray, optional
        The fit's weight at each of ``f_hz`` (inverse standard deviation of the estimate's
        logarithm).
    residual_variance : float, optional
        The weighted residual's variance per degree of freedom, at least 1 (the factor of
        the covariance; a model error raises it).
    """

    values: dict
    bounds: dict
    sigma: dict
    residual_rms: float
    f_hz: np.ndarray
    measured: np.ndarray
    fitted: np.ndarray
    coherence: np.ndarray
    covariance: np.ndarray | None = None
    weights: np.ndarray | None = None
    residual_variance: float | None = None

    def contains(self, truth: dict) -> dict:
        """Per identified quantity: whether ``truth`` lies within the bound."""
        return {k: bool(lo <= truth[k] <= hi) for k, (lo, hi) in self.bounds.items()}

    def to_json(self) -> dict:
        """Estimate, bounds and fit quality, JSON-ready."""
        return {
            "values": dict(self.values),
            "bounds": {k: list(v) for k, v in self.bounds.items()},
            "sigma": dict(self.sigma),
            "bound_sigmas": BOUND_SIGMAS,
            "residual_rms": self.residual_rms,
            "covariance": None if self.covariance is None else self.covariance.tolist(),
        }


@functools.lru_cache(maxsize=16)
def _butterworth(lo: float, hi: float, fs: float) -> np.ndarray:
    """Second-order sections of the 4th-order Butterworth band pass (low pass if ``lo`` is 0),
    designed once per band (every member's record uses the same two; 1 ms each)."""
    if lo > 0:
        sos = sig.butter(4, (lo, hi), btype="bandpass", fs=fs, output="sos")
    else:
        sos = sig.butter(4, hi, btype="lowpass", fs=fs, output="sos")
    sos.flags.writeable = False
    return sos


def _band_noise(rng, n, fs, band, rms):
    """Gaussian noise through a 4th-order Butterworth band (or low) pass, scaled to ``rms``."""
    w = rng.standard_normal(n + 4096)
    # a copy: sosfilt takes a writable array
    sos = _butterworth(float(band[0]), float(band[1]), float(fs)).copy()
    y = sig.sosfilt(sos, w)[4096:]
    return y * (rms / max(float(np.std(y)), 1e-300))


def simulate_calibration(
    loop, protocol: CalibrationProtocol | None = None, *, seed: int = 0
) -> CalibrationRecord:
    """The calibration record of one operator on one machine (module notes, step 1).

    Parameters
    ----------
    loop : backhoe.model.loop.BDFTLoop
        The member (operator and machine); no compensator is in the loop.
    protocol : CalibrationProtocol, optional
    seed : int
        Seed of the excitation, the remnant and the accelerometer noise.

    Returns
    -------
    CalibrationRecord
    """
    pr = protocol or CalibrationProtocol()
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"simulate_calibration: seed must be an integer >= 0; got {seed!r}")
    rng = np.random.default_rng(int(seed))
    fs, n = pr.fs_hz, int(round(pr.duration_s * pr.fs_hz))
    spec = Specification()
    amp = loop.intended_amplitude(spec.limits(), spec.intent_fraction)
    rms_u = amp / math.sqrt(2.0)
    r = _band_noise(rng, n, fs, pr.excitation_band_hz, pr.excitation_fraction * loop.k_psf * rms_u)
    u = (
        _band_noise(rng, n, fs, (0.0, spec.intent_bandwidth_hz), pr.remnant_fraction * rms_u)
        if pr.remnant_fraction > 0
        else np.zeros(n)
    )
    # calibration mode: the handle does not command the stick (no BDFT loop to go
    # unstable); the machine's excitation drives the cylinder, the cab and the hand
    blocks = loop.blocks(bdft=False, reference_correction=True)
    blocks += [loop.structure_system(), loop.human_system()]
    P = connect(
        blocks,
        inputs=["u", "r_corr"],
        outputs=["c", "h"],
        name="calibration",
        ignore_inputs=["f"] if loop.human.has_force_port else [],
    )
    Ad, Bd, Cd, Dd, _ = sig.cont2discrete((P.A, P.B[:, [1]], P.C, P.D[:, [1]]), 1.0 / fs)
    # both outputs in one pass (the same numbers as one call per output row)
    c, h = lifted_response(Ad, Bd[:, 0], Cd, Dd[:, 0], r)
    x = u + loop.handle_gain * h
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(c))):
        raise DataError(
            "simulate_calibration: the loop's response is not finite (unstable member?)"
        )
    if pr.encoder_mm > 0:
        q = pr.encoder_mm * 1e-3 * loop.handle_units_per_m()
        x = q * np.round(x / q)
    c = c + pr.accel_rms * rng.standard_normal(n)
    return CalibrationRecord(r=r, x=x, c=c, fs_hz=fs, seed=int(seed))


def excitation_responses(
    record: CalibrationRecord, protocol: CalibrationProtocol | None = None
) -> tuple:
    """The record's two H1 estimates with the excitation as input, and the fitted band.

    What :func:`identify_operator` and :func:`identify_cab` both start from; computed
    once (the excitation's segments transformed once,
    :func:`robust.sysid.spectral.estimate_frequency_responses`) and passed to both.

    Parameters
    ----------
    record : CalibrationRecord
        The record.
    protocol : CalibrationProtocol, optional
        Its protocol (the band and segment length).

    Returns
    -------
    tuple
        ``(excitation -> handle, excitation -> cab, band mask)``: two
        :class:`robust.sysid.spectral.FrequencyResponseEstimate` and a boolean array over
        their frequencies.

    Raises
    ------
    robust.errors.DataError
        If a channel of the record is not a finite 1-D array.
    """
    return _excitation_responses(record, protocol or CalibrationProtocol(), "excitation_responses")


def _excitation_responses(record, pr, where):
    """The two H1 estimates with the excitation as input (to the handle, to the cab)."""
    for name in ("r", "x", "c"):
        a = np.asarray(getattr(record, name), float)
        if a.ndim != 1 or not np.all(np.isfinite(a)):
            raise DataError(f"{where}: record.{name} must be a finite 1-D array")
    nseg = min(pr.nperseg, record.r.size // 2)
    ex, ec = estimate_frequency_responses(
        record.r, [record.x, record.c], record.fs_hz, nperseg=nseg
    )
    band = (ex.f_hz >= pr.band_hz[0]) & (ex.f_hz <= pr.band_hz[1])
    return ex, ec, band


def _coherent(coh, pr, where, n_params: int = 4):
    good = coh > 0.2
    if good.sum() < 3 * n_params:
        raise DataError(
            f"{where}: only {int(good.sum())} frequencies in {pr.band_hz} Hz have a "
            "coherence above 0.2; the record is too short or too noisy"
        )
    return good
