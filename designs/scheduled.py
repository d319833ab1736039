"""A per-operator design: a short calibration picks (or builds) the compensator.

The design, top to bottom:

1. set: the cylinder reference shaped from the cab accelerometer (the limit map's
   ``reference/handle+cab``, :data:`LIMIT_SET`), whose limit coverage at the Omni's own
   force limits is the highest of the map's sets (every reference set reaches it; no
   handle force is used);
2. what is scheduled on: what the calibration identifies (:mod:`designs.calibration`):
   the seated chain's two modes, each a natural frequency and a damping ratio, ordered by
   frequency (:data:`designs.calibration.IDENTIFIED`), and the cab's gain and two modes
   (:data:`designs.calibration.CAB_IDENTIFIED`), each with an error bound
   (:class:`Calibrations`);
3. the design delivered (:data:`DESIGN_RULE`, :func:`damped_cancellation`), made at each
   operator's calibration from the record alone: the model-based cancellation of the
   identified human's hand motion (:func:`designs.cancellation.cancellation_controller`
   of that human, masses nominal) plus a damper of the identified cab's less damped mode
   (a band-pass from the accelerometer to the reference, :func:`cab_damper`), its phase and
   gain the candidates' (:data:`DAMPER_PHASES` x :data:`DAMPER_GAINS`, or none) with the
   smallest largest utilisation on the identified member (with the machine's own valve:
   the machine measures the cylinder position its PI loop closes on, so its rig knows its
   cylinder loop; :attr:`Calibrations.valves`); the candidates' closed loops are
   evaluated together in numpy (checked against :func:`designs.spec.check_specification`
   in the tests);
4. the bank beside it: a grid of ``cells_per_axis`` intervals per identified quantity of
   the operator over the family's ranges (logarithmic in the frequencies, linear in the
   damping ratios; a cell whose lower mode's frequency interval lies wholly above the
   upper mode's is dropped), one compensator per cell: the cancellation built from the
   cell centre's human; selection rule (:meth:`ScheduledBank.select`): the cell that
   contains the estimate, clipped to the grid first; the design of step 3 is the limit of
   ever finer cells, each operator's cell the box its calibration bounds;
5. coverage (:func:`continuous_coverage`, :func:`bank_coverage`): on fresh Monte Carlo
   members (seed + 2, never used to build anything), each member's own simulated
   calibration record, identification, design or selection, and the whole specification
   checked on the true member; Clopper-Pearson bound as for every design
   (:mod:`uncertainty.randomized`); beside it how often the true operator lies within the
   calibration's bound (the design's "right cell") or the selected cell is the cell of
   the member's true modes, whether a wrong choice keeps the loop stable
   (:func:`border_check` for the design: estimates wrong by the bound's half-width), and
   the coverage against the number of cells.

What it does and does not do (measured, see the tests, ``benchmarks/bench_calibration.py``
and ``bdft design scheduled``): a cancellation needs the hand's response to within a few
percent (only about 9 % of the family's uncompensated loops are stable), so coarse cells
cover almost nobody. Built from the record's own estimate, the design is stable for every
estimate on the boundary of the calibration's joint error region (4.03 standard deviations
of the hand's response around what the record without its noise identifies, the 99.73 %
region; :func:`border_check`, measured on 200 members). It is not robust to errors the
record rules out: the true modes paired with the nominal masses, or one mode moved alone to
its marginal bound, destabilise about one design in ten (the box construction of
:func:`border_check`). Over the marginal box its calibration bounds no design is certified
(:func:`operator_certificates`: margins of a few hundredths of the bound, members breaking
the region within a third of it): the box holds hand responses no record of the operator
gives. The damper acts on one cab mode, and most members it still fails are members where
the identified member meets the specification and the true one does not (the cancellation's
mismatch).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from backhoe.model.blocks import VALVE_FIELDS
from designs.cab_damper import (
    DAMPER_GAINS,
    DAMPER_PHASES,
    cab_damper,
    damped_cancellation,
    member_valve,
)
from designs.cab_damper import TIE_RTOL as TIE_RTOL
from designs.cab_damper import _damper_candidates as _damper_candidates
from designs.cab_damper import _identified_row as _identified_row
from designs.cab_damper import _utilisations as _utilisations
from designs.calibration_record import CalibrationProtocol
from designs.constants import CELLS_PER_AXIS
from designs.coverage import COVERAGE_SEED_OFFSET
from designs.limit import limit_map
from designs.scheduled_bank import LIMIT_SET, BankCoverage, ScheduledBank, bank_coverage, build_bank
from designs.scheduled_calibrations import Calibrations, calibrate_members
from designs.scheduled_checks import (
    border_check,
    cancellation_gap,
    continuous_coverage,
    operator_certificates,
    operator_family,
)
from designs.specification import Specification
from robust.checks import check_int
from uncertainty import sample
from uncertainty.randomized import CoverageBound

__all__ = [
    "LIMIT_SET",
    "CELLS_PER_AXIS",
    "ScheduledBank",
    "build_bank",
    "BankCoverage",
    "bank_coverage",
    "calibrate_members",
    "scheduled_design",
    "continuous_coverage",
    "cancellation_gap",
    "cab_damper",
    "damped_cancellation",
    "DAMPER_PHASES",
    "DAMPER_GAINS",
    "DESIGN_RULE",
    "VALVE_FIELDS",
    "member_valve",
    "Calibrations",
    "border_check",
    "operator_family",
    "operator_certificates",
]

#: Members (the first of the coverage members) whose joint error region is computed.
REGION_SAMPLES = 200
# CELLS_PER_AXIS (default cells per identified quantity) is defined in designs.constants
# (the command line reads it without NumPy)
#: What ``bdft design scheduled`` delivers, in one sentence (its JSON ``design``).
DESIGN_RULE = (
    "at each operator's calibration: the cancellation of the identified human (masses "
    "nominal) plus a damper of the identified cab's less damped mode, its phase and gain "
    "picked from damper_candidates on the identified member (damped_cancellation)"
)


def scheduled_design(
    family,
    *,
    cells_per_axis: int = CELLS_PER_AXIS,
    samples: int = 2000,
    seed: int = 0,
    cells_sweep=(1, 2, 3, 5),
    sweep_samples: int = 400,
    border_samples: int = 50,
    certify_samples: int = 10,
    limit_samples: int = 64,
    protocol: CalibrationProtocol | None = None,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[ScheduledBank, dict]:
    """The design made at each operator's calibration, its coverage, and the banks beside it.

    Parameters
    ----------
    family : backhoe.Family
    cells_per_axis : int
        Cells per identified quantity of the bank written with the result.
    samples : int
        Fresh Monte Carlo members of the coverage certificate (seed ``seed + 2``), each
        with its own simulated calibration (the first :data:`REGION_SAMPLES`, or
        ``border_samples`` if more, also with the joint error region: the coverage's
        ``estimate_within_confidence_region`` over ``confidence_region_samples``).
    seed : int
        Design seed; the members are drawn with ``seed + 2``, their records ``seed + 2 +
        1000 + i``.
    cells_sweep : sequence of int
        Cells per axis of the banks compared (on the first ``sweep_samples`` members),
        followed by the cancellation built from each operator's estimate without and with
        the cab's damper.
    sweep_samples : int
        Members of the comparison.
    border_samples : int
        Members (the first of the coverage members) of :func:`border_check`, both
        constructions (``wrong_within_bound``: the joint error region, ``wrong_within_box``:
        the marginal box around the true modes; 0 skips it).
    certify_samples : int
        Members (the first of the coverage members) whose design's robust margin over the
        box its calibration bounds is computed (:func:`operator_certificates`, about 6
        core-seconds each; 0 skips it).
    limit_samples : int
        Latin-hypercube members of the limit map computed for the default sets at the
        Omni's force (:func:`designs.limit.limit_map`, seed ``seed``): which set covers
        most, and the design's coverage as a fraction of its own set's (0 skips it).
    protocol : CalibrationProtocol, optional
    n_jobs : int
        Parallel processes.
    progress : callable, optional
        ``progress(done, total)`` of the calibrations.

    Returns
    -------
    (ScheduledBank, dict)
        The bank and the JSON-ready result (``coverage``, ``bank``, ``coverage_by_cells``,
        ``wrong_within_bound``, ``wrong_within_box``, ``limit``...).
    """
    samples = check_int("samples", samples, low=1, owner="scheduled_design")
    border_samples = check_int("border_samples", border_samples, low=0, owner="scheduled_design")
    certify_samples = check_int("certify_samples", certify_samples, low=0, owner="scheduled_design")
    spec = Specification()
    mseed = seed + COVERAGE_SEED_OFFSET
    rows = sample(family.parameters, samples, method="mc", seed=mseed).values
    n_reg = min(samples, max(border_samples, REGION_SAMPLES))
    cal = calibrate_members(
        family,
        rows,
        seed=mseed + 1000,
        protocol=protocol,
        n_jobs=n_jobs,
        progress=progress,
        regions=n_reg,
    )
    est, truth, inside = cal.estimates, cal.truth, cal.operator_inside
    holds, binding = continuous_coverage(
        family, rows, est, cabs=cal.cabs, spec=spec, n_jobs=n_jobs, binding=True
    )
    bound = CoverageBound(samples=len(rows), failures=int((~holds).sum()), seed=mseed)
    failures: dict = {}
    for ok, b in zip(holds, binding):
        if not ok:
            failures[b] = failures.get(b, 0) + 1
    coverage = dict(
        bound.to_json(),
        failures_by_constraint=dict(sorted(failures.items())),
        operator_within_error_bound=float(np.mean(inside)),
        estimate_within_confidence_region=float(np.mean(cal.within_confidence_region)),
        confidence_region_samples=n_reg,
        cab_within_error_bound=float(np.mean(cal.cab_inside)),
    )
    m = min(sweep_samples, samples)
    bank = build_bank(family, cells_per_axis)
    sweep = []
    bank_cov = None
    for n in sorted(set(cells_sweep) | {cells_per_axis}):
        b = bank if n == cells_per_axis else build_bank(family, n)
        c = bank_coverage(
            b, family, rows[:m], est[:m], truth[:m], inside[:m], seed=mseed, n_jobs=n_jobs
        )
        if n == cells_per_axis:
            bank_cov = c
        if n in cells_sweep:
            sweep.append(
                {
                    "cells_per_axis": n,
                    "cells": len(b.cells),
                    "samples": m,
                    "fraction": c.bound.fraction,
                    "right_cell": c.right_cell,
                }
            )
    plain = continuous_coverage(family, rows[:m], est[:m], spec=spec, n_jobs=n_jobs)
    for label, frac in (
        ("continuous", float(np.mean(plain))),
        ("continuous with the cab damper", float(np.mean(holds[:m]))),
    ):
        sweep.append(
            {
                "cells_per_axis": None,
                "cells": label,
                "samples": m,
                "fraction": frac,
                "right_cell": None,
            }
        )
    nb = min(border_samples, samples)
    border = border_check(family, rows[:nb], cal[:nb], spec=spec, n_jobs=n_jobs) if nb else None
    box = (
        border_check(family, rows[:nb], cal[:nb], spec=spec, n_jobs=n_jobs, construction="box")
        if nb
        else None
    )
    nc = min(certify_samples, samples)
    certified = operator_certificates(family, cal[:nc], spec=spec, n_jobs=n_jobs) if nc else None
    pr = protocol or CalibrationProtocol()
    limit = None
    if limit_samples:
        lm = limit_map(family, samples=limit_samples, seed=seed, force_scales=(1.0,), n_jobs=n_jobs)
        by_set = {name: lm.coverage(name, 1.0) for name in lm.sets}
        top = max(by_set.values())
        limit = {
            "samples": limit_samples,
            "seed": seed,
            "coverage_by_set": by_set,
            "best_sets": [k for k, v in by_set.items() if v == top],
            "coverage": by_set[LIMIT_SET],
            "fraction_of_limit": bound.fraction / by_set[LIMIT_SET]
            if by_set[LIMIT_SET] > 0
            else None,
        }
    return bank, {
        "name": "scheduled",
        "design": DESIGN_RULE,
        "limit_set": LIMIT_SET,
        "force_scale": 1.0,
        "limit": limit,
        "coverage": coverage,
        "wrong_within_bound": border,
        "wrong_within_box": box,
        "certified_over_bound": certified,
        "bank": dict(bank_cov.to_json(), cells_per_axis=cells_per_axis),
        "coverage_by_cells": sweep,
        "damper_candidates": {"phases_rad": list(DAMPER_PHASES), "gains": list(DAMPER_GAINS)},
        "calibration": dataclasses.asdict(pr),
    }
