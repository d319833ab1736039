"""Mu-synthesis of handle-force feedback over a box of the family (D-G-K).

The design, top to bottom:

1. family: the default family; the design box is the family's box scaled about the
   nominal by :data:`DESIGN_SCALE` (:func:`uncertainty.search.scaled_bounds`, each
   parameter in its own coordinates), the scale at which a robust performance below 1 is
   within reach (on the whole box the mixed-mu bound of the force-feedback problem is about
   2e4: no controller meets the weights for every member of it);
2. weights: :class:`backhoe.synthesis.forcefb.ForceFeedbackWeights` (the same as
   ``hinf-nominal``'s), around the family's Figure 5 loop as an uncertain system
   (:func:`backhoe.families.force_plant.force_feedback_uss`);
3. synthesis: :func:`uncertainty.musyn`, D-G-K (the parameters as real scalars, D and G
   scalings; Young, Automatica 32(8), 1996) on :data:`FREQUENCIES_RAD_S`, at most
   :data:`MAX_ITER` scaled syntheses after the first, the scalings fitted by constants
   (:data:`ORDERS`);
4. no reduction: the constant scalings keep the controller at the plant's order (22), and
   the certified peak mu (the mu cover, no frequency grid trusted) is then the exported
   controller's own (a reduced controller's would be certified again by
   :func:`uncertainty.certified_mu_peak`);
5. validation and export: the common pipeline (:func:`designs.registry.run_design`),
   which also gives the certified robust stability margin over the whole family's box and
   the coverage under the specification, as for every design.

Run it alone with ``python -m designs musyn [--samples N] [--seed S] [--out DIR]``.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from backhoe.families.force_plant import force_feedback_uss
from backhoe.synthesis.forcefb import (
    FORCE_PLANT_SIGNALS,
    ForceFeedbackWeights,
    as_loop_controller,
)
from designs.result import Design, DesignFacts, DesignResult
from uncertainty import musyn
from uncertainty.search import scaled_bounds

__all__ = [
    "DESIGN_SCALE",
    "MAX_ITER",
    "ORDERS",
    "FREQUENCIES_RAD_S",
    "MuSynthesis",
    "MuSynthesisFacts",
    "design_musyn",
    "scaled_family",
    "build",
    "DESIGN",
]

DESIGN_NAME = "musyn"
DESCRIPTION = (
    "mu-synthesis (D-G-K) of handle-force feedback over the family's box scaled about the nominal"
)

#: Scale of the family's box the design is robust over (measured: the first synthesis
#: gives a peak mu of 1.56 at 0.02, 2.74 at 0.05; on the whole box about 2e4).
DESIGN_SCALE = 0.02
#: Scaled syntheses after the first (measured at 0.02: peak mu 1.56, 1.09, 1.017).
MAX_ITER = 2
#: Orders of the D and G fits: constants, so the controller keeps the plant's order (22);
#: with dynamic fits of the 38 channels the scaled plant reached order 202 and its
#: synthesis found no verified controller after the first iterate.
ORDERS = (0,)
#: The mu-step's frequency grid, rad/s (0.016-500 Hz; the structure's modes near 40 rad/s).
FREQUENCIES_RAD_S = np.logspace(-1.0, 3.5, 13)
#: Wall-clock limit of the certificate, s (180 s did not certify the peak of 1.04).
CERTIFICATE_TIME_S = 600.0


def scaled_family(family, k: float):
    """``family`` with every parameter's range scaled by ``k`` about its nominal.

    Parameters
    ----------
    family : backhoe.Family
        The family.
    k : float
        Scale, in (0, 1].

    Returns
    -------
    backhoe.Family
        The same family on the box :func:`uncertainty.search.scaled_bounds` gives (a
        truncated-normal parameter's standard deviation scaled by ``k`` too).
    """
    lo, hi = scaled_bounds(family, k)
    params = []
    for p, low, high in zip(family.parameters, lo, hi):
        change = {"low": float(min(low, p.nominal)), "high": float(max(high, p.nominal))}
        if p.std is not None:
            change["std"] = p.std * k
        params.append(dataclasses.replace(p, **change))
    return family.replace(parameters=tuple(params))


@dataclasses.dataclass(frozen=True)
class MuSynthesis:
    """The mu-synthesis and its certificates.

    Parameters
    ----------
    controller : control.StateSpace
        Full-order controller, loop convention ``x, c -> f``.
    scale : float
        The design box's scale of the family's box.
    mu_peak_grid : float
        Grid peak of the mixed-mu upper bound of the full-order closed loop (true structure).
    mu_peak_certified : float
        Its certified peak over every frequency (``inf`` when the cover ran out of time).
    certificate_seconds : float
        Wall time of the certificate, s.
    history : tuple of dict
        The iterations (:class:`uncertainty.MusynResult`'s).
    stopped : str
        Why the iteration stopped (:attr:`uncertainty.MusynResult.stopped`).
    weights : ForceFeedbackWeights
        The weights.
    """

    controller: object
    scale: float
    mu_peak_grid: float
    mu_peak_certified: float
    certificate_seconds: float
    history: tuple
    stopped: str
    weights: ForceFeedbackWeights


def design_musyn(
    family, *, weights: ForceFeedbackWeights | None = None, limits=None, scale: float = DESIGN_SCALE
) -> MuSynthesis:
    """D-G-K synthesis of handle-force feedback over ``family``'s box scaled by ``scale``.

    Parameters
    ----------
    family : backhoe.Family
        The family (physical human).
    weights : ForceFeedbackWeights, optional
        Weights (default: the documented defaults).
    limits : DeviceLimits, optional
        Device limits (default: the Omni's).
    scale : float
        Scale of the design box.

    Returns
    -------
    MuSynthesis
        The full-order controller and the synthesis' figures.
    """
    w = weights or ForceFeedbackWeights()
    P = force_feedback_uss(scaled_family(family, scale), w, limits)
    res = musyn(
        P,
        len(FORCE_PLANT_SIGNALS["y"]),
        len(FORCE_PLANT_SIGNALS["u"]),
        method="dgk",
        max_iter=MAX_ITER,
        orders=ORDERS,
        frequencies=FREQUENCIES_RAD_S,
        time_limit_s=CERTIFICATE_TIME_S,
    )
    K = ct.ss(
        res.controller.A,
        res.controller.B,
        res.controller.C,
        res.controller.D,
        inputs=FORCE_PLANT_SIGNALS["y"],
        outputs=FORCE_PLANT_SIGNALS["u"],
    )
    return MuSynthesis(
        as_loop_controller(K, name="musyn"),
        float(scale),
        float(res.mu_peak_grid),
        float(res.mu_peak_certified),
        float(res.certificate.get("seconds", math.nan)),
        tuple(res.history),
        res.stopped,
        w,
    )


@dataclasses.dataclass(frozen=True)
class MuSynthesisFacts(DesignFacts):
    """What the mu-synthesis design reports of itself.

    Parameters
    ----------
    design : MuSynthesis
        The synthesis (its controller is the one exported: not reduced, so its certificate
        is the exported controller's).
    """

    design: MuSynthesis

    def to_json(self) -> dict:
        """The facts under ``bdft design --json``'s keys (no controller)."""
        d = self.design
        return {
            "design_scale": d.scale,
            "method": "D-G-K (uncertainty.musyn)",
            "frequencies_rad_s": [float(w) for w in FREQUENCIES_RAD_S],
            "max_iter": MAX_ITER,
            "orders": list(ORDERS),
            "stopped": d.stopped,
            "iterations": [
                {k: v for k, v in h.items() if k != "orders"} | {"orders": dict(h["orders"])}
                for h in d.history
            ],
            "mu_peak_grid": d.mu_peak_grid,
            "mu_peak_certified": d.mu_peak_certified,
            "certificate_seconds": d.certificate_seconds,
            "weights": dataclasses.asdict(d.weights),
            "order_synthesised": d.controller.nstates,
        }


def build(family, samples, limits) -> DesignResult:
    """The mu-synthesis on ``family``'s scaled box (the controller as synthesised).

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
    d = design_musyn(family, limits=limits)
    return DesignResult(
        name=DESIGN_NAME,
        description=DESCRIPTION,
        family=family,
        controller=d.controller,
        order_full=d.controller.nstates,
        reduction_error_bound=0.0,
        facts=MuSynthesisFacts(d),
    )


#: On demand only: about 20 minutes of CPU (the mu SDPs of 38 real channels).
DESIGN = Design(DESIGN_NAME, DESCRIPTION, build, in_report=False)
