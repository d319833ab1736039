"""The joint error region of an operator estimate (step 6 of :mod:`designs.calibration`).

:func:`confidence_points` gives the boundary points of the covariance's ellipsoid along
its principal axes, :func:`response_distance` how far a candidate's hand response lies
from the record's in standard deviations, and :func:`region_points` the likelihood
region's points along each axis at :data:`REGION_RADIUS` standard deviations. What a
compensator built from an estimate must withstand, apart from how the estimate is found.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from designs.calibration_fit import LOG_AXES, _coords, _values
from designs.calibration_models import human_response
from designs.calibration_record import BOUND_SIGMAS, OperatorEstimate
from robust.errors import ParameterError

__all__ = ["REGION_RADIUS", "confidence_points", "response_distance", "region_points"]


#: Radius of the joint error region (:func:`region_points`), in standard deviations: the
#: region that holds four Gaussian quantities with the probability of one within
#: :data:`BOUND_SIGMAS` (99.73 %), 4.03.
REGION_RADIUS = float(math.sqrt(chi2.ppf(chi2.cdf(BOUND_SIGMAS**2, 1), 4)))


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
    family : backhoe.Family
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
    family : backhoe.Family
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
