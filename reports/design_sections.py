"""The sections of the design comparison page, one function each.

The margins, the population coverage, the per-operator scheduled bank, the specification
table, the saturation and the force trade-off: each ``_..._section`` adds its part of the
page that :func:`reports.designs.write_design_report` assembles, from the designs'
results. Kept apart from the assembly and the verdict so that each section reads on its
own.
"""

from __future__ import annotations

import math

import matplotlib.pyplot as plt

from backhoe import default_family
from backhoe.model.device import DeviceLimits
from designs.calibration_region import REGION_RADIUS
from designs.limit_sets import design_set, limit_coverage_of
from reports.html import HtmlPage
from uncertainty.randomized import coverage_consistent

#: Nothing public: :mod:`reports.designs`'s own.
__all__: list[str] = []


def _certificate_text(certificate: dict) -> str:
    """What certified the lower bound: mu's frequencies and peak bound, or the sub-boxes."""
    cert = certificate.get("certified_stats")
    scale = certificate.get("certified_scale")
    if scale is None or cert is None:
        return "none: the centre member is outside the region"
    if scale == 0:
        return "the centre member only"
    if certificate.get("method") == "mu":
        return f"mu: {cert['frequencies']} frequencies, peak bound {cert['peak_mu_upper']:.3f}"
    routes = ", ".join(f"{k} {v}" for k, v in cert.get("routes", {}).items())
    return f"{cert.get('boxes', 0)} sub-boxes ({routes or '-'})"


def _margin_section(page: HtmlPage, runs: dict) -> None:
    """Both bounds of every design's robust margin, the member that breaks it, the method."""
    margins = {
        k: r.checks.margin
        for k, r in runs.items()
        if not isinstance(r, Exception) and r.checks is not None and r.checks.margin is not None
    }
    if not margins:
        return
    page.h2("Robust margins")
    rows = []
    for name, m in margins.items():
        crit = m.critical or {}
        worst = ""
        if len(crit.get("poles", ())):
            p = max(crit["poles"], key=lambda z: z.real)
            worst = f"{p.real:+.3f} {p.imag:+.3f}j"
        gap = m.upper / m.lower if m.lower > 0 else float("inf")
        rows.append([name, m.lower, m.upper, gap, worst, _certificate_text(m.certificate)])
    page.table(
        [
            "design",
            "certified lower bound",
            "upper bound",
            "gap upper/lower",
            "critical member's rightmost pole [1/s]",
            "certificate at the lower bound",
        ],
        rows,
    )
    first = next(iter(margins.values()))
    page.p(
        f"Region: {first.region.describe()}. Lower bound: {first.method['lower']}. "
        f"Upper bound: {first.method['upper']}. Scaling: {first.method['scaling']}.",
        cls="note",
    )
    fig, ax = plt.subplots(figsize=(7.5, 0.45 * len(margins) + 1.2))
    for i, m in enumerate(margins.values()):
        lo = max(m.lower, 1e-4)
        up = m.upper if math.isfinite(m.upper) else 10.0
        ax.plot([lo, up], [i, i], "-", lw=6, color="0.75", solid_capstyle="butt")
        ax.plot([lo], [i], "o", color="tab:green", label="certified lower" if i == 0 else None)
        if m.lower <= 0:
            ax.annotate(
                "0: no scale > 0 certified",
                (lo, i),
                xytext=(6, 6),
                textcoords="offset points",
                fontsize=7,
            )
        ax.plot(
            [up], [i], "x", color="tab:red", label="upper (violating member)" if i == 0 else None
        )
    ax.axvline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_yticks(range(len(margins)), list(margins))
    ax.set_xlabel("robust margin (scale of the family's box; 1 = whole family)")
    ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    page.figure(
        fig,
        "margins",
        "Robust margin of every design: the true margin lies between the certified lower "
        "bound (green; a bound of 0 is drawn at 1e-4) and the upper bound (red); the dashed "
        "line is the whole family.",
    )
    plt.close(fig)


def _population_coverage_section(page: HtmlPage, runs: dict, limit: dict | None = None) -> None:
    """Every design's coverage with its certificate, beside its margin and its set's limit."""
    covered = {
        k: r
        for k, r in runs.items()
        if not isinstance(r, Exception) and getattr(r, "coverage", None) is not None
    }
    if not covered:
        return
    page.h2("Coverage of the population")
    rows, classes = [], []
    for name, r in covered.items():
        c = r.coverage.to_json()
        fails = {k: v for k, v in c["binding"].items() if v}
        top = max(fails, key=fails.get) if fails else "-"
        m = r.checks.margin if r.checks is not None else None
        p = r.checks.performance if r.checks is not None else None
        row = [
            name,
            f"{100 * c['fraction']:.2f} %",
            f"{c['failures']} / {c['samples']}",
            f"{c['epsilon']:.3g}",
            f"{100 * c['lower']:.2f} %",
            top if not fails else f"{top} ({fails[top]})",
            float("nan") if m is None else m.lower,
            "-" if p is None else f"[{p.lower:.4g}, {p.upper:.4g}]",
        ]
        if limit is not None:
            row += _limit_cells(r, limit)
        rows.append(row)
        classes.append("holds" if c["failures"] == 0 else "fails")
    first = next(iter(covered.values())).coverage.bound
    head = [
        "design",
        "coverage (observed)",
        "failures / members",
        f"epsilon (confidence {first.confidence:g})",
        "certified coverage 1 - epsilon",
        "most frequent binding constraint",
        "margin, certified lower",
        "tracking robust performance margin [certified, upper]",
    ]
    if limit is not None:
        head += ["its set (actuators/sensors)", "limit coverage of the set, Omni's force"]
    page.table(head, rows, row_classes=classes)
    if limit is not None:
        page.p(
            f"Limit coverage: the achievable-limit map (bdft limit) on {limit['samples']} "
            f"members (Latin hypercube, seed {limit['seed']}): the fraction that a "
            "compensator with the design's actuators and sensors, knowing the member exactly, "
            "can protect within the Omni's force limits (for a set the map did not compute, "
            "the smallest computed set containing it). A design cannot exceed it beyond the "
            "sampling error of both fractions; the design's is bounded (its Clopper-Pearson "
            "bound, independent members), the limit's is not (a Latin hypercube's fraction has "
            "no tail bound), so the check uses the design's alone. Best set at the Omni's limits: "
            f"{limit['conclusions'][0] if limit.get('conclusions') else '-'}",
            cls="note",
        )
    page.p(
        f"Coverage: the fraction of the population (the default family's distributions) on "
        f"which the whole specification holds, checked member by member on {first.samples} "
        f"members drawn independently (Monte Carlo, seed {first.seed}) that no design used. "
        f"k failures in N members give P(failure) <= epsilon with confidence "
        f"{first.confidence:g}, epsilon the one-sided Clopper-Pearson bound (the binomial "
        "tail of k or fewer failures equals 1 - confidence at epsilon; Tempo, Calafiore & "
        "Dabbene). The certified margin is a different guarantee: the pole region on every "
        "member of the scaled box, no probability. The tracking robust performance margin is "
        "the largest scale of the box on which every member is stable and meets the tracking "
        "bound |Y/Y_ref - 1| <= |W_t| at every frequency of the operator's band: its lower "
        "bound certified by mu with a performance block over the band (and the box's "
        "stability by mu over every frequency), its upper bound a member that breaks the "
        "bound, with its exact peak over the band (bdft design --json: robust_performance).",
        cls="note",
    )


def _scheduled_section(page: HtmlPage, sched: dict, limit: dict | None) -> None:
    """The per-operator design (``bdft design scheduled``): coverage beside its set's limit."""
    c = sched["coverage"]
    fails = c["failures_by_constraint"]
    top = max(fails, key=fails.get) if fails else "-"
    page.h2("The per-operator design (bdft design scheduled)")
    row = [
        "scheduled",
        f"{100 * c['fraction']:.2f} %",
        f"{c['failures']} / {c['samples']}",
        f"{c['epsilon']:.3g}",
        f"{100 * c['lower']:.2f} %",
        f"{top} ({fails[top]})" if fails else "-",
        sched["limit_set"],
    ]
    head = [
        "design",
        "coverage (observed)",
        "failures / members",
        f"epsilon (confidence {c['confidence']:g})",
        "certified coverage 1 - epsilon",
        "most frequent binding constraint",
        "its set (actuators/sensors)",
    ]
    found = limit_coverage_of(limit["sets"], sched["limit_set"], 1.0) if limit else None
    consistent = None
    if found is not None:
        _, e = found
        consistent = coverage_consistent(c["fraction"], c["samples"], e["coverage"])
        row += [
            f"{100 * e['coverage']:.1f} % of {e['samples']}",
            f"{c['fraction'] / e['coverage']:.3f}" if e["coverage"] > 0 else "-",
            "yes" if consistent else "NO",
        ]
        head += [
            "limit coverage of the set, Omni's force",
            "fraction of the limit",
            "within the limit (the design's sampling error)",
        ]
    page.table(head, [row], row_classes=["holds" if c["failures"] == 0 else "fails"])
    wb = sched.get("wrong_within_bound")
    text = (
        f"Design: {sched['design']}. Each of the {c['samples']} fresh members (Monte Carlo, "
        f"seed {c['seed']}) has its own simulated 60 s calibration record; the compensator is "
        "built from the record alone and the whole specification checked on the true member. "
        f"The operator's true modes lie within the calibration's error bound for "
        f"{100 * c['operator_within_error_bound']:.1f} % of them, the cab's for "
        f"{100 * c['cab_within_error_bound']:.1f} %."
    )
    if "estimate_within_confidence_region" in c:
        text += (
            f" The estimate lies within the calibration's joint error region ({REGION_RADIUS:.2f} "
            f"standard deviations of the hand's response, the 99.73 % region of four "
            f"quantities) around what the same record without its noise identifies for "
            f"{100 * c['estimate_within_confidence_region']:.1f} % of the first "
            f"{c['confidence_region_samples']}."
        )
    if wb:
        text += (
            f" Designs from estimates on the boundary of that joint error region "
            f"({wb['designs']} designs on {wb['members']} members: the operator along the "
            f"region's principal axes, the cab's modes moved to their bounds): the loop stays "
            f"stable in {100 * wb['stable']:.1f} % and meets the specification in "
            f"{100 * wb['specification']:.1f} %."
        )
    wx = sched.get("wrong_within_box")
    if wx:
        text += (
            f" The harsher box (the true modes, masses nominal, one quantity moved to its "
            f"marginal bound: estimates the record rules out): stable in "
            f"{100 * wx['stable']:.1f} %, the specification in "
            f"{100 * wx['specification']:.1f} %."
        )
    cb = sched.get("certified_over_bound")
    if cb:
        text += (
            f" Certified (the specification's pole region, interval certificate) for every "
            f"operator and cab within a scale of the calibration's bound, on "
            f"{cb['members']} members: median {cb['median_lower']:.3g} (a member breaking it "
            f"found at a median {cb['median_upper']:.3g}); {cb['certified_whole_bound']} "
            "certified on the whole bound."
        )
    page.p(text, cls="note")
    page.table(
        ["cells", "members", "coverage", "right cell"],
        [
            [
                str(r["cells"]),
                r["samples"],
                f"{100 * r['fraction']:.1f} %",
                "-" if r["right_cell"] is None else f"{100 * r['right_cell']:.1f} %",
            ]
            for r in sched["coverage_by_cells"]
        ],
    )
    page.p(
        "Coverage against the number of cells: a bank of cells over the identified operator "
        "modes, each with the cancellation of its centre's human, against the compensator "
        "built from each operator's own estimate, without and with the cab's damper (the "
        "design above).",
        cls="note",
    )


def _limit_cells(run, limit: dict) -> list:
    """The design's set and that set's limit coverage at the Omni's force (two table cells)."""
    default_k = default_family().k_psf
    if run.family is not None and abs(run.family.k_psf - default_k) > 1e-12 * default_k:
        return ["another machine (workspace changed)", "-"]
    name = design_set(run.controller)
    if name is None:
        return ["-", "-"]
    found = limit_coverage_of(limit["sets"], name, 1.0)
    if found is None:
        return [name, "not computed"]
    used, e = found
    note = "" if used == name else f" (as {used})"
    return [name, f"{100 * e['coverage']:.1f} % of {e['samples']}{note}"]


def _fmt(value) -> str:
    """A number to 3 significant digits; JSON's strings for non-finite values as they are."""
    return value if isinstance(value, str) else f"{value:.3g}"


def _spec_section(page: HtmlPage, runs: dict) -> None:
    """Every design against the specification: each constraint's worst value, the binding one."""
    checks = {
        k: r.checks
        for k, r in runs.items()
        if not isinstance(r, Exception) and r.checks is not None
    }
    if not checks:
        return
    page.h2("Specification")
    first = next(iter(checks.values()))
    names = [c.name for c in first.spec.constraints]
    rows, classes = [], []
    for name, ch in checks.items():
        c = ch.spec
        rows.append(
            [name, "holds" if c.holds else "fails", c.binding]
            + [_fmt(c.constraint(n).value) + ("" if c.constraint(n).holds else " !") for n in names]
        )
        classes.append("holds" if c.holds else "fails")
    sp = first.specification.to_json()
    page.table(["design", "verdict", "binding"] + names, rows, row_classes=classes)
    page.p(
        f"Checked on the nominal member, the worst sampled member and 8 seeded sampled "
        f"members. Limits: decay rate {sp['decay_rate']:g} rad/s (largest real part below "
        f"-{sp['decay_rate']:g}); damping ratio >= {sp['min_damping']:g} for poles in "
        f"{sp['damping_band_hz'][0]:g}-{sp['damping_band_hz'][1]:g} Hz; peak force "
        f"{sp['peak_force_n']:g} N and RMS force {sp['continuous_force_n']:g} N under the "
        f"realistic intended motion (0-{sp['intent_bandwidth_hz']:g} Hz, "
        f"{100 * sp['intent_fraction']:g} % of the half-workspace, with the operator's remnant "
        f"and the sensor noise); the deviation |Y/Y_ref - 1| within its bound at every "
        f"frequency (tracking: up to {sp['tracking_band_hz'][1]:g} Hz, "
        f"{sp['tracking_error']:g} in the operator's band; feedthrough: above it, reduced by "
        f"{sp['feedthrough_reduction_db']:g} dB over {sp['feedthrough_band_hz'][0]:g}-"
        f"{sp['feedthrough_band_hz'][1]:g} Hz, values as multiples of the bound, see the "
        f"figure); the cylinder position and force caused by the sensor noise within "
        f"{sp['noise_cylinder_mm']:g} mm and {sp['noise_force_n']:g} N RMS; a reference "
        f"correction's cylinder speed and valve command within "
        f"{100 * sp['correction_flow_share']:g} % of the valve's (3 sigma). '!' marks a "
        "violated constraint; the binding one has the "
        "largest utilisation.",
        cls="note",
    )


def _saturation_section(page: HtmlPage, runs: dict) -> None:
    sat = {
        k: r.checks.saturation
        for k, r in runs.items()
        if not isinstance(r, Exception) and r.checks is not None and r.checks.saturation
    }
    if not sat:
        return
    page.h2("Saturated 1 kHz simulations")
    rows = []
    for name, members in sat.items():
        for label, c in members.items():
            rows.append(
                [
                    name,
                    label,
                    "ok"
                    if c.check.ok
                    else ("diverged" if c.check.diverged else "sustained oscillation"),
                    "stable" if c.linear_stable else "unstable",
                    c.check.saturated_fraction,
                    c.check.peak_request_n,
                    c.check.correction_clipped_fraction,
                    c.check.valve_clipped_fraction,
                    c.check.flow_limited_fraction,
                    c.check.stroke_end_fraction,
                    c.check.final_amplitude_mm,
                    c.check.decay_ratio,
                ]
            )
    page.table(
        [
            "design",
            "member",
            "outcome",
            "linear 1 kHz loop",
            "force clipped",
            "peak force asked [N]",
            "correction clipped",
            "valve at full opening",
            "flow-limited",
            "at a stroke end",
            "amplitude left [mm]",
            "decay ratio",
        ],
        rows,
    )
    page.p(
        "Each member driven by 20 s of the seeded realistic intended motion, then left to "
        "settle, with the discrete (1 kHz) controller, the handle force clipped at the "
        "device's peak, the reference correction at a quarter of the stroke, and the "
        "hydraulics the linear model leaves out (the valve command at full opening and "
        "through the spool's dead zone, the flow limit on the cylinder's speed, the stroke "
        "ends; backhoe.model.components.HydraulicLimits). The clipped and limited columns "
        "are fractions of the samples; 'amplitude left' is the cylinder's oscillation in the "
        "last second. 'Sustained' means the response did not die out after the motion "
        "stopped (the limit cycles the paper's hardware showed). 'Linear 1 kHz loop': the "
        "same member's loop without saturation; a member that diverges with an unstable "
        "linear loop lies outside what the controller stabilises (for the LMI designs: "
        "outside the family scale they hold), a member that diverges or oscillates with a "
        "stable linear loop does so because of the saturation.",
        cls="note",
    )


def _tradeoff_section(page: HtmlPage, tradeoff) -> None:
    if not tradeoff:
        return
    page.h2("Force budget against family scale")
    rows = [
        [
            p.continuous_force_n,
            p.peak_force_n,
            p.force_budget_n,
            p.scale,
            p.certified_scale,
            p.binding or "-",
            p.failed_scale,
        ]
        for p in tradeoff
    ]
    page.table(
        [
            "continuous limit [N]",
            "peak limit [N]",
            "RMS budget of the synthesis [N]",
            "scale reached",
            "scale certified",
            "binding beyond",
            "first scale failed",
        ],
        rows,
    )
    fig, ax = plt.subplots(figsize=(6.5, 3.6))
    x = [p.continuous_force_n for p in tradeoff]
    ax.plot(x, [max(p.scale, 1e-4) for p in tradeoff], "o-", label="specification holds (checked)")
    ax.plot(x, [max(p.certified_scale, 1e-4) for p in tradeoff], "s--", label="region certified")
    ax.axvline(DeviceLimits().continuous_force_n, color="k", lw=0.8, ls=":")
    ax.annotate("Omni", (DeviceLimits().continuous_force_n, 1e-4), fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("continuous-force limit [N] (peak limit in proportion)")
    ax.set_ylabel("family scale (1 = whole family)")
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.legend(fontsize=8)
    fig.tight_layout()
    page.figure(
        fig,
        "tradeoff",
        "Pareto curve of the robust handle-force LMI design: the largest scale of the "
        "family's box on which the ladder's constraints (pole region, forces, tracking) hold "
        "on the checked members, and on which "
        "the pole region is certified, against the force limits (0 drawn at 1e-4).",
    )
    plt.close(fig)
