"""Who the family covers: its operators' arm and trunk dynamics against the published ranges.

:func:`family_coverage` computes, for a physical-human family and a seeded sample of
it, the sampled arm and trunk natural frequencies and damping ratios, the range and
source of every human parameter (a provenance table), and the fraction of members
stable without compensation at the family's workspace and at the doubled workspace
(the paper's remedy). :func:`coverage_figure` draws the members against the published
box (and the labelled stress box); :func:`add_coverage_section` puts both on a page.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle
from matplotlib.ticker import FormatStrFormatter

from backhoe import Family
from backhoe.model.blocks import block_of, field_of
from backhoe.model.literature import published_box, stress_box
from backhoe.model.physical import EQN5_FIT
from reports.html import HtmlPage
from uncertainty import sample, validate_family

__all__ = ["FamilyCoverage", "family_coverage", "coverage_figure", "add_coverage_section"]

_PAIRS = (("arm", "f_arm_hz", "zeta_arm"), ("trunk", "f_trunk_hz", "zeta_trunk"))


@dataclasses.dataclass(frozen=True)
class FamilyCoverage:
    """The family's human dynamics and provenance (see the module notes).

    Parameters
    ----------
    family : str
        Family name.
    posture : str
        Posture of its ranges.
    ranges : str
        ``"published"`` or ``"stress"``.
    samples, seed : int
        Size and seed of the LHS sample drawn.
    members : dict of str to ndarray
        Sampled values of every human parameter (``"f_arm_hz"`` ...), shape (samples,).
    nominal : dict of str to float
        The nominal operator's values.
    provenance : list of dict
        One row per human parameter: name, nominal, low, high, units, distribution, source.
    fraction_stable : dict of str to float
        Fraction of the sample stable without compensation: ``"nominal workspace"`` and
        ``"doubled workspace"``.
    """

    family: str
    posture: str
    ranges: str
    samples: int
    seed: int
    members: dict
    nominal: dict
    provenance: list
    fraction_stable: dict

    def to_json(self) -> dict:
        """The JSON object (member arrays summarised by their min and max)."""
        return {
            "family": self.family,
            "posture": self.posture,
            "ranges": self.ranges,
            "samples": self.samples,
            "seed": self.seed,
            "nominal": self.nominal,
            "sampled_span": {
                k: [float(np.min(v)), float(np.max(v))] for k, v in self.members.items()
            },
            "provenance": self.provenance,
            "fraction_stable_uncompensated": self.fraction_stable,
        }


def family_coverage(family: Family, *, samples: int = 2000, seed: int = 0) -> FamilyCoverage:
    """Sample ``family`` and describe whom it covers.

    Parameters
    ----------
    family : backhoe.Family
        A physical-human family.
    samples : int
        LHS sample size.
    seed : int
        Sampling seed.
    """
    S = sample(family.parameters, samples, method="lhs", seed=seed)
    human = [p for p in family.parameters if block_of(p.name) == "human"]
    members = {field_of(p.name): S.column(p.name) for p in human}
    nominal = {field_of(p.name): p.nominal for p in human}
    provenance = [
        {
            "parameter": p.name,
            "nominal": p.nominal,
            "low": p.low,
            "high": p.high,
            "units": p.units,
            "distribution": p.distribution,
            "source": p.source,
        }
        for p in human
    ]
    fractions = {
        label: validate_family(family.with_workspace_factor(factor), S).fraction_stable
        for label, factor in (("nominal workspace", 1.0), ("doubled workspace", 2.0))
    }
    return FamilyCoverage(
        family=family.name,
        posture=family.posture,
        ranges=family.ranges,
        samples=samples,
        seed=seed,
        members=members,
        nominal=nominal,
        provenance=provenance,
        fraction_stable=fractions,
    )


def coverage_figure(cov: FamilyCoverage) -> Figure:
    """Arm and trunk natural frequency vs damping ratio of the sampled members.

    The published box of the posture is drawn solid, the stress box dashed; the nominal
    operator and the ``eqn5-fit`` variant (outside the box) are marked.

    Parameters
    ----------
    cov : FamilyCoverage
        The coverage to draw.
    """
    fig = Figure(figsize=(10.0, 4.2), constrained_layout=True)
    axes = fig.subplots(1, 2)
    pub, stress = published_box(cov.posture), stress_box(cov.posture)
    e5 = {f: getattr(EQN5_FIT, f) for _, f, z in _PAIRS for f in (f, z)}
    for ax, (label, f, z) in zip(axes, _PAIRS):
        n = min(cov.samples, 1500)
        ax.plot(cov.members[f][:n], cov.members[z][:n], ".", ms=2, alpha=0.4, label="members")
        for box, style, name in ((pub, "-", "published"), (stress, "--", "STRESS variant")):
            rf, rz = box[f], box[z]
            ax.add_patch(
                Rectangle(
                    (rf.low, rz.low),
                    rf.high - rf.low,
                    rz.high - rz.low,
                    fill=False,
                    ls=style,
                    lw=1.2,
                    color="k" if style == "-" else "C3",
                    label=f"{name} range",
                )
            )
        ax.plot(cov.nominal[f], cov.nominal[z], "k*", ms=12, label="nominal operator")
        ax.plot(e5[f], e5[z], "C3x", ms=10, mew=2, label="eqn5-fit variant")
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(FormatStrFormatter("%g"))
        ax.tick_params(axis="x", which="minor", labelsize=7)
        ax.set_xlabel(f"{label} natural frequency [Hz]")
        ax.set_ylabel(f"{label} damping ratio")
        ax.set_title(f"{label} ({'trunk held' if label == 'arm' else cov.posture})")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper right")
    return fig


def add_coverage_section(page: HtmlPage, cov: FamilyCoverage) -> None:
    """Append the coverage section (figure, stability without compensation, provenance).

    Parameters
    ----------
    page : reports.html.HtmlPage
        The page.
    cov : FamilyCoverage
        What to show.
    """
    label = " (STRESS VARIANT: beyond the published ranges)" if cov.ranges == "stress" else ""
    page.h2(f"Who the family covers: {cov.family}{label}")
    page.p(
        f"Human parameters of {cov.samples} members (LHS, seed {cov.seed}) against the "
        f"published ranges for the '{cov.posture}' posture. Without compensation "
        + ", ".join(
            f"{v:.3g} of them are stable at the {k}" for k, v in cov.fraction_stable.items()
        )
        + "."
    )
    page.figure(
        coverage_figure(cov),
        "family_coverage",
        "Arm endpoint (trunk held) and trunk (on the seat) natural frequency and damping ratio "
        "of the sampled members; solid box: published range; dashed: stress variant; star: "
        "nominal operator (the box's member closest to Eqn 5); cross: the unconstrained "
        "eqn5-fit variant.",
    )
    page.table(
        ["parameter", "nominal", "range", "units", "distribution", "source"],
        [
            [
                r["parameter"],
                r["nominal"],
                f"{r['low']:.4g} - {r['high']:.4g}",
                r["units"],
                r["distribution"],
                r["source"],
            ]
            for r in cov.provenance
        ],
    )
