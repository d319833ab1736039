"""What every design builds, and what running it adds: one result type for all designs.

A design is a :class:`Design`: a name, a one-line description and a ``build``
function ``build(family, samples, limits) -> DesignResult``. The pipeline of
:func:`designs.registry.run_design` then validates the result on the family,
reduces and discretises the controller and writes the artifact, filling in the
``evaluation`` and ``artifact`` fields of the same :class:`DesignResult`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from designs.evaluate import DesignEvaluation

__all__ = ["Design", "DesignResult"]


@dataclasses.dataclass(frozen=True)
class DesignResult:
    """A compensator design on a family, before and after validation.

    Parameters
    ----------
    name : str
        Design name (as registered).
    description : str
        One line: what the design is.
    family : uncertainty.Family
        The family the design runs on (the workspace design changes its ``k_psf``).
    controller : control.StateSpace or None
        The compensator in the loop's signal convention (inputs among ``x, c, y``,
        outputs among ``f, r_corr``), after reduction; ``None`` for a design that is
        only a change of the loop (workspace scaling).
    order_full : int
        Controller order as synthesised, before reduction.
    reduction_error_bound : float
        Balanced-truncation error bound of the reduction (0 if none).
    details : dict
        Design-specific facts (JSON-able): gains, weights, solver statistics, scans.
    notes : tuple of str
        Caveats the design itself states (a search that did not converge...).
    cost_note : str
        What the design costs besides force and tracking (e.g. the workspace factor),
        used in the comparison report's verdict; empty if nothing.
    artifact_exclude : tuple of str
        Keys of ``details`` left out of the controller artifact (bulky tables).
    evaluation : DesignEvaluation or None
        Validation on the family (set by :func:`designs.registry.run_design`).
    artifact : str or None
        Path of the written artifact's JSON file (set by ``run_design``).
    coverage : designs.coverage.DesignCoverage or None
        Fraction of the population meeting the specification, with its probabilistic
        certificate (set by ``run_design`` unless skipped).
    """

    name: str
    description: str
    family: object
    controller: object
    order_full: int
    reduction_error_bound: float
    details: dict
    notes: tuple[str, ...] = ()
    cost_note: str = ""
    artifact_exclude: tuple[str, ...] = ()
    evaluation: DesignEvaluation | None = None
    artifact: str | None = None
    coverage: object = None

    @property
    def order_reduced(self) -> int:
        """Order of the controller as shipped (0 without a controller)."""
        return 0 if self.controller is None else int(self.controller.nstates)

    @property
    def drives_force(self) -> bool:
        """Whether the controller drives the handle force ``f``."""
        return self.controller is not None and "f" in self.controller.output_labels

    def replace(self, **changes) -> DesignResult:
        """A copy with ``changes`` applied (``dataclasses.replace``).

        Parameters
        ----------
        **changes
            Field values to change.
        """
        return dataclasses.replace(self, **changes)

    def to_json(self) -> dict:
        """The JSON object of ``bdft design --json`` (requires the evaluation)."""
        ev = self.evaluation
        if ev is None:
            raise ValueError(f"design {self.name!r} has not been evaluated; run it with run_design")
        return {
            "name": self.name,
            "description": self.description,
            "fraction_stable": ev.fraction_stable,
            "max_real_pole": ev.max_real_pole,
            "min_damping": ev.min_damping,
            "worst": ev.worst,
            "suppression_db": ev.suppression_db,
            "tracking_error": ev.tracking_error,
            "peak_force_N": ev.peak_force_n,
            "rms_force_N": ev.rms_force_n,
            "force_within_limits": ev.force_within_limits,
            "order": self.order_full,
            "order_reduced": self.order_reduced,
            "reduction_error_bound": self.reduction_error_bound,
            "k_psf": ev.k_psf,
            "samples": ev.samples,
            "seed": ev.seed,
            "method": ev.method,
            "notes": list(ev.notes),
            "coverage": None if self.coverage is None else self.coverage.to_json(),
            "details": self.details,
            "artifact": self.artifact,
        }


@dataclasses.dataclass(frozen=True)
class Design:
    """A registered design: its name, description and builder.

    Parameters
    ----------
    name : str
        Name used by ``bdft design NAME`` and the report.
    description : str
        One line: what the design is.
    build : callable
        ``build(family, samples, limits) -> DesignResult``: the design on ``family``
        (an :class:`uncertainty.Family`), tuned or checked on ``samples`` (an
        :class:`uncertainty.SampleSet`), within ``limits`` (a
        :class:`robust.model.device.DeviceLimits`).
    """

    name: str
    description: str
    build: Callable
