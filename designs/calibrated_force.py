"""A calibrated handle-force design: each operator's force feedback from their own records.

The design, top to bottom:

1. set: handle force from the handle's encoder alone (the limit map's ``force/handle``):
   no accelerometer, no cylinder-reference correction;
2. calibration: the cab-shaking record of :mod:`designs.calibration` (the hand's response
   to the cab, and the cab's own gain and modes) and the force record of
   :mod:`designs.force_calibration` (the hand's response to the handle's force), fitted
   together (:func:`designs.force_calibration.identify_force` with the cab record's
   estimate): the arm's and the body's masses, both modes with their labels; the valve is
   the machine's own, which its rig knows (as for :mod:`designs.scheduled`);
3. the design delivered: the best handle-force controller of the limit map's Youla basis
   (:func:`designs.limit.member_controller`: the least RMS force meeting the specification,
   re-checked at every frequency) for the member the calibration identified, the pole
   region's damping raised as a margin for the calibration's errors (:func:`design_for`:
   the first of :data:`DESIGN_DAMPINGS` whose controller is verified within the device's
   force on the identified member); certainty equivalence, made at the calibration from the
   records alone;
4. coverage (:func:`calibrated_force_coverage`): on fresh Monte Carlo members (seed + 2,
   never used to build anything), each member's own two records, identification and
   design, and the whole specification checked on the *true* member, with the
   Clopper-Pearson bound of every design (:mod:`uncertainty.randomized`); beside it, on the
   first ``limit_samples`` of the same members, the member's own limit (the same synthesis
   with the true member and the specification's own region): what full knowledge gives on
   the same operators;
5. certificates (:func:`calibrated_force_certificates`): for the first few operators, the
   robust stability margin (:func:`uncertainty.margins.robust_margin`, mu on the
   specification's region) of the operator's design over the box the calibration bounds
   (:func:`force_operator_family`: the six quantities of the seated chain within their
   bounds, the cab's within its bounds, every other parameter over the family's range, the
   valve the machine's own). A margin of at least 1 proves the design for every operator and
   machine the calibration admits.

What it does and does not do is measured in ``bdft design calibrated-force`` (the CLI
prints the figures) and the tests: the design is certainty-equivalent, not synthesised
robust over the calibration's box; the certificate of step 5 is what tells how far the
box is covered.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import numpy as np

from backhoe.families.batched import closed_loop_matrices
from backhoe.model.blocks import VALVE_FIELDS
from designs.cab_calibration import identify_cab
from designs.cab_damper import _cab_names, _identified_row, _valve_params, calibration_box
from designs.calibration import IDENTIFIED, identify_operator
from designs.calibration_record import (
    CalibrationProtocol,
    excitation_responses,
    simulate_calibration,
)
from designs.coverage import COVERAGE_SEED_OFFSET
from designs.force_calibration import (
    FORCE_IDENTIFIED,
    ForceProtocol,
    identify_force,
    simulate_force_record,
)
from designs.limit_member import member_controller
from designs.spec import check_specification
from designs.specification import Specification
from robust.checks import check_int
from robust.engine import run_calls
from robust.errors import BDFTError
from robust.synthesis.solve import deterministic_solvers
from uncertainty import sample
from uncertainty.margins import robust_margin
from uncertainty.randomized import DEFAULT_CONFIDENCE, CoverageBound

__all__ = [
    "ACTUATORS",
    "SENSORS",
    "DESIGN_DAMPINGS",
    "BOX_MEMBERS",
    "OperatorCalibration",
    "calibrate_operator",
    "design_for",
    "force_operator_family",
    "CalibratedForceCoverage",
    "calibrated_force_coverage",
    "calibrated_force_certificates",
]

#: The limit map's actuator and sensor sets the design uses.
ACTUATORS, SENSORS = "force", "handle"
#: The damping ratios the design may ask of the identified member's poles in the
#: specification's band, tried in this order (the specification asks 0.1; measured on 60
#: members, a fixed 0.1, 0.12, 0.15 and 0.2 covered 3, 4, 6 and 4 of them, the larger
#: ratios leaving more identified members without a design within the device's force).
DESIGN_DAMPINGS = (0.15, 0.12, 0.1)
#: Members of the calibration's box whose poles are checked under each design (seeded per
#: operator; a figure of the design, not a choice).
BOX_MEMBERS = 32
#: Members per parallel task.
_CHUNK = 10


@dataclasses.dataclass(frozen=True)
class OperatorCalibration:
    """One operator's two records' estimates, and the member they identify.

    Parameters
    ----------
    row : numpy.ndarray
        The identified member's parameter values (``family.names``' order).
    force : designs.force_calibration.ForceEstimate
        The seated chain's estimate from both records.
    cab : designs.calibration.OperatorEstimate
        The cab's estimate (:data:`designs.cab_calibration.CAB_IDENTIFIED`).
    valve : numpy.ndarray
        The machine's own valve/cylinder (:data:`backhoe.model.blocks.VALVE_FIELDS`).
    """

    row: np.ndarray
    force: object
    cab: object
    valve: np.ndarray


def _record_seeds(seed: int) -> tuple[int, int]:
    """The cab record's seed and the force record's, apart (one seed sequence)."""
    a, b = np.random.SeedSequence([int(seed), 7]).generate_state(2)
    return int(a), int(b)


def calibrate_operator(family, row, *, seed: int) -> OperatorCalibration:
    """Both records of the member ``row``, simulated, and what they identify.

    Parameters
    ----------
    family : backhoe.Family
        The family (physical human).
    row : array_like
        The true member.
    seed : int
        Seeds both records (apart).

    Returns
    -------
    OperatorCalibration
    """
    loop = family.member(np.asarray(row, float))
    s_cab, s_force = _record_seeds(seed)
    rec = simulate_calibration(loop, seed=s_cab)
    resp = excitation_responses(rec)
    e = identify_operator(rec, family, loop.handle_gain, responses=resp)
    c = identify_cab(rec, loop, None, family, responses=resp)
    fe = identify_force(
        simulate_force_record(loop, seed=s_force), family, loop.handle_gain, cab_estimate=e
    )
    est = _identified_row(
        family, dict(zip(IDENTIFIED, [e.values[k] for k in IDENTIFIED])), c.values
    )
    for k in FORCE_IDENTIFIED:
        est[family.names.index(k)] = fe.values[k]
    valve = np.array([getattr(loop.valve, f) for f in VALVE_FIELDS], float)
    return OperatorCalibration(row=est, force=fe, cab=c, valve=valve)


def _box_poles_hold(box, rows, K, region) -> int:
    """How many of the box's members ``rows`` keep their closed-loop poles in ``region``."""
    A = closed_loop_matrices(box, rows, controller=K, check_bounds=False)
    if not np.all(np.isfinite(A)):
        return 0
    return int((region.violation(np.linalg.eigvals(A)) <= 0).sum())


def design_for(family, cal: OperatorCalibration, spec: Specification | None = None, *, seed=0):
    """The operator's handle-force controller from their calibration (module notes, step 3).

    Each damping ratio of :data:`DESIGN_DAMPINGS` in turn is asked of the identified
    member's poles (the rest of the specification as it is); the first candidate verified
    on the identified member within the device's force is the design, else the first with a
    controller. Beside it, how many of :data:`BOX_MEMBERS` members drawn from the
    calibration's box (:func:`force_operator_family`, seeded with ``seed``) keep the pole
    region under it: what the calibration's errors leave of the design.

    Parameters
    ----------
    family : backhoe.Family
    cal : OperatorCalibration
        :func:`calibrate_operator`'s.
    spec : Specification, optional
    seed : int
        Seed of the box's members.

    Returns
    -------
    (designs.limit.SetLimit, control.StateSpace or None, dict)
        The identified member's limit, its controller (inputs ``x``, output ``f``; ``None``
        where no candidate met tracking and feedthrough on it) and the choice:
        ``damping`` asked, ``box_members`` and how many kept the region (``box_held``).
    """
    spec = spec or Specification()
    hat = family.member(cal.row, check_bounds=False).replace(valve=_valve_params(cal.valve))
    first = chosen = None
    for z in DESIGN_DAMPINGS:
        res, K = member_controller(
            hat, ACTUATORS, SENSORS, dataclasses.replace(spec, min_damping=max(spec.min_damping, z))
        )
        if K is None:
            continue
        if res.verified and res.required_force <= 1.0:
            chosen = (res, K, z)
            break
        first = first or (res, K, z)
    chosen = chosen or first
    if chosen is None:
        return res, None, {"damping": None, "box_members": BOX_MEMBERS, "box_held": 0}
    res, K, z = chosen
    box = force_operator_family(family, cal)
    rows = np.asarray(sample(box.parameters, BOX_MEMBERS, seed=int(seed)).values, float)
    held = _box_poles_hold(box, rows, K, spec.region())
    return res, K, {"damping": z, "box_members": BOX_MEMBERS, "box_held": held}


def force_operator_family(family, cal: OperatorCalibration):
    """The family the operator's calibration leaves (module notes, step 5).

    Parameters
    ----------
    family : backhoe.Family
    cal : OperatorCalibration

    Returns
    -------
    backhoe.Family
    """
    where = {k: (cal.force.values[k], cal.force.bounds[k]) for k in FORCE_IDENTIFIED}
    for name, key in _cab_names(cal.cab.values).items():
        where[name] = (cal.cab.values[key], cal.cab.bounds[key])
    return calibration_box(family, where, cal.valve, "force-calibrated operator")


def _coverage_chunk(family, rows, seeds, spec, limits):
    with deterministic_solvers():
        out = []
        for row, s, lim in zip(rows, seeds, limits):
            cal = calibrate_operator(family, row, seed=int(s))
            res, K, choice = design_for(family, cal, spec, seed=int(s))
            true = family.member(row)
            if K is None:
                holds, binding = False, f"no design ({res.binding})"
            else:
                chk = check_specification([true], K, spec, seed=int(s))
                holds, binding = bool(chk.holds), chk.binding
            limit = None
            if lim:
                Kt = member_controller(true, ACTUATORS, SENSORS, spec)[1]
                limit = bool(
                    Kt is not None and check_specification([true], Kt, spec, seed=int(s)).holds
                )
            inside = all(cal.force.contains(dict(zip(family.names, row))).values())
            out.append((holds, binding, limit, inside, choice["damping"]))
        return out


@dataclasses.dataclass(frozen=True)
class CalibratedForceCoverage:
    """The calibrated design's coverage and its comparison with full knowledge.

    Parameters
    ----------
    coverage : uncertainty.randomized.CoverageBound
        Over the fresh Monte Carlo members.
    binding : dict
        Failing members per binding constraint (``"no design (...)"`` where the identified
        member got no controller).
    limit : dict
        On the first ``limit_samples`` members: ``samples``, ``covered`` (the member's own
        limit within the device's force), ``calibrated`` (the calibrated design's verdict on
        the same members), ``ratio`` (calibrated over limit).
    operator_within_bound : float
        Fraction of members whose six quantities lay within the force calibration's bounds.
    dampings : dict
        Members per damping ratio the design asked (:func:`design_for`; ``"none"``: no
        design).
    seed : int
        The coverage sample's seed.
    """

    coverage: CoverageBound
    binding: dict
    limit: dict
    operator_within_bound: float
    dampings: dict
    seed: int

    def to_json(self) -> dict:
        """JSON-ready."""
        return {
            "coverage": dataclasses.asdict(self.coverage)
            | {
                "fraction": self.coverage.fraction,
                "epsilon": self.coverage.epsilon,
                "lower": self.coverage.lower,
            },
            "binding": dict(self.binding),
            "limit": dict(self.limit),
            "operator_within_bound": self.operator_within_bound,
            "dampings": dict(self.dampings),
            "seed": self.seed,
        }


def _seeds(s: int, n: int) -> np.ndarray:
    """The records' seeds of ``n`` members of the sample drawn with ``s``."""
    return s * 100_003 + np.arange(n)


def _counts(labels) -> dict:
    out: dict = {}
    for lab in labels:
        out[lab] = out.get(lab, 0) + 1
    return dict(sorted(out.items()))


def calibrated_force_coverage(
    family,
    *,
    samples: int = 2000,
    limit_samples: int = 200,
    seed: int = 0,
    spec: Specification | None = None,
    confidence: float = DEFAULT_CONFIDENCE,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> CalibratedForceCoverage:
    """The calibrated design's coverage on fresh members (module notes, step 4).

    Parameters
    ----------
    family : backhoe.Family
        The family (physical human).
    samples : int
        Monte Carlo members, drawn with ``seed + 2``.
    limit_samples : int
        Of them, how many also get their own limit (about as costly as the design).
    seed : int
        The design's seed.
    spec : Specification, optional
    confidence : float
        Of the coverage bound.
    n_jobs : int
        Parallel processes (the same numbers in any count).
    progress : callable, optional
        ``progress(done, total)``.

    Returns
    -------
    CalibratedForceCoverage
    """
    spec = spec or Specification()
    samples = check_int("samples", samples, low=1, owner="calibrated_force_coverage")
    limit_samples = check_int(
        "limit_samples", limit_samples, low=0, owner="calibrated_force_coverage"
    )
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="calibrated_force_coverage")
    s = seed + COVERAGE_SEED_OFFSET
    rows = np.asarray(sample(family.parameters, samples, seed=s).values, float)
    seeds = _seeds(s, samples)
    lim = np.arange(samples) < limit_samples
    chunks = [(i, min(i + _CHUNK, samples)) for i in range(0, samples, _CHUNK)]
    calls = [
        functools.partial(_coverage_chunk, family, rows[a:b], seeds[a:b], spec, lim[a:b])
        for a, b in chunks
    ]
    done = [0]

    def step(i):
        done[0] += chunks[i][1] - chunks[i][0]
        if progress:
            progress(done[0], samples)

    res = [r for part in run_calls(calls, jobs=n_jobs, progress=step) for r in part]
    holds = np.array([r[0] for r in res], bool)
    binding: dict = {}
    for ok, b, *_ in res:
        if not ok:
            binding[b] = binding.get(b, 0) + 1
    lim_res = [(r[0], r[2]) for r in res if r[2] is not None]
    covered = int(sum(b for _, b in lim_res))
    calibrated = int(sum(a for a, _ in lim_res))
    limit = {
        "samples": len(lim_res),
        "covered": covered,
        "calibrated": calibrated,
        "coverage": covered / len(lim_res) if lim_res else math.nan,
        "calibrated_coverage": calibrated / len(lim_res) if lim_res else math.nan,
        "ratio": calibrated / covered if covered else math.nan,
    }
    cov = CoverageBound(
        samples=samples, failures=int((~holds).sum()), confidence=confidence, seed=s, method="mc"
    )
    return CalibratedForceCoverage(
        coverage=cov,
        binding=dict(sorted(binding.items(), key=lambda kv: -kv[1])),
        limit=limit,
        operator_within_bound=float(np.mean([r[3] for r in res])),
        dampings=_counts(["none" if r[4] is None else f"{r[4]:g}" for r in res]),
        seed=s,
    )


def _certify_one(family, row, seed, spec, time_limit_s, iterations, search_samples):
    with deterministic_solvers():
        cal = calibrate_operator(family, row, seed=int(seed))
        res, K, choice = design_for(family, cal, spec, seed=int(seed))
        if K is None:
            return {"designed": False, "binding": res.binding}
        try:
            r = robust_margin(
                force_operator_family(family, cal),
                controller=K,
                region=spec.region(),
                samples=search_samples,
                ladder=6,
                iterations=iterations,
                time_limit_s=time_limit_s,
                method="mu",
            )
        except BDFTError as e:  # the certificate's own check refused its answer
            return {"designed": True, "error": str(e), "order": int(K.nstates), "choice": choice}
        return {
            "designed": True,
            "lower": r.lower,
            "upper": r.upper,
            "method": r.method,
            "order": int(K.nstates),
            "choice": choice,
        }


def calibrated_force_certificates(
    family,
    *,
    operators: int = 3,
    seed: int = 0,
    spec: Specification | None = None,
    time_limit_s: float = 300.0,
    n_jobs: int = 1,
    rows=None,
    population: int = 2000,
    iterations: int = 2,
    search_samples: int = 200,
) -> dict:
    """Certified margins of operators' designs over their calibration's box (module notes,
    step 5): the first ``operators`` members of a sample of ``population`` drawn with the
    coverage sample's seed.

    Parameters
    ----------
    family : backhoe.Family
    operators : int
        How many.
    seed : int
        The design's seed.
    spec : Specification, optional
    time_limit_s : float
        Per certificate.
    n_jobs : int
        Parallel processes.
    rows : array_like, optional
        The operators' true members (``family.names``' order) instead of ``operators``
        draws; their records are seeded as the first draws' would be.
    population : int
        Size of the Monte Carlo sample the operators are the first members of: with the
        coverage's sample size (:func:`calibrated_force_coverage`'s ``samples``) they are the
        coverage's first members, with the same records and designs.
    iterations : int
        Bisection steps of each margin after its first certified scale (0: the first of
        15/16, 7/8, 3/4 of the upper bound that mu certifies, then halving).
    search_samples : int
        Latin-hypercube members of the upper bound's search (its local searches start from
        the worst of them).

    Returns
    -------
    dict
        ``members`` (per operator: ``lower``, ``upper``, ``method``, ``order``, ``choice``,
        or ``designed: False``), ``certified_whole_bound`` (how many reach 1).
    """
    spec = spec or Specification()
    s = seed + COVERAGE_SEED_OFFSET
    if rows is None:
        operators = check_int("operators", operators, low=0, owner="calibrated_force_certificates")
        population = check_int(
            "population", population, low=max(operators, 1), owner="calibrated_force_certificates"
        )
        rows = np.asarray(sample(family.parameters, population, seed=s).values, float)
        rows = rows[:operators]
    else:
        rows = family.check_members(rows, where="calibrated_force_certificates")
    iterations = check_int("iterations", iterations, low=0, owner="calibrated_force_certificates")
    search_samples = check_int(
        "search_samples", search_samples, low=1, owner="calibrated_force_certificates"
    )
    seeds = _seeds(s, len(rows))
    calls = [
        functools.partial(
            _certify_one, family, rows[i], seeds[i], spec, time_limit_s, iterations, search_samples
        )
        for i in range(len(rows))
    ]
    out = run_calls(calls, jobs=n_jobs) if calls else []
    return {
        "members": out,
        "certified_whole_bound": int(sum(m.get("lower", 0.0) >= 1.0 for m in out)),
        "time_limit_s": time_limit_s,
    }


#: The design's name in ``bdft design``.
DESIGN_NAME = "calibrated-force"
#: One line of what it is, for ``bdft design --list``.
DESCRIPTION = (
    "per-operator handle-force feedback from two calibration records (the cab shaken, the "
    "handle pushed), certified over what the calibration allows"
)


def calibrated_force_design(
    family,
    *,
    samples: int = 2000,
    limit_samples: int = 200,
    certify: int = 3,
    seed: int = 0,
    spec: Specification | None = None,
    time_limit_s: float = 300.0,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> dict:
    """The calibrated handle-force design's figures (module notes), JSON-ready.

    Parameters
    ----------
    family : backhoe.Family
        The family (physical human).
    samples, limit_samples : int
        :func:`calibrated_force_coverage`'s (``samples`` 0 skips the coverage).
    certify : int
        Operators certified (:func:`calibrated_force_certificates`; 0 skips them).
    seed : int
        The design's seed.
    spec : Specification, optional
    time_limit_s : float
        Per certificate, s.
    n_jobs : int
        Parallel processes.
    progress : callable, optional
        ``progress(done, total)`` of the coverage.

    Returns
    -------
    dict
        ``name``, ``set`` (actuators and sensors), ``design_damping``, ``protocols`` (both
        records'), ``coverage`` (:meth:`CalibratedForceCoverage.to_json`, or ``None``),
        ``certificates`` (or ``None``), ``specification``, ``seed``.
    """
    spec = spec or Specification()
    samples = check_int("samples", samples, low=0, owner="calibrated_force_design")
    certify = check_int("certify", certify, low=0, owner="calibrated_force_design")
    cov = None
    if samples:
        cov = calibrated_force_coverage(
            family,
            samples=samples,
            limit_samples=min(limit_samples, samples),
            seed=seed,
            spec=spec,
            n_jobs=n_jobs,
            progress=progress,
        ).to_json()
    cert = None
    if certify:
        cert = calibrated_force_certificates(
            family,
            operators=certify,
            seed=seed,
            spec=spec,
            time_limit_s=time_limit_s,
            n_jobs=n_jobs,
            population=max(samples, certify),
        )
    return {
        "name": DESIGN_NAME,
        "description": DESCRIPTION,
        "set": {"actuators": ACTUATORS, "sensors": SENSORS},
        "design_dampings": list(DESIGN_DAMPINGS),
        "box_members": BOX_MEMBERS,
        "protocols": {
            "cab": dataclasses.asdict(CalibrationProtocol()),
            "force": dataclasses.asdict(ForceProtocol()),
        },
        "coverage": cov,
        "certificates": cert,
        "specification": spec.to_json(),
        "seed": seed,
    }
