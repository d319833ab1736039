"""Robust compensators by LMI synthesis, with the certified robust margin maximised.

The design, top to bottom (the same steps serve the three designs of this module):

1. family and specification: the default family (or its doubled workspace) and the
   handle-force specification :class:`designs.spec.Specification` (device force limits
   under the realistic intended motion, pole region, tracking, feedthrough);
2. start: a fixed-order controller (the nominal LMI H-infinity design balanced-truncated
   to ``order`` for handle force; a seeded low-gain filter for the cylinder reference);
3. a ladder of family scales ``k`` (the box scaled about the nominal, as the robust margin
   scales it, :mod:`uncertainty.margins`). At each scale, rounds of:

   * design members: the nominal, then the member of the scaled box whose closed-loop
     poles break the region most (:func:`uncertainty.search.worst_member`) and the
     sampled member that binds the specification;
   * synthesis: a start placing every design member's poles in the region with the
     budgets' largest utilisation minimised, by linear programs
     (:func:`robust.synthesis.tuning.minimax_start`; where they end outside the region,
     the nonsmooth tuning :func:`robust.synthesis.tuning.tune_members`), then
     :func:`robust.synthesis.pk.pksyn_multi`, the LMI synthesis: the P-K iteration with
     a certificate per design member (bounded-real with decay rate, H2 for the RMS
     force, Chilali-Gahinet region);
   * checks: no member of the scaled box found outside the region, and the
     specification on the design members and on seeded samples of the scaled box
     (:func:`designs.spec.check_specification`);

4. bisection between the last scale reached and the first that failed;
5. the pole region certified over the whole scaled box of every scale reached, with the
   controller found there (:func:`uncertainty.margins.margin_lower_bound` at ``k``). The
   path never depends on it, so the scales are certified after the ladder, together
   (in the processes :func:`robust.engine.nested_jobs` grants);
6. result: the controller of the largest scale reached, its certificates, the largest
   scale certified, and the constraint that binds at the first scale not reached.

Within a synthesis the members' P-step SDPs are independent, and run in the processes
granted the same way; ``bdft design`` grants its ``--jobs``, a design in the report's
pool of designs none. Every split is combined in order, so the controller is the same
to the bit on any number of processes.

The force budget of the synthesis is the RMS force ``min(budget_fraction * continuous,
peak / crest_factor)``: the peak force of a realistic motion is about ``crest_factor``
times its RMS (4.2 on the 20 s simulations of the specification).

Where the parts live: the settings and one rung of the ladder (step 3) in
:mod:`designs.robust_lmi_rung`; the ladder, its bisection and certification (steps 2 to 6,
:func:`maximise_margin`) in :mod:`designs.robust_lmi_ladder`; the rung cache and the worker
that tries a bisection scale beside the ladder in :mod:`designs.robust_lmi_ahead`; the
force-budget trade-off (:func:`force_tradeoff`) in :mod:`designs.robust_lmi_tradeoff`. This
module builds the three designs from them and re-exports their names.
"""

from __future__ import annotations

import dataclasses

from designs.result import Design, DesignFacts, DesignResult
from designs.robust_lmi_ahead import _Ahead as _Ahead
from designs.robust_lmi_ahead import _cached_rung as _cached_rung
from designs.robust_lmi_ahead import _keep_rung as _keep_rung
from designs.robust_lmi_ahead import _rung_inputs as _rung_inputs
from designs.robust_lmi_ahead import _rung_task as _rung_task
from designs.robust_lmi_ahead import _Stale as _Stale
from designs.robust_lmi_ahead import _stored_rung as _stored_rung
from designs.robust_lmi_ahead import _wanted as _wanted
from designs.robust_lmi_ladder import RobustLMIDesign, maximise_margin
from designs.robust_lmi_ladder import _certify_rung as _certify_rung
from designs.robust_lmi_ladder import _certify_rungs as _certify_rungs
from designs.robust_lmi_ladder import _given_start as _given_start
from designs.robust_lmi_ladder import _maximise as _maximise
from designs.robust_lmi_ladder import _start as _start
from designs.robust_lmi_rung import DESIGN_AMPLIFICATION_DB as DESIGN_AMPLIFICATION_DB
from designs.robust_lmi_rung import LADDER as LADDER
from designs.robust_lmi_rung import LADDER_CONSTRAINTS as LADDER_CONSTRAINTS
from designs.robust_lmi_rung import START_METHODS as START_METHODS
from designs.robust_lmi_rung import RobustOptions, ScaleLevel
from designs.robust_lmi_rung import _accepted as _accepted
from designs.robust_lmi_rung import _loop_controller as _loop_controller
from designs.robust_lmi_rung import _members as _members
from designs.robust_lmi_rung import _spec_rows as _spec_rows
from designs.robust_lmi_rung import _try_scale as _try_scale
from designs.robust_lmi_tradeoff import (
    TradeoffPoint,
    force_tradeoff,
    tradeoff_point,
    tradeoff_tasks,
)
from designs.spec import Specification
from robust.errors import InfeasibleError

__all__ = [
    "RobustOptions",
    "ScaleLevel",
    "RobustLMIDesign",
    "RobustLMIFacts",
    "maximise_margin",
    "TradeoffPoint",
    "force_tradeoff",
    "tradeoff_tasks",
    "tradeoff_point",
    "build",
    "build_cylinder",
    "build_workspace_force",
    "DESIGN",
    "DESIGN_CYLINDER",
    "DESIGN_WORKSPACE_FORCE",
]


@dataclasses.dataclass(frozen=True)
class RobustLMIFacts(DesignFacts):
    """What a robust LMI design reports of itself.

    Parameters
    ----------
    design : RobustLMIDesign
        The ladder's result (scales, levels, synthesis, design members, options).
    specification : Specification
        The specification designed for.
    """

    design: RobustLMIDesign
    specification: Specification

    artifact_exclude = ("levels",)

    def to_json(self) -> dict:
        """The facts under ``bdft design --json``'s keys (no controller or member rows)."""
        d = self.design
        return {
            "scale": d.scale,
            "certified_scale": d.certified_scale,
            "force_budget_rms_n": d.force_budget,
            "levels": [dataclasses.asdict(x) for x in d.levels],
            "binding_at_failure": None if d.failed is None else dataclasses.asdict(d.failed),
            "synthesis": d.synthesis,
            "spec_at_scale": d.spec,
            "design_members": len(d.design_rows),
            "options": dataclasses.asdict(d.options),
            "specification": self.specification.to_json(),
            "seed": d.options.seed,
        }


def _result(name, description, family, d: RobustLMIDesign, spec) -> DesignResult:
    notes = []
    if d.controller is None:
        raise InfeasibleError(
            f"{name}: no controller meets the specification even on the nominal member: "
            f"{d.failed.reason if d.failed else ''}"
        )
    if d.failed is not None:
        notes.append(
            "the ladder's constraints (pole region, forces, tracking) hold on the checked "
            f"members up to family scale {d.scale:.3g}; "
            f"at scale {d.failed.scale:.3g} it fails: {d.failed.reason} (binding constraint: "
            f"{d.failed.binding}, utilisation {d.failed.utilisation:.3g})"
        )
    return DesignResult(
        name=name,
        description=description,
        family=family,
        controller=d.controller,
        order_full=d.controller.nstates,
        reduction_error_bound=0.0,
        facts=RobustLMIFacts(d, spec),
        notes=tuple(notes),
    )


def _spec_for(limits) -> Specification:
    return Specification(
        peak_force_n=limits.peak_force_n, continuous_force_n=limits.continuous_force_n
    )


def build(family, samples, limits) -> DesignResult:
    """Robust handle-force H-infinity by LMI synthesis (design (i) of the comparison).

    Parameters
    ----------
    family : backhoe.Family
        The default family.
    samples : uncertainty.SampleSet
        Unused (the design members come from the worst-member search and seeded samples).
    limits : backhoe.model.device.DeviceLimits
        Device limits.
    """
    spec = Specification(
        peak_force_n=limits.peak_force_n, continuous_force_n=limits.continuous_force_n
    )
    d = maximise_margin(family, spec=spec, limits=limits)
    return _result(DESIGN_NAME, DESCRIPTION, family, d, spec)


def build_cylinder(family, samples, limits) -> DesignResult:
    """Cab-vibration control through the cylinder reference, no handle force (design (ii)).

    Parameters
    ----------
    family : backhoe.Family
        The default family.
    samples : uncertainty.SampleSet
        Unused.
    limits : backhoe.model.device.DeviceLimits
        Device limits.
    """
    spec = Specification(
        peak_force_n=limits.peak_force_n, continuous_force_n=limits.continuous_force_n
    )
    options = RobustOptions(controls=("r_corr",), measurements=("c", "y"))
    d = maximise_margin(family, spec=spec, options=options, limits=limits)
    return _result(CYLINDER_NAME, CYLINDER_DESCRIPTION, family, d, spec)


def build_workspace_force(family, samples, limits) -> DesignResult:
    """The doubled workspace with robust handle-force feedback (design (iii)).

    Parameters
    ----------
    family : backhoe.Family
        The default family (its workspace is doubled here).
    samples : uncertainty.SampleSet
        Unused.
    limits : backhoe.model.device.DeviceLimits
        Device limits.
    """
    spec = Specification(
        peak_force_n=limits.peak_force_n, continuous_force_n=limits.continuous_force_n
    )
    fam2 = family.with_workspace_factor(2.0)
    d = maximise_margin(fam2, spec=spec, limits=limits)
    res = _result(WORKSPACE_FORCE_NAME, WORKSPACE_FORCE_DESCRIPTION, fam2, d, spec)
    return res.replace(cost_note="a handle workspace twice the Omni's (142 mm)")


DESIGN_NAME = "hinf-robust-lmi"
DESCRIPTION = (
    "robust H-infinity handle-force feedback: P-K LMI synthesis with per-member certificates, "
    "certified family scale maximised"
)
CYLINDER_NAME = "cylinder-lmi"
CYLINDER_DESCRIPTION = (
    "cab-vibration control through the cylinder reference (no handle force), same LMI synthesis"
)
WORKSPACE_FORCE_NAME = "workspace2-hinf-lmi"
WORKSPACE_FORCE_DESCRIPTION = (
    "doubled handle workspace combined with robust handle-force feedback (same LMI synthesis)"
)
DESIGN = Design(DESIGN_NAME, DESCRIPTION, build)
DESIGN_CYLINDER = Design(CYLINDER_NAME, CYLINDER_DESCRIPTION, build_cylinder)
DESIGN_WORKSPACE_FORCE = Design(
    WORKSPACE_FORCE_NAME, WORKSPACE_FORCE_DESCRIPTION, build_workspace_force
)
