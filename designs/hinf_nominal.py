"""H-infinity handle-force feedback, LMI synthesis on the family's nominal member.

The design, top to bottom:

1. family: the default family; synthesis uses its nominal member only;
2. weights: :class:`backhoe.synthesis.forcefb.ForceFeedbackWeights` (intended motion
   0-2 Hz, tracking error 0.2, force relative to the device's peak, sensor noise);
3. synthesis: :func:`robust.synthesis.hinfsyn_lmi` on
   :func:`backhoe.synthesis.forcefb.force_feedback_plant` (Gahinet & Apkarian 1994,
   verified there by closed-loop poles and an independent H-infinity norm), then
   balanced truncation keeping the nominal loop stable;
4. validation and export: the common pipeline (:func:`designs.registry.run_design`).

Run it alone with ``python -m designs hinf-nominal [--samples N] [--seed S] [--out DIR]``.
"""

from __future__ import annotations

import dataclasses

from backhoe.analysis.loops import reduce_controller
from backhoe.model.device import DeviceLimits
from backhoe.synthesis.forcefb import ForceFeedbackWeights, as_loop_controller, force_feedback_plant
from designs.result import Design, DesignFacts, DesignResult
from robust.synthesis import hinfsyn_lmi

__all__ = [
    "NominalHinf",
    "NominalHinfFacts",
    "synthesis_json",
    "design_hinf_nominal",
    "build",
    "DESIGN",
]

DESIGN_NAME = "hinf-nominal"
DESCRIPTION = "H-infinity handle-force feedback, LMI synthesis on the nominal member"


@dataclasses.dataclass(frozen=True)
class NominalHinf:
    """The nominal LMI synthesis and its verified facts.

    Parameters
    ----------
    controller : control.StateSpace
        Full-order controller, loop convention ``x, c -> f``.
    gamma : float
        Verified closed-loop H-infinity norm on the nominal member.
    gamma_bound : float
        The LMI's certified bound.
    solver : dict
        Method, solver name and status.
    weights : ForceFeedbackWeights
        The weights used.
    """

    controller: object
    gamma: float
    gamma_bound: float
    solver: dict
    weights: ForceFeedbackWeights


def design_hinf_nominal(
    family, *, weights: ForceFeedbackWeights | None = None, limits: DeviceLimits | None = None
) -> NominalHinf:
    """Nominal H-infinity force feedback: LMI synthesis on the family's nominal member.

    Parameters
    ----------
    family : backhoe.Family
        The family (physical human); its nominal member is the plant.
    weights : ForceFeedbackWeights, optional
        Weights of the generalized plant (default: the documented defaults).
    limits : DeviceLimits, optional
        Device limits (force scale, encoder resolution, workspace).

    Returns
    -------
    NominalHinf
        The full-order controller, before reduction.
    """
    w = weights or ForceFeedbackWeights()
    nominal = family.member(family.nominal_values())
    res = hinfsyn_lmi(force_feedback_plant(nominal, w, limits))
    K = as_loop_controller(res.K, name="hinf_nominal")
    solver = {
        "method": "LMI (Gahinet-Apkarian 1994), Clarabel/SCS",
        "solver": res.solver,
        "status": res.status,
        "gamma_bound": res.gamma_bound,
        "gamma_verified": res.gamma,
    }
    return NominalHinf(K, res.gamma, res.gamma_bound, solver, w)


def synthesis_json(solver: dict, weights, order_synthesised: int, bound: float) -> dict:
    """The synthesis facts both H-infinity designs report, under their JSON keys.

    Parameters
    ----------
    solver : dict
        The solver's statistics.
    weights : ForceFeedbackWeights
        The weights used.
    order_synthesised : int
        Controller order as synthesised.
    bound : float
        Balanced-truncation error bound of the reduction.
    """
    return {
        "solver": solver,
        "weights": dataclasses.asdict(weights),
        "order_synthesised": order_synthesised,
        "reduction_error_bound": bound,
    }


@dataclasses.dataclass(frozen=True)
class NominalHinfFacts(DesignFacts):
    """What the nominal H-infinity design reports of itself.

    Parameters
    ----------
    design : NominalHinf
        The synthesis (its full-order controller, norms, solver and weights).
    reduction_error_bound : float
        Balanced-truncation error bound of the controller's reduction.
    """

    design: NominalHinf
    reduction_error_bound: float

    def to_json(self) -> dict:
        """The facts under ``bdft design --json``'s keys (no controller)."""
        d = self.design
        return dict(
            gamma=d.gamma,
            gamma_bound=d.gamma_bound,
            **synthesis_json(d.solver, d.weights, d.controller.nstates, self.reduction_error_bound),
        )


def build(family, samples, limits) -> DesignResult:
    """The nominal H-infinity design on ``family``, reduced.

    Parameters
    ----------
    family : backhoe.Family
        The default family.
    samples : uncertainty.SampleSet
        Unused by the synthesis (the pipeline validates on it).
    limits : backhoe.model.device.DeviceLimits
        Device limits.

    Returns
    -------
    DesignResult
        Not yet evaluated (the pipeline fills in ``evaluation``).
    """
    d = design_hinf_nominal(family, limits=limits)
    nominal = family.member(family.nominal_values())
    K, bound = reduce_controller(d.controller, [nominal])
    return DesignResult(
        name=DESIGN_NAME,
        description=DESCRIPTION,
        family=family,
        controller=K,
        order_full=d.controller.nstates,
        reduction_error_bound=bound,
        facts=NominalHinfFacts(d, bound),
    )


DESIGN = Design(DESIGN_NAME, DESCRIPTION, build)
