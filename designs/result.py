"""What every design builds, and what running it adds: one result type for all designs.

A design is a :class:`Design`: a name, a one-line description and a ``build``
function ``build(family, samples, limits) -> DesignResult``. The pipeline of
:func:`designs.registry.run_design` then validates the result on the family,
reduces and discretises the controller and writes the artifact, filling in the
``evaluation``, ``checks`` (:class:`DesignChecks`: held-out validation, specification,
robust margin, 1 kHz and saturated runs), ``coverage`` and ``artifact`` fields of the same
:class:`DesignResult`. What a design reports of itself (gains, weights, solver statistics,
scans) is typed too: a :class:`DesignFacts` subclass defined beside the design, whose
:meth:`~DesignFacts.to_json` gives ``bdft design --json``'s ``details``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import ClassVar

from backhoe.analysis.sampled import SampledDataCheck
from backhoe.analysis.saturation import SaturationCheck
from designs.evaluate import DesignEvaluation
from designs.spec import SpecCheck
from designs.specification import Specification
from designs.tracking_performance import TRACKING_REQUIREMENT, performance_summary
from uncertainty.performance import PerformanceResult
from uncertainty.region import MarginResult

__all__ = [
    "Design",
    "DesignFacts",
    "DesignResult",
    "DesignChecks",
    "HeldOutCheck",
    "SaturatedRun",
]


@dataclasses.dataclass(frozen=True)
class DesignFacts:
    """What one design reports of itself, typed: the base of each design's facts.

    Each design defines its subclass beside it (e.g.
    :class:`designs.robust_lmi.RobustLMIFacts`), with its fields, the JSON of ``bdft
    design --json``'s ``details`` (:meth:`to_json`) and the keys of that JSON left out of
    the controller artifact (:attr:`artifact_exclude`).
    """

    #: Keys of :meth:`to_json` left out of the controller artifact (bulky tables).
    artifact_exclude: ClassVar[tuple[str, ...]] = ()

    def to_json(self) -> dict:
        """The fields as a JSON-able dict (a subclass with nested types writes its own)."""
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class HeldOutCheck:
    """Batched validation of a design on members it was not designed on.

    Parameters
    ----------
    samples : int
        Members checked.
    seed : int
        Their sampling seed.
    method : str
        Their sampling method.
    fraction_stable : float
        Fraction whose closed loop is stable.
    max_real_pole : float
        Largest closed-loop real part over them, rad/s.
    """

    samples: int
    seed: int
    method: str
    fraction_stable: float
    max_real_pole: float

    def to_json(self) -> dict:
        """The fields as a JSON-able dict."""
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class SaturatedRun:
    """A saturated 1 kHz simulation of one member and whether that member's linear 1 kHz
    loop is stable (a divergence the saturation causes told apart from a member the
    controller does not stabilise at all).

    Parameters
    ----------
    check : SaturationCheck
        The simulation's verdicts and figures (:meth:`of` drops its histories).
    linear_stable : bool
        The member's unsaturated sampled-data loop is stable.
    """

    check: SaturationCheck
    linear_stable: bool

    @classmethod
    def of(cls, check: SaturationCheck, linear_stable: bool) -> SaturatedRun:
        """``check`` without its histories, and ``linear_stable``.

        Parameters
        ----------
        check : SaturationCheck
            The simulation.
        linear_stable : bool
            Whether the member's linear 1 kHz loop is stable.
        """
        return cls(check.without_histories(), bool(linear_stable))

    def to_json(self) -> dict:
        """The check's JSON and ``linear_stable``."""
        return dict(self.check.to_json(), linear_stable=self.linear_stable)


@dataclasses.dataclass(frozen=True)
class DesignChecks:
    """What :func:`designs.registry.run_design` checks on every design, typed.

    Parameters
    ----------
    held_out : HeldOutCheck
        Validation on members the design did not use.
    spec : designs.spec.SpecCheck
        The specification on the nominal, the worst sampled and 8 seeded members.
    specification : designs.spec.Specification
        The specification checked.
    margin : uncertainty.MarginResult or None
        The certified robust margin for the specification's pole region (``None``: not
        computed).
    performance : uncertainty.PerformanceResult or None
        The robust performance margin of the specification's tracking bound
        (:func:`designs.tracking_performance.tracking_performance`; ``None``: not computed).
    sampled_data : dict
        Label (``"nominal"``, ``"worst"``) -> :class:`backhoe.analysis.sampled.SampledDataCheck`
        of the 1 kHz loop (empty without a controller).
    saturation : dict
        Label -> :class:`SaturatedRun` (empty unless the controller drives the force).
    """

    held_out: HeldOutCheck
    spec: SpecCheck
    specification: Specification
    margin: MarginResult | None = None
    performance: PerformanceResult | None = None
    sampled_data: dict[str, SampledDataCheck] = dataclasses.field(default_factory=dict)
    saturation: dict[str, SaturatedRun] = dataclasses.field(default_factory=dict)

    def to_json(self) -> dict:
        """The checks under the keys of ``bdft design --json``'s ``details`` (the margin
        without its timings, which are run information)."""
        out = {
            "held_out": self.held_out.to_json(),
            "spec": dict(self.spec.to_json(), specification=self.specification.to_json()),
        }
        if self.margin is not None:
            margin = self.margin.to_json()
            margin.pop("timings_s")
            out["robust_margin"] = margin
        if self.performance is not None:
            out["robust_performance"] = dict(
                performance_summary(self.performance), requirement=TRACKING_REQUIREMENT
            )
        if self.sampled_data:
            out["sampled_data_check"] = {k: v.to_json() for k, v in self.sampled_data.items()}
        if self.saturation:
            out["saturation_check"] = {k: v.to_json() for k, v in self.saturation.items()}
        return out


@dataclasses.dataclass(frozen=True)
class DesignResult:
    """A compensator design on a family, before and after validation.

    Parameters
    ----------
    name : str
        Design name (as registered).
    description : str
        One line: what the design is.
    family : backhoe.Family
        The family the design runs on (the workspace design changes its ``k_psf``).
    controller : control.StateSpace or None
        The compensator in the loop's signal convention (inputs among ``x, c, y``,
        outputs among ``f, r_corr``), after reduction; ``None`` for a design that is
        only a change of the loop (workspace scaling).
    order_full : int
        Controller order as synthesised, before reduction.
    reduction_error_bound : float
        Balanced-truncation error bound of the reduction (0 if none).
    facts : DesignFacts
        What the design reports of itself (gains, weights, solver statistics, scans), as
        the design's own :class:`DesignFacts` subclass. What every design is checked on is
        in ``checks``.
    notes : tuple of str
        Caveats the design itself states (a search that did not converge...).
    cost_note : str
        What the design costs besides force and tracking (e.g. the workspace factor),
        used in the comparison report's verdict; empty if nothing.
    evaluation : DesignEvaluation or None
        Validation on the family (set by :func:`designs.registry.run_design`).
    artifact : str or None
        Path of the written artifact's JSON file (set by ``run_design``).
    coverage : designs.coverage.DesignCoverage or None
        Fraction of the population meeting the specification, with its probabilistic
        certificate (set by ``run_design`` unless skipped).
    checks : DesignChecks or None
        Held-out validation, specification, robust margin, sampled-data and saturation
        checks (set by ``run_design``).
    """

    name: str
    description: str
    family: object
    controller: object
    order_full: int
    reduction_error_bound: float
    facts: DesignFacts
    notes: tuple[str, ...] = ()
    cost_note: str = ""
    evaluation: DesignEvaluation | None = None
    artifact: str | None = None
    coverage: object = None
    checks: DesignChecks | None = None

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
            "details": self.details_json(),
            "artifact": self.artifact,
        }

    def details_json(self) -> dict:
        """The JSON of ``facts`` followed by that of ``checks``: ``bdft design --json``'s
        ``details``, as the artifact's weights carry them too."""
        checks = {} if self.checks is None else self.checks.to_json()
        return dict(self.facts.to_json(), **checks)


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
        (an :class:`backhoe.Family`), tuned or checked on ``samples`` (an
        :class:`uncertainty.SampleSet`), within ``limits`` (a
        :class:`backhoe.model.device.DeviceLimits`).
    in_report : bool
        Whether ``bdft report`` runs it (a design that takes tens of minutes runs on
        demand, ``bdft design NAME``).
    """

    name: str
    description: str
    build: Callable
    in_report: bool = True
