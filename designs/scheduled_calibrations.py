"""The members' calibrations: each member's simulated record, its operator and cab
estimates, their bounds and error regions.

:func:`calibrate_members` runs, per member, the calibration of :mod:`designs.calibration`
(record, identification of the operator and of the cab, optionally the noise-free
estimate and the joint error region) and gathers the results in :class:`Calibrations`;
the members are taken in chunks on worker processes (``_run``, through
:func:`robust.engine.run_calls`). The coverage and border checks of
:mod:`designs.scheduled_checks` start from these.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

import numpy as np

from backhoe.model.blocks import VALVE_FIELDS
from designs.cab_calibration import CAB_IDENTIFIED, cab_truth, identify_cab
from designs.calibration import IDENTIFIED, identify_operator, noise_free_estimate, operator_truth
from designs.calibration_record import (
    CalibrationProtocol,
    excitation_responses,
    simulate_calibration,
)
from designs.calibration_region import REGION_RADIUS, region_points, response_distance
from robust.checks import check_int
from robust.engine import run_calls
from robust.synthesis.solve import deterministic_solvers

__all__ = ["Calibrations", "calibrate_members"]


@dataclasses.dataclass(frozen=True)
class Calibrations:
    """Members' simulated calibrations and what they identified (:func:`calibrate_members`).

    Parameters
    ----------
    estimates, truth : numpy.ndarray, shape (n, 4)
        The operators' estimates and true values of :data:`designs.calibration.IDENTIFIED`.
    bounds : numpy.ndarray, shape (n, 4, 2)
        Each estimate's error bound (low, high).
    cabs, cab_truth : numpy.ndarray, shape (n, 5)
        The cabs' estimates and true values of :data:`designs.calibration.CAB_IDENTIFIED`.
    cab_bounds : numpy.ndarray, shape (n, 5, 2)
        Their error bounds.
    noise_free : numpy.ndarray, shape (n, 4)
        What each record without its noise identifies
        (:func:`designs.calibration.noise_free_estimate`; NaN where not computed, with the
        two following).
    region_points : numpy.ndarray, shape (n, 8, 4)
        The joint error region's principal points around each noise-free estimate
        (:func:`designs.calibration.region_points`, radius
        :data:`designs.calibration.REGION_RADIUS`).
    region_distance : numpy.ndarray, shape (n,)
        Each estimate's distance from its noise-free estimate, in standard deviations of
        the hand's response (:func:`designs.calibration.response_distance`).
    valves : numpy.ndarray, shape (n, 4)
        Each machine's valve/cylinder (:data:`VALVE_FIELDS`: ``K_VC``, ``p1`` rad/s,
        ``wn_hz`` Hz, ``zeta``), which its rig knows: the machine measures the cylinder
        position its PI loop closes on, so the record's cylinder loop is its own
        (:func:`designs.calibration.identify_cab` divides by it); the designs made at the
        calibration are made with it.
    """

    estimates: np.ndarray
    truth: np.ndarray
    bounds: np.ndarray
    cabs: np.ndarray
    cab_truth: np.ndarray
    cab_bounds: np.ndarray
    noise_free: np.ndarray
    region_points: np.ndarray
    region_distance: np.ndarray
    valves: np.ndarray

    @property
    def operator_inside(self) -> np.ndarray:
        """Per member: every quantity of the operator within its bound."""
        return _within(self.truth, self.bounds)

    @property
    def within_confidence_region(self) -> np.ndarray:
        """Per member with a region: the estimate within the joint error region (radius
        :data:`designs.calibration.REGION_RADIUS`) around the noise-free estimate."""
        d = self.region_distance
        return d[np.isfinite(d)] <= REGION_RADIUS

    @property
    def cab_inside(self) -> np.ndarray:
        """Per member: every quantity of the cab within its bound."""
        return _within(self.cab_truth, self.cab_bounds)

    def __getitem__(self, index) -> Calibrations:
        return Calibrations(*(getattr(self, f.name)[index] for f in dataclasses.fields(self)))

    def __len__(self) -> int:
        return len(self.estimates)


def _run(calls, n_jobs: int) -> list:
    """Calls (partials) in ``n_jobs`` processes (in this one for 1 or a single call), in order."""
    return run_calls(list(calls), jobs=n_jobs)


def _within(values: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    return np.all((bounds[..., 0] <= values) & (values <= bounds[..., 1]), axis=1)


def _calibrate_chunk(family, rows, seeds, protocol, regions):
    with deterministic_solvers():
        out = [[] for _ in dataclasses.fields(Calibrations)]
        for row, s, region in zip(rows, seeds, regions):
            loop = family.member(row)
            rec = simulate_calibration(loop, protocol, seed=int(s))
            resp = excitation_responses(rec, protocol)
            e = identify_operator(rec, family, loop.handle_gain, protocol, responses=resp)
            t = operator_truth(family, row)
            c = identify_cab(rec, loop, protocol, family, responses=resp)
            ev = [e.values[k] for k in IDENTIFIED]
            if region:
                nf = noise_free_estimate(loop, family, e, protocol, seed=int(s))
                pts = region_points(family, e, nf, loop.handle_gain)[0]
                dist = response_distance(family, e, ev, nf, loop.handle_gain)[0]
            else:
                nf, pts, dist = np.full(4, np.nan), np.full((8, 4), np.nan), np.nan
            ct_ = cab_truth(family, row)
            for j, v in enumerate(
                (
                    ev,
                    [t[k] for k in IDENTIFIED],
                    [e.bounds[k] for k in IDENTIFIED],
                    [c.values[k] for k in CAB_IDENTIFIED],
                    [ct_[k] for k in CAB_IDENTIFIED],
                    [c.bounds[k] for k in CAB_IDENTIFIED],
                    nf,
                    pts,
                    dist,
                    [getattr(loop.valve, f) for f in VALVE_FIELDS],
                )
            ):
                out[j].append(v)
        return Calibrations(*(np.array(v, float) for v in out))


def calibrate_members(
    family,
    values,
    *,
    seed: int = 0,
    protocol: CalibrationProtocol | None = None,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
    regions: int | None = None,
) -> Calibrations:
    """Each member's simulated calibration and identification (record ``i`` seeded ``seed + i``).

    The operator (:func:`designs.calibration.identify_operator`) and the cab
    (:func:`designs.calibration.identify_cab`) are identified from the same record.

    Parameters
    ----------
    family : backhoe.Family
    values : array_like, shape (n, d)
        Member rows.
    seed : int
        Seed of the first member's record.
    protocol : CalibrationProtocol, optional
    n_jobs : int
        Parallel processes (the same numbers in any count).
    progress : callable, optional
        ``progress(done, total)``.
    regions : int, optional
        For the first ``regions`` members (default: all) also the noise-free estimate and
        the joint error region (:attr:`Calibrations.noise_free`, about 0.06 s each); NaN for
        the others.

    Returns
    -------
    Calibrations
    """
    rows = np.atleast_2d(np.asarray(values, float))
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="calibrate_members")
    size = 25
    chunks = [(i, min(i + size, len(rows))) for i in range(0, len(rows), size)]
    seeds = seed + np.arange(len(rows))
    n_reg = (
        len(rows)
        if regions is None
        else check_int("regions", regions, low=0, owner="calibrate_members")
    )
    reg = np.arange(len(rows)) < n_reg
    calls = [
        functools.partial(_calibrate_chunk, family, rows[a:b], seeds[a:b], protocol, reg[a:b])
        for a, b in chunks
    ]
    done = [0]

    def step(i):
        done[0] += chunks[i][1] - chunks[i][0]
        if progress:
            progress(done[0], len(rows))

    parts = run_calls(calls, jobs=n_jobs, progress=step)
    return Calibrations(
        *(
            np.concatenate([getattr(p, f.name) for p in parts])
            for f in dataclasses.fields(Calibrations)
        )
    )
