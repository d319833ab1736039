"""A per-operator scheduled bank: a short calibration picks the compensator.

The design, top to bottom:

1. set: the cylinder reference shaped from the cab accelerometer (the limit map's
   ``reference/handle+cab``, :data:`LIMIT_SET`), whose limit coverage at the Omni's own
   force limits is the highest of the map's sets (every reference set reaches it; no
   handle force is used);
2. what is scheduled on: what the calibration identifies (:mod:`designs.calibration`):
   the seated chain's two modes, each a natural frequency and a damping ratio, ordered by
   frequency (:data:`designs.calibration.IDENTIFIED`), and the cab's gain and two modes
   (:data:`designs.calibration.CAB_IDENTIFIED`);
3. the bank: a grid of ``cells_per_axis`` intervals per identified quantity of the
   operator over the family's ranges (logarithmic in the frequencies, linear in the
   damping ratios; a cell whose lower mode's frequency interval lies wholly above the
   upper mode's is dropped), one compensator per cell: the model-based cancellation of the
   hand's motion (:func:`designs.cancellation.cancellation_controller`) built from the cell
   centre's human; selection rule (:meth:`ScheduledBank.select`): the cell that contains
   the estimate, clipped to the grid first;
4. the continuous schedule, the limit of ever finer cells: the cancellation built from
   each operator's own estimate (:func:`continuous_coverage`), and with it a damper of the
   identified cab's less damped mode (:func:`damped_cancellation`: a band-pass from the
   accelerometer to the reference, its phase and gain picked from a small set on the
   identified member), designed at the calibration from the record alone;
5. coverage (:func:`bank_coverage`, :func:`continuous_coverage`): on fresh Monte Carlo
   members (seed + 2, never used to build anything), each member's own simulated
   calibration record, identification, selection or design, and the whole specification
   checked on the true member; Clopper-Pearson bound as for every design
   (:mod:`uncertainty.randomized`); beside it how often the selected cell is the cell of
   the member's true modes, whether a wrong choice keeps the loop stable, and the
   coverage against the number of cells.

What it does not do (measured, see the tests, ``benchmarks/bench_calibration.py`` and
``bdft design scheduled``): a cancellation needs the operator's modes to within a few
percent, so coarse cells cover almost nobody; a cancellation alone leaves the cab's own
first mode where it is (``struct.zeta1`` in 0.063-0.1, about a fifth of the family fails
the damping); no cell or design has a certified margin over a box (the per-member checks
are the evidence); and the limit map's own controllers, which do damp that mode, sit on the
region's edge and lose the specification at 0.3 % of parameter error.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable

import control as ct
import numpy as np
from joblib import Parallel, delayed

from designs.calibration import (
    CAB_IDENTIFIED,
    IDENTIFIED,
    LOG_AXES,
    CalibrationProtocol,
    identified_ranges,
    identify_cab,
    identify_operator,
    operator_row,
    operator_truth,
    simulate_calibration,
)
from designs.cancellation import cancellation_controller
from designs.coverage import COVERAGE_SEED_OFFSET, member_verdicts
from designs.limit import limit_map
from designs.spec import Specification, check_specification
from robust.checks import check_int
from robust.errors import ParameterError
from robust.model.components import structure
from robust.model.physical import physical_human_matrices
from robust.model.wiring import connect
from robust.synthesis.solve import deterministic_solvers
from uncertainty import member_metrics, sample
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
]

#: The limit map's set the bank acts and measures with.
LIMIT_SET = "reference/handle+cab"
#: Default cells per identified quantity.
CELLS_PER_AXIS = 5


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
    A, B, C, D = physical_human_matrices(*(a[f"human.{k}"] for k in keys))
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


def _calibrate_chunk(family, rows, seeds, protocol):
    with deterministic_solvers():
        est, truth, inside, cab = [], [], [], []
        for row, s in zip(rows, seeds):
            loop = family.member(row)
            rec = simulate_calibration(loop, protocol, seed=int(s))
            e = identify_operator(rec, family, loop.handle_gain, protocol)
            t = operator_truth(family, row)
            est.append([e.values[k] for k in IDENTIFIED])
            truth.append([t[k] for k in IDENTIFIED])
            inside.append(all(e.contains(t).values()))
            c = identify_cab(rec, loop, protocol, family)
            cab.append([c.values[k] for k in CAB_IDENTIFIED])
        return np.array(est), np.array(truth), np.array(inside), np.array(cab)


def calibrate_members(
    family,
    values,
    *,
    seed: int = 0,
    protocol: CalibrationProtocol | None = None,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
    cab: bool = False,
):
    """Each member's simulated calibration and identification (record ``i`` seeded ``seed + i``).

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
    cab : bool
        Also return the cabs' estimates (:func:`designs.calibration.identify_cab`).

    Returns
    -------
    (estimates, truth, inside) or (estimates, truth, inside, cabs)
        Arrays ``(n, 4)``, ``(n, 4)`` of :data:`designs.calibration.IDENTIFIED`, ``(n,)``
        bool (every quantity within its bound) and ``(n, 5)`` of
        :data:`designs.calibration.CAB_IDENTIFIED`.
    """
    rows = np.atleast_2d(np.asarray(values, float))
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="calibrate_members")
    size = 25
    chunks = [(i, min(i + size, len(rows))) for i in range(0, len(rows), size)]
    seeds = seed + np.arange(len(rows))
    jobs = (delayed(_calibrate_chunk)(family, rows[a:b], seeds[a:b], protocol) for a, b in chunks)
    parts = []
    runner = Parallel(n_jobs=n_jobs, return_as="generator") if n_jobs > 1 else None
    it = runner(jobs) if runner is not None else (f(*a, **k) for f, a, k in jobs)
    done = 0
    for part in it:
        parts.append(part)
        done += len(part[2])
        if progress:
            progress(done, len(rows))
    out = tuple(np.concatenate([p[j] for p in parts]) for j in range(4))
    return out if cab else out[:3]


#: Candidates of the cab damper: phase shifts at the cab's mode (rad) and loop gains there
#: (as fractions of 1 / |c / r_corr| at that frequency); gain 0 is the plain cancellation.
DAMPER_PHASES = tuple(float(x) for x in np.linspace(-0.95 * math.pi, 0.95 * math.pi, 12))
DAMPER_GAINS = (0.05, 0.1, 0.2, 0.4)


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
    K = ct.tf([gain * w, 0.0], [1.0, w, w * w])
    if abs(phase) > 1e-9:
        a = w / math.tan(abs(phase) / 2)
        K = K * ct.tf([-1.0, a], [1.0, a]) * (-1.0 if phase > 0 else 1.0)
    return ct.ss(K)


def _identified_row(family, human: dict, cab: dict) -> np.ndarray:
    row = operator_row(family, human)
    low_first = cab["zeta_cab_low"] <= cab["zeta_cab_high"]
    d, o = ("low", "high") if low_first else ("high", "low")
    for name, val in (
        ("struct.k_s", cab["k_s"]),
        ("struct.f1_hz", cab[f"f_cab_{d}_hz"]),
        ("struct.zeta1", cab[f"zeta_cab_{d}"]),
        ("struct.f2_hz", cab[f"f_cab_{o}_hz"]),
        ("struct.zeta2", cab[f"zeta_cab_{o}"]),
    ):
        if name in family.names:
            row[family.names.index(name)] = val
    return row


def damped_cancellation(family, human: dict, cab: dict, spec=None) -> ct.StateSpace:
    """The cancellation of the identified human plus a damper of the identified cab's mode.

    The member the calibration identified (human and cab, masses nominal) is built; the
    damper acts at the cab's less damped mode (:func:`cab_damper`); its phase and gain are
    the candidates (:data:`DAMPER_PHASES` x :data:`DAMPER_GAINS`, and no damper) with the
    smallest largest utilisation of decay rate, damping, tracking and feedthrough on that
    identified member (:func:`designs.spec.check_specification`): a design made at the
    calibration, from the record alone.

    Parameters
    ----------
    family : uncertainty.Family
    human : dict
        :data:`designs.calibration.IDENTIFIED` -> estimate.
    cab : dict
        :data:`designs.calibration.CAB_IDENTIFIED` -> estimate.
    spec : Specification, optional
    """
    spec = spec or Specification()
    hat = family.member(_identified_row(family, human, cab), check_bounds=False)
    Kc = _cancellations(family, np.array([[human[k] for k in IDENTIFIED]]))[0]
    f_d = hat.struct.f1_hz
    P = connect(
        hat.blocks(bdft=False, reference_correction=True) + [structure(hat.struct)],
        inputs=["u", "r_corr"],
        outputs=["c"],
        name="cab",
    )
    scale = 1.0 / abs(complex(P(2j * math.pi * f_d)[0, 1]))
    keys = ("decay rate", "damping", "tracking", "feedthrough")
    best = None
    for phase, gain in [(0.0, 0.0)] + [(p, g) for p in DAMPER_PHASES for g in DAMPER_GAINS]:
        K = Kc
        if gain:
            K = ct.parallel(ct.ss(Kc.A, Kc.B, Kc.C, Kc.D), cab_damper(f_d, gain * scale, phase))
            K = ct.ss(K.A, K.B, K.C, K.D, inputs="c", outputs="r_corr", name="damped_cancellation")
        r = check_specification([hat], K, spec, simulate_peak=0)
        u = max(c.utilisation for c in r.constraints if c.name in keys)
        if best is None or u < best[0]:
            best = (u, K)
    return best[1]


def _continuous_chunk(family, rows, est, spec, cabs=None):
    with deterministic_solvers():
        holds = np.zeros(len(rows), bool)
        binding = []
        for i, (row, e) in enumerate(zip(rows, est)):
            if cabs is None:
                K = _cancellations(family, np.asarray(e, float)[None, :])[0]
            else:
                K = damped_cancellation(
                    family, dict(zip(IDENTIFIED, e)), dict(zip(CAB_IDENTIFIED, cabs[i])), spec
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
        delayed(_continuous_chunk)(
            family, rows[a:b], estimates[a:b], spec, None if cabs is None else cabs[a:b]
        )
        for a, b in chunks
    ]
    parts = Parallel(n_jobs=n_jobs)(jobs) if n_jobs > 1 else [f(*a, **k) for f, a, k in jobs]
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
    est, _, inside = calibrate_members(family, rows, seed=seed, protocol=protocol)
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
    damped_samples: int = 200,
    limit_samples: int = 64,
    protocol: CalibrationProtocol | None = None,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[ScheduledBank, dict]:
    """The bank, its coverage on ``samples`` fresh members, and coverage against cells.

    Parameters
    ----------
    family : uncertainty.Family
    cells_per_axis : int
        Cells per identified quantity of the bank.
    samples : int
        Fresh Monte Carlo members of the coverage certificate (seed ``seed + 2``).
    seed : int
        Design seed; the members are drawn with ``seed + 2``, their records ``seed + 2 +
        1000 + i``.
    cells_sweep : sequence of int
        Cells per axis of the banks compared (on the first ``sweep_samples`` members),
        followed by the continuous schedule (:func:`continuous_coverage`).
    sweep_samples : int
        Members of the comparison.
    damped_samples : int
        Members on which the compensator designed from each calibration with the cab's
        damper (:func:`damped_cancellation`, about 2.2 core-seconds each) is checked (0 skips
        it).
    limit_samples : int
        Latin-hypercube members of the limit map computed for the default sets at the
        Omni's force (:func:`designs.limit.limit_map`, seed ``seed``): which set covers
        most, and the bank's coverage as a fraction of its own set's (0 skips it).
    protocol : CalibrationProtocol, optional
    n_jobs : int
        Parallel processes.
    progress : callable, optional
        ``progress(done, total)`` of the calibrations.

    Returns
    -------
    (ScheduledBank, dict)
        The bank and the JSON-ready result (``coverage``, ``coverage_by_cells``, ...).
    """
    samples = check_int("samples", samples, low=1, owner="scheduled_design")
    mseed = seed + COVERAGE_SEED_OFFSET
    rows = sample(family.parameters, samples, method="mc", seed=mseed).values
    est, truth, inside, cabs = calibrate_members(
        family,
        rows,
        seed=mseed + 1000,
        protocol=protocol,
        n_jobs=n_jobs,
        progress=progress,
        cab=True,
    )
    bank = build_bank(family, cells_per_axis)
    cov = bank_coverage(bank, family, rows, est, truth, inside, seed=mseed, n_jobs=n_jobs)
    m = min(sweep_samples, samples)
    sweep = []
    for n in cells_sweep:
        b = bank if n == cells_per_axis else build_bank(family, n)
        c = bank_coverage(
            b, family, rows[:m], est[:m], truth[:m], inside[:m], seed=mseed, n_jobs=n_jobs
        )
        sweep.append(
            {
                "cells_per_axis": n,
                "cells": len(b.cells),
                "samples": m,
                "fraction": c.bound.fraction,
                "right_cell": c.right_cell,
            }
        )
    cont = continuous_coverage(family, rows[:m], est[:m], n_jobs=n_jobs)
    sweep.append(
        {
            "cells_per_axis": None,
            "cells": "continuous",
            "samples": m,
            "fraction": float(np.mean(cont)),
            "right_cell": None,
        }
    )
    md = min(damped_samples, samples)
    if md:
        damped = continuous_coverage(family, rows[:md], est[:md], cabs=cabs[:md], n_jobs=n_jobs)
        sweep.append(
            {
                "cells_per_axis": None,
                "cells": "continuous with the cab damper",
                "samples": md,
                "fraction": float(np.mean(damped)),
                "right_cell": None,
            }
        )
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
            "fraction_of_limit": cov.bound.fraction / by_set[LIMIT_SET]
            if by_set[LIMIT_SET] > 0
            else None,
        }
    return bank, {
        "name": "scheduled",
        "limit_set": LIMIT_SET,
        "force_scale": 1.0,
        "limit": limit,
        "cells_per_axis": cells_per_axis,
        "cells": len(bank.cells),
        "coverage": cov.to_json(),
        "coverage_by_cells": sweep,
        "calibration": dataclasses.asdict(pr),
    }
