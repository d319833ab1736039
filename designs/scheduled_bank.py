"""The scheduled bank: one cancellation per cell of the identified operator's quantities,
and its coverage.

:class:`ScheduledBank` holds a grid of cells over the family's ranges of
:data:`designs.calibration.IDENTIFIED` (step 4 of :mod:`designs.scheduled`), each with
the cancellation built from its centre's human (:func:`build_bank`), and picks the cell
of an estimate; :func:`bank_coverage` checks the bank's selection on fresh members
(:class:`BankCoverage`). :data:`LIMIT_SET` is the limit map's set the bank and the
per-operator design act and measure with.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import control as ct
import numpy as np

from backhoe import member_metrics
from backhoe.model.blocks import parameter_name
from backhoe.model.physical import physical_human_matrices
from designs.calibration import IDENTIFIED, identified_ranges, operator_row
from designs.calibration_fit import LOG_AXES
from designs.constants import CELLS_PER_AXIS
from designs.coverage import member_verdicts
from designs.specification import Specification
from robust.checks import check_int
from robust.errors import ParameterError
from uncertainty.randomized import DEFAULT_CONFIDENCE, CoverageBound

__all__ = ["LIMIT_SET", "ScheduledBank", "build_bank", "BankCoverage", "bank_coverage"]


#: The limit map's set the bank acts and measures with.
LIMIT_SET = "reference/handle+cab"


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

    The humans' matrices come from :meth:`backhoe.Family.model_arrays` of the centres'
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
    family : backhoe.Family
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
    family : backhoe.Family
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
