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
   the seated 2-DOF chain (:mod:`backhoe.model.physical`), whose response depends on the
   arm-to-trunk mass ratio and the four modal parameters only (the stiffnesses and
   dampings follow the masses, :func:`backhoe.model.modal.modal_to_physical`), not on the
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
import itertools
import math

import numpy as np

from backhoe.model.blocks import parameter_name
from backhoe.model.modal import physical_to_modal
from designs.cab_calibration import CAB_IDENTIFIED, CAB_LOG_AXES, cab_truth, identify_cab
from designs.calibration_fit import LOG_AXES, _coords, _fit, _values
from designs.calibration_fit import _local_fit as _local_fit
from designs.calibration_models import _cab_jacobian as _cab_jacobian
from designs.calibration_models import _cab_residual as _cab_residual
from designs.calibration_models import (
    _human_jacobian,
    _human_residual,
    cab_log_derivatives,
    cab_response,
    human_log_derivatives,
    human_response,
)
from designs.calibration_record import (
    BOUND_SIGMAS,
    CalibrationProtocol,
    CalibrationRecord,
    OperatorEstimate,
    _coherent,
    _excitation_responses,
    excitation_responses,
    simulate_calibration,
)
from designs.calibration_region import (
    REGION_RADIUS,
    confidence_points,
    region_points,
    response_distance,
)
from robust.errors import ParameterError

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


def operator_truth(family, row) -> dict:
    """The identifiable quantities (:data:`IDENTIFIED`) of one member of ``family``.

    Parameters
    ----------
    family : backhoe.Family
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


def identified_ranges(family):
    """Ranges of the identified quantities and of the held mass ratio over ``family``.

    Parameters
    ----------
    family : backhoe.Family
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
    family : backhoe.Family
        The family whose ranges bound the fit (physical human).
    handle_gain : float
        ``sigma * kappa`` of the loop (:attr:`backhoe.model.loop.BDFTLoop.handle_gain`).
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
    loop : backhoe.model.loop.BDFTLoop
        The member the record was taken on.
    family : backhoe.Family
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
    family : backhoe.Family
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
