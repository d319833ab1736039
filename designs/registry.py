"""The designs the workbench ships, by name, and running one end to end.

``run_design(name, ...)`` builds the compensator on the default family, validates
it on a seeded sample of that family (:func:`designs.evaluate.evaluate_design`),
reduces it by balanced truncation, discretises it at the servo rate (Tustin,
prewarped at the structure mode) and writes the artifact (JSON + ``.mat``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from pathlib import Path

from designs.evaluate import DesignEvaluation, evaluate_design
from designs.simple import cancellation_controller, design_virtual_damping, design_workspace
from robust.errors import ParameterError
from robust.model.device import DeviceLimits

__all__ = ["DESIGNS", "DesignRun", "run_design", "design_names"]


@dataclasses.dataclass(frozen=True)
class DesignRun:
    """A design's controller (or workspace), its evaluation and where its artifact went."""

    name: str
    description: str
    evaluation: DesignEvaluation
    controller: object  # control.StateSpace or None
    order_full: int
    order_reduced: int
    reduction_error_bound: float
    details: dict
    artifact: str | None

    def to_json(self) -> dict:
        ev = self.evaluation
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
            "details": self.details,
            "artifact": self.artifact,
        }


def _workspace(family, samples, limits):
    res = design_workspace(family, samples)
    fam = family.with_workspace_factor(res.factor)
    notes = (
        []
        if res.stabilises_family
        else [
            f"no workspace factor up to {max(res.factors):g} stabilises every sampled member; "
            f"best x{res.factor:g} with {max(res.fraction_stable):.4f} stable"
        ]
    )
    details = {
        "factor": res.factor,
        "stabilises_family": res.stabilises_family,
        "scan": {
            "factor": list(res.factors),
            "fraction_stable": list(res.fraction_stable),
            "max_real_pole": list(res.max_real_pole),
        },
    }
    return fam, None, details, notes


def _virtual_damping(family, samples, limits):
    b, k, K, table, within = design_virtual_damping(
        family, samples, limits=limits, seed=samples.seed
    )
    notes = (
        []
        if within
        else [
            "no damping/stiffness pair in the grid keeps the nominal member's force within the "
            "device limits; the most stabilising pair is shown"
        ]
    )
    details = {
        "damping_N_s_per_m": b,
        "stiffness_N_per_m": k,
        "force_limited_choice": within,
        "grid": [
            dict(zip(("damping", "stiffness", "fraction_stable", "max_real_pole"), r))
            for r in table
        ],
    }
    return family, K, details, notes


def _cancellation(family, samples, limits):
    nominal = family.member(family.nominal_values())
    return family, cancellation_controller(nominal), {"model": "nominal physical human, c -> h"}, []


def _hinf_nominal(family, samples, limits):
    from designs.hinf import design_hinf_nominal, reduce_controller

    d = design_hinf_nominal(family, limits=limits)
    nominal = family.member(family.nominal_values())
    K, bound = reduce_controller(d.controller, [nominal])
    details = {
        "gamma": d.gamma,
        "gamma_bound": d.gamma_bound,
        "solver": d.solver,
        "weights": dataclasses.asdict(d.weights),
        "order_synthesised": d.controller.nstates,
        "reduction_error_bound": bound,
    }
    return family, K, details, []


def _hinf_robust(family, samples, limits, **options):
    from designs.hinf import design_hinf_nominal, design_hinf_robust, reduce_controller

    nominal = family.member(family.nominal_values())
    nominal_design = design_hinf_nominal(family, limits=limits)
    K0, bound = reduce_controller(nominal_design.controller, [nominal])
    d = design_hinf_robust(family, samples, K0=K0, limits=limits, **options)
    details = {
        "gamma_worst_design_member": d.gamma,
        "gamma_nominal": d.solver["gamma_nominal"],
        "gamma_nominal_design": nominal_design.gamma,
        "design_members": d.design_members,
        "solver": d.solver,
        "weights": dataclasses.asdict(d.weights),
        "order_synthesised": nominal_design.controller.nstates,
        "reduction_error_bound": bound,
    }
    notes = []
    if not d.solver["converged"]:
        notes.append(
            "the multi-model tuning did not reach the required decay rate on every sampled member"
        )
    fp = d.solver.get("force_phase")
    if fp is not None and not fp["accepted"]:
        notes.append(
            "the force-budget phase met the budget on the design members only by losing stability "
            f"(fraction stable {fp['fraction_stable']:.4f}, worst real part {fp['worst_sampled_max_real']:.3g} "
            "rad/s); it was rejected: the stabilising handle-position gain acts in the intended-motion band, "
            "where it also resists the operator"
        )
    return family, d.controller, details, notes


#: name -> (description, builder(family, samples, limits) -> (family, controller, details, notes))
DESIGNS: dict[str, tuple[str, Callable]] = {
    "workspace": (
        "workspace scaling: smallest handle-workspace factor that stabilises the family",
        _workspace,
    ),
    "virtual-damping": (
        "virtual damping and stiffness rendered by the handle, tuned over the family",
        _virtual_damping,
    ),
    "cancellation": (
        "model-based cancellation of the hand's motion from the measured cab acceleration",
        _cancellation,
    ),
    "hinf-nominal": (
        "H-infinity handle-force feedback, LMI synthesis on the nominal member",
        _hinf_nominal,
    ),
    "hinf-robust": (
        "robust H-infinity handle-force feedback: nominal LMI design tuned over family members",
        functools.partial(_hinf_robust, reference_correction=False, margin=0.3),
    ),
    "hinf-robust-corr": (
        "robust H-infinity handle force plus cylinder-reference correction, tuned over family "
        "members with a tracking budget",
        functools.partial(_hinf_robust, reference_correction=True, margin=0.15, tracking_error=0.5),
    ),
}


def _held_out(family, K, n: int, seed: int) -> dict:
    """Fraction stable and worst real part on a sample the design did not use."""
    from uncertainty import sample
    from uncertainty.batched import validate_family

    v = validate_family(family, sample(family.parameters, n, method="lhs", seed=seed), controller=K)
    return {
        "samples": n,
        "seed": seed,
        "method": "lhs",
        "fraction_stable": v.fraction_stable,
        "max_real_pole": v.max_real_pole,
    }


def _sampled_checks(family, samples, ev, K, Kd) -> dict:
    """Continuous vs 1 kHz sampled-data loop on the nominal member and the worst sampled member."""
    from robust.analysis.sampled import sampled_data_check

    out = {}
    worst = ev.worst
    rows = {
        "nominal": family.nominal_values(),
        "worst": [worst[n] for n in family.names] if worst else None,
    }
    for label, row in rows.items():
        if row is not None:
            out[label] = sampled_data_check(family.member(row), K, Kd).to_json()
    return out


def design_names() -> list[str]:
    return list(DESIGNS)


def run_design(
    name: str,
    *,
    samples: int = 2000,
    seed: int = 0,
    method: str = "lhs",
    out_dir=None,
    limits: DeviceLimits | None = None,
    held_out: int = 10000,
) -> DesignRun:
    """Build, validate, reduce, discretise and export the design ``name`` on the default family.

    Besides the design sample (``samples`` members, ``seed``), the controller is validated on
    ``held_out`` members the design never saw (LHS, seed ``seed + 1``): designs tuned on the
    sample guarantee nothing between its members.
    """
    from robust.export import ControllerArtifact, discretize, write_artifact
    from uncertainty import default_family, sample

    if name not in DESIGNS:
        raise ParameterError(f"unknown design {name!r}; choose one of {design_names()}")
    lim = limits or DeviceLimits()
    description, builder = DESIGNS[name]
    family = default_family()
    members = sample(family.parameters, samples, method=method, seed=seed)
    fam, K, details, notes = builder(family, members, lim)
    order_red = 0 if K is None else K.nstates
    order_full = int(details.get("order_synthesised", order_red))
    bound = float(details.get("reduction_error_bound", 0.0))
    ev = evaluate_design(name, fam, members, K, limits=lim, notes=notes)
    details["held_out"] = _held_out(fam, K, held_out, seed + 1)
    artifact = None
    if K is not None:
        prewarp = math.sqrt(fam.struct.f1_hz * fam.struct.f2_hz)
        Kd = discretize(K, lim.sample_time_s, prewarp_hz=prewarp)
        details["sampled_data_check"] = _sampled_checks(fam, members, ev, K, Kd)
    if out_dir is not None and K is not None:
        art = ControllerArtifact(
            name=name,
            continuous=K,
            discrete=Kd,
            prewarp_hz=prewarp,
            weights=details
            if name != "virtual-damping"
            else {k: v for k, v in details.items() if k != "grid"},
            family={
                "name": fam.name,
                "seed": members.seed,
                "method": members.method,
                "samples": len(members),
                "k_psf": fam.k_psf,
            },
            validation=ev.to_json(),
        )
        artifact = str(write_artifact(art, Path(out_dir) / f"{name}.json")["json"])
    return DesignRun(name, description, ev, K, order_full, order_red, bound, details, artifact)
