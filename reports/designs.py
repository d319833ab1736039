"""The design comparison report (``bdft report``): every design on the same family, one page."""

from __future__ import annotations

import dataclasses
import json
import math

from backhoe import default_family
from backhoe.constants import DAMPING_BAND_HZ
from backhoe.model.components import StructureParams
from backhoe.model.device import DeviceLimits
from designs.evaluate import INTENT_FRACTION
from designs.robust_lmi import RobustLMIFacts
from reports.coverage import FamilyCoverage, add_coverage_section, family_coverage
from reports.design_figures import _figures
from reports.design_runs import run_all_designs, run_designs_with
from reports.design_sections import (
    _margin_section,
    _population_coverage_section,
    _saturation_section,
    _scheduled_section,
    _spec_section,
    _tradeoff_section,
)
from reports.html import HtmlPage, write_report_dir
from robust.jsonio import to_jsonable

__all__ = ["run_all_designs", "run_designs_with", "verdict", "write_design_report"]


def verdict(runs: dict, tradeoff=None) -> list[str]:
    """The report's verdict: plain sentences generated from the runs.

    Which design (if any) stabilises every sampled member within the force limits,
    what each costs, why the handle-force designs fail if they do, how far the LMI
    designs hold the specification and what more force would buy.

    Parameters
    ----------
    runs : dict
        Design name -> :class:`designs.DesignResult` (evaluated) or the exception it raised.
    tradeoff : list of designs.robust_lmi_tradeoff.TradeoffPoint, optional
        The force-budget sweep.

    Returns
    -------
    list of str
        One sentence or short paragraph per entry.
    """
    ok = {n: r for n, r in runs.items() if not isinstance(r, Exception)}
    valid = [
        n
        for n, r in ok.items()
        if r.evaluation.fraction_stable == 1.0 and r.evaluation.force_within_limits
    ]
    robust = [n for n, r in ok.items() if r.evaluation.fraction_stable == 1.0]
    force_designs = [n for n, r in ok.items() if r.drives_force]
    valid_force = [n for n in valid if n in force_designs]
    out = []
    if valid:
        out.append(
            "Designs that stabilise every sampled member within the force limits: "
            + ", ".join(valid)
            + "."
        )
    else:
        out.append(
            "No design stabilises every sampled member while keeping the handle force within "
            "the device limits."
        )
    if force_designs and not valid_force:
        out.append(
            "No handle-force design ("
            + ", ".join(force_designs)
            + ") stabilises every sampled member within the device's force limits."
        )
    for n in robust:
        r = ok[n]
        e = r.evaluation
        force = (
            f"peak force {e.peak_force_n:.3g} N, RMS {e.rms_force_n:.3g} N"
            if r.drives_force
            else "no force"
        )
        cost = ", ".join(
            x for x in (r.cost_note, f"tracking error {e.tracking_error:.3g}", force) if x
        )
        ho = None if r.checks is None else r.checks.held_out
        held = f"; {ho.fraction_stable:.4g} of {ho.samples} held-out members" if ho else ""
        out.append(
            f"{n} stabilises every sampled member (worst real part {e.max_real_pole:.3g} "
            f"rad/s{held}) at the cost of: {cost}."
        )
    partial = [n for n in ok if n not in robust]
    if partial:
        out.append(
            "The others leave members unstable: "
            + ", ".join(
                f"{n} {ok[n].evaluation.fraction_stable:.3g} stable "
                f"(peak force {ok[n].evaluation.peak_force_n:.3g} N)"
                for n in partial
            )
            + "."
        )
    for n, r in ok.items():
        if not isinstance(r.facts, RobustLMIFacts):
            continue
        d = r.facts.design
        syn = d.synthesis
        rm = None if r.checks is None else r.checks.margin
        fail = d.failed
        text = (
            f"{n} (LMI synthesis, {syn.get('members', 0)} design members, certificates "
            f"re-checked; worst certified H-infinity level {syn.get('gamma_bound', math.nan):.3g}) "
            f"meets the specification on the checked members of the family's box scaled to "
            f"{d.scale:.3g}"
        )
        if rm:
            text += (
                f"; its certified robust margin for the specification's pole region is "
                f"{rm.lower:.3g} (upper bound {rm.upper:.3g})"
            )
        if fail:
            text += (
                f". Beyond, at scale {fail.scale:.3g}, the binding constraint is "
                f"{fail.binding} (utilisation {fail.utilisation:.3g})"
            )
        out.append(text + ".")
    if tradeoff:
        pts = "; ".join(
            f"{p.continuous_force_n:.3g} N continuous / {p.peak_force_n:.3g} N peak: scale "
            f"{p.scale:.3g} (certified margin {p.certified_scale:.3g})"
            + (f", {p.binding} binds beyond" if p.binding else "")
            for p in tradeoff
        )
        whole = any(p.scale >= 1 for p in tradeoff)
        out.append(
            f"The robust handle-force LMI design against the force limits: {pts}. "
            + (
                "With enough force one controller meets the specification on the whole family."
                if whole
                else "No limit in this sweep lets one controller meet the specification on the "
                "whole family (scale 1)."
            )
        )
    failing_force = [n for n in force_designs if n not in valid_force]
    hard = _hardest_member({n: ok[n] for n in failing_force})
    if force_designs and not valid_force and hard:
        band = (
            "That mode lies in the 0-2 Hz band people command in, so handle force that damps it "
            "also resists the operator's intended motion; "
            if hard["f_arm"] <= 2.0
            else "The feedthrough loop closes through that structure mode; "
        )
        out.append(
            f"Why: the member {hard['which']} does worst on has an arm of stiffness "
            f"{hard['k_arm']:.3g} N/m and damping {hard['c_arm']:.3g} N s/m, a handle-arm mode "
            f"at {hard['f_arm']:.3g} Hz with damping ratio {hard['zeta_arm']:.3g}, on a "
            f"structure whose first mode is at {hard['f1']:.3g} Hz (nominal "
            f"{StructureParams().f1_hz:.3g} Hz). "
            + band
            + "a cylinder-reference correction avoids the force but costs tracking; workspace "
            "scaling works only by shrinking the stick's motion per handle millimetre."
        )
    return out


def _hardest_member(failing: dict) -> dict | None:
    """Arm and structure figures of the worst member of the least robust failing force design.

    The least robust design is the one with the smallest fraction of stable members
    (ties: the largest worst real part).
    """
    candidates = [(n, r) for n, r in failing.items() if r.evaluation.worst]
    if not candidates:
        return None
    name, run = min(
        candidates,
        key=lambda nr: (nr[1].evaluation.fraction_stable, -nr[1].evaluation.max_real_pole),
    )
    fam = run.family
    worst = run.evaluation.worst
    loop = fam.member([worst[n] for n in fam.names])
    p = loop.human.params
    return {
        "which": name,
        "k_arm": p.k_arm,
        "c_arm": p.c_arm,
        "f_arm": math.sqrt(p.k_arm / p.m_arm) / (2 * math.pi),
        "zeta_arm": p.c_arm / (2 * math.sqrt(p.k_arm * p.m_arm)),
        "f1": loop.struct.f1_hz,
    }


def write_design_report(
    runs: dict,
    out_dir,
    *,
    samples: int,
    seed: int,
    coverage: FamilyCoverage | None = None,
    tradeoff=None,
    limit: dict | None = None,
    scheduled: dict | None = None,
):
    """One HTML page comparing the designs: table, pole clouds, ratio envelopes, force histories.

    The folder is replaced atomically (:func:`reports.html.write_report_dir`) and
    holds ``index.html``, the figures and ``designs.json`` (every design's summary).

    Parameters
    ----------
    runs : dict
        Design name -> evaluated :class:`designs.DesignResult` or the exception it
        raised, as :func:`run_all_designs` returns.
    out_dir : path-like
        The report folder.
    samples : int
        Members each design was validated on (the figures redraw the same sample).
    seed : int
        Sampling seed of that sample.
    coverage : reports.coverage.FamilyCoverage, optional
        Who the family covers (default: computed for the default family on the same
        sample size and seed).
    tradeoff : list of designs.robust_lmi_tradeoff.TradeoffPoint, optional
        The force-budget sweep (:func:`designs.robust_lmi_tradeoff.force_tradeoff`), drawn as a
        Pareto curve.
    limit : dict, optional
        The achievable-limit map (``bdft limit --json``'s object, with ``conclusions``):
        each design's coverage is shown beside its set's limit coverage.
    scheduled : dict, optional
        The per-operator design's result (:func:`designs.scheduled.scheduled_design`),
        shown beside its set's limit coverage.

    Returns
    -------
    pathlib.Path
        The page's ``index.html``.
    """
    limits = DeviceLimits()
    coverage = coverage or family_coverage(default_family(), samples=samples, seed=seed)
    page = HtmlPage("Compensators against biodynamic feedthrough: comparison on the default family")
    page.p(
        f"Every design is validated on the same {samples} members of the default family "
        f"(Latin hypercube, seed {seed}): the operator's body mass, arm-endpoint mass, "
        "natural frequency and damping ratio and trunk natural frequency and damping ratio "
        "over their published ranges (section 'Who the family covers'), and the structure's "
        "frequencies, damping ratios and gain. "
        "Force is simulated on the nominal member and the three worst stable members with a "
        "0.1-8 Hz chirp and a seeded 0-2 Hz intended motion "
        f"({100 * INTENT_FRACTION:g} % of the half-workspace); the Omni's limits are "
        f"{limits.peak_force_n:g} N peak, {limits.continuous_force_n:g} N continuous."
    )
    rows, classes = [], []
    for name, run in runs.items():
        if isinstance(run, Exception):
            rows.append([name, "FAILED", str(run)[:300]] + [""] * 11)
            classes.append("fails")
            continue
        e = run.evaluation
        valid = e.fraction_stable == 1.0 and e.force_within_limits
        ho = run.checks.held_out if run.checks is not None else None
        rm = run.checks.margin if run.checks is not None else None
        nan = float("nan")
        rows.append(
            [
                name,
                "valid" if valid else "invalid",
                "; ".join(e.notes) or run.description,
                e.fraction_stable,
                nan if ho is None else ho.fraction_stable,
                e.max_real_pole,
                e.min_damping,
                e.suppression_db,
                e.tracking_error,
                e.peak_force_n,
                e.rms_force_n,
                f"{run.order_full} -> {run.order_reduced}",
                nan if rm is None else rm.lower,
                nan if rm is None else rm.upper,
            ]
        )
        classes.append("holds" if valid else "fails")
    page.h2("Summary")
    page.table(
        [
            "design",
            "verdict",
            "notes",
            "fraction stable",
            "held-out stable",
            "worst real part [1/s]",
            f"min damping ({DAMPING_BAND_HZ[0]:g}-{DAMPING_BAND_HZ[1]:g} Hz)",
            "BDFT near 6 Hz [dB]",
            "tracking error 0-2 Hz",
            "peak force [N]",
            "RMS force [N]",
            "order",
            "margin, certified lower",
            "margin, upper",
        ],
        rows,
        row_classes=classes,
    )
    page.p(
        "A design is valid only if every sampled member is stable and its force stays within "
        "the device limits. "
        "Held-out: fraction stable on 10000 further members (LHS, seed + 1) that no design saw. "
        "BDFT near 6 Hz: largest |20 log10 |Y/Y_ref|| over 5-7.5 Hz on the nominal member "
        "(0 dB: no effect). "
        "Tracking error: max |Y/Y_ref - 1| over 0.05-2 Hz on the nominal member. "
        "Margin: the largest scale of the family's box (about its nominal, each parameter in "
        "its own coordinates; 1 = the family) at which every member's poles are in the "
        "specification's region (decay rate and damping): the certified lower bound covers "
        "the whole scaled box, not samples; "
        "the upper bound is the scale of the worst member found (details in 'Robust margins' "
        "below; nan when not computed).",
        cls="note",
    )
    _margin_section(page, runs)
    _population_coverage_section(page, runs, limit)
    if scheduled is not None:
        _scheduled_section(page, scheduled, limit)
    _spec_section(page, runs)
    _tradeoff_section(page, tradeoff)
    _saturation_section(page, runs)
    page.h2("Verdict")
    for text in verdict(runs, tradeoff):
        page.p(text)
    if scheduled is not None:
        c = scheduled["coverage"]
        wb = scheduled.get("wrong_within_bound")
        robust = (
            ""
            if not wb
            else f"; designs from estimates on the boundary of the calibration's joint error "
            f"region keep the loop stable in {100 * wb['stable']:.1f} % of {wb['designs']}"
        )
        page.p(
            f"The per-operator design (built at each operator's calibration, set "
            f"{scheduled['limit_set']}) meets the whole specification on "
            f"{100 * c['fraction']:.1f} % of the population ({c['samples']} fresh members; at "
            f"least {100 * c['lower']:.1f} % with confidence {c['confidence']:g}){robust} "
            "(section 'The per-operator design')."
        )
    add_coverage_section(page, coverage)
    _figures(page, runs, samples, seed, limits)
    page.attach(
        "designs.json",
        json.dumps(
            to_jsonable(
                {
                    "designs": {
                        k: (str(r) if isinstance(r, Exception) else r.to_json())
                        for k, r in runs.items()
                    },
                    "tradeoff": [dataclasses.asdict(p) for p in tradeoff or []],
                    "scheduled": scheduled,
                }
            ),
            indent=2,
            allow_nan=False,
        ),
    )
    return write_report_dir(page, out_dir)
