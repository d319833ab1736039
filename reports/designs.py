"""The design comparison report (``bdft report``): every design on the same family, one page."""

from __future__ import annotations

import dataclasses
import json
import math

import matplotlib.pyplot as plt
import numpy as np

from designs import design_names, run_design
from designs.calibration import REGION_RADIUS
from designs.evaluate import INTENT_FRACTION, force_histories, output_ratio
from designs.limit import design_set, limit_coverage_of
from designs.robust_lmi import RobustLMIFacts
from designs.spec import Specification
from reports.coverage import FamilyCoverage, add_coverage_section, family_coverage
from reports.html import HtmlPage, write_report_dir
from robust.analysis.loops import loop_poles
from robust.analysis.stability import DAMPING_BAND_HZ
from robust.engine import map_tasks
from robust.errors import BDFTError
from robust.jsonio import to_jsonable
from robust.model.components import StructureParams
from robust.model.device import DeviceLimits
from uncertainty import batched_poles, default_family, sample
from uncertainty.randomized import coverage_consistent

__all__ = ["run_all_designs", "run_designs_with", "verdict", "write_design_report"]


#: The designs that take minutes (robust synthesis), started first when designs run in
#: parallel.
_LONG_DESIGNS = (
    "hinf-robust-lmi",
    "workspace2-hinf-lmi",
    "cylinder-lmi",
    "hinf-robust-corr",
    "hinf-robust",
)


def run_all_designs(**kwargs):
    """Run every design (or ``names``); a design that fails is kept with its error, not dropped.

    :func:`run_designs_with` without other tasks; the keywords are its.

    Parameters
    ----------
    **kwargs
        As for :func:`run_designs_with` (``extra_tasks`` aside).

    Returns
    -------
    dict
        Design name to its evaluated :class:`designs.DesignResult`, or to the
        :class:`robust.errors.BDFTError` it raised.
    """
    return run_designs_with(**kwargs)[0]


def _pool_task(item):
    """One task of :func:`run_designs_with`'s pool: a design, or another ``(fn, arg)``."""
    kind, payload = item
    if kind == "design":
        return _design_task(payload)
    fn, arg = payload
    return fn(arg)


def run_designs_with(
    *,
    samples: int = 2000,
    seed: int = 0,
    out_dir=None,
    names=None,
    progress=None,
    margin_boxes: int = 0,
    coverage_samples: int = 0,
    n_jobs: int = 1,
    member_progress=None,
    cache: bool = False,
    design_jobs: int = 1,
    scheduler: str | None = None,
    extra_tasks=(),
):
    """Run every design (or ``names``) and other long tasks in one pool of processes.

    Each design runs through :func:`designs.run_design` on the default family; a design
    that fails is kept with its error, not dropped. With ``design_jobs`` above 1 (or a
    Dask ``scheduler``) the designs themselves run in parallel processes
    (:func:`robust.engine.map_tasks`), each with its coverage checks in one process; every
    design is deterministic in its process (the robust designs run their BLAS on one
    thread), so the results are those of the serial run. ``extra_tasks`` (``bdft report``:
    the points of the force trade-off) run in the same pool, ahead of the designs, so that
    no core waits for the slowest task of one batch before the next batch starts.

    Parameters
    ----------
    samples : int
        Members of the design and validation sample (the same for every design).
    seed : int
        Sampling seed.
    out_dir : path-like, optional
        Folder for the designs' artifacts; ``None`` writes none.
    names : sequence of str, optional
        Designs to run (default: every registered design, in report order).
    progress : callable, optional
        Called with each design's name before it runs.
    margin_boxes : int
        Sub-boxes per scale of each design's certified robust margin (0: not computed).
    coverage_samples : int
        Independent members of each design's coverage certificate (0: not computed).
    n_jobs : int
        Parallel processes of the coverage checks.
    member_progress : callable, optional
        ``member_progress(done, total)`` during each coverage check.
    cache : bool
        Use the result cache (see :func:`designs.run_design`).
    design_jobs : int
        Designs run at once in local processes (1: one after the other in this process,
        with ``n_jobs`` processes for each coverage check).
    scheduler : str, optional
        Address of a Dask scheduler to run the designs on instead of local processes.
    extra_tasks : sequence of (str, callable, object)
        Other tasks: a label (for ``progress``), a module-level function and its one
        argument. Run after the designs when ``design_jobs`` is 1.

    Returns
    -------
    runs : dict
        Design name to its evaluated :class:`designs.DesignResult`, or to the
        :class:`robust.errors.BDFTError` it raised.
    extra : list
        The results of ``extra_tasks``, in order (an exception they raise is raised).
    """
    names = list(names or design_names())
    extra_tasks = list(extra_tasks)
    options = dict(
        samples=samples,
        seed=seed,
        out_dir=out_dir,
        margin_boxes=margin_boxes,
        coverage_samples=coverage_samples,
        cache=cache,
    )
    if design_jobs == 1 and scheduler is None:
        runs = {}
        for name in names:
            if progress:
                progress(name)
            runs[name] = _design_task(
                (name, dict(options, n_jobs=n_jobs, progress=member_progress))
            )
        extra = []
        for label, fn, arg in extra_tasks:
            extra.append(fn(arg))
            if progress:
                progress(f"{label} done")
        return runs, extra
    # the other tasks and the longest designs first, so that the last to start is short
    rank = {n: i for i, n in enumerate(_LONG_DESIGNS)}
    order = sorted(names, key=lambda n: (rank.get(n, len(rank)), names.index(n)))
    items = [("task", (fn, arg)) for _, fn, arg in extra_tasks]
    items += [("design", (n, dict(options, n_jobs=1))) for n in order]
    labels = [label for label, _, _ in extra_tasks] + list(order)

    def finished(i):
        if progress:
            progress(f"{labels[i]} done")

    results = map_tasks(_pool_task, items, jobs=design_jobs, scheduler=scheduler, progress=finished)
    k = len(extra_tasks)
    by_name = dict(zip(order, results[k:]))
    return {n: by_name[n] for n in names}, list(results[:k])


def _design_task(task):
    """One design's :func:`designs.run_design`, or the :class:`BDFTError` it raised."""
    name, options = task
    try:
        return run_design(name, **options)
    except BDFTError as exc:
        return exc


def _ratio_envelope(family, values, controller, freqs):
    curves = []
    for row in values:
        m = family.member(row)
        if loop_poles(m, controller=controller).stable:
            curves.append(20 * np.log10(np.abs(output_ratio(m, controller, freqs))))
    return np.array(curves)


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
        cert = m.certificate.get("certified_stats") or {}
        routes = ", ".join(f"{k} {v}" for k, v in cert.get("routes", {}).items())
        gap = m.upper / m.lower if m.lower > 0 else float("inf")
        rows.append(
            [
                name,
                m.lower,
                m.upper,
                gap,
                worst,
                f"{cert.get('boxes', 0)} sub-boxes ({routes or '-'})",
            ]
        )
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
        row = [
            name,
            f"{100 * c['fraction']:.2f} %",
            f"{c['failures']} / {c['samples']}",
            f"{c['epsilon']:.3g}",
            f"{100 * c['lower']:.2f} %",
            top if not fails else f"{top} ({fails[top]})",
            float("nan") if m is None else m.lower,
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
        "member of the scaled box, no probability.",
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
        "ends; robust.model.components.HydraulicLimits). The clipped and limited columns "
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


def _bound_figure(page: HtmlPage, ok: dict) -> None:
    """Every design's deviation from the BDFT-free response on its nominal member against the
    specification's bound, 0.01-100 Hz (the check itself holds at every frequency)."""
    spec = Specification()
    freqs = np.geomspace(0.01, 100.0, 600)
    w = 2 * np.pi * freqs
    n = len(ok)
    if not n:
        return
    cols = 2
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(9, 2.4 * rows), sharex=True, squeeze=False)
    for ax, (name, run) in zip(axes.ravel(), ok.items()):
        fam = default_family(k_psf=run.evaluation.k_psf)
        m = fam.member(fam.nominal_values())
        r0 = output_ratio(m.replace(k_psf=spec.reference_k_psf), None, freqs) - 1.0
        bound = spec.deviation_bound(w, r0)
        ax.loglog(freqs, bound, "k--", lw=0.9, label="bound")
        if loop_poles(m, controller=run.controller).stable:
            r = np.abs(output_ratio(m, run.controller, freqs) - 1.0)
            ax.loglog(freqs, r, lw=1.0, label="|Y/Y_ref - 1|")
            bad = r > bound
            if bad.any():
                ax.loglog(freqs[bad], r[bad], "r.", ms=2, label="above the bound")
        else:
            ax.text(0.5, 0.5, "unstable", transform=ax.transAxes, ha="center")
        ax.axvline(spec.split_hz, color="0.6", lw=0.6)
        ax.set_title(name, fontsize=9)
        ax.grid(True, which="both", alpha=0.2)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes[0, 0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    fig.tight_layout()
    page.figure(
        fig,
        "deviation_bounds",
        "Each design's deviation of the cylinder's response from the BDFT-free response, "
        "|Y/Y_ref - 1|, on the nominal member, against the specification's bound: |W_t| up to "
        f"{spec.split_hz:g} Hz (the operator's band, {spec.tracking_error:g} there), above it "
        f"the larger of |W_t| and |W_f R0| (the uncompensated deviation R0 of the machine as "
        f"built, halved over {spec.feedthrough_band_hz[0]:g}-{spec.feedthrough_band_hz[1]:g} "
        f"Hz, at most {spec.max_amplification_db:g} dB above it elsewhere). The "
        "specification's check holds at every frequency, not on this plot's grid.",
    )


def _figures(page: HtmlPage, runs: dict, samples: int, seed: int, limits: DeviceLimits) -> None:
    ok = {k: r for k, r in runs.items() if not isinstance(r, Exception)}
    n_show = min(samples, 400)
    fig, axes = plt.subplots(1, len(ok), figsize=(3.2 * len(ok), 3.4), sharey=True, squeeze=False)
    for ax, (name, run) in zip(axes[0], ok.items()):
        fam = default_family(k_psf=run.evaluation.k_psf)
        vals = sample(fam.parameters, samples, method=run.evaluation.method, seed=seed).values[
            :n_show
        ]
        p = batched_poles(fam, vals, controller=run.controller).ravel()
        p = p[np.abs(p.imag) / (2 * np.pi) < 15]
        ax.plot(p.real, p.imag / (2 * np.pi), ".", ms=1.5, alpha=0.4)
        ax.axvline(0, color="k", lw=0.8)
        ax.set_xlim(-25, 8)
        ax.set_ylim(0, 12)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("real part [rad/s]")
    axes[0, 0].set_ylabel("frequency [Hz]")
    fig.tight_layout()
    page.figure(
        fig,
        "pole_clouds",
        f"Closed-loop poles of {n_show} family members per design (seed {seed}).",
    )

    freqs = np.geomspace(0.1, 15, 200)
    fig, ax = plt.subplots(figsize=(8, 4.2))
    for name, run in ok.items():
        fam = default_family(k_psf=run.evaluation.k_psf)
        vals = sample(fam.parameters, samples, method=run.evaluation.method, seed=seed).values[:60]
        env = _ratio_envelope(fam, vals, run.controller, freqs)
        if env.size:
            line = ax.semilogx(
                freqs, np.median(env, axis=0), label=f"{name} ({len(env)} stable of 60)"
            )[0]
            ax.fill_between(
                freqs, env.min(axis=0), env.max(axis=0), color=line.get_color(), alpha=0.15
            )
    ax.axhline(0, color="k", lw=0.8)
    ax.set_ylim(-30, 30)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|Y / Y without BDFT| [dB]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    page.figure(
        fig,
        "ratio_envelopes",
        "With/without-BDFT output ratio (the paper's Figure 13 measure): median and "
        "envelope over the stable members among the first 60 sampled, per design.",
    )

    _bound_figure(page, ok)

    force_runs = {
        k: r
        for k, r in ok.items()
        if r.controller is not None and "f" in r.controller.output_labels
    }
    if force_runs:
        fig, axes = plt.subplots(
            len(force_runs), 1, figsize=(8, 2.2 * len(force_runs)), sharex=True, squeeze=False
        )
        for ax, (name, run) in zip(axes[:, 0], force_runs.items()):
            fam = default_family(k_psf=run.evaluation.k_psf)
            nominal = fam.member(fam.nominal_values())
            amp = nominal.intended_amplitude(limits, INTENT_FRACTION)
            hist = force_histories(nominal, run.controller, amplitude=amp, seed=seed)
            t = np.arange(len(hist[1])) / 1000.0 if hist else np.zeros(0)
            if hist:
                ax.plot(t, hist[1], lw=0.7, label="realistic intended motion")
                ax.plot(t, hist[0], lw=0.7, alpha=0.7, label="chirp 0.1-8 Hz")
            ax.axhline(limits.peak_force_n, color="r", ls="--", lw=0.8)
            ax.axhline(-limits.peak_force_n, color="r", ls="--", lw=0.8)
            ax.set_ylabel(f"{name}\nforce [N]", fontsize=8)
            ax.legend(fontsize=7, loc="upper right")
        axes[-1, 0].set_xlabel("time [s]")
        fig.tight_layout()
        page.figure(
            fig,
            "forces",
            "Handle force on the nominal member "
            f"(dashed: the {limits.peak_force_n:g} N peak limit).",
        )


def verdict(runs: dict, tradeoff=None) -> list[str]:
    """The report's verdict: plain sentences generated from the runs.

    Which design (if any) stabilises every sampled member within the force limits,
    what each costs, why the handle-force designs fail if they do, how far the LMI
    designs hold the specification and what more force would buy.

    Parameters
    ----------
    runs : dict
        Design name -> :class:`designs.DesignResult` (evaluated) or the exception it raised.
    tradeoff : list of designs.robust_lmi.TradeoffPoint, optional
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
    tradeoff : list of designs.robust_lmi.TradeoffPoint, optional
        The force-budget sweep (:func:`designs.robust_lmi.force_tradeoff`), drawn as a
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
