"""The handle-force calibration: what a force-feedback design must know of the operator.

The operator's calibration of :mod:`designs.calibration` shakes the cab and records the hand;
that response ``x / c`` depends on the arm-to-trunk mass ratio and the four modes only,
and is symmetric in the two modes (the record tells the modes, not which is the arm's), so
it cannot tell what a handle-force loop acts on: the hand's admittance ``x / f``, whose
high-frequency asymptote is the arm's mass and whose two modes are not interchangeable.
A force-feedback design built from that record on the nominal masses destabilises or
breaks the specification on most operators (measured in :mod:`designs.calibrated_force`).

This module adds the record a force-feedback rig can take with the device it already has:

1. **Record** (:func:`simulate_force_record`). The machine stands still; the Omni pushes
   the handle with a band-limited random force of :attr:`ForceProtocol.force_rms_n` (within
   the device's continuous force) while the operator holds it; recorded at 1 kHz: the
   commanded force (known exactly: the rig generates it; the device's own dynamics are
   neglected, as the paper neglects them) and the handle position through the encoder
   (quantised), with the operator's involuntary motion (the remnant, as in
   :class:`designs.calibration.CalibrationProtocol`) on it.
2. **Frequency response**. The H1 estimate ``x / f`` (the remnant and the quantisation are
   uncorrelated with the commanded force, so it is unbiased), its variance from the
   coherence (Bendat & Piersol, *Random Data*, 4th ed., 2010, Sec. 9.2).
3. **Physical fit** (:func:`identify_force`). The seated chain's admittance in closed form
   (:func:`hand_admittance`): with ``A_t = m_t s^2 + (c_t + c_a) s + k_t + k_a``,
   ``A_a = m_a s^2 + c_a s + k_a`` and ``N_a = c_a s + k_a`` (the equations of
   :mod:`backhoe.model.physical` with the seat still),
   ``z_a / f = A_t / (A_a A_t - N_a^2)``; the stiffnesses and dampings follow the masses and
   the modes (:func:`backhoe.model.modal.modal_to_physical`). It has seven free
   coefficients for the six quantities of :data:`FORCE_IDENTIFIED` (the body mass, the arm's
   mass, each mode's natural frequency and damping ratio, with their labels), fitted in
   logarithms by weighted nonlinear least squares of the complex log-ratio over
   :attr:`ForceProtocol.band_hz` from a grid of starts within the family's ranges
   (:func:`designs.calibration_fit._fit`: Levenberg-Marquardt, the bounded trust-region
   method where a bound is active).
   The body mass is all but unidentifiable (fitted beside the rest, its standard deviation
   came out about its whole range and, pinned at an end of it, it pulled the arm's mass
   outside its bound): it is held at the family's nominal, as the cab record's fit holds
   the mass ratio, and its bound is the family's range.
4. **Error bound**: the covariance ``s^2 (J' W J)^-1`` at the solution (``s^2`` the residual
   variance per degree of freedom, at least 1), and :data:`BOUND_SIGMAS` standard deviations
   of each quantity's logarithm (a relative bound) around the estimate plus the largest
   shift of the estimate that the held body mass can cause over its range (the
   Gauss-Newton step of the residual's change at either end), within the family's range.

With the cab record's estimate in the same fit (``cab_estimate``: the hand's response to
the cab, with the mass ratio the two masses give), the arm's mass is known to about 1 %,
its mode to a few per cent and the trunk's to about ten (measured in the tests and by
:mod:`designs.calibrated_force`). Without the hold's factor (step 3) the fit read the
half-sample delay as an arm damping 10-15 % too low.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import scipy.signal as sig

from backhoe.analysis.simulation import lifted_response
from backhoe.model.blocks import parameter_name
from backhoe.model.wiring import connect
from designs.calibration_fit import _fit
from designs.calibration_models import human_response
from designs.calibration_record import BOUND_SIGMAS, _band_noise, check_record_timing
from designs.limit_plant import ENCODER_MM
from designs.specification import Specification
from robust.checks import POSITIVE, Spec, validate_fields
from robust.errors import DataError, ParameterError
from robust.sysid.spectral import estimate_frequency_responses

__all__ = [
    "FORCE_IDENTIFIED",
    "ForceProtocol",
    "ForceRecord",
    "ForceEstimate",
    "simulate_force_record",
    "hand_admittance",
    "identify_force",
]


#: What the force record identifies: the family's parameters of the seated chain.
FORCE_IDENTIFIED = tuple(
    parameter_name("human", k)
    for k in ("body_mass", "m_arm", "f_arm_hz", "zeta_arm", "f_trunk_hz", "zeta_trunk")
)


@dataclasses.dataclass(frozen=True)
class ForceProtocol:
    """How the force record is taken (every field changes the estimate; all reported).

    Parameters
    ----------
    duration_s : float
        Length of the record, s.
    fs_hz : float
        Sampling rate (the servo rate), Hz.
    force_rms_n : float
        RMS of the commanded force, N (the Omni holds 0.88 N continuously; its 3.3 N peak
        is about 4 RMS at the default 0.4 N).
    excitation_band_hz : tuple of float
        Pass band of the commanded force, Hz.
    remnant_fraction : float
        RMS of the operator's involuntary motion while holding, as a fraction of the
        intended motion's RMS (as :class:`designs.calibration.CalibrationProtocol`).
    band_hz : tuple of float
        Band of the fit, Hz.
    nperseg : int
        Segment length of the spectral estimate, samples.
    encoder_mm : float
        Encoder resolution, mm.
    """

    duration_s: float = 30.0
    fs_hz: float = 1000.0
    force_rms_n: float = 0.4
    excitation_band_hz: tuple = (0.3, 25.0)
    remnant_fraction: float = 0.05
    band_hz: tuple = (0.5, 20.0)
    nperseg: int = 8192
    encoder_mm: float = ENCODER_MM

    def __post_init__(self):
        validate_fields(
            self,
            {
                "duration_s": POSITIVE,
                "fs_hz": POSITIVE,
                "force_rms_n": POSITIVE,
                "remnant_fraction": Spec(0.0, math.inf, False, False),
                "encoder_mm": Spec(0.0, math.inf, False, False),
            },
        )
        check_record_timing(self)


@dataclasses.dataclass(frozen=True)
class ForceRecord:
    """One simulated force record.

    Parameters
    ----------
    f : numpy.ndarray
        Commanded handle force, N (known exactly).
    x : numpy.ndarray
        Handle position through the encoder, handle units.
    fs_hz : float
        Sampling rate, Hz.
    seed : int
        Seed of the force and the remnant.
    """

    f: np.ndarray
    x: np.ndarray
    fs_hz: float
    seed: int


@dataclasses.dataclass(frozen=True)
class ForceEstimate:
    """What the force record tells of the operator.

    Parameters
    ----------
    values : dict
        :data:`FORCE_IDENTIFIED` -> estimate.
    bounds : dict
        :data:`FORCE_IDENTIFIED` -> ``(low, high)``, :data:`BOUND_SIGMAS` standard
        deviations of the logarithm around the estimate and the held body mass's shift,
        within the family's range (the body mass: its whole range).
    sigma : dict
        :data:`FORCE_IDENTIFIED` -> standard deviation of the logarithm (a relative error;
        ``inf`` for the body mass, held at the family's nominal).
    residual_rms : float
        RMS of the weighted residual (about 1 when the model explains the estimate).
    f_hz : numpy.ndarray
        Frequencies of the fit, Hz.
    measured, fitted : numpy.ndarray of complex
        The estimate ``x / f`` and the fitted model at ``f_hz``.
    covariance : numpy.ndarray
        Covariance of the logarithms of :data:`FORCE_IDENTIFIED` but the body mass, in
        that order.
    """

    values: dict
    bounds: dict
    sigma: dict
    residual_rms: float
    f_hz: np.ndarray
    measured: np.ndarray
    fitted: np.ndarray
    covariance: np.ndarray

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
        }


def simulate_force_record(
    loop, protocol: ForceProtocol | None = None, *, seed: int = 0
) -> ForceRecord:
    """The force record of one operator on one machine (module notes, step 1).

    Parameters
    ----------
    loop : backhoe.model.loop.BDFTLoop
        The member (physical human: the force port).
    protocol : ForceProtocol, optional
    seed : int
        Seed of the commanded force and the remnant.

    Returns
    -------
    ForceRecord

    Raises
    ------
    robust.errors.ParameterError
        If ``seed`` is not an integer >= 0 or the member's human has no force port.
    """
    pr = protocol or ForceProtocol()
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"simulate_force_record: seed must be an integer >= 0; got {seed!r}")
    if not loop.human.has_force_port:
        raise ParameterError(
            "simulate_force_record: the member's human has no force port (a physical human "
            f"is needed); got the {loop.human.variant!r} variant"
        )
    rng = np.random.default_rng(int(seed))
    fs, n = pr.fs_hz, int(round(pr.duration_s * pr.fs_hz))
    spec = Specification()
    rms_u = loop.intended_amplitude(spec.limits(), spec.intent_fraction) / math.sqrt(2.0)
    f = _band_noise(rng, n, fs, pr.excitation_band_hz, pr.force_rms_n)
    u = (
        _band_noise(rng, n, fs, (0.0, spec.intent_bandwidth_hz), pr.remnant_fraction * rms_u)
        if pr.remnant_fraction > 0
        else np.zeros(n)
    )
    # calibration mode (the handle does not command the stick), the machine at rest: the
    # commanded force drives the hand, and through the loop anything the hand moves
    blocks = loop.blocks(bdft=False, reference_correction=True)
    blocks += [loop.structure_system(), loop.human_system()]
    P = connect(blocks, inputs=["u", "r_corr", "f"], outputs=["h"], name="force_calibration")
    Ad, Bd, Cd, Dd, _ = sig.cont2discrete((P.A, P.B[:, [2]], P.C, P.D[:, [2]]), 1.0 / fs)
    (h,) = lifted_response(Ad, Bd[:, 0], Cd, Dd[:, 0], f)
    x = u + loop.handle_gain * h
    if not np.all(np.isfinite(x)):
        raise DataError("simulate_force_record: the hand's response is not finite")
    if pr.encoder_mm > 0:
        q = pr.encoder_mm * 1e-3 * loop.handle_units_per_m()
        x = q * np.round(x / q)
    return ForceRecord(f=f, x=x, fs_hz=fs, seed=int(seed))


def hand_admittance(family, theta, f_hz, handle_gain: float) -> np.ndarray:
    """The handle's response to its force, ``x / f``, for rows of :data:`FORCE_IDENTIFIED`.

    In closed form (module notes, step 3), equal to the state-space chain of
    :func:`backhoe.model.physical.physical_human_matrices` to rounding (tested).

    Parameters
    ----------
    family : backhoe.Family
        Gives the upper body's share of the body mass and ``h_gain``.
    theta : array_like, shape (N, 6)
        Rows of (body mass kg, arm mass kg, f_arm Hz, zeta_arm, f_trunk Hz, zeta_trunk).
    f_hz : array_like, shape (F,)
        Frequencies, Hz.
    handle_gain : float
        ``sigma * kappa`` of the loop (handle units per unit of ``h``).

    Returns
    -------
    numpy.ndarray of complex, shape (N, F)
    """
    th = np.atleast_2d(np.asarray(theta, float))
    m_t = family.trunk_share * th[:, 0:1]
    m_a = th[:, 1:2]
    wa, wt = 2 * np.pi * th[:, 2:3], 2 * np.pi * th[:, 4:5]
    big_m = m_t + m_a
    k_t, c_t = big_m * wt * wt, 2.0 * th[:, 5:6] * big_m * wt
    k_a, c_a = m_a * wa * wa, 2.0 * th[:, 3:4] * m_a * wa
    s = 2j * np.pi * np.asarray(f_hz, float)[None, :]
    a_t = m_t * s * s + (c_t + c_a) * s + k_t + k_a
    a_a = m_a * s * s + c_a * s + k_a
    n_a = c_a * s + k_a
    return handle_gain * family.physical.h_gain * a_t / (a_a * a_t - n_a * n_a)


def _ranges(family) -> tuple[np.ndarray, np.ndarray]:
    p = {q.name: q for q in family.parameters}
    missing = [k for k in FORCE_IDENTIFIED if k not in p]
    if missing:
        raise ParameterError(
            f"identify_force: the family must vary {list(FORCE_IDENTIFIED)}; it lacks {missing}"
        )
    return (
        np.array([p[k].low for k in FORCE_IDENTIFIED], float),
        np.array([p[k].high for k in FORCE_IDENTIFIED], float),
    )


def identify_force(
    record: ForceRecord,
    family,
    handle_gain: float,
    protocol: ForceProtocol | None = None,
    *,
    cab_estimate=None,
) -> ForceEstimate:
    """Estimate :data:`FORCE_IDENTIFIED` with an error bound from one force record.

    Parameters
    ----------
    record : ForceRecord
        The record (:func:`simulate_force_record`, or a rig's, in the same units).
    family : backhoe.Family
        The family whose ranges bound the fit (physical human).
    handle_gain : float
        ``sigma * kappa`` of the loop.
    protocol : ForceProtocol, optional
        The protocol the record was taken with (its band and segment length).
    cab_estimate : designs.calibration.OperatorEstimate, optional
        The same operator's estimate from the cab-shaking record
        (:func:`designs.calibration.identify_operator`): its measured ``x / c`` and weights
        join the fit (the hand's response to the cab, with the mass ratio the two masses
        give), which pins the trunk's mode that a force on the hand barely moves.

    Returns
    -------
    ForceEstimate

    Raises
    ------
    robust.errors.DataError
        If the record holds NaN or infinite values, or too little coherent data in the band.
    """
    pr = protocol or ForceProtocol()
    for name in ("f", "x"):
        a = np.asarray(getattr(record, name), float)
        if a.ndim != 1 or not np.all(np.isfinite(a)):
            raise DataError(f"identify_force: record.{name} must be a finite 1-D array")
    lo, hi = _ranges(family)
    (est,) = estimate_frequency_responses(
        record.f, [record.x], record.fs_hz, nperseg=min(pr.nperseg, record.f.size // 2)
    )
    band = (est.f_hz >= pr.band_hz[0]) & (est.f_hz <= pr.band_hz[1])
    g = est.coherence[band]
    good = g > 0.2
    if good.sum() < 3 * len(FORCE_IDENTIFIED):
        raise DataError(
            f"identify_force: only {int(good.sum())} frequencies in {pr.band_hz} Hz have a "
            "coherence above 0.2; the record is too short or too noisy"
        )
    f, H, g = est.f_hz[band][good], est.h1[band][good], g[good]
    # the standard deviation of log H1 (real and imaginary parts) from the coherence
    w = np.sqrt(2.0 * est.n_effective * g / (1.0 - np.minimum(g, 1.0 - 1e-9)))

    # the force is held between the servo's samples: the record's response is the chain's
    # times the zero-order hold's (half a sample's delay; its magnitude, sinc): 1 degree of
    # phase at 5 Hz, which the fit would otherwise read as a lower arm damping
    hold = np.exp(-1j * np.pi * f / record.fs_hz) * np.sinc(f / record.fs_hz)
    if cab_estimate is not None:
        fc, Hc, wc = cab_estimate.f_hz, cab_estimate.measured, cab_estimate.weights
        if wc is None:
            raise ParameterError(
                "identify_force: cab_estimate must carry the fit's weights (an estimate of "
                "designs.calibration.identify_operator); got weights=None"
            )

    # the body mass is held at the family's nominal (its standard deviation came out about
    # its whole range: a force on the hand barely moves the trunk); its effect enters the
    # bound (the estimate's shift with the body mass at either end of its range)
    bm_nom = float(family.body_mass)

    def resid(z, body_mass=bm_nom):
        v = np.concatenate([[body_mass], np.exp(z)])
        # the principal log of the ratio: its phase in (-pi, pi], a whole turn no misfit
        d = np.log(hand_admittance(family, v[None, :], f, handle_gain)[0] * hold / H) * w
        parts = [d.real, d.imag]
        if cab_estimate is not None:
            ratio = v[1] / (family.trunk_share * v[0])
            m = human_response(family, v[None, 2:], fc, handle_gain, mass_ratio=ratio)[0]
            dc = np.log(m / Hc) * wc
            parts += [dc.real, dc.imag]
        return np.concatenate(parts)

    def jacobian(z):
        h = 1e-6
        cols = [(resid(z + h * e) - resid(z - h * e)) / (2 * h) for e in np.eye(z.size)]
        return np.stack(cols, axis=1)

    zlo, zhi = np.log(lo[1:]), np.log(hi[1:])
    mid = 0.5 * (zlo + zhi)
    starts = []  # a grid over the arm's mass and the two natural frequencies
    for ma, fa, ft in itertools.product(*(np.linspace(zlo[j], zhi[j], 3) for j in (0, 1, 3))):
        z0 = mid.copy()
        z0[0], z0[1], z0[3] = ma, fa, ft
        starts.append(z0)
    n_res = f.size + (0 if cab_estimate is None else fc.size)
    best, J, JtJ_inv, cov, _ = _fit(resid, jacobian, starts, zlo, zhi, n_res)
    z = best.x
    r0 = resid(z)
    shift = np.zeros(z.size)
    for bm in (lo[0], hi[0]):
        shift = np.maximum(shift, np.abs(JtJ_inv @ (J.T @ (resid(z, bm) - r0))))
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    half = BOUND_SIGMAS * sd + shift
    vals = np.concatenate([[bm_nom], np.exp(z)])
    b_lo = np.concatenate([[lo[0]], np.maximum(np.exp(z - half), lo[1:])])
    b_hi = np.concatenate([[hi[0]], np.minimum(np.exp(z + half), hi[1:])])
    return ForceEstimate(
        values={k: float(v) for k, v in zip(FORCE_IDENTIFIED, vals)},
        bounds={k: (float(a), float(b)) for k, a, b in zip(FORCE_IDENTIFIED, b_lo, b_hi)},
        sigma={k: float(v) for k, v in zip(FORCE_IDENTIFIED, np.concatenate([[np.inf], sd]))},
        residual_rms=float(math.sqrt(2.0 * best.cost / (2 * n_res))),
        f_hz=f,
        measured=H,
        fitted=hand_admittance(family, vals[None, :], f, handle_gain)[0] * hold,
        covariance=cov,
    )
