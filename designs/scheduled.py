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
   evaluated together in numpy (16 ms per design, checked against
   :func:`designs.spec.check_specification` in the tests);
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
import functools
import itertools
import math
from collections.abc import Callable

import control as ct
import numpy as np

from designs.cab_calibration import CAB_IDENTIFIED, CAB_LOG_AXES, cab_truth, identify_cab
from designs.calibration import (
    IDENTIFIED,
    OPERATOR_NAMES,
    identified_ranges,
    identify_operator,
    noise_free_estimate,
    operator_row,
    operator_truth,
)
from designs.calibration_fit import LOG_AXES
from designs.calibration_record import (
    CalibrationProtocol,
    excitation_responses,
    simulate_calibration,
)
from designs.calibration_region import REGION_RADIUS, region_points, response_distance
from designs.cancellation import cancellation_controller
from designs.constants import CELLS_PER_AXIS
from designs.coverage import COVERAGE_SEED_OFFSET, member_verdicts
from designs.limit import limit_map
from designs.specification import N_TRACKING_FREQS, Specification
from robust.analysis.loops import resolvent_times
from robust.analysis.small_eig import eigvals_stack
from robust.analysis.stability import damping_in_band, stability_bound
from robust.checks import check_int
from robust.engine import run_calls
from robust.errors import ModelStructureError, ParameterError
from robust.model.blocks import VALVE_FIELDS, block_of, parameter_name
from robust.model.components import ValveCylinderParams, realise_siso
from robust.model.physical import physical_human_matrices
from robust.model.wiring import connect
from robust.synthesis.solve import deterministic_solvers
from uncertainty import member_metrics, sample
from uncertainty.margins import robust_margin
from uncertainty.randomized import DEFAULT_CONFIDENCE, CoverageBound

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
#: The limit map's set the bank acts and measures with.
LIMIT_SET = "reference/handle+cab"
# CELLS_PER_AXIS (default cells per identified quantity) is defined in designs.constants
# (the command line reads it without NumPy)
#: What ``bdft design scheduled`` delivers, in one sentence (its JSON ``design``).
DESIGN_RULE = (
    "at each operator's calibration: the cancellation of the identified human (masses "
    "nominal) plus a damper of the identified cab's less damped mode, its phase and gain "
    "picked from damper_candidates on the identified member (damped_cancellation)"
)


@dataclasses.dataclass(frozen=True)
class ScheduledBank:
    """Cells over the identified quantities and one compensator per cell.

    Parameters
    ----------
    edges : tuple of numpy.ndarray
        Per quantity of :data:`designs.calibration.IDENTIFIED`, the cell edges (in the
        quantity's own units; logarithmically spaced for the frequencies).
    cells : tuple of tuple of int
        The grid index of every kept cell.
    centres : numpy.ndarray, shape (n_cells, 4)
        Each cell's centre (geometric for the frequencies).
    controllers : tuple of control.StateSpace
        Each cell's compensator (input ``c``, output ``r_corr``).
    """

    edges: tuple
    cells: tuple
    centres: np.ndarray
    controllers: tuple

    @property
    def cells_per_axis(self) -> int:
        """Cells per identified quantity."""
        return len(self.edges[0]) - 1

    def select(self, values) -> np.ndarray:
        """The selection rule: the cell containing each estimate (clipped to the grid).

        Parameters
        ----------
        values : array_like, shape (n, 4) or (4,)
            Estimates of :data:`designs.calibration.IDENTIFIED`.

        Returns
        -------
        numpy.ndarray of int
            Index into :attr:`cells` per estimate (the nearest kept cell where the grid cell
            was dropped).
        """
        v = np.atleast_2d(np.asarray(values, float))
        if v.shape[1] != len(IDENTIFIED) or not np.all(np.isfinite(v)):
            raise ParameterError(
                f"ScheduledBank.select: values must be finite rows of {list(IDENTIFIED)}; "
                f"got shape {v.shape}"
            )
        n = self.cells_per_axis
        idx = np.stack(
            [
                np.clip(np.searchsorted(e, v[:, j], side="right") - 1, 0, n - 1)
                for j, e in enumerate(self.edges)
            ],
            axis=1,
        )
        lookup = {c: i for i, c in enumerate(self.cells)}
        out = np.empty(len(v), int)
        grid = np.array(self.cells)
        for r, key in enumerate(map(tuple, idx)):
            if key in lookup:
                out[r] = lookup[key]
            else:
                out[r] = int(np.argmin(np.abs(grid - np.array(key)).sum(axis=1)))
        return out

    def to_json(self) -> dict:
        """The bank as the artifact holds it: grid, rule, every cell's compensator."""
        return {
            "set": LIMIT_SET,
            "identified": list(IDENTIFIED),
            "cells_per_axis": self.cells_per_axis,
            "edges": {k: e.tolist() for k, e in zip(IDENTIFIED, self.edges)},
            "selection_rule": "the cell containing the calibration's estimate (estimate "
            "clipped to the grid; a dropped grid cell goes to the nearest kept one)",
            "cells": [
                {
                    "index": list(c),
                    "centre": dict(zip(IDENTIFIED, centre.tolist())),
                    "controller": {
                        "A": K.A.tolist(),
                        "B": K.B.tolist(),
                        "C": K.C.tolist(),
                        "D": K.D.tolist(),
                        "inputs": list(K.input_labels),
                        "outputs": list(K.output_labels),
                    },
                }
                for c, centre, K in zip(self.cells, self.centres, self.controllers)
            ],
        }


def _cancellations(family, centres: np.ndarray) -> tuple:
    """:func:`designs.cancellation.cancellation_controller` of each centre's human, batched.

    The humans' matrices come from :meth:`uncertainty.Family.model_arrays` of the centres'
    rows (:func:`designs.calibration.operator_row`, masses nominal), so each compensator is
    the one the member's own loop would give, without assembling the loops.
    """
    rows = np.array([operator_row(family, dict(zip(IDENTIFIED, c))) for c in centres])
    a = family.model_arrays(rows, check_bounds=False)
    keys = ("m_trunk", "m_arm", "k_trunk", "c_trunk", "k_arm", "c_arm", "h_gain", "c_unit")
    A, B, C, D = physical_human_matrices(*(a[parameter_name("human", k)] for k in keys))
    cal = family.calibration
    g = -family.k_psf * cal.handle_sign * cal.loop_scale
    return tuple(
        ct.ss(
            A[i],
            B[i][:, [0]],
            g * C[i],
            g * D[i][:, [0]],
            inputs="c",
            outputs="r_corr",
            name="cancellation",
        )
        for i in range(len(rows))
    )


def build_bank(family, cells_per_axis: int = CELLS_PER_AXIS) -> ScheduledBank:
    """The bank on ``family`` (module notes, steps 3-4).

    Parameters
    ----------
    family : uncertainty.Family
        A family with the physical human.
    cells_per_axis : int
        Cells per identified quantity (>= 1).
    """
    n = check_int("cells_per_axis", cells_per_axis, low=1, high=12, owner="build_bank")
    lo, hi, _ = identified_ranges(family)
    edges = tuple(
        np.geomspace(lo[j], hi[j], n + 1) if LOG_AXES[j] else np.linspace(lo[j], hi[j], n + 1)
        for j in range(len(IDENTIFIED))
    )
    cells, centres = [], []
    for key in itertools.product(range(n), repeat=len(IDENTIFIED)):
        # the lower mode's frequency interval must reach below the upper mode's
        if edges[0][key[0]] > edges[2][key[2] + 1]:
            continue
        centres.append(
            [
                math.sqrt(e[k] * e[k + 1]) if LOG_AXES[j] else 0.5 * (e[k] + e[k + 1])
                for j, (e, k) in enumerate(zip(edges, key))
            ]
        )
        cells.append(key)
    ctrls = _cancellations(family, np.array(centres))
    return ScheduledBank(edges, tuple(cells), np.array(centres), ctrls)


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
    family : uncertainty.Family
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


#: Candidates of the cab damper: phase shifts at the cab's mode (rad) and loop gains there
#: (as fractions of 1 / |c / r_corr| at that frequency); gain 0 is the plain cancellation.
DAMPER_PHASES = tuple(float(x) for x in np.linspace(-0.95 * math.pi, 0.95 * math.pi, 12))
DAMPER_GAINS = (0.05, 0.1, 0.2, 0.4)
#: Relative difference of utilisation below which two candidates count as equally good.
TIE_RTOL = 1e-6


def cab_damper(f_hz: float, gain: float, phase: float) -> ct.StateSpace:
    """A band-pass from the cab accelerometer to the reference, phase-shifted at ``f_hz``.

    ``gain * s 2 zeta w / (s^2 + 2 zeta w s + w^2)`` (``zeta = 0.5``: unit gain and zero
    phase at ``w = 2 pi f_hz``) times a first-order all-pass ``(a - s) / (a + s)`` with
    ``a = w / tan(|phase| / 2)`` (phase ``-|phase|`` at ``w``), negated for a positive
    ``phase`` (``pi - |phase|``).

    Parameters
    ----------
    f_hz : float
        The cab mode's natural frequency, Hz.
    gain : float
        Gain at ``f_hz`` (reference units per cab acceleration unit).
    phase : float
        Phase shift at ``f_hz``, rad, in (-pi, pi).
    """
    w = 2 * math.pi * float(f_hz)
    num, den = np.array([gain * w, 0.0]), np.array([1.0, w, w * w])
    if abs(phase) > 1e-9:
        a = w / math.tan(abs(phase) / 2)
        # the coefficients python-control's product of the two transfer functions has (and
        # its realisation below): the certified margins over a damped cancellation depend on
        # the controller's coordinates, so they are the same as ever; the products of
        # python-control's objects and their conversion took six times as long
        num, den = np.polymul(num, [-1.0, a]), np.polymul(den, [1.0, a])
        if phase > 0:
            num = num * -1.0
    return ct.ss(*realise_siso(num, den))


def _cab_names(cab: dict) -> dict:
    """The family's parameter carrying each identified cab quantity: the less damped mode
    as the structure's first (where :func:`damped_cancellation` puts its damper)."""
    d, o = ("low", "high") if cab["zeta_cab_low"] <= cab["zeta_cab_high"] else ("high", "low")
    return {
        parameter_name("structure", "k_s"): "k_s",
        parameter_name("structure", "f1_hz"): f"f_cab_{d}_hz",
        parameter_name("structure", "zeta1"): f"zeta_cab_{d}",
        parameter_name("structure", "f2_hz"): f"f_cab_{o}_hz",
        parameter_name("structure", "zeta2"): f"zeta_cab_{o}",
    }


def _valve_params(valve) -> ValveCylinderParams:
    """``ValveCylinderParams`` of a row of :data:`VALVE_FIELDS` values."""
    v = np.asarray(valve, float).reshape(-1)
    if v.shape != (len(VALVE_FIELDS),):
        raise ParameterError(
            f"valve must hold {len(VALVE_FIELDS)} values {VALVE_FIELDS}; got {valve!r}"
        )
    return ValveCylinderParams(**{f: float(x) for f, x in zip(VALVE_FIELDS, v)})


def member_valve(family, row) -> np.ndarray:
    """The valve/cylinder of the member ``row`` of ``family`` (:data:`VALVE_FIELDS` values;
    the family's nominal for a parameter it does not vary).

    Parameters
    ----------
    family : uncertainty.Family
    row : array_like, shape (d,)
        The member's values (``family.names`` order).
    """
    a = family.model_arrays(np.atleast_2d(np.asarray(row, float)), check_bounds=False)
    return np.array([a[parameter_name("valve", f)][0] for f in VALVE_FIELDS])


def _identified_row(family, human: dict, cab: dict) -> np.ndarray:
    row = operator_row(family, human)
    for name, key in _cab_names(cab).items():
        if name in family.names:
            row[family.names.index(name)] = cab[key]
    return row


@dataclasses.dataclass(frozen=True)
class _OpenLoop:
    """One member's loop opened at the cylinder-reference correction (numpy)."""

    A: np.ndarray  # loop states
    Br: np.ndarray  # r_corr -> states
    Cc: np.ndarray  # states -> c (the cab acceleration)
    G: np.ndarray  # (n_freq, 2, 2): [y, c] / [u, r_corr] at the grid
    y_ref: np.ndarray  # y / u without BDFT at the grid
    n_track: int  # the first n_track frequencies are the tracking grid
    bound: np.ndarray  # the specification's bound on |Y/Y_ref - 1| at the grid


def _spec_grid(spec: Specification) -> tuple[np.ndarray, int]:
    return 2j * math.pi * spec.check_frequencies_hz(), N_TRACKING_FREQS


def _freq_resp(A, B, C, D, s) -> np.ndarray:
    return C @ resolvent_times(A, s.imag, B) + D


def _open_loop(loop, spec: Specification) -> _OpenLoop:
    """:class:`_OpenLoop` of ``loop`` on the specification's tracking and feedthrough grids."""
    P = connect(
        loop.blocks(bdft=True, reference_correction=True),
        inputs=["u", "r_corr"],
        outputs=["y", "c"],
        name="open_at_r_corr",
        ignore_inputs=["human.f"] if loop.human.has_force_port else (),
    )
    A, B, C, D = (np.asarray(m, float) for m in (P.A, P.B, P.C, P.D))
    if np.any(D[1, 1] != 0):  # pragma: no cover - the loop has no direct r_corr -> c path
        raise ModelStructureError("damped_cancellation: the loop has a direct r_corr -> c path")
    R = loop.system(bdft=False, outputs=["y"])
    s, nt = _spec_grid(spec)
    G = _freq_resp(A, B, C, D, s)
    y_ref = _freq_resp(*(np.asarray(m, float) for m in (R.A, R.B, R.C, R.D)), s)[:, 0, 0]
    bound = spec.deviation_bound(s.imag, G[:, 0, 0] / y_ref - 1.0)
    return _OpenLoop(A, B[:, [1]], C[[1]], G, y_ref, nt, bound)


def _damper_states(w: float, gain, phase) -> tuple:
    """Batched :func:`cab_damper` realisations (3 states each; ``phase`` never 0)."""
    gain, phase = np.asarray(gain, float), np.asarray(phase, float)
    n = gain.size
    a = w / np.tan(np.abs(phase) / 2)
    sign = np.where(phase > 0, -1.0, 1.0)
    A = np.zeros((n, 3, 3))
    A[:, 0, 1] = 1.0
    A[:, 1, 0] = -w * w
    A[:, 1, 1] = -w
    A[:, 2, 1] = gain * w  # the band-pass output drives the all-pass
    A[:, 2, 2] = -a
    B = np.zeros((n, 3, 1))
    B[:, 1, 0] = 1.0
    C = np.zeros((n, 1, 3))
    C[:, 0, 1] = -sign * gain * w
    C[:, 0, 2] = sign * 2 * a
    return A, B, C


def _damper_response(w: float, gain, phase, s) -> np.ndarray:
    """:func:`cab_damper` at ``s``, shape ``(n_candidates, n_freq)``."""
    gain, phase = np.asarray(gain, float)[:, None], np.asarray(phase, float)[:, None]
    a = w / np.tan(np.abs(phase) / 2)
    sign = np.where(phase > 0, -1.0, 1.0)
    return sign * gain * w * s / (s * s + w * s + w * w) * (a - s) / (a + s)


def _closed_loop_poles(ol: _OpenLoop, Kc, w: float, gain, phase) -> np.ndarray:
    """Poles of ``ol`` closed by ``Kc`` plus :func:`cab_damper` ``(w, gain, phase)``, per candidate.

    Every candidate's realisation is minimal up to the cancellation's own modes, which are
    the same in each; without a damper (every gain 0) one candidate, without its states.
    The stack's eigenvalues come from :func:`robust.analysis.small_eig.eigvals_stack` (half
    the time of LAPACK's one by one); the choice among the candidates does not hinge on
    their last digits (ties within :data:`TIE_RTOL`).
    """
    Ak, Bk, Ck, Dk = (np.asarray(m, float) for m in (Kc.A, Kc.B, Kc.C, Kc.D))
    Ad, Bd, Cd = _damper_states(w, gain, phase)
    n_c, n, nk = Ad.shape[0], ol.A.shape[0], Ak.shape[0]
    if not np.any(gain):  # the cancellation alone: no damper states
        Ad, Bd, Cd = Ad[:, :0, :0], Bd[:, :0], Cd[:, :, :0]
    N = n + nk + Ad.shape[1]
    A = np.zeros((n_c, N, N))
    A[:, :n, :n] = ol.A + ol.Br @ Dk @ ol.Cc
    A[:, :n, n : n + nk] = ol.Br @ Ck
    A[:, :n, n + nk :] = ol.Br @ Cd
    A[:, n : n + nk, :n] = Bk @ ol.Cc
    A[:, n : n + nk, n : n + nk] = Ak
    A[:, n + nk :, :n] = Bd @ ol.Cc
    A[:, n + nk :, n + nk :] = Ad
    return eigvals_stack(A)


def _utilisations(ol: _OpenLoop, spec: Specification, Kc, w: float, gain, phase) -> np.ndarray:
    """Utilisations of decay rate, damping, tracking and feedthrough per damper candidate.

    The closed loop of ``ol`` with ``Kc`` plus :func:`cab_damper` ``(w, gain, phase)`` per
    candidate, evaluated as :func:`designs.spec.check_specification` defines the four
    constraints, batched in numpy (:func:`_closed_loop_poles`).

    Returns
    -------
    numpy.ndarray, shape (n_candidates, 4)
    """
    Ak, Bk, Ck, Dk = (np.asarray(m, float) for m in (Kc.A, Kc.B, Kc.C, Kc.D))
    p = _closed_loop_poles(ol, Kc, w, gain, phase)
    n_c = p.shape[0]
    s, nt = _spec_grid(spec)
    Kf = _freq_resp(Ak, Bk, Ck, Dk, s)[:, 0, 0] + _damper_response(w, gain, phase, s)
    if not np.any(gain):
        Kf = Kf[:1]
    G = ol.G
    y = G[:, 0, 0] + G[:, 0, 1] * Kf * G[:, 1, 0] / (1.0 - G[:, 1, 1] * Kf)
    ratio = y / ol.y_ref
    out = np.full((n_c, 4), math.inf)
    max_real = p.real.max(axis=1)
    stable = max_real < stability_bound(0.0)
    out[stable, 0] = spec.decay_rate / -max_real[stable]
    zeta = damping_in_band(p, spec.damping_band_hz)
    out[:, 1] = np.where(zeta > 0, spec.min_damping / np.where(zeta > 0, zeta, 1.0), math.inf)
    out[:, 1] = np.where(np.isinf(zeta), 0.0, out[:, 1])
    util = np.abs(ratio - 1.0) / ol.bound
    trk, feed = util[:, :nt].max(axis=1), util[:, nt:].max(axis=1)
    out[stable, 2] = trk[stable]
    out[stable, 3] = feed[stable]
    return out


def damped_cancellation(family, human: dict, cab: dict, spec=None, *, valve=None) -> ct.StateSpace:
    """The cancellation of the identified human plus a damper of the identified cab's mode.

    The member the calibration identified (human and cab, masses nominal) is built; the
    damper acts at the cab's less damped mode (:func:`cab_damper`); its phase and gain are
    the candidates (:data:`DAMPER_PHASES` x :data:`DAMPER_GAINS`, and no damper) with the
    smallest largest utilisation of decay rate, damping, tracking and feedthrough on that
    identified member (as :func:`designs.spec.check_specification` defines them, evaluated
    for every candidate at once on the loop opened at the reference correction): a design
    made at the calibration, from the record alone.

    Parameters
    ----------
    family : uncertainty.Family
    human : dict
        :data:`designs.calibration.IDENTIFIED` -> estimate.
    cab : dict
        :data:`designs.calibration.CAB_IDENTIFIED` -> estimate.
    spec : Specification, optional
    valve : array_like, optional
        The machine's valve/cylinder (:data:`VALVE_FIELDS`; :attr:`Calibrations.valves`),
        which its rig knows; the family's nominal valve when omitted.
    """
    spec = spec or Specification()
    c = _damper_candidates(family, human, cab, spec, valve)
    util = _utilisations(c.open_loop, spec, c.cancellation, c.w, c.gain, c.phase).max(axis=1)
    plain = _utilisations(c.open_loop, spec, c.cancellation, c.w, [0.0], [1.0]).max(axis=1)[0]
    # candidates within TIE_RTOL of each other are equally good on the identified member
    # (the damper leaves the binding constraint where it is): the plain cancellation is
    # kept unless a damper lowers the utilisation by more, else the first of the best,
    # so that rounding at 1e-8 does not pick the design
    Kc = c.cancellation
    if not util.min() < plain * (1.0 - TIE_RTOL):
        return Kc
    k = int(np.flatnonzero(util <= util.min() * (1.0 + TIE_RTOL))[0])
    K = ct.parallel(
        ct.ss(Kc.A, Kc.B, Kc.C, Kc.D),
        cab_damper(c.w / (2 * math.pi), float(c.gain[k]), float(c.phase[k])),
    )
    return ct.ss(K.A, K.B, K.C, K.D, inputs="c", outputs="r_corr", name="damped_cancellation")


@dataclasses.dataclass(frozen=True)
class _Candidates:
    open_loop: _OpenLoop  # the identified member, opened at r_corr
    cancellation: ct.StateSpace  # the identified human's cancellation
    w: float  # the damper's frequency, rad/s
    gain: np.ndarray  # per candidate, reference units per cab acceleration unit
    phase: np.ndarray  # per candidate, rad


def _damper_candidates(
    family, human: dict, cab: dict, spec: Specification, valve=None
) -> _Candidates:
    """The identified member's open loop, its cancellation and the damper candidates."""
    hat = family.member(_identified_row(family, human, cab), check_bounds=False)
    if valve is not None:
        hat = hat.replace(valve=_valve_params(valve))
    Kc = _cancellations(family, np.array([[human[k] for k in IDENTIFIED]]))[0]
    w = 2 * math.pi * hat.struct.f1_hz
    P = connect(
        hat.blocks(bdft=False, reference_correction=True) + [hat.structure_system()],
        inputs=["u", "r_corr"],
        outputs=["c"],
        name="cab",
    )
    scale = 1.0 / abs(complex(P(1j * w)[0, 1]))
    phase, gain = (np.array(x, float) for x in zip(*itertools.product(DAMPER_PHASES, DAMPER_GAINS)))
    return _Candidates(_open_loop(hat, spec), Kc, w, gain * scale, phase)


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
    family : uncertainty.Family
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
    family : uncertainty.Family
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
    family : uncertainty.Family
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
    family : uncertainty.Family
        The family the member was drawn from.
    cal : Calibrations
        Calibrations (:func:`calibrate_members`).
    i : int
        Which of them.

    Returns
    -------
    (uncertainty.Family, dict, dict)
        The family, the operator's and the cab's estimates.
    """
    h, c = dict(zip(IDENTIFIED, cal.estimates[i])), dict(zip(CAB_IDENTIFIED, cal.cabs[i]))
    hb, cb = dict(zip(IDENTIFIED, cal.bounds[i])), dict(zip(CAB_IDENTIFIED, cal.cab_bounds[i]))
    where = {name: (key, h, hb) for name, key in OPERATOR_NAMES.items()}
    where.update({name: (key, c, cb) for name, key in _cab_names(c).items()})
    params = []
    for p in family.parameters:
        if block_of(p.name) == "valve":  # the machine's own valve, which the rig knows
            continue
        if p.name not in where:
            params.append(p)
            continue
        key, v, b = where[p.name]
        lo, hi = max(float(b[key][0]), 1e-3), float(b[key][1])
        nominal = min(max(float(v[key]), lo), hi)
        params.append(dataclasses.replace(p, nominal=nominal, low=lo, high=hi, std=None))
    fam = family.replace(
        parameters=tuple(params), valve=_valve_params(cal.valves[i]), name="calibrated operator"
    )
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
    family : uncertainty.Family
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


@dataclasses.dataclass(frozen=True)
class BankCoverage:
    """The bank's coverage of the population (module notes, step 6).

    Parameters
    ----------
    bound : CoverageBound
        Fraction of the members on which the whole specification holds with the selected
        compensator, with its certificate.
    right_cell : float
        Fraction of the members whose selected cell is the cell of their true modes.
    wrong_stable : float
        Of the members given another cell, the fraction whose loop is still stable (nan
        where none was).
    inside : float
        Fraction of the members whose true modes lie within the calibration's error bound.
    binding : dict
        Failures per binding constraint.
    cells : int
        Cells of the bank.
    """

    bound: CoverageBound
    right_cell: float
    wrong_stable: float
    inside: float
    binding: dict
    cells: int

    def to_json(self) -> dict:
        """The certificate's fields (``fraction``, ``samples``, ``failures``, ``epsilon``,
        ``confidence``...) and the calibration's."""
        return dict(
            self.bound.to_json(),
            right_cell=self.right_cell,
            wrong_choice_stable=self.wrong_stable,
            within_error_bound=self.inside,
            failures_by_constraint=dict(self.binding),
            cells=self.cells,
        )


def bank_coverage(
    bank: ScheduledBank,
    family,
    values,
    estimates,
    truth,
    inside,
    *,
    spec: Specification | None = None,
    seed: int = 0,
    confidence: float = DEFAULT_CONFIDENCE,
    n_jobs: int = 1,
) -> BankCoverage:
    """The bank's coverage on members whose calibration is done (:func:`calibrate_members`).

    Parameters
    ----------
    bank : ScheduledBank
    family : uncertainty.Family
    values : array_like, shape (n, d)
        The members (fresh Monte Carlo draws for the certificate).
    estimates, truth, inside : numpy.ndarray
        What :func:`calibrate_members` returned for them.
    spec : Specification, optional
    seed : int
        Seed of the members (written into the certificate).
    confidence : float
        Confidence of the certificate.
    n_jobs : int
        Parallel processes of the specification checks.
    """
    spec = spec or Specification()
    rows = np.atleast_2d(np.asarray(values, float))
    chosen = bank.select(estimates)
    right = bank.select(truth)
    holds = np.zeros(len(rows), bool)
    stable = np.ones(len(rows), bool)
    binding: dict = {}
    for c in np.unique(chosen):
        sel = np.flatnonzero(chosen == c)
        K = bank.controllers[c]
        v = member_verdicts(family, rows[sel], K, spec, n_jobs=n_jobs)
        holds[sel] = v.holds
        for ok, b in zip(v.holds, v.binding):
            if not ok:
                binding[b] = binding.get(b, 0) + 1
        wrong = sel[right[sel] != c]
        if wrong.size:
            stable[wrong] = member_metrics(family, rows[wrong], controller=K)[0] < 0
    wrong = chosen != right
    return BankCoverage(
        bound=CoverageBound(
            samples=len(rows),
            failures=int((~holds).sum()),
            confidence=confidence,
            seed=seed,
        ),
        right_cell=float(np.mean(~wrong)),
        wrong_stable=float(np.mean(stable[wrong])) if wrong.any() else math.nan,
        inside=float(np.mean(inside)),
        binding=dict(sorted(binding.items())),
        cells=len(bank.cells),
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
    family : uncertainty.Family
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
