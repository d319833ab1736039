"""Virtual damping and stiffness rendered by the handle: ``f = -(b s + k) x / (tau s + 1)``.

The design, top to bottom:

1. family: the default family at the nominal workspace;
2. synthesis: a grid of damping ``b`` and stiffness ``k``; every pair is validated
   on the sample, ranked by fraction stable, and the first whose handle force on
   the nominal member stays within the device limits is chosen
   (:func:`design_virtual_damping`);
3. validation and export: the common pipeline (:func:`designs.registry.run_design`).

Run it alone with ``python -m designs virtual-damping [--samples N] [--seed S] [--out DIR]``.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from backhoe.analysis.loops import loop_poles
from backhoe.model.device import DeviceLimits, check_force
from backhoe.model.loop import BDFTLoop
from designs.evaluate import INTENT_FRACTION, force_histories
from designs.result import Design, DesignFacts, DesignResult
from robust.checks import POSITIVE, Spec, check_scalar
from uncertainty import validate_family

__all__ = [
    "VirtualDampingResult",
    "virtual_damping_controller",
    "design_virtual_damping",
    "build",
    "DESIGN",
]

DESIGN_NAME = "virtual-damping"
DESCRIPTION = "virtual damping and stiffness rendered by the handle, tuned over the family"
#: Default grids: damping N s/m, stiffness N/m.
DAMPINGS = (0, 1, 2, 5, 10, 20, 40, 80)
STIFFNESSES = (0, 25, 50, 100, 200, 400)


@dataclasses.dataclass(frozen=True)
class VirtualDampingResult(DesignFacts):
    """Outcome of the virtual damping/stiffness grid search: the design's facts.

    Parameters
    ----------
    damping : float
        Chosen virtual damping, N s/m.
    stiffness : float
        Chosen virtual stiffness, N/m.
    controller : control.StateSpace
        The rendered force law, ``x -> f``.
    table : tuple of tuple
        ``(damping, stiffness, fraction_stable, max_real_pole)`` for every pair (``grid``
        in the JSON, left out of the artifact).
    within_limits : bool
        Whether the chosen pair keeps the nominal member's force within the limits.
    """

    damping: float
    stiffness: float
    controller: ct.StateSpace
    table: tuple
    within_limits: bool

    artifact_exclude = ("grid",)

    def to_json(self) -> dict:
        """The facts under ``bdft design --json``'s keys (units in the names; no controller)."""
        return {
            "damping_N_s_per_m": self.damping,
            "stiffness_N_per_m": self.stiffness,
            "force_limited_choice": self.within_limits,
            "grid": [
                dict(zip(("damping", "stiffness", "fraction_stable", "max_real_pole"), r))
                for r in self.table
            ],
        }


def virtual_damping_controller(
    loop: BDFTLoop, damping: float, stiffness: float, *, rolloff_hz: float = 50.0
) -> ct.StateSpace:
    """Force rendered by the handle: ``f = -(b s + k) / (tau s + 1) * x_m``.

    ``x_m`` is the handle position in metres, ``f`` the force on the hand in N.

    Parameters
    ----------
    loop : BDFTLoop
        The loop whose handle units convert ``x`` to metres (physical human).
    damping : float
        Virtual damping ``b``, N s/m (>= 0).
    stiffness : float
        Virtual stiffness ``k``, N/m (>= 0).
    rolloff_hz : float
        First-order roll-off that makes the rendered damping proper (the velocity
        estimate's filter), Hz.

    Returns
    -------
    control.StateSpace
        First-order force law, input ``x`` (handle units), output ``f``.
    """
    b = check_scalar("damping", damping, Spec(low=0.0))
    k = check_scalar("stiffness", stiffness, Spec(low=0.0))
    tau = 1.0 / (2 * math.pi * check_scalar("rolloff_hz", rolloff_hz, POSITIVE))
    per_m = loop.handle_units_per_m(signed=True)
    g = ct.tf([-b / per_m, -k / per_m], [tau, 1.0])
    return ct.ss(g, inputs="x", outputs="f", name="virtual_damping")


def design_virtual_damping(
    family,
    samples,
    *,
    dampings=DAMPINGS,
    stiffnesses=STIFFNESSES,
    limits: DeviceLimits | None = None,
    intent_fraction: float = INTENT_FRACTION,
    seed: int = 0,
) -> VirtualDampingResult:
    """Grid search of virtual damping and stiffness over the family, within the force limits.

    Every pair is validated on ``samples``; candidates are ranked by fraction of
    stable members (ties: smaller worst real part, then smaller gains). The first
    candidate whose handle force on the nominal member (chirp and seeded intended
    motion, :func:`designs.evaluate.force_histories`) stays within ``limits``
    is chosen; if none does, the most stabilising one is returned and flagged.

    Parameters
    ----------
    family : backhoe.Family
        The family (physical human).
    samples : uncertainty.SampleSet
        Members to validate every pair on.
    dampings, stiffnesses : sequence of float
        The grid, N s/m and N/m.
    limits : DeviceLimits, optional
        Device limits (default: the Omni's).
    intent_fraction : float
        Intended-motion amplitude as a fraction of the half-workspace.
    seed : int
        Seed of the simulated intended motion.

    Returns
    -------
    VirtualDampingResult
    """
    lim = limits or DeviceLimits()
    nominal = family.member(family.nominal_values())
    amp = nominal.intended_amplitude(lim, intent_fraction)
    table = []
    for b in dampings:
        for k in stiffnesses:
            K = virtual_damping_controller(nominal, b, k)
            v = validate_family(family, samples, controller=K)
            table.append((float(b), float(k), v.fraction_stable, v.max_real_pole))
    ranked = sorted(table, key=lambda r: (-r[2], r[3], r[0], r[1]))
    for b, k, _, _ in ranked:
        K = virtual_damping_controller(nominal, b, k)
        if not loop_poles(nominal, controller=K).stable:
            continue
        hist = force_histories(nominal, K, amplitude=amp, seed=seed)
        if (
            hist
            and check_force(np.concatenate(hist), lim).within_limits
            and all(np.sqrt(np.mean(np.asarray(h) ** 2)) <= lim.continuous_force_n for h in hist)
        ):
            return VirtualDampingResult(b, k, K, tuple(table), True)
    b, k = ranked[0][:2]
    return VirtualDampingResult(
        b, k, virtual_damping_controller(nominal, b, k), tuple(table), False
    )


def build(family, samples, limits) -> DesignResult:
    """The virtual damping/stiffness design on ``family``.

    Parameters
    ----------
    family : backhoe.Family
        The default family.
    samples : uncertainty.SampleSet
        Members to tune and validate on (its seed also seeds the force simulation).
    limits : backhoe.model.device.DeviceLimits
        Device limits the nominal member's force must respect.

    Returns
    -------
    DesignResult
        Not yet evaluated (the pipeline fills in ``evaluation``).
    """
    res = design_virtual_damping(family, samples, limits=limits, seed=samples.seed)
    notes = []
    if not res.within_limits:
        notes.append(
            "no damping/stiffness pair in the grid keeps the nominal member's force within the "
            "device limits; the most stabilising pair is shown"
        )
    return DesignResult(
        name=DESIGN_NAME,
        description=DESCRIPTION,
        family=family,
        controller=res.controller,
        order_full=res.controller.nstates,
        reduction_error_bound=0.0,
        facts=res,
        notes=tuple(notes),
    )


DESIGN = Design(DESIGN_NAME, DESCRIPTION, build)
