"""The designs the workbench ships, by name, and the pipeline that runs one end to end.

:func:`run_design` builds the compensator on the default family (the design's own
module says how), validates it on a seeded sample of that family
(:func:`designs.evaluate.evaluate_design`) and on a held-out sample, discretises
it at the servo rate (Tustin, prewarped at the structure mode), compares the
continuous and the 1 kHz sampled-data loops, and writes the artifact (JSON +
``.mat``). Nothing here depends on which design it runs.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from backhoe import default_family
from backhoe.analysis.sampled import sampled_data_check
from backhoe.analysis.saturation import saturated_response
from backhoe.model.device import DeviceLimits
from designs import (
    cancellation,
    hinf_nominal,
    hinf_robust,
    hinf_robust_corr,
    mu_synthesis,
    robust_lmi,
    virtual_damping,
    workspace,
)
from designs.coverage import COVERAGE_SAMPLES, COVERAGE_SEED_OFFSET, design_coverage
from designs.evaluate import INTENT_FRACTION, evaluate_design, intended_motion
from designs.result import Design, DesignChecks, DesignResult, HeldOutCheck, SaturatedRun
from designs.spec import SpecCheck, check_specification
from designs.specification import Specification
from designs.tracking_performance import tracking_performance
from robust.cache import cached, caching
from robust.engine import nested_jobs
from robust.errors import ParameterError
from robust.export import ControllerArtifact, discretize, write_artifact
from robust.synthesis.solve import deterministic_solvers
from uncertainty import sample, validate_family
from uncertainty.margins import robust_margin

__all__ = ["DESIGNS", "design_names", "report_design_names", "get_design", "run_design"]

#: The shipped designs, in the order reports list them.
DESIGNS: dict[str, Design] = {
    d.name: d
    for d in (
        workspace.DESIGN,
        virtual_damping.DESIGN,
        cancellation.DESIGN,
        hinf_nominal.DESIGN,
        hinf_robust.DESIGN,
        hinf_robust_corr.DESIGN,
        robust_lmi.DESIGN,
        robust_lmi.DESIGN_CYLINDER,
        robust_lmi.DESIGN_WORKSPACE_FORCE,
        mu_synthesis.DESIGN,
    )
}


def design_names() -> list[str]:
    """Names of the shipped designs, in report order.

    Returns
    -------
    list of str
        The keys of :data:`DESIGNS`.
    """
    return list(DESIGNS)


def report_design_names() -> list[str]:
    """Names of the designs ``bdft report`` runs, in report order (the others run on demand).

    Returns
    -------
    list of str
        The keys of :data:`DESIGNS` whose :attr:`~designs.result.Design.in_report` is set.
    """
    return [name for name, d in DESIGNS.items() if d.in_report]


def get_design(name: str) -> Design:
    """The registered design called ``name``.

    Parameters
    ----------
    name : str
        A name from :func:`design_names`.

    Returns
    -------
    Design

    Raises
    ------
    robust.errors.ParameterError
        If no design has that name.
    """
    try:
        return DESIGNS[name]
    except (KeyError, TypeError):
        raise ParameterError(f"unknown design {name!r}; choose one of {design_names()}") from None


def _held_out(family, K, n: int, seed: int) -> HeldOutCheck:
    """Fraction stable and worst real part on a sample the design did not use."""
    v = validate_family(family, sample(family.parameters, n, method="lhs", seed=seed), controller=K)
    return HeldOutCheck(
        samples=n,
        seed=seed,
        method="lhs",
        fraction_stable=v.fraction_stable,
        max_real_pole=v.max_real_pole,
    )


def _sampled_checks(family, worst: dict, K, Kd) -> dict:
    """Continuous vs 1 kHz sampled-data loop on the nominal member and the worst sampled member."""
    rows = {
        "nominal": family.nominal_values(),
        "worst": [worst[n] for n in family.names] if worst else None,
    }
    return {
        label: sampled_data_check(family.member(row), K, Kd)
        for label, row in rows.items()
        if row is not None
    }


def _spec_check(family, members, ev, K, spec: Specification, seed: int) -> SpecCheck:
    """The specification on the nominal member, the worst sampled member and 8 more.

    The worst sampled member is the one with the largest closed-loop real part; the
    others are the first members of the sample (seeded), so the check is reproducible.
    """
    rows = [family.nominal_values()]
    if ev.worst:
        rows.append([ev.worst[n] for n in family.names])
    rows += [members.values[i] for i in range(min(8, len(members)))]
    return check_specification([family.member(r) for r in rows], K, spec, seed=seed)


def _saturation_checks(family, worst: dict, margin, K, Kd, limits, seed: int) -> dict:
    """Saturated 1 kHz simulations of the critical members (limit cycles, divergence).

    The nominal member, the worst sampled member and the margin search's critical member
    (where it is a member of the family), each driven by the seeded realistic intended
    motion for 20 s, then left to settle, with every actuator clipped (the handle force at
    the peak, the reference correction) and the hydraulic limits applied.
    Each entry also says whether that member's linear (unsaturated) 1 kHz loop is stable
    (``linear_stable``), so a divergence the saturation causes is told apart from a member
    the controller does not stabilise at all.
    """
    rows = {"nominal": family.nominal_values()}
    if worst:
        rows["worst sampled"] = [worst[n] for n in family.names]
    crit = None if margin is None else margin.critical
    if crit and crit.get("scale", 2.0) <= 1.0:
        rows["margin critical"] = [crit["parameters"][n] for n in family.names]
    out = {}
    dt = float(Kd.dt)
    t = np.arange(int(round(20.0 / dt))) * dt
    for label, row in rows.items():
        loop = family.member(row)
        amp = loop.intended_amplitude(limits, INTENT_FRACTION)
        u = intended_motion(t, amp, 2.0, seed=seed)
        out[label] = SaturatedRun.of(
            saturated_response(loop, Kd, u, peak_force_n=limits.peak_force_n),
            sampled_data_check(loop, K, Kd).stable_discrete,
        )
    return out


def run_design(
    name: str,
    *,
    samples: int = 2000,
    seed: int = 0,
    method: str = "lhs",
    out_dir=None,
    limits: DeviceLimits | None = None,
    held_out: int = 10000,
    margin_boxes: int = 0,
    coverage_samples: int = COVERAGE_SAMPLES,
    n_jobs: int = 1,
    progress=None,
    cache: bool = False,
) -> DesignResult:
    """Build, validate, discretise and export the design ``name`` on the default family.

    Besides the design sample (``samples`` members, ``seed``), the controller is
    validated on ``held_out`` members the design never saw (LHS, seed ``seed + 1``):
    designs tuned on the sample guarantee nothing between its members.

    Parameters
    ----------
    name : str
        A registered design (:func:`design_names`).
    samples : int
        Members of the design and validation sample.
    seed : int
        Sampling seed (written into the result and the artifact).
    method : str
        Sampling method (``"lhs"``, ``"mc"``, ``"grid"``, ``"vertices"``).
    out_dir : path-like, optional
        Folder for the artifact; ``None`` writes nothing.
    limits : DeviceLimits, optional
        Device limits (default: the Omni's).
    held_out : int
        Members of the held-out validation sample.
    margin_boxes : int
        Sub-boxes per scale of the certified robust margin
        (:func:`uncertainty.margins.robust_margin`, open left half-plane, eigenvalue
        method); 0 skips the margin. Both bounds, the critical member, the method and the
        certificate's summary go into ``checks.margin``; with it, the robust performance
        margin of the specification's tracking bound
        (:func:`designs.tracking_performance.tracking_performance`) into
        ``checks.performance``.
    coverage_samples : int
        Independent members (Monte Carlo, seed ``seed + 2``, never used by the design)
        of the coverage certificate (:func:`designs.coverage.design_coverage`: the
        fraction on which the whole specification holds and ``P(failure) <= epsilon``
        with confidence 0.999); 0 skips it.
    n_jobs : int
        Parallel processes of the coverage check, of the certified margin's sub-boxes
        and of the design's own independent solves (granted through
        :func:`robust.engine.nested_jobs`); the same result on any number.
    progress : callable, optional
        ``progress(done, total)`` during the coverage check.
    cache : bool
        Take the result from the content-addressed cache (:mod:`robust.cache`) when the
        same design was run with the same inputs and code, and store it there otherwise
        (the artifact is written either way); the robust LMI ladders' rungs are kept and
        reused the same way (:func:`robust.cache.caching`).

    Returns
    -------
    DesignResult
        With ``evaluation`` and (when written) ``artifact`` filled in.
    """
    lim = limits or DeviceLimits()
    inputs = {
        "name": name,
        "samples": samples,
        "seed": seed,
        "method": method,
        "limits": dataclasses.asdict(lim),
        "held_out": held_out,
        "margin_boxes": margin_boxes,
        "coverage_samples": coverage_samples,
    }

    def compute():
        # one BLAS thread and one Clarabel thread for the whole design, as in the report's
        # worker processes: a saturated run's last digits depend on the BLAS's thread count,
        # so without it `bdft report --jobs 1` and `--jobs 2` differed in them
        with deterministic_solvers():
            return _build_design(
                name,
                samples,
                seed,
                method,
                lim,
                held_out,
                margin_boxes,
                coverage_samples,
                n_jobs,
                progress,
            )

    with caching(cache):  # (and its steps: the robust LMI ladders' rungs)
        (result, art), _ = cached("design", inputs, compute, enabled=cache)
    if art is not None and out_dir is not None:
        path = write_artifact(art, Path(out_dir) / f"{name}.json")["json"]
        result = result.replace(artifact=str(path))
    return result


def _build_design(
    name, samples, seed, method, lim, held_out, margin_boxes, coverage_samples, n_jobs, progress
):
    """:func:`run_design`'s work: the result (no artifact path) and the artifact to write."""
    design = get_design(name)
    family = default_family()
    members = sample(family.parameters, samples, method=method, seed=seed)
    # a design that splits its own work (the LMI designs' P-steps) may use the processes
    with nested_jobs(n_jobs):
        res = design.build(family, members, lim)
    fam, K = res.family, res.controller
    ev = evaluate_design(name, fam, members, K, limits=lim, notes=res.notes)
    spec = Specification(peak_force_n=lim.peak_force_n, continuous_force_n=lim.continuous_force_n)
    checks = DesignChecks(
        held_out=_held_out(fam, K, held_out, seed + 1),
        spec=_spec_check(fam, members, ev, K, spec, seed),
        specification=spec,
    )
    if margin_boxes:
        margin = robust_margin(
            fam,
            controller=K,
            region=spec.region(),
            samples=1000,
            seed=seed,
            max_boxes=margin_boxes,
            ladder=6,
            iterations=1,
            jobs=n_jobs,
        )
        # the tracking bound's robust performance margin, with the same switch
        performance = tracking_performance(fam, K, spec, seed=seed)
        checks = dataclasses.replace(checks, margin=margin, performance=performance)
    coverage = None
    if coverage_samples:
        coverage = design_coverage(
            fam,
            K,
            spec,
            samples=coverage_samples,
            seed=seed + COVERAGE_SEED_OFFSET,
            n_jobs=n_jobs,
            progress=progress,
        )
    art = None
    if K is not None:
        prewarp = math.sqrt(fam.struct.f1_hz * fam.struct.f2_hz)
        Kd = discretize(K, lim.sample_time_s, prewarp_hz=prewarp)
        checks = dataclasses.replace(checks, sampled_data=_sampled_checks(fam, ev.worst, K, Kd))
        if {"f", "r_corr"} & set(K.output_labels):
            checks = dataclasses.replace(
                checks,
                saturation=_saturation_checks(fam, ev.worst, checks.margin, K, Kd, lim, seed),
            )
        details = res.replace(checks=checks).details_json()
        art = ControllerArtifact(
            name=name,
            continuous=K,
            discrete=Kd,
            prewarp_hz=prewarp,
            weights={k: v for k, v in details.items() if k not in res.facts.artifact_exclude},
            family={
                "name": fam.name,
                "seed": members.seed,
                "method": members.method,
                "samples": len(members),
                "k_psf": fam.k_psf,
            },
            validation=dict(
                ev.to_json(), coverage=None if coverage is None else coverage.to_json()
            ),
        )
    return res.replace(evaluation=ev, checks=checks, artifact=None, coverage=coverage), art
