"""The cab's calibration: the structure's gain and two modes from the operator's record.

The same record tells the machine too (step 5 of :mod:`designs.calibration`): the cab's
acceleration per excitation, divided by the machine's known cylinder loop, is the
structure's response, fitted for :data:`CAB_IDENTIFIED` by :func:`identify_cab` in the
coordinates of :data:`CAB_LOG_AXES`; :func:`cab_truth` gives a member's true values. Apart
from the operator's fit, with which it shares the record and the fitting.
"""

from __future__ import annotations

import math

import numpy as np

from backhoe import default_family
from backhoe.model.blocks import parameter_name
from backhoe.model.wiring import connect
from designs.calibration_fit import _coords, _fit, _values
from designs.calibration_models import _cab_jacobian, _cab_residual, cab_response
from designs.calibration_record import (
    BOUND_SIGMAS,
    CalibrationProtocol,
    CalibrationRecord,
    OperatorEstimate,
    _coherent,
    _excitation_responses,
)

__all__ = ["CAB_IDENTIFIED", "CAB_LOG_AXES", "cab_truth", "identify_cab"]


#: What the calibration identifies of the cab (module notes of :func:`identify_cab`).
CAB_IDENTIFIED = ("k_s", "f_cab_low_hz", "zeta_cab_low", "f_cab_high_hz", "zeta_cab_high")

#: The gain and the natural frequencies fitted in logarithms, the damping ratios linearly.
CAB_LOG_AXES = (True, True, False, True, False)


def cab_truth(family, row) -> dict:
    """The cab's identifiable quantities (:data:`CAB_IDENTIFIED`) of one member.

    Parameters
    ----------
    family : backhoe.Family
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
    loop : backhoe.model.loop.BDFTLoop
        The member the record is of (its own cylinder loop, valve included, divides the
        estimate).
    protocol : CalibrationProtocol, optional
    family : backhoe.Family, optional
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
