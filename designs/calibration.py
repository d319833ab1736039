"""The operator's calibration: a short record of holding the handle while the cab shakes.

A scheduled compensator needs to know the operator in front of it. This module simulates
the calibration a rig would run and identifies, from the record alone, what of the
operator it can tell, with an error bound:

1. **Record** (:func:`simulate_calibration`). The operator holds the handle still; the
   machine shakes its own cab by adding a band-limited random signal ``r`` to the
   cylinder reference (no compensator in the loop). Recorded at the 1 kHz servo rate: the
   excitation ``r`` (known exactly: the rig generates it), the handle position through
   the Omni's encoder (quantised to :data:`designs.limit.ENCODER_MM`) and the cab
   acceleration through an accelerometer (white noise of RMS
   :data:`designs.limit.ACCEL_NOISE_RMS`). The operator is not perfectly still: an
   involuntary motion (the remnant, :attr:`CalibrationProtocol.remnant_fraction` of the
   intended motion's RMS, low-pass at 2 Hz) adds to the handle.
2. **Frequency response** (:func:`identify_operator`). The hand's response to the cab,
   ``x / c``, is estimated through the excitation: ``H = G_rx / G_rc``, the ratio of two
   H1 estimates of :func:`robust.sysid.spectral.estimate_frequency_response` with ``r``
   as input. Since ``r`` is uncorrelated with the remnant and the sensor noise, the
   ratio is unbiased where a direct ``c -> x`` estimate would not be: in the closed
   loop the remnant moves the cab too, and the accelerometer noise sits on the input
   (the joint input-output / indirect approach of closed-loop identification; Ljung,
   *System Identification*, 2nd ed., 1999, Sec. 13.5; Pintelon & Schoukens, *System
   Identification: A Frequency Domain Approach*, 2nd ed., 2012, Ch. 2).
3. **Physical fit**. What the record can tell: seat acceleration drives the hand through
   the seated 2-DOF chain (:mod:`robust.model.physical`), whose response depends on the
   arm-to-trunk mass ratio and the four modal parameters only (the stiffnesses and
   dampings follow the masses, :func:`robust.model.modal.modal_to_physical`), not on the
   masses themselves; fitted beside the four, the mass ratio (an arm of 0.5-3 kg on an
   upper body of 25-55 kg) is all but unidentifiable from a 40-60 s record (its standard
   deviation came out larger than itself), so it is held at the family's nominal ratio
   (its effect enters the error bound, step 4). The response is
   symmetric in the two modes: at a vanishing mass ratio ``h/c = -(D_a + N_t) / (D_t
   D_a)`` with ``D_i = s^2 + 2 zeta_i w_i s + w_i^2`` and ``N_i = 2 zeta_i w_i s + w_i^2``,
   whose numerator ``D_a + N_t = D_t + N_a``, and swapping the pairs leaves it unchanged
   at any mass ratio (the trunk's stiffness carries both masses; checked in the tests):
   the record tells the two modes, not which is the arm's. The fit therefore estimates
   :data:`IDENTIFIED`, the two (natural frequency, damping ratio) pairs ordered by
   frequency, by weighted nonlinear least squares of the complex log-ratio of model
   and estimate over :attr:`CalibrationProtocol.band_hz` (weights: the inverse variance
   of the estimate from the coherences, Bendat & Piersol, *Random Data*, 4th ed., 2010,
   Sec. 9.2), from several starts, within the family's ranges of both pairs. The
   residual (real parts of the log-ratio, then its phases) and its Jacobian are compiled
   loops over the frequencies (Numba; the same closed forms as :func:`human_response`,
   :func:`human_log_derivatives`, :func:`cab_response` and :func:`cab_log_derivatives`,
   tested equal to rounding): a residual and a Jacobian take about 10 us each where the
   NumPy expressions of a single member took 55 and 140 us, most of it the overhead of
   small arrays.
4. **Error bound**. The covariance of the estimate is ``s^2 (J' W J)^-1`` at the
   solution (``J`` the Jacobian in the fit coordinates, ``s^2`` the residual variance
   per degree of freedom, at least 1, so a model error widens it). The bound of each
   parameter is :data:`BOUND_SIGMAS` standard deviations (in logarithms for the natural
   frequencies: a relative bound) plus the largest shift of the estimate that the held
   mass ratio can cause over the family's range (the Gauss-Newton step of the residual's
   change at either end of the range); the calibration test measures how often the
   truth lies inside.
5. **The cab** (:func:`identify_cab`). The same record tells the machine too: the cab's
   acceleration per excitation, divided by the machine's cylinder loop (known: it measures
   the cylinder position), is the structure's response, fitted for its gain and its two
   modes (:data:`CAB_IDENTIFIED`).
6. **Joint error region** (:func:`region_points`, :func:`response_distance`). The
   marginal bounds of step 4 take each quantity alone; the estimate's errors are
   correlated (the two modes trade damping for frequency), and the bounds' mass term
   moves the modes without moving the hand's response (the fit compensates the held
   ratio). What a compensator built from the estimate has to withstand is the region of
   estimates the record allows: along each principal axis of the covariance, as far as
   the fitted hand response moves :data:`REGION_RADIUS` standard deviations (4.03, the
   99.73 % region of four quantities: the probability of the marginal 3 sigma), the
   likelihood region of the nonlinear fit. Its centre, in simulation, is what the same
   record without its noise identifies (:func:`noise_free_estimate`): the estimate lies
   within 4.03 of it for 98 % of 200 seeded operators (within 3 for 93 %; a Gaussian
   estimate: 99.73 % and 94 %). Where the two modes nearly coincide, the covariance's
   ellipsoid reaches estimates whose responses lie tens of standard deviations from the
   record's, which the likelihood region excludes.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math

import numba
import numpy as np
import scipy.optimize as sopt
import scipy.signal as sig
from scipy.stats import chi2

from designs.limit import ACCEL_NOISE_RMS, ENCODER_MM
from designs.specification import Specification
from robust.analysis.simulation import lifted_response
from robust.checks import POSITIVE, Spec, validate_fields
from robust.errors import DataError, ParameterError
from robust.model.blocks import parameter_name
from robust.model.modal import physical_to_modal
from robust.model.wiring import connect
from robust.sysid.levenberg import levenberg_marquardt
from robust.sysid.spectral import estimate_frequency_responses
from uncertainty import default_family

__all__ = [
    "IDENTIFIED",
    "BOUND_SIGMAS",
    "REGION_RADIUS",
    "CalibrationProtocol",
    "CalibrationRecord",
    "OperatorEstimate",
    "simulate_calibration",
    "identify_operator",
    "excitation_responses",
    "operator_truth",
    "human_response",
    "human_log_derivatives",
    "operator_row",
    "OPERATOR_NAMES",
    "LOG_AXES",
    "identified_ranges",
    "CAB_IDENTIFIED",
    "CAB_LOG_AXES",
    "cab_response",
    "cab_log_derivatives",
    "cab_truth",
    "identify_cab",
    "noise_free_estimate",
    "confidence_points",
    "response_distance",
    "region_points",
]

#: What the calibration identifies (module notes, step 3).
IDENTIFIED = ("f_low_hz", "zeta_low", "f_high_hz", "zeta_high")
#: Natural frequencies fitted in logarithms (relative errors), damping ratios linearly.
LOG_AXES = (True, False, True, False)
#: Standard deviations of the error bound.
BOUND_SIGMAS = 3.0
#: Radius of the joint error region (:func:`region_points`), in standard deviations: the
#: region that holds four Gaussian quantities with the probability of one within
#: :data:`BOUND_SIGMAS` (99.73 %), 4.03.
REGION_RADIUS = float(math.sqrt(chi2.ppf(chi2.cdf(BOUND_SIGMAS**2, 1), 4)))


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
        for name in ("excitation_band_hz", "band_hz"):
            lo, hi = (float(v) for v in getattr(self, name))
            if not (0 < lo < hi < self.fs_hz / 2):
                raise ParameterError(
                    f"CalibrationProtocol.{name} must be 0 < low < high < fs/2 = "
                    f"{self.fs_hz / 2:g} Hz; got {getattr(self, name)!r}"
                )
            object.__setattr__(self, name, (lo, hi))
        n = int(round(self.duration_s * self.fs_hz))
        if isinstance(self.nperseg, bool) or not 64 <= int(self.nperseg) <= n // 2:
            raise ParameterError(
                f"CalibrationProtocol.nperseg must be an integer in [64, {n // 2}] (at least "
                f"two segments in the record); got {self.nperseg!r}"
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


def operator_truth(family, row) -> dict:
    """The identifiable quantities (:data:`IDENTIFIED`) of one member of ``family``.

    Parameters
    ----------
    family : uncertainty.Family
        A family with the physical human.
    row : array_like
        The member's parameter values (columns of ``family.names``).
    """
    if family.human != "physical":
        raise ParameterError(
            f"operator_truth: the calibration identifies the physical human; got {family.human!r}"
        )
    a = family.model_arrays(np.atleast_2d(np.asarray(row, float)), check_bounds=False)
    mt, ma = a[parameter_name("human", "m_trunk")][0], a[parameter_name("human", "m_arm")][0]
    f_t, z_t, f_a, z_a = physical_to_modal(
        mt,
        ma,
        a[parameter_name("human", "k_trunk")][0],
        a[parameter_name("human", "c_trunk")][0],
        a[parameter_name("human", "k_arm")][0],
        a[parameter_name("human", "c_arm")][0],
    )
    return dict(zip(IDENTIFIED, _ordered(np.array([f_a, z_a, f_t, z_t], float)).tolist()))


def _ordered(v: np.ndarray) -> np.ndarray:
    """(f_a, zeta_a, f_t, zeta_t) -> the two pairs ordered by frequency."""
    return v if v[0] <= v[2] else v[[2, 3, 0, 1]]


def human_response(
    family, theta: np.ndarray, f_hz: np.ndarray, handle_gain: float, mass_ratio=None
) -> np.ndarray:
    """The hand's response to the cab ``x / c`` for rows of modal parameters.

    In closed form: the seated chain's transfer function from seat acceleration to hand
    motion is ``-c_u g (s^2 + d_3 s + R (w_a^2 + w_t^2)) / D(s)``, ``D`` its characteristic
    quartic with ``d_3 = R (s_a + s_t)``, ``d_2 = R (w_a^2 + w_t^2 + s_a s_t)``, ``d_1 = R
    (s_a w_t^2 + s_t w_a^2)``, ``d_0 = R w_a^2 w_t^2`` (``s_i = 2 zeta_i w_i``, ``R = 1 +``
    the mass ratio; :mod:`uncertainty.valueset`), equal to the state-space model of
    :func:`robust.model.physical.physical_human_matrices` to rounding (tested) and a tenth
    of its cost.

    Parameters
    ----------
    family : uncertainty.Family
        Gives the nominal masses (their ratio is held), ``h_gain`` and ``c_unit``.
    theta : ndarray, shape (N, 4)
        Rows of (f_arm_hz, zeta_arm, f_trunk_hz, zeta_trunk).
    mass_ratio : float, optional
        Arm-endpoint over upper-body mass (default: the family's nominal).
    f_hz : ndarray, shape (F,)
        Frequencies, Hz.
    handle_gain : float
        ``sigma * kappa`` of the loop (handle units per unit of ``h``).

    Returns
    -------
    ndarray of complex, shape (N, F)
    """
    th = np.atleast_2d(np.asarray(theta, float))
    p = family.physical
    big_r = 1.0 + (p.m_arm / p.m_trunk if mass_ratio is None else float(mass_ratio))
    wa, wt = 2 * np.pi * th[:, 0:1], 2 * np.pi * th[:, 2:3]
    sa, st = 2 * th[:, 1:2] * wa, 2 * th[:, 3:4] * wt
    wa2, wt2 = wa * wa, wt * wt
    d3 = big_r * (sa + st)
    d2 = big_r * (wa2 + wt2 + sa * st)
    d1 = big_r * (sa * wt2 + st * wa2)
    d0 = big_r * wa2 * wt2
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    den = (((s + d3) * s + d2) * s + d1) * s + d0
    num = (s + d3) * s + big_r * (wa2 + wt2)
    return (-handle_gain * p.c_unit * p.h_gain) * num / den


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


def human_log_derivatives(family, theta: np.ndarray, f_hz: np.ndarray) -> np.ndarray:
    """Derivatives of ``log`` :func:`human_response` in its modal parameters, analytically.

    With ``num`` and ``D`` as in :func:`human_response`, ``d log(x/c) = d num / num - dD / D``;
    the coefficients ``d_3 ... d_0`` and ``num``'s constant are polynomials in ``w_a, s_a,
    w_t, s_t`` (``s_i = 2 zeta_i w_i``), differentiated term by term. The gain and the held
    mass ratio do not depend on the parameters.

    Parameters
    ----------
    family : uncertainty.Family
        Gives the nominal mass ratio (held).
    theta : ndarray, shape (N, 4)
        Rows of (f_arm_hz, zeta_arm, f_trunk_hz, zeta_trunk).
    f_hz : ndarray, shape (F,)
        Frequencies, Hz.

    Returns
    -------
    ndarray of complex, shape (N, F, 4)
        ``d log(x/c) / d theta_k`` (per Hz for the frequencies).
    """
    th = np.atleast_2d(np.asarray(theta, float))
    p = family.physical
    big_r = 1.0 + p.m_arm / p.m_trunk
    wa, wt = 2 * np.pi * th[:, 0:1], 2 * np.pi * th[:, 2:3]
    sa, st = 2 * th[:, 1:2] * wa, 2 * th[:, 3:4] * wt
    wa2, wt2 = wa * wa, wt * wt
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    d3 = big_r * (sa + st)
    num = (s + d3) * s + big_r * (wa2 + wt2)
    den = (((s + d3) * s + big_r * (wa2 + wt2 + sa * st)) * s + big_r * (sa * wt2 + st * wa2)) * s
    den = den + big_r * wa2 * wt2

    def dlog(e3, e2, e1, e0, ec):
        # the log-derivative for coefficient derivatives (d3, d2, d1, d0, num's constant)
        return (e3 * s + ec) / num - (((e3 * s + e2) * s + e1) * s + e0) / den

    zero = np.zeros_like(wa)
    # per primitive variable: w_a, s_a, w_t, s_t
    d_wa = dlog(zero, 2 * big_r * wa, 2 * big_r * st * wa, 2 * big_r * wa * wt2, 2 * big_r * wa)
    d_sa = dlog(big_r + zero, big_r * st, big_r * wt2, zero, zero)
    d_wt = dlog(zero, 2 * big_r * wt, 2 * big_r * sa * wt, 2 * big_r * wt * wa2, 2 * big_r * wt)
    d_st = dlog(big_r + zero, big_r * sa, big_r * wa2, zero, zero)
    za, zt = th[:, 1:2], th[:, 3:4]
    return np.stack(
        [
            2 * np.pi * (d_wa + 2 * za * d_sa),  # d/d f_arm_hz (s_a moves with w_a)
            2 * wa * d_sa,
            2 * np.pi * (d_wt + 2 * zt * d_st),
            2 * wt * d_st,
        ],
        axis=-1,
    )


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
    loop : robust.model.loop.BDFTLoop
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


def _coords(theta, log=LOG_AXES):
    return np.where(log, np.log(np.where(log, theta, 1.0)), theta)


def _values(z, log=LOG_AXES):
    return np.where(log, np.exp(np.where(log, z, 0.0)), z)


def identified_ranges(family):
    """Ranges of the identified quantities and of the held mass ratio over ``family``.

    Parameters
    ----------
    family : uncertainty.Family
        A family with the physical human.

    Returns
    -------
    (low, high, ratio)
        ``low`` and ``high`` (arrays of 4) bound each pair's natural frequency and damping
        ratio, the same for both pairs (their labels are not identifiable: each spans the
        arm's and the trunk's ranges together); ``ratio`` the arm-to-trunk mass ratio's
        ``(low, high)``.
    """
    p = {q.name: q for q in family.parameters}
    ph = family.physical

    def rng_of(name, default):
        q = p.get(name)
        return (q.low, q.high) if q is not None else (default, default)

    fa, ft = (
        rng_of(parameter_name("human", "f_arm_hz"), ph.f_arm_hz),
        rng_of(parameter_name("human", "f_trunk_hz"), ph.f_trunk_hz),
    )
    za, zt = (
        rng_of(parameter_name("human", "zeta_arm"), ph.zeta_arm),
        rng_of(parameter_name("human", "zeta_trunk"), ph.zeta_trunk),
    )
    f_lo, f_hi = min(fa[0], ft[0]), max(fa[1], ft[1])
    z_lo, z_hi = min(za[0], zt[0]), max(za[1], zt[1])
    if f_hi <= f_lo:
        f_lo, f_hi = f_lo / 2, f_hi * 2
    if z_hi <= z_lo:
        z_lo, z_hi = max(z_lo / 2, 1e-3), min(z_hi * 2, 0.99)
    bm = rng_of(parameter_name("human", "body_mass"), family.body_mass)
    ma = rng_of(parameter_name("human", "m_arm"), ph.m_arm)
    mt_lo, mt_hi = ph.m_trunk * bm[0] / family.body_mass, ph.m_trunk * bm[1] / family.body_mass
    ratio = (ma[0] / mt_hi, ma[1] / mt_lo)
    lo = np.array([f_lo, z_lo, f_lo, z_lo])
    hi = np.array([f_hi, z_hi, f_hi, z_hi])
    return lo, hi, ratio


def identify_operator(
    record: CalibrationRecord,
    family,
    handle_gain: float,
    protocol: CalibrationProtocol | None = None,
    *,
    responses: tuple | None = None,
) -> OperatorEstimate:
    """Estimate :data:`IDENTIFIED` with an error bound from one record (module notes).

    Parameters
    ----------
    record : CalibrationRecord
        The record (:func:`simulate_calibration`, or a rig's, in the same units).
    family : uncertainty.Family
        The family whose ranges bound the fit (physical human).
    handle_gain : float
        ``sigma * kappa`` of the loop (:attr:`robust.model.loop.BDFTLoop.handle_gain`).
    protocol : CalibrationProtocol, optional
        The protocol the record was taken with (its band and segment length).
    responses : tuple, optional
        :func:`excitation_responses` of this record and protocol, when already computed
        (:func:`identify_cab` uses the same).

    Returns
    -------
    OperatorEstimate

    Raises
    ------
    robust.errors.DataError
        If the record holds NaN or infinite values, or too little coherent data in the band.
    """
    pr = protocol or CalibrationProtocol()
    ex, ec, band = responses or _excitation_responses(record, pr, "identify_operator")
    f = ex.f_hz[band]
    H = ex.g_uy[band] / ec.g_uy[band]
    gx, gc = ex.coherence[band], ec.coherence[band]
    coh = np.minimum(gx, gc)
    # variance of log H: the two H1 estimates' relative variances add (Bendat & Piersol)
    n_d = min(ex.n_effective, ec.n_effective)
    var = sum((1 - g) / (2 * n_d * np.maximum(g, 1e-6)) for g in (gx, gc))
    good = _coherent(coh, pr, "identify_operator")
    f, H, var, coh_g = f[good], H[good], var[good], coh[good]
    w = 1.0 / np.sqrt(var)
    z, cov, half, best, s2 = _operator_fit(family, f, H, w, handle_gain)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    vals, b_lo, b_hi = _values(z), _values(z - half), _values(z + half)
    return OperatorEstimate(
        values={k: float(v) for k, v in zip(IDENTIFIED, vals)},
        bounds={k: (float(a), float(b)) for k, a, b in zip(IDENTIFIED, b_lo, b_hi)},
        sigma={k: float(v) for k, v in zip(IDENTIFIED, sd)},
        residual_rms=float(math.sqrt(2.0 * best.cost / (2 * f.size))),
        f_hz=f,
        measured=H,
        fitted=human_response(family, vals[None, :], f, handle_gain)[0],
        coherence=coh_g,
        covariance=cov,
        weights=w,
        residual_variance=s2,
    )


def _operator_fit(family, f, H, w, handle_gain, start=None):
    """The weighted fit of :func:`identify_operator` (module notes, steps 3-4).

    From the grid of starts, or from ``start`` alone (values of :data:`IDENTIFIED`).

    Returns
    -------
    (z, covariance, half, result, s2)
        The estimate in the fit coordinates (:data:`IDENTIFIED`, ordered by frequency),
        its covariance there, the error bound's half-widths, the least-squares result, the
        residual variance per degree of freedom (at least 1).
    """
    lo, hi, ratio = identified_ranges(family)
    zlo, zhi = _coords(lo), _coords(hi)
    p = family.physical
    gain = -handle_gain * p.c_unit * p.h_gain
    r_nom = 1.0 + p.m_arm / p.m_trunk
    f, w = np.ascontiguousarray(f, float), np.ascontiguousarray(w, float)
    H = np.ascontiguousarray(H, complex)

    def resid(z, mass_ratio=None):
        big_r = r_nom if mass_ratio is None else 1.0 + float(mass_ratio)
        return _human_residual(np.asarray(z, float), f, H, w, big_r, gain)

    if start is not None:
        starts = [np.clip(_coords(np.asarray(start, float)), zlo, zhi)]
    else:  # a grid over the two natural frequencies, the lower pair's below the upper's
        starts = []
        grid = itertools.product(np.geomspace(lo[0], hi[0], 4), np.geomspace(lo[2], hi[2], 4))
        for fa, ft in grid:
            if ft >= fa:
                z0 = 0.5 * (zlo + zhi)
                z0[0], z0[2] = math.log(fa), math.log(ft)
                starts.append(np.clip(z0, zlo, zhi))

    def jacobian(z):
        return _human_jacobian(np.asarray(z, float), f, w, r_nom)

    best, J, JtJ_inv, cov, s2 = _fit(resid, jacobian, starts, zlo, zhi, f.size)
    z = best.x
    # the held mass ratio: the estimate's shift if the ratio were at either end of its range
    r0 = resid(z)
    shift = np.zeros(z.size)
    for mu in ratio:
        dr = resid(z, mu) - r0
        shift = np.maximum(shift, np.abs(JtJ_inv @ (J.T @ dr)))
    half = BOUND_SIGMAS * np.sqrt(np.maximum(np.diag(cov), 0.0)) + shift
    order = [0, 1, 2, 3] if _values(z)[0] <= _values(z)[2] else [2, 3, 0, 1]
    return z[order], cov[np.ix_(order, order)], half[order], best, s2


def noise_free_estimate(
    loop,
    family,
    estimate: OperatorEstimate,
    protocol: CalibrationProtocol | None = None,
    *,
    seed: int,
) -> np.ndarray:
    """What the calibration would identify from the same record without its noise.

    The record of ``loop`` is simulated again with the same excitation (``seed``) but
    without the operator's involuntary motion, the encoder's quantisation and the
    accelerometer's noise, and its ratio of H1 estimates fitted as ``estimate`` was (its
    frequencies and weights, :func:`identify_operator`), from ``estimate``. The estimate's distance
    to it is the calibration's statistical error, which the estimate's covariance
    describes. Its own distance to the member's true modes is the fit's bias: the mass
    ratio held at the nominal and the spectral estimate's leakage, which move the modes but
    leave the fitted hand response (what a cancellation is built from) close to the
    member's. A simulation's quantity: a rig has no noise-free record.

    Parameters
    ----------
    loop : robust.model.loop.BDFTLoop
        The member the record was taken on.
    family : uncertainty.Family
        The family ``estimate`` was fitted within.
    estimate : OperatorEstimate
        :func:`identify_operator`'s estimate from the noisy record (with its weights).
    protocol : CalibrationProtocol, optional
        The record's protocol.
    seed : int
        The record's seed.

    Returns
    -------
    numpy.ndarray, shape (4,)
        :data:`IDENTIFIED`, ordered by frequency.
    """
    pr = protocol or CalibrationProtocol()
    if estimate.weights is None:
        raise ParameterError(
            "noise_free_estimate: estimate must carry the fit's weights (an estimate of "
            "identify_operator); got weights=None"
        )
    quiet = dataclasses.replace(pr, remnant_fraction=0.0, encoder_mm=0.0, accel_rms=0.0)
    ex, ec, band = _excitation_responses(
        simulate_calibration(loop, quiet, seed=seed), quiet, "noise_free_estimate"
    )
    keep = np.isin(ex.f_hz[band], estimate.f_hz)
    if keep.sum() != estimate.f_hz.size:  # pragma: no cover - the same grid by construction
        raise ParameterError("noise_free_estimate: estimate.f_hz is not the protocol's grid")
    H0 = (ex.g_uy[band] / ec.g_uy[band])[keep]
    start = [estimate.values[k] for k in IDENTIFIED]
    z = _operator_fit(family, estimate.f_hz, H0, estimate.weights, loop.handle_gain, start)[0]
    return _values(z)


def confidence_points(values, covariance, radius: float = REGION_RADIUS, log_axes=LOG_AXES):
    """Points of the joint error region's boundary along its principal axes.

    The region ``{z : (z - z0)' C^-1 (z - z0) <= radius^2}`` in the fit coordinates
    (logarithms where ``log_axes``): the points within ``radius`` standard deviations in
    every direction (its projections are the marginal bounds ``z0 +- radius sigma``), the
    region an estimate's correlated errors span; with :data:`REGION_RADIUS` it holds a
    Gaussian estimate with the probability of the marginal :data:`BOUND_SIGMAS`. Its
    ``2 n`` points ``z0 +- radius sqrt(lambda_k) v_k`` (eigenpairs of ``C`` from the
    largest, each vector's largest entry positive) are returned as values, damping ratios
    at least 0.01.

    Parameters
    ----------
    values : array_like, shape (n,)
        The region's centre, in the quantities' own units.
    covariance : array_like, shape (n, n)
        Covariance in the fit coordinates.
    radius : float
        In standard deviations.
    log_axes : sequence of bool
        Which quantities are fitted in logarithms.

    Returns
    -------
    numpy.ndarray, shape (2 n, n)
        Rows ``+axis 1, -axis 1, +axis 2, ...``.
    """
    # (a logarithm's point too far out to be a number is returned as inf)
    with np.errstate(over="ignore", under="ignore"):
        return _values(_axis_coords(values, covariance, radius, log_axes), log_axes)


def _axis_coords(values, covariance, radius: float, log_axes=LOG_AXES) -> np.ndarray:
    """:func:`confidence_points` in the fit coordinates (always finite)."""
    C = np.asarray(covariance, float)
    v0 = np.asarray(values, float)
    if C.shape != (v0.size, v0.size) or not np.all(np.isfinite(C)):
        raise ParameterError(
            f"confidence_points: covariance must be a finite {v0.size}x{v0.size} matrix; "
            f"got shape {C.shape}"
        )
    lam, V = np.linalg.eigh(0.5 * (C + C.T))
    lam, V = lam[::-1], V[:, ::-1]
    V = V * np.where(V[np.abs(V).argmax(axis=0), np.arange(V.shape[1])] < 0, -1.0, 1.0)
    z0 = _coords(v0, log_axes)
    steps = radius * np.sqrt(np.maximum(lam, 0.0))[None, :] * V  # column k: axis k
    rows = np.array([z0 + g * steps[:, k] for k in range(v0.size) for g in (1.0, -1.0)])
    lin = ~np.asarray(log_axes, bool)
    rows[:, lin] = np.maximum(rows[:, lin], 0.01)  # (damping ratios: values = coordinates)
    return rows


def response_distance(family, estimate: OperatorEstimate, a, b, handle_gain: float) -> np.ndarray:
    """How far apart two humans' hand responses are, in the calibration's standard deviations.

    ``|| W log(R_a / R_b) || / sqrt(s2)``: the responses (:func:`human_response`, masses
    nominal, as the fit models them) at the estimate's frequencies, the log-ratio's real
    part and phase (wrapped) weighted by the fit's weights, over the residual's standard
    deviation: the distance the fit itself measures, so that a model linear in its
    parameters has it equal to the covariance's distance (:func:`confidence_points`).

    Parameters
    ----------
    family : uncertainty.Family
    estimate : OperatorEstimate
        Whose frequencies, weights and residual variance are used.
    a, b : array_like, shape (m, 4) or (4,)
        Rows of :data:`IDENTIFIED` (either pair order: the response is symmetric).
    handle_gain : float
        ``sigma * kappa`` of the loop.

    Returns
    -------
    numpy.ndarray, shape (m,)
    """
    if estimate.weights is None or estimate.residual_variance is None:
        raise ParameterError(
            "response_distance: estimate must carry the fit's weights and residual variance "
            "(an estimate of identify_operator)"
        )
    ra = human_response(family, np.atleast_2d(np.asarray(a, float)), estimate.f_hz, handle_gain)
    rb = human_response(family, np.atleast_2d(np.asarray(b, float)), estimate.f_hz, handle_gain)
    d = np.log(ra / rb)
    w = estimate.weights[None, :]
    sq = (d.real * w) ** 2 + (np.angle(np.exp(1j * d.imag)) * w) ** 2
    return np.sqrt(sq.sum(axis=1) / estimate.residual_variance)


def region_points(
    family,
    estimate: OperatorEstimate,
    centre,
    handle_gain: float,
    radius: float = REGION_RADIUS,
    *,
    reach: float = 4.0,
    grid: int = 16,
) -> tuple[np.ndarray, np.ndarray]:
    """Points of the calibration's joint error region around ``centre``, on its principal axes.

    The directions are the principal axes of the estimate's covariance
    (:func:`confidence_points`); along each, both ways, the point is where the hand's
    response has moved ``radius`` standard deviations from the centre's as the fit measures
    it (:func:`response_distance`): the boundary of the nonlinear fit's likelihood region
    (Bates & Watts, *Nonlinear Regression Analysis and Its Applications*, Wiley 1988, Sec.
    6.1), which the covariance's ellipsoid linearises. The two agree where the response is
    nearly linear in the modes (measured: the ellipsoid's points move it by 3.0-3.4
    standard deviations at radius 3); where the two modes nearly coincide the ellipsoid's
    points move it by tens of standard deviations, estimates no record of that operator
    returns. The first crossing along each axis is found on ``grid`` steps up to ``reach``
    times the ellipsoid's distance, then by bisection (to 1e-4 of the step, or of the
    distance when the crossing comes before the first step); an axis that
    never reaches the radius ends at ``reach``. A point whose values or response overflow
    (an ellipsoid wide enough to reach them) counts as beyond the radius: the axis ends
    before it, at finite values.

    Parameters
    ----------
    family : uncertainty.Family
    estimate : OperatorEstimate
        :func:`identify_operator`'s estimate (covariance, weights, residual variance).
    centre : array_like, shape (4,)
        The region's centre (:data:`IDENTIFIED`).
    handle_gain : float
        ``sigma * kappa`` of the loop.
    radius : float
        In standard deviations.
    reach : float
        Longest step, in multiples of the ellipsoid's.
    grid : int
        Steps of the first search.

    Returns
    -------
    (points, factors)
        ``points`` shape (8, 4), in :func:`confidence_points`' order; ``factors`` shape
        (8,): each point's distance from the centre over the ellipsoid's.
    """
    if estimate.covariance is None:
        raise ParameterError("region_points: estimate must carry its covariance")
    c0 = np.asarray(centre, float)
    z0 = _coords(c0)
    lin = _axis_coords(c0, estimate.covariance, radius) - z0[None, :]

    def at(t):  # t shape (8, k): the points z0 + t * lin, as values
        with np.errstate(over="ignore", under="ignore"):  # (overflow: beyond the region)
            v = _values(z0[None, None, :] + t[:, :, None] * lin[:, None, :])
        v[..., 1::2] = np.maximum(v[..., 1::2], 0.01)
        return v

    def dist(t):
        # a point whose values or response overflow is no operator's: it counts as
        # beyond the radius, so the region ends before it (never a NaN taken as inside)
        v = at(t)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
            d = response_distance(family, estimate, v.reshape(-1, 4), c0, handle_gain)
        return np.where(np.isfinite(d), d, np.inf).reshape(t.shape)

    ts = np.linspace(0.0, reach, grid + 1)[1:]
    g = dist(np.broadcast_to(ts, (lin.shape[0], ts.size)).copy())
    over = g >= radius
    j = np.where(over.any(axis=1), over.argmax(axis=1), ts.size - 1)
    hi = ts[j]
    lo = np.where(j > 0, ts[np.maximum(j - 1, 0)], 0.0)
    crossed = over.any(axis=1)
    step = reach / grid
    # (to 1e-4 of the step, or of the crossing's own distance when it comes before the first
    # step: a steep response)
    while np.any(hi - lo > 1e-4 * np.minimum(step, hi)):
        mid = 0.5 * (lo + hi)
        up = dist(mid[:, None])[:, 0] >= radius
        hi, lo = np.where(up, mid, hi), np.where(up, lo, mid)
    t = np.where(crossed, hi, reach)
    # where the crossing is an overflow's edge, the last point inside (finite)
    t = np.where(np.isfinite(dist(t[:, None])[:, 0]), t, lo)
    return at(t[:, None])[:, 0, :], t


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


def _local_fit(resid, jacobian, z0, zlo, zhi):
    """One local weighted least-squares solve from ``z0`` within ``zlo .. zhi``.

    Levenberg-Marquardt first, unbounded (:func:`robust.sysid.levenberg.levenberg_marquardt`,
    Moré 1978, deterministic): where it converges strictly inside the box, its answer is a
    local minimum of the bounded problem too (no bound is active), found at less than half
    the cost of the bounded trust-region method. Otherwise (a bound active, no convergence,
    a non-finite answer) the bounded trust-region reflective method
    (:func:`scipy.optimize.least_squares`, ``"trf"``) solves from ``z0`` again.
    """
    try:
        with np.errstate(all="ignore"):
            sol = levenberg_marquardt(resid, jacobian, z0)
    except (ParameterError, np.linalg.LinAlgError):  # a non-finite residual on the way
        sol = None
    if (
        sol is not None
        and sol.converged
        and np.isfinite(sol.cost)
        and np.all(np.isfinite(sol.jac))
        and np.all((zlo < sol.x) & (sol.x < zhi))
    ):
        return sol
    return sopt.least_squares(
        resid, z0, jac=jacobian, bounds=(zlo, zhi), x_scale="jac", method="trf"
    )


def _fit(resid, jacobian, starts, zlo, zhi, n_freq):
    """Weighted least squares from the three best of ``starts``; covariance (module notes).

    ``resid(z)`` is the weighted residual at one point, ``jacobian(z)`` its Jacobian
    (analytic: the models' log responses are differentiated term by term, the compiled
    :func:`_human_jacobian` and :func:`_cab_jacobian`); the starts are ranked by their
    residual's squared norm. Returns ``(result, jacobian, (J'J)^-1, covariance, s2)``,
    the covariance in the fit coordinates, ``s2`` the residual variance per degree of
    freedom (at least 1).
    """
    cost0 = np.array([float(r @ r) for r in map(resid, starts)])
    best = None
    for k in np.argsort(cost0, kind="stable")[:3]:
        sol = _local_fit(resid, jacobian, starts[k], zlo, zhi)
        if best is None or sol.cost < best.cost:
            best = sol
    z, J = best.x, best.jac
    dof = max(2 * n_freq - z.size, 1)
    s2 = max(2.0 * best.cost / dof, 1.0)
    try:
        JtJ_inv = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        JtJ_inv = np.full((z.size, z.size), np.inf)
    return best, J, JtJ_inv, s2 * JtJ_inv, s2


#: The family's parameter carrying each identified quantity of the operator (the lower pair
#: as the arm's: the pairs' labels do not change the hand's response).
OPERATOR_NAMES = {
    parameter_name("human", "f_arm_hz"): "f_low_hz",
    parameter_name("human", "zeta_arm"): "zeta_low",
    parameter_name("human", "f_trunk_hz"): "f_high_hz",
    parameter_name("human", "zeta_trunk"): "zeta_high",
}


def operator_row(family, values: dict, row=None) -> np.ndarray:
    """A member row carrying the identified human: the lower pair as the arm's.

    The pairs' labels do not change the hand's response (module notes), so the choice is
    free; the masses stay at ``row``'s values (default: the nominal), which the record
    cannot tell.

    Parameters
    ----------
    family : uncertainty.Family
        The family (its parameter names).
    values : dict
        :data:`IDENTIFIED` -> value (an :attr:`OperatorEstimate.values`).
    row : array_like, optional
        The member row whose other parameters are kept (default: the nominal).
    """
    out = np.array(family.nominal_values() if row is None else row, float)
    for name, key in OPERATOR_NAMES.items():
        if name in family.names:
            out[family.names.index(name)] = values[key]
    return out


#: What the calibration identifies of the cab (module notes of :func:`identify_cab`).
CAB_IDENTIFIED = ("k_s", "f_cab_low_hz", "zeta_cab_low", "f_cab_high_hz", "zeta_cab_high")
#: The gain and the natural frequencies fitted in logarithms, the damping ratios linearly.
CAB_LOG_AXES = (True, True, False, True, False)


def cab_response(theta: np.ndarray, f_hz: np.ndarray) -> np.ndarray:
    """The cab's acceleration per cylinder position (Eqn 4) for rows of cab parameters.

    ``C/Y = K_s s^2 prod_i (2 zeta_i w_i s + w_i^2) / (s^2 + 2 zeta_i w_i s + w_i^2)``
    (:func:`robust.model.components.structure`): a product, so symmetric in its two modes.

    Parameters
    ----------
    theta : ndarray, shape (N, 5)
        Rows of (k_s, f_a_hz, zeta_a, f_b_hz, zeta_b).
    f_hz : ndarray, shape (F,)
        Frequencies, Hz.

    Returns
    -------
    ndarray of complex, shape (N, F)
    """
    th = np.atleast_2d(np.asarray(theta, float))
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    out = th[:, [0]] * s**2
    for fi, zi in ((1, 2), (3, 4)):
        w, z = 2 * np.pi * th[:, [fi]], th[:, [zi]]
        out = out * (2 * z * w * s + w**2) / (s**2 + 2 * z * w * s + w**2)
    return out


def cab_log_derivatives(theta: np.ndarray, f_hz: np.ndarray) -> np.ndarray:
    """Derivatives of ``log`` :func:`cab_response` in its parameters, analytically.

    ``log(C/Y) = log K_s + 2 log s + sum_i [log(2 zeta_i w_i s + w_i^2) - log(s^2 + 2 zeta_i
    w_i s + w_i^2)]``, differentiated term by term.

    Parameters
    ----------
    theta : ndarray, shape (N, 5)
        Rows of (k_s, f_a_hz, zeta_a, f_b_hz, zeta_b).
    f_hz : ndarray, shape (F,)
        Frequencies, Hz.

    Returns
    -------
    ndarray of complex, shape (N, F, 5)
        ``d log(C/Y) / d theta_k``.
    """
    th = np.atleast_2d(np.asarray(theta, float))
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    out = [np.broadcast_to(1.0 / th[:, [0]], (th.shape[0], s.shape[1])).astype(complex)]
    for fi, zi in ((1, 2), (3, 4)):
        w, z = 2 * np.pi * th[:, [fi]], th[:, [zi]]
        num, den = 2 * z * w * s + w**2, s**2 + 2 * z * w * s + w**2
        out.append(2 * np.pi * (2 * z * s + 2 * w) * (1.0 / num - 1.0 / den))
        out.append(2 * w * s * (1.0 / num - 1.0 / den))
    return np.stack(out, axis=-1)


_kernel = numba.njit(cache=True, nogil=True, error_model="numpy")


@_kernel
def _human_parts(z, big_r):
    """The modal quantities at ``z`` and the seated chain's coefficients (``d3 .. d0`` and
    the numerator's constant, as in :func:`human_response`)."""
    fa, za, ft, zt = math.exp(z[0]), z[1], math.exp(z[2]), z[3]
    wa, wt = 2 * math.pi * fa, 2 * math.pi * ft
    sa, st = 2 * za * wa, 2 * zt * wt
    wa2, wt2 = wa * wa, wt * wt
    # the quartic's coefficients d3 .. d0 and the numerator's constant
    coef = np.array(
        [
            big_r * (sa + st),
            big_r * (wa2 + wt2 + sa * st),
            big_r * (sa * wt2 + st * wa2),
            big_r * wa2 * wt2,
            big_r * (wa2 + wt2),
        ]
    )
    prim = np.array([fa, za, ft, zt, wa, wt, sa, st, wa2, wt2])
    return prim, coef


@_kernel
def _human_residual(z, f, H, w, big_r, gain):
    """The weighted log residual of :func:`human_response` at the fit coordinates ``z``
    (:data:`LOG_AXES`), compiled: real parts then phases, shape ``(2 F,)``."""
    d3, d2, d1, d0, c0 = _human_parts(z, big_r)[1]
    n = f.size
    out = np.empty(2 * n)
    for k in range(n):
        s = 2j * math.pi * f[k]
        num = (s + d3) * s + c0
        den = (((s + d3) * s + d2) * s + d1) * s + d0
        r = np.log(gain * num / den / H[k])
        out[k] = r.real * w[k]
        out[n + k] = r.imag * w[k]  # the principal log's phase: in (-pi, pi]
    return out


@_kernel
def _human_jacobian(z, f, w, big_r):
    """The Jacobian of :func:`_human_residual` in ``z`` (:func:`human_log_derivatives`
    through the log axes), compiled, shape ``(2 F, 4)``."""
    prim, coef = _human_parts(z, big_r)
    fa, za, ft, zt, wa, wt, sa, st, wa2, wt2 = prim
    d3, d2, d1, d0, c0 = coef
    r = big_r
    n = f.size
    out = np.empty((2 * n, 4))
    # per primitive variable (w_a, s_a, w_t, s_t): the derivatives of d3, d2, d1, d0, c0
    e = np.array(
        [
            [0.0, 2 * r * wa, 2 * r * st * wa, 2 * r * wa * wt2, 2 * r * wa],
            [r, r * st, r * wt2, 0.0, 0.0],
            [0.0, 2 * r * wt, 2 * r * sa * wt, 2 * r * wt * wa2, 2 * r * wt],
            [r, r * sa, r * wa2, 0.0, 0.0],
        ]
    )
    dl = np.empty(4, np.complex128)
    for k in range(n):
        s = 2j * math.pi * f[k]
        num = (s + d3) * s + c0
        den = (((s + d3) * s + d2) * s + d1) * s + d0
        for j in range(4):
            dl[j] = (e[j, 0] * s + e[j, 4]) / num - (
                ((e[j, 0] * s + e[j, 1]) * s + e[j, 2]) * s + e[j, 3]
            ) / den
        cols = (
            2 * math.pi * (dl[0] + 2 * za * dl[1]) * fa,  # d/d log f_arm
            2 * wa * dl[1],
            2 * math.pi * (dl[2] + 2 * zt * dl[3]) * ft,
            2 * wt * dl[3],
        )
        for j in range(4):
            out[k, j] = cols[j].real * w[k]
            out[n + k, j] = cols[j].imag * w[k]
    return out


@_kernel
def _cab_residual(z, f, H, w):
    """The weighted log residual of :func:`cab_response` at the fit coordinates ``z``
    (:data:`CAB_LOG_AXES`), compiled, shape ``(2 F,)``."""
    ks = math.exp(z[0])
    w1, z1, w2, z2 = 2 * math.pi * math.exp(z[1]), z[2], 2 * math.pi * math.exp(z[3]), z[4]
    n = f.size
    out = np.empty(2 * n)
    for k in range(n):
        s = 2j * math.pi * f[k]
        v = ks * s * s
        v = v * (2 * z1 * w1 * s + w1 * w1) / (s * s + 2 * z1 * w1 * s + w1 * w1)
        v = v * (2 * z2 * w2 * s + w2 * w2) / (s * s + 2 * z2 * w2 * s + w2 * w2)
        r = np.log(v / H[k])
        out[k] = r.real * w[k]
        out[n + k] = r.imag * w[k]  # the principal log's phase: in (-pi, pi]
    return out


@_kernel
def _cab_jacobian(z, f, w):
    """The Jacobian of :func:`_cab_residual` in ``z`` (:func:`cab_log_derivatives` through
    the log axes), compiled, shape ``(2 F, 5)``."""
    n = f.size
    out = np.empty((2 * n, 5))
    cols = np.empty(5, np.complex128)
    for k in range(n):
        s = 2j * math.pi * f[k]
        cols[0] = 1.0  # d log K_s / d log K_s
        for m in range(2):
            fi = math.exp(z[1 + 2 * m])
            wi, zi = 2 * math.pi * fi, z[2 + 2 * m]
            num = 2 * zi * wi * s + wi * wi
            den = s * s + 2 * zi * wi * s + wi * wi
            q = 1.0 / num - 1.0 / den
            cols[1 + 2 * m] = 2 * math.pi * (2 * zi * s + 2 * wi) * q * fi
            cols[2 + 2 * m] = 2 * wi * s * q
        for j in range(5):
            out[k, j] = cols[j].real * w[k]
            out[n + k, j] = cols[j].imag * w[k]
    return out


def cab_truth(family, row) -> dict:
    """The cab's identifiable quantities (:data:`CAB_IDENTIFIED`) of one member.

    Parameters
    ----------
    family : uncertainty.Family
    row : array_like
        The member's parameter values.
    """
    a = family.model_arrays(np.atleast_2d(np.asarray(row, float)), check_bounds=False)
    v = [a[parameter_name("structure", k)][0] for k in ("k_s", "f1_hz", "zeta1", "f2_hz", "zeta2")]
    pairs = sorted([(v[1], v[2]), (v[3], v[4])])
    return dict(zip(CAB_IDENTIFIED, [float(v[0]), *pairs[0], *pairs[1]]))


def _cab_ranges(family):
    p = {q.name: q for q in family.parameters}
    st = family.struct

    def rng_of(name, default):
        q = p.get(parameter_name("structure", name))
        return (q.low, q.high) if q is not None else (default, default)

    ks = rng_of("k_s", st.k_s)
    f1, f2 = rng_of("f1_hz", st.f1_hz), rng_of("f2_hz", st.f2_hz)
    z1, z2 = rng_of("zeta1", st.zeta1), rng_of("zeta2", st.zeta2)
    f = (min(f1[0], f2[0]), max(f1[1], f2[1]))
    z = (min(z1[0], z2[0]), max(z1[1], z2[1]))
    lo = np.array([ks[0], f[0], z[0], f[0], z[0]])
    hi = np.array([ks[1], f[1], z[1], f[1], z[1]])
    # a parameter the family does not vary still gets room to be fitted
    hi = np.where(hi > lo, hi, lo * 2)
    lo = np.where(hi > lo * 2 - 1e-12, lo, lo / 2)
    return lo, hi


def identify_cab(
    record: CalibrationRecord,
    loop,
    protocol: CalibrationProtocol | None = None,
    family=None,
    *,
    responses: tuple | None = None,
) -> OperatorEstimate:
    """Estimate the cab's modes (:data:`CAB_IDENTIFIED`) with an error bound from one record.

    The same record as :func:`identify_operator`: the cab's acceleration per excitation,
    an H1 estimate with the excitation as input, divided by the cylinder loop's own
    response, gives the structure's response ``C/Y``. The valve varies across the family,
    so that response is the member's (``loop``'s): the machine measures the
    cylinder position its PI loop closes on, so the rig knows its own cylinder loop's response
    ``r -> y`` (taken as exact here: a position sensor's noise is far below the
    accelerometer's); a weighted least-squares fit of
    :func:`cab_response` (weights as in the module notes; bound: 3 standard deviations of
    the fit coordinates plus the spectral estimate's resolution, two frequency bins on each
    natural frequency and one bin of half-power bandwidth on each damping ratio). The two
    modes are reported ordered by frequency: like the seated chain's, the response cannot
    tell which is which.

    Parameters
    ----------
    record : CalibrationRecord
    loop : robust.model.loop.BDFTLoop
        The member the record is of (its own cylinder loop, valve included, divides the
        estimate).
    protocol : CalibrationProtocol, optional
    family : uncertainty.Family, optional
        Whose ranges bound the fit (default: the default family).
    responses : tuple, optional
        :func:`excitation_responses` of this record and protocol, when already computed.

    Returns
    -------
    OperatorEstimate
        With :data:`CAB_IDENTIFIED` as its quantities.
    """
    pr = protocol or CalibrationProtocol()
    family = family if family is not None else default_family()
    _, ec, band = responses or _excitation_responses(record, pr, "identify_cab")
    f = ec.f_hz[band]
    T = connect(
        loop.blocks(bdft=False, reference_correction=True),
        inputs=["u", "r_corr"],
        outputs=["y"],
        name="cylinder",
    )
    Tf = np.asarray(T(2j * np.pi * f, squeeze=False))[0, 1]
    H = ec.h1[band] / Tf
    g = ec.coherence[band]
    var = (1 - g) / (2 * ec.n_effective * np.maximum(g, 1e-6))
    good = _coherent(g, pr, "identify_cab", len(CAB_IDENTIFIED))
    f, H, var, coh = f[good], H[good], var[good], g[good]
    w = 1.0 / np.sqrt(var)
    lo, hi = _cab_ranges(family)
    log = CAB_LOG_AXES
    zlo, zhi = _coords(lo, log), _coords(hi, log)

    f, w = np.ascontiguousarray(f, float), np.ascontiguousarray(w, float)
    H = np.ascontiguousarray(H, complex)

    def resid(z):
        return _cab_residual(np.asarray(z, float), f, H, w)

    starts = []
    for fa in np.geomspace(lo[1], hi[1], 4):
        for fb in np.geomspace(lo[3], hi[3], 4):
            if fb < fa:
                continue
            z0 = 0.5 * (zlo + zhi)
            z0[1], z0[3] = math.log(fa), math.log(fb)
            starts.append(np.clip(z0, zlo, zhi))

    def jacobian(z):
        return _cab_jacobian(np.asarray(z, float), f, w)

    best, _, _, cov, _ = _fit(resid, jacobian, starts, zlo, zhi, f.size)
    z = best.x
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    # the spectral estimate's resolution: leakage at a lightly damped mode biases its
    # frequency by up to about a bin (bound: two bins) and its half-power bandwidth 2 zeta f
    # by about one (bound: zeta +- df / 2f); the noise's 3 sigma alone missed the truth for
    # 14 of 20 cabs (errors of 0.3-1.3 %), with the resolution term 1 of 40
    df = ec.f_hz[1] - ec.f_hz[0]
    v = _values(z, log)
    res = np.array([0.0, 2 * df / v[1], df / (2 * v[1]), 2 * df / v[3], df / (2 * v[3])])
    half = BOUND_SIGMAS * sd + res
    order = [0, 1, 2, 3, 4] if _values(z, log)[1] <= _values(z, log)[3] else [0, 3, 4, 1, 2]
    z, sd, half, cov = z[order], sd[order], half[order], cov[np.ix_(order, order)]
    vals, b_lo, b_hi = _values(z, log), _values(z - half, log), _values(z + half, log)
    return OperatorEstimate(
        values={k: float(v) for k, v in zip(CAB_IDENTIFIED, vals)},
        bounds={k: (float(a), float(b)) for k, a, b in zip(CAB_IDENTIFIED, b_lo, b_hi)},
        sigma={k: float(v) for k, v in zip(CAB_IDENTIFIED, sd)},
        residual_rms=float(math.sqrt(2.0 * best.cost / (2 * f.size))),
        f_hz=f,
        measured=H,
        fitted=cab_response(vals[None, :], f)[0],
        coherence=coh,
        covariance=cov,
        weights=w,
    )
