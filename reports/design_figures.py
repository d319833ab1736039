"""The figures of the design comparison page.

``_figures`` draws, with matplotlib, what :func:`reports.designs.write_design_report`
places on the page: the closed-loop pole clouds of every design over family members, the
with/without-BDFT output ratio envelopes, each design's deviation against the
specification's bound, and the handle forces on the nominal member. Apart from the page's
text sections (:mod:`reports.design_sections`).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from backhoe import batched_poles, default_family
from backhoe.analysis.loops import loop_poles
from backhoe.model.device import DeviceLimits
from designs.evaluate import INTENT_FRACTION, force_histories, output_ratio
from designs.spec import Specification
from reports.html import HtmlPage
from uncertainty import sample

#: Nothing public: :mod:`reports.designs`'s own.
__all__: list[str] = []


def _ratio_envelope(family, values, controller, freqs):
    curves = []
    for row in values:
        m = family.member(row)
        if loop_poles(m, controller=controller).stable:
            curves.append(20 * np.log10(np.abs(output_ratio(m, controller, freqs))))
    return np.array(curves)


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
