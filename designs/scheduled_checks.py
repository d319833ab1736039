"""The checks of the per-operator design on true members: coverage, wrong estimates and
certified margins.

:func:`continuous_coverage` (each member's design from its own estimate, checked on the
true member), :func:`cancellation_gap`, :func:`border_check` (designs from estimates on the
boundary of the error region, or the box constructions, checked for stability and the
specification), :func:`operator_family` and :func:`operator_certificates` (the robust
margin of each operator's design over the box its calibration bounds). Each runs its
members in chunks through :func:`robust.engine.run_calls`; what the checks measure is
described in :mod:`designs.scheduled`.
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np

from backhoe import member_metrics
from designs.cab_calibration import CAB_IDENTIFIED, CAB_LOG_AXES
from designs.cab_damper import _cab_names, calibration_box, damped_cancellation, member_valve
from designs.calibration import IDENTIFIED, OPERATOR_NAMES
from designs.calibration_fit import LOG_AXES
from designs.calibration_region import REGION_RADIUS
from designs.cancellation import cancellation_controller
from designs.coverage import member_verdicts
from designs.scheduled_bank import _cancellations
from designs.scheduled_calibrations import Calibrations, _run, calibrate_members
from designs.specification import Specification
from robust.checks import check_int
from robust.errors import ParameterError
from robust.synthesis.solve import deterministic_solvers
from uncertainty.margins import robust_margin

__all__ = [
    "continuous_coverage",
    "cancellation_gap",
    "border_check",
    "operator_family",
    "operator_certificates",
]


def _continuous_chunk(family, rows, est, spec, cabs=None):
    with deterministic_solvers():
        holds = np.zeros(len(rows), bool)
        binding = []
        for i, (row, e) in enumerate(zip(rows, est)):
            if cabs is None:
                K = _cancellations(family, np.asarray(e, float)[None, :])[0]
            else:
                K = damped_cancellation(
                    family,
                    dict(zip(IDENTIFIED, e)),
                    dict(zip(CAB_IDENTIFIED, cabs[i])),
                    spec,
                    valve=member_valve(family, row),
                )
            v = member_verdicts(family, row[None, :], K, spec)
            holds[i] = v.holds[0]
            binding.append(v.binding[0])
        return holds, binding


def continuous_coverage(
    family, values, estimates, *, cabs=None, spec=None, n_jobs: int = 1, binding: bool = False
):
    """Per member: whether the specification holds with the compensator built from its estimate.

    The limit of ever finer cells: each operator's cancellation built from the human the
    calibration identified (masses nominal), no grid.

    Parameters
    ----------
    family : backhoe.Family
    values : array_like, shape (n, d)
        The members.
    estimates : numpy.ndarray, shape (n, 4)
        Their calibrations' estimates (:func:`calibrate_members`).
    cabs : numpy.ndarray, shape (n, 5), optional
        The cabs' estimates: then each compensator is :func:`damped_cancellation`.
    spec : Specification, optional
    n_jobs : int
        Parallel processes.
    binding : bool
        Also return each member's binding constraint.

    Returns
    -------
    numpy.ndarray of bool, shape (n,)
        Whether the specification holds (with ``binding``: and the list of binding
        constraints).
    """
    spec = spec or Specification()
    rows = np.atleast_2d(np.asarray(values, float))
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="continuous_coverage")
    size = 25
    chunks = [(i, min(i + size, len(rows))) for i in range(0, len(rows), size)]
    jobs = [
        functools.partial(
            _continuous_chunk,
            family,
            rows[a:b],
            estimates[a:b],
            spec,
            None if cabs is None else cabs[a:b],
        )
        for a, b in chunks
    ]
    parts = _run(jobs, n_jobs)
    holds = np.concatenate([p[0] for p in parts])
    if binding:
        return holds, [b for p in parts for b in p[1]]
    return holds


def cancellation_gap(family, values, *, seed: int = 0, protocol=None, spec=None) -> dict:
    """What the operator's calibration is worth to the model-based cancellation.

    For each member of ``values``: the specification checked with three cancellations of
    the hand's motion (:func:`designs.cancellation.cancellation_controller`), built from the
    nominal human (the shipped design), from the human the member's simulated calibration
    identifies (:func:`calibrate_members` with seed ``seed``, then
    :func:`continuous_coverage`: the masses, which the record does not tell, nominal), and
    from the member's own human (what exact knowledge gives).

    Parameters
    ----------
    family : backhoe.Family
    values : array_like, shape (n, d)
        Member rows.
    seed : int
        Seed of the first member's record.
    protocol : CalibrationProtocol, optional
    spec : Specification, optional

    Returns
    -------
    dict
        ``"nominal"``, ``"identified"``, ``"exact"`` -> bool array (the whole specification
        holds), ``"binding_<name>"`` -> list of binding constraints, ``"inside"`` -> bool
        array (every identified quantity within its bound).
    """
    spec = spec or Specification()
    rows = np.atleast_2d(np.asarray(values, float))
    cal = calibrate_members(family, rows, seed=seed, protocol=protocol)
    est, inside = cal.estimates, cal.operator_inside
    out = {"nominal": None, "identified": None, "exact": None, "inside": inside}
    nominal = member_verdicts(
        family, rows, cancellation_controller(family.member(family.nominal_values())), spec
    )
    out["nominal"], bind_nom = nominal.holds, list(nominal.binding)
    out["identified"], bind_id = continuous_coverage(family, rows, est, spec=spec, binding=True)
    exact, bind_ex = np.zeros(len(rows), bool), []
    for i, row in enumerate(rows):
        v = member_verdicts(family, row[None, :], cancellation_controller(family.member(row)), spec)
        exact[i] = v.holds[0]
        bind_ex.append(v.binding[0])
    out["exact"] = exact
    out.update(binding_nominal=bind_nom, binding_identified=bind_id, binding_exact=bind_ex)
    return out


def _displaced(values: np.ndarray, bounds: np.ndarray, log_axes, j: int, sign: int) -> np.ndarray:
    """``values`` with quantity ``j`` moved by its bound's half-width (a factor for logs)."""
    out = np.array(values, float)
    lo, hi = bounds[j]
    if log_axes[j]:
        out[j] *= math.sqrt(hi / lo) ** sign
    else:
        out[j] = max(out[j] + sign * 0.5 * (hi - lo), 0.01)  # a damping ratio stays physical
    return out


#: How :func:`border_check` builds its wrong estimates.
BORDER_CONSTRUCTIONS = ("confidence", "box")


def _border_cases(cal: Calibrations, i: int, construction: str = "confidence") -> list:
    """``(label, operator, cab)``: the 16 wrong estimates of member ``i`` (:func:`border_check`)."""
    t, tc = cal.truth[i], cal.cab_truth[i]
    out = []
    if construction == "confidence":
        pts = cal.region_points[i]
        for k, p in enumerate(pts):
            out.append((f"axis{k // 2 + 1}{'+-'[k % 2]}", p, tc))
        t = cal.noise_free[i]  # the cab's cases with the operator a noise-free record tells
    else:
        for j, g in itertools.product(range(len(IDENTIFIED)), (-1, 1)):
            out.append(
                (f"{IDENTIFIED[j]}{'-+'[g > 0]}", _displaced(t, cal.bounds[i], LOG_AXES, j, g), tc)
            )
    for j, g in itertools.product(range(1, len(CAB_IDENTIFIED)), (-1, 1)):
        d = _displaced(tc, cal.cab_bounds[i], CAB_LOG_AXES, j, g)
        out.append((f"{CAB_IDENTIFIED[j]}{'-+'[g > 0]}", t, d))
    return out


def _border_chunk(family, rows, cal: Calibrations, spec, construction):
    with deterministic_solvers():
        labels, stable, holds = [], [], []
        for i, row in enumerate(rows):
            for label, h, c in _border_cases(cal, i, construction):
                K = damped_cancellation(
                    family,
                    dict(zip(IDENTIFIED, h)),
                    dict(zip(CAB_IDENTIFIED, c)),
                    spec,
                    valve=cal.valves[i],
                )
                labels.append(label)
                stable.append(bool(member_metrics(family, row[None, :], controller=K)[0][0] < 0))
                holds.append(bool(member_verdicts(family, row[None, :], K, spec).holds[0]))
        return labels, np.array(stable), np.array(holds)


def border_check(
    family,
    values,
    cal: Calibrations,
    *,
    spec=None,
    n_jobs: int = 1,
    construction="confidence",
) -> dict:
    """Designs from a wrong estimate within the error bound, checked on the true member.

    Per member, 16 compensators (:func:`damped_cancellation`) are designed from estimates a
    calibration may return while being wrong, and checked on the true member: is the loop
    stable (every pole in the open left half-plane), does the whole specification hold?

    ``construction="confidence"`` (the default): the operator's estimate on the boundary of
    the calibration's joint error region around the noise-free estimate
    (:attr:`Calibrations.region_points`: along each principal axis of the estimate's
    covariance, both ways, where the hand's response has moved
    :data:`designs.calibration.REGION_RADIUS` standard deviations as the fit measures it,
    :func:`designs.calibration.region_points`; 8 designs): the statistical error a record
    can have. The noise-free estimate (:func:`designs.calibration.noise_free_estimate`)
    carries the fit's bias, which the same record would carry without its noise. The cab's
    true modes moved as in the other construction, with the noise-free operator (8
    designs).

    ``construction="box"``: the member's true modes with one identified quantity moved to
    the edge of the member's marginal error bound (each of the operator's four and the cab's
    two modes' four, each way; the half-width of the bound, a factor for the frequencies),
    masses nominal as in every design. The true modes paired with nominal masses are not an
    estimate the fit returns (it compensates the held mass ratio by moving the modes, the
    bound's mass term), and one quantity moved alone to its marginal edge ignores the
    estimate's correlations, so this construction lies outside what a record can tell (the
    hand responses of its estimates lie a median 12 standard deviations from the noise-free
    estimate's, up to 180, on the first 50 members of ``bdft design scheduled``, against the
    region's 4.03); it is kept as the harsher check it was.

    Parameters
    ----------
    family : backhoe.Family
    values : array_like, shape (n, d)
        The members.
    cal : Calibrations
        Their calibrations (the bounds' widths, the region points, the noise-free
        estimates).
    spec : Specification, optional
    n_jobs : int
        Parallel processes.
    construction : {"confidence", "box"}
        How the wrong estimates are built (above).

    Returns
    -------
    dict
        ``members``, ``designs``, ``construction``, ``radius`` (standard deviations of the
        region; None for the box), ``stable`` (fraction of the designs),
        ``specification`` (fraction meeting the whole specification), ``unstable_by_case``
        (per case, e.g. ``"axis1+"`` or ``"f_low_hz-"``, the members whose loop it
        destabilised).
    """
    spec = spec or Specification()
    rows = np.atleast_2d(np.asarray(values, float))
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="border_check")
    if construction not in BORDER_CONSTRUCTIONS:
        raise ParameterError(
            f"border_check: construction must be one of {BORDER_CONSTRUCTIONS}; "
            f"got {construction!r}"
        )
    if construction == "confidence" and not np.all(np.isfinite(cal.region_points)):
        raise ParameterError(
            "border_check: the confidence construction needs every member's error region "
            "(calibrate_members with regions covering these members)"
        )
    size = 5  # 16 designs per member: small chunks keep both processes busy to the end
    chunks = [(i, min(i + size, len(rows))) for i in range(0, len(rows), size)]
    jobs = [
        functools.partial(_border_chunk, family, rows[a:b], cal[a:b], spec, construction)
        for a, b in chunks
    ]
    parts = _run(jobs, n_jobs)
    labels = [lab for p in parts for lab in p[0]]
    stable = np.concatenate([p[1] for p in parts])
    holds = np.concatenate([p[2] for p in parts])
    unstable: dict = {}
    for lab, ok in zip(labels, stable):
        unstable[lab] = unstable.get(lab, 0) + int(not ok)
    return {
        "members": len(rows),
        "designs": int(stable.size),
        "construction": construction,
        "radius": REGION_RADIUS if construction == "confidence" else None,
        "stable": float(stable.mean()),
        "specification": float(holds.mean()),
        "unstable_by_case": unstable,
    }


def operator_family(family, cal: Calibrations, i: int):
    """The family the calibration of member ``i`` leaves: its estimate within its bound.

    The identified quantities (:data:`designs.calibration.IDENTIFIED` as the arm's and the
    trunk's pairs, :data:`designs.calibration.CAB_IDENTIFIED` as the structure's, the less
    damped cab mode as the structure's first mode, as :func:`damped_cancellation`
    builds its member) range over their error bounds with the estimate as nominal; the
    masses, which the record does not tell, over the family's whole ranges; the valve is
    the machine's own (:attr:`Calibrations.valves`: its rig knows its cylinder loop).

    Parameters
    ----------
    family : backhoe.Family
        The family the member was drawn from.
    cal : Calibrations
        Calibrations (:func:`calibrate_members`).
    i : int
        Which of them.

    Returns
    -------
    (backhoe.Family, dict, dict)
        The family, the operator's and the cab's estimates.
    """
    h, c = dict(zip(IDENTIFIED, cal.estimates[i])), dict(zip(CAB_IDENTIFIED, cal.cabs[i]))
    hb, cb = dict(zip(IDENTIFIED, cal.bounds[i])), dict(zip(CAB_IDENTIFIED, cal.cab_bounds[i]))
    where = {name: (h[key], hb[key]) for name, key in OPERATOR_NAMES.items()}
    where.update({name: (c[key], cb[key]) for name, key in _cab_names(c).items()})
    fam = calibration_box(family, where, cal.valves[i], "calibrated operator")
    return fam, h, c


def _certify_chunk(family, cal: Calibrations, spec, max_boxes: int):
    with deterministic_solvers():
        out = []
        for i in range(len(cal)):
            fam_i, h, c = operator_family(family, cal, i)
            K = damped_cancellation(family, h, c, spec, valve=cal.valves[i])
            r = robust_margin(
                fam_i,
                controller=K,
                region=spec.region(),
                samples=200,
                max_boxes=max_boxes,
                ladder=6,
                iterations=3,
                time_limit_s=300.0,
                # the enclosures, about 6 core-seconds an operator: mu took 4-8 times longer
                # on these boxes (its scales up to the upper bound, often beyond the whole
                # calibration box), and only whether the whole box holds is reported
                method="eigenvalues",
            )
            out.append({"lower": r.lower, "upper": r.upper})
        return out


def operator_certificates(
    family, cal: Calibrations, *, spec=None, max_boxes: int = 60, n_jobs: int = 1
) -> dict:
    """Certified margins of each operator's design over the box its calibration bounds.

    For each calibrated member: the design made from its estimate
    (:func:`damped_cancellation`) and the robust margin
    (:func:`uncertainty.margins.robust_margin`, the specification's pole region) of
    :func:`operator_family`: ``lower`` certifies the region for every operator and cab
    within ``lower`` times the calibration's bounds (masses: that scale of their whole
    ranges); ``upper`` is the scale at which a member breaking it was found. A margin of
    at least 1 would prove the design for every operator the calibration's bound admits.

    Parameters
    ----------
    family : backhoe.Family
        The family the members were drawn from.
    cal : Calibrations
        Their calibrations (:func:`calibrate_members`).
    spec : Specification, optional
        Gives the pole region and the design's checks.
    max_boxes : int
        Sub-boxes of the certificate per scale.
    n_jobs : int
        Parallel processes.

    Returns
    -------
    dict
        ``members``, ``lower`` and ``upper`` (per member), ``certified_whole_bound`` (how
        many have ``lower >= 1``), ``median_lower``, ``median_upper``, ``max_boxes``.
    """
    spec = spec or Specification()
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="operator_certificates")
    # one member per task: the margins take unequal times, and pairs left one process idle
    chunks = [(i, i + 1) for i in range(len(cal))]
    jobs = [functools.partial(_certify_chunk, family, cal[a:b], spec, max_boxes) for a, b in chunks]
    res = [r for part in _run(jobs, n_jobs) for r in part]
    lower = [r["lower"] for r in res]
    upper = [r["upper"] for r in res]
    return {
        "members": len(res),
        "lower": lower,
        "upper": upper,
        "certified_whole_bound": int(sum(x >= 1.0 for x in lower)),
        "median_lower": float(np.median(lower)) if res else math.nan,
        "median_upper": float(np.median(upper)) if res else math.nan,
        "max_boxes": max_boxes,
    }
