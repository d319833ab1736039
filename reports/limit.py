"""The limit-map page (``bdft limit``): what any compensator could achieve, set by set.

The map is computed by :func:`designs.limit.limit_map`; this page shows the coverage of
each actuator set at each force multiple, the curve of coverage against the device's
force, the members over the two parameters that matter most, the critical members, the
basis check and the conclusions the numbers support.
"""

from __future__ import annotations

import json
import math

import matplotlib.pyplot as plt
import numpy as np
from scipy import stats

from designs.limit import ACTUATOR_SETS, LimitMap
from designs.limit_sets import split_set
from reports.html import HtmlPage, write_report_dir
from robust.jsonio import to_jsonable

__all__ = ["best_set", "important_parameters", "limit_conclusions", "write_limit_report"]


def important_parameters(lm: LimitMap, actuators: str = "force/full", k: int = 2) -> list:
    """The ``k`` parameters whose values rank-correlate most with the required force.

    Spearman's rho between each parameter and the required force multiple (unreachable
    members ranked last) over the Latin hypercube; parameters that do not vary are skipped.

    Parameters
    ----------
    lm : designs.limit.LimitMap
        The map.
    actuators : str
        One of its sets.
    k : int
        How many parameters.

    Returns
    -------
    list of (str, float)
        Name and rho, largest ``|rho|`` first.
    """
    lhs = lm.lhs_index()
    req = lm.required(actuators)[lhs]
    req = np.where(np.isfinite(req), req, np.nanmax(np.where(np.isfinite(req), req, 0)) * 10 + 1)
    out = []
    for j, name in enumerate(lm.names):
        x = lm.values[lhs, j]
        if np.ptp(x) == 0 or np.ptp(req) == 0:
            continue
        rho = stats.spearmanr(x, req).statistic
        out.append((name, float(rho)))
    out.sort(key=lambda t: -abs(t[1]))
    return out[:k]


def best_set(lm: LimitMap, force_scale: float = 1.0) -> str:
    """The set of widest coverage at ``force_scale``; on a tie the one with the fewest
    actuators, then the least information (handle < handle + cab < full).

    Parameters
    ----------
    lm : designs.limit.LimitMap
        The map.
    force_scale : float
        The force multiple.
    """
    order = ("handle", "handle+cab", "full")

    def key(name):
        a, s_ = split_set(name)
        return (lm.coverage(name, force_scale), -len(ACTUATOR_SETS[a]), -order.index(s_))

    return max(lm.sets, key=key)


def limit_conclusions(lm: LimitMap) -> list:
    """Sentences the numbers support: the best set at the Omni's limits, and what reaches 95 %.

    Parameters
    ----------
    lm : designs.limit.LimitMap
        The map.
    """
    lines = []
    best = best_set(lm)
    lines.append(
        f"At the Omni's own force limits the set with the highest limit coverage (the "
        f"smallest such set on a tie) is '{best}' ({100 * lm.coverage(best, 1.0):.1f} % of "
        f"{lm.samples} members)."
    )
    spec = lm.specification
    for a in lm.sets:
        br = lm.bracket_for(a, 0.95)
        s95, low = br["upper"], br["lower"]
        if "f" not in ACTUATOR_SETS[split_set(a)[0]]:
            if math.isfinite(s95):
                verdict = "reaches 95 % coverage without any force"
            elif not math.isfinite(low):
                verdict = (
                    "cannot reach 95 % coverage: on more than 5 % of the members no "
                    "reference correction meets the bounds within its effort limits "
                    "(the relaxation's lower bound exceeds them)"
                )
            else:
                verdict = (
                    "does not reach 95 % coverage with the verified controllers (the "
                    "relaxation does not exclude it)"
                )
            lines.append(f"'{a}' {verdict}.")
            continue
        bracket = f"between {low:.3g} and {s95:.3g} x" if math.isfinite(s95) else f">= {low:.3g} x"
        if not math.isfinite(s95):
            lines.append(
                f"'{a}' does not reach 95 % coverage with the verified controllers at any "
                f"force; no compensator of the set reaches it below {low:.3g} x the Omni's "
                "forces."
            )
        elif s95 < 1e-3:
            lines.append(f"'{a}' reaches 95 % coverage with a negligible force ({s95:.2g} x).")
        elif s95 <= 1.0:
            lines.append(
                f"'{a}' reaches 95 % coverage within the Omni's limits (needs {bracket} its "
                "forces)."
            )
        else:
            lines.append(
                f"'{a}' needs {bracket} the Omni's forces for 95 % coverage: a device with "
                f"{low * spec['continuous_force_n']:.2g}-{s95 * spec['continuous_force_n']:.2g} N "
                f"continuous and {low * spec['peak_force_n']:.2g}-"
                f"{s95 * spec['peak_force_n']:.2g} N peak force."
            )
    return lines


def _pct(x) -> str:
    return "-" if not (isinstance(x, float) and math.isfinite(x)) else f"{100 * x:.3g} %"


def _coverage_curve(lm: LimitMap):
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    lhs = lm.lhs_index()
    grid = np.geomspace(1e-3, 20.0, 400)
    for a in lm.sets:
        req = lm.required(a)[lhs]
        cov = [(req <= g).mean() for g in grid]
        (line,) = ax.plot(grid, 100 * np.asarray(cov), label=a)
        low = lm.lower(a)[lhs]
        if "f" in ACTUATOR_SETS[split_set(a)[0]]:
            ceiling = [(low <= g).mean() for g in grid]
            ax.plot(grid, 100 * np.asarray(ceiling), color=line.get_color(), lw=0.8, ls="-.")
    for s in lm.force_scales:
        ax.axvline(s, color="0.6", lw=0.8, ls="--")
    ax.axhline(95, color="k", lw=0.6, ls=":")
    ax.set_xscale("log")
    ax.set_xlabel("device force, multiple of the Omni's limits (3.3 N peak, 0.88 N continuous)")
    ax.set_ylabel("members covered [%]")
    ax.set_ylim(-2, 102)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _member_map(lm: LimitMap, actuators: str, params):
    (p1, _), (p2, _) = params
    i1, i2 = lm.names.index(p1), lm.names.index(p2)
    lhs = lm.lhs_index()
    req = lm.required(actuators)[lhs]
    x, y = lm.values[lhs, i1], lm.values[lhs, i2]
    fig, ax = plt.subplots(figsize=(7.0, 5.0))
    fin = np.isfinite(req)
    sc = ax.scatter(
        x[fin],
        y[fin],
        c=np.log2(np.maximum(req[fin], 1e-3)),
        cmap="viridis",
        vmin=-2,
        vmax=3,
        s=22,
    )
    if (~fin).any():
        ax.scatter(x[~fin], y[~fin], marker="x", color="tab:red", s=26, label="not reachable")
        ax.legend(fontsize=8)
    cb = fig.colorbar(sc, ax=ax)
    cb.set_label("log2 of the required force multiple (0: the Omni's limits)")
    ax.set_xlabel(p1)
    ax.set_ylabel(p2)
    ax.set_title(f"'{actuators}': required force over the two parameters that matter most")
    fig.tight_layout()
    return fig


def write_limit_report(lm: LimitMap, out_dir, *, basis: dict | None = None):
    """One HTML page for a limit map; ``limit.json`` (the ``--json`` object) beside it.

    Parameters
    ----------
    lm : designs.limit.LimitMap
    out_dir : path-like
        The report folder (replaced atomically).
    basis : dict, optional
        :func:`designs.limit.basis_check` output.

    Returns
    -------
    pathlib.Path
        The page's ``index.html``.
    """
    page = HtmlPage("The achievable-limit map: what any compensator could protect")
    spec = lm.specification
    noise = lm.noise
    page.p(
        f"For each of {lm.samples} members of the default family (Latin hypercube, seed "
        f"{lm.seed}) and each set of actuators and sensors, the compensator that knows that "
        "member exactly and meets the specification's tracking and feedthrough requirements "
        "with the least RMS handle force, every closed-loop pole in the specification's "
        "region by construction (Youla/Q-parametrisation over an orthonormal basis of "
        f"{len(lm.basis_poles)} real-pole lags, {min(lm.basis_poles):g}-"
        f"{max(lm.basis_poles):g} rad/s, and the loop's own poles; Boyd & Barratt 1991). "
        "Sensors: 'full' measures every state of the loop without noise (full information); "
        f"'handle' the handle position through the encoder ({noise['encoder_mm']:g} mm "
        "quantisation, white at 1 kHz); 'handle+cab' adds a cab accelerometer (noise RMS "
        f"{noise['accel_rms']:g} in the paper's units of c at 1 kHz), both through an "
        "observer-based output feedback. Each controller found is closed around its member "
        "and re-checked in numpy: eigenvalues against the region, |Y/Y_ref - 1| against its "
        "bound at every frequency (exact crossings), the exact RMS force with the sensor noise "
        "(Lyapunov) and the peak force of a simulated 20 s realistic intended motion. A member "
        "is covered at a "
        "force multiple when that controller meets the whole specification within that "
        "multiple of the Omni's limits "
        f"({spec['peak_force_n']:g} N peak, {spec['continuous_force_n']:g} N continuous)."
    )
    page.h2("What the map bounds")
    page.p(
        "Coverage here is a lower bound of what compensators of each set, knowing the member, "
        "can cover: every member counted has a verified controller. A member not covered "
        "needs, for controllers of this basis, at least the force multiple (or the relaxation "
        "of tracking and feedthrough) reported; a richer basis can only lower these numbers "
        "(the basis check below measures by how much). A robust design for the whole family, "
        "or a scheduled bank that must identify the operator, knows less than the member "
        "itself: it cannot beat the map of its set, up to the basis' approximation. The "
        "Latin hypercube is not an independent sample: the coverage fractions are fractions "
        "of these members, without a probabilistic certificate (designs carry one).",
        cls="note",
    )
    page.h2("Coverage by actuator set and force")
    rows = []
    for e in lm.sets_json():
        binding = ", ".join(f"{k} {v}" for k, v in sorted(e["binding"].items())) or "-"
        rows.append(
            [
                "+".join(e["actuators"]),
                e["sensors"],
                f"x{e['force_scale']:g}",
                f"{100 * e['coverage']:.1f} %",
                f"{e['covered']} / {e['samples']}",
                f"{100 * e['coverage_own']:.1f} %",
                binding,
                e["proven_uncovered"],
            ]
        )
    page.table(
        [
            "actuators",
            "sensors",
            "force",
            "coverage",
            "members",
            "of which by the set's own problem",
            "binding (uncovered members)",
            "of which no compensator covers",
        ],
        rows,
    )
    page.p(
        "Coverage counts a member when the set's own controller or the controller of a "
        "smaller set it contains (fewer actuators, or sensors that tell less: handle < "
        "handle + cab < full information) is verified within the force multiple; the "
        "column beside it counts the set's own problem alone. The last column counts the "
        "uncovered members whose lower bound (the frequency-wise relaxation: at each "
        "frequency the least effort that meets the deviation's bound, integrated against "
        "the operator's spectrum; designs.relaxation) exceeds the force multiple, or, for a "
        "reference correction alone, its effort limits: no compensator of the set, with any "
        "sensors, covers them. Solver gap (re-checked minus "
        "predicted RMS force, relative, forces above 1 mN): median "
        f"{_pct(lm.to_json()['solver_gap']['median'])}, largest "
        f"{_pct(lm.to_json()['solver_gap']['max'])}.",
        cls="note",
    )
    page.h2("Conclusions")
    for line in limit_conclusions(lm):
        page.p(line)
    page.figure(
        _coverage_curve(lm),
        "coverage_curve",
        "Members covered against the device's force (a multiple of the Omni's peak and "
        "continuous limits together): the curve of each actuator set (verified controllers); "
        "dash-dotted, same colour: the ceiling no compensator of the set can pass (members "
        "whose relaxation bound is below the multiple); dashed: the multiples of the table; "
        "dotted: 95 %.",
    )
    plt.close("all")
    force_sets = [a for a in lm.sets if split_set(a)[0] == "force"]
    if force_sets:
        best = max(force_sets, key=lambda a: lm.coverage(a, 1.0))
        params = important_parameters(lm, best)
        if len(params) == 2:
            page.figure(
                _member_map(lm, best, params),
                "force_map",
                f"Handle force alone ('{best}', the handle-force set of widest coverage): "
                f"each member's required force multiple over the two "
                f"parameters whose values rank-correlate most with it ({params[0][0]}: "
                f"Spearman rho {params[0][1]:+.2f}; {params[1][0]}: {params[1][1]:+.2f}).",
            )
            plt.close("all")
    crit = [i for i, lab in enumerate(lm.labels) if lab != "lhs"]
    if crit:
        page.h2("Critical members")
        rows = []
        for i in crit:
            for lim in lm.limits[i]:
                rows.append(
                    [
                        lm.labels[i],
                        f"{lim.actuators}/{lim.sensors}",
                        lim.required_force,
                        lim.rms_force_n,
                        lim.peak_force_n,
                        lim.relaxation,
                        lim.binding or "-",
                    ]
                )
        page.table(
            [
                "member",
                "set",
                "required force multiple",
                "RMS force at x1 [N]",
                "peak force at x1 [N]",
                "relaxation (if tracking/feedthrough fail)",
                "binding",
            ],
            rows,
        )
        page.p(
            "The nominal member and the member of the box whose uncompensated loop breaks "
            "the specification's pole region most (the margin search's worst member).",
            cls="note",
        )
    if basis:
        page.h2("Basis check")
        rows = []
        for a, b in basis.items():
            rows.append(
                [
                    a,
                    b["members"],
                    f"{b['poles'][0]} -> {b['poles'][1]}",
                    _pct(b["median_decrease"]),
                    _pct(b["largest_decrease"]),
                ]
            )
        page.table(
            ["set", "members", "basis lags", "median decrease", "largest decrease"],
            rows,
        )
        page.p(
            "The first members of the sample again with a basis of twice as many poles over "
            "the same range: the decrease of their required force multiple says how far the "
            "map's numbers are from the limit of an infinite basis ('-': no member needs a "
            "force above a thousandth of the Omni's).",
            cls="note",
        )
    obj = lm.to_json()
    if basis:
        obj["basis_check"] = basis
    page.attach("limit.json", json.dumps(to_jsonable(obj), indent=2, allow_nan=False))
    return write_report_dir(page, out_dir)
