"""Figures of the reproduction report.

Every function returns a matplotlib ``Figure``; nothing is saved here (the page
builder, :meth:`reports.html.HtmlPage.figure`, saves and closes them).
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg", force=False)
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = [
    "bode_figure",
    "pole_map_figure",
    "time_response_figure",
    "ratio_figure",
    "loop_gain_figure",
]


def bode_figure(
    curves: list[tuple[str, object]],
    freqs_hz: np.ndarray,
    *,
    title: str,
    inp: str,
    out: str,
    phase: bool = True,
    ylabel: str = "magnitude [dB]",
):
    """Bode plot of one channel of several systems.

    Parameters
    ----------
    curves : list of (str, control.LTI)
        ``(legend label, system)`` pairs; each system has the signal names ``inp``
        and ``out``.
    freqs_hz : ndarray
        Frequencies, Hz.
    title : str
        Title of the magnitude plot.
    inp, out : str
        Input and output signal names of the plotted channel.
    phase : bool
        Add the phase plot (unwrapped, deg) below the magnitude.
    ylabel : str
        Label of the magnitude axis (the magnitude is ``20 log10 |G|``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, axes = plt.subplots(
        2 if phase else 1, 1, figsize=(7, 5.2 if phase else 3.4), sharex=True, squeeze=False
    )
    w = 2 * np.pi * freqs_hz
    for label, sys in curves:
        h = np.asarray(sys(1j * w, squeeze=False))[
            sys.output_labels.index(out), sys.input_labels.index(inp), :
        ]
        axes[0, 0].semilogx(freqs_hz, 20 * np.log10(np.abs(h)), label=label)
        if phase:
            axes[1, 0].semilogx(freqs_hz, np.degrees(np.unwrap(np.angle(h))), label=label)
    axes[0, 0].set_ylabel(ylabel)
    axes[0, 0].set_title(title)
    axes[0, 0].grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    if phase:
        axes[1, 0].set_ylabel("phase [deg]")
        axes[1, 0].grid(True, which="both", alpha=0.3)
    axes[-1, 0].set_xlabel("frequency [Hz]")
    fig.tight_layout()
    return fig


def pole_map_figure(
    pole_sets: list[tuple[str, np.ndarray]], *, title: str, xlim=None, ylim_hz=None
):
    """Closed-loop pole map: real part (rad/s) against frequency (Hz) of each pole set.

    Parameters
    ----------
    pole_sets : list of (str, ndarray)
        ``(legend label, complex poles in rad/s)`` pairs; the imaginary part is
        plotted in Hz.
    title : str
        Plot title.
    xlim : (float, float), optional
        Real-axis limits, rad/s (default: matplotlib's).
    ylim_hz : (float, float), optional
        Imaginary-axis limits, Hz (default: matplotlib's).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = plt.subplots(figsize=(7, 4.2))
    markers = "xo+sd^v"
    for i, (label, p) in enumerate(pole_sets):
        p = np.asarray(p)
        ax.plot(
            p.real, p.imag / (2 * np.pi), markers[i % len(markers)], label=label, mfc="none", ms=7
        )
    ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel("real part [rad/s]")
    ax.set_ylabel("imaginary part [Hz]")
    if xlim:
        ax.set_xlim(*xlim)
    if ylim_hz:
        ax.set_ylim(*ylim_hz)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    return fig


def time_response_figure(with_bdft, without_bdft, *, title: str, signal: str = "y"):
    """Cylinder position with and without BDFT against time (the paper's Figures 11-12).

    The top plot is the intended motion ``u`` of ``with_bdft``; the bottom plot
    switches to a symlog scale when the response with BDFT exceeds 20 times the one
    without (an unstable loop).

    Parameters
    ----------
    with_bdft, without_bdft : backhoe.analysis.simulation.TimeResponse
        The same intended motion simulated with and without the feedthrough path.
    title : str
        Title of the top plot.
    signal : str
        Output plotted (default ``"y"``, the cylinder position).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    axes[0].plot(with_bdft.t, with_bdft.u, color="0.4", lw=0.8)
    axes[0].set_ylabel("intended u")
    axes[1].plot(without_bdft.t, without_bdft[signal], label="without BDFT", lw=0.9)
    axes[1].plot(with_bdft.t, with_bdft[signal], label="with BDFT", lw=0.9, alpha=0.85)
    peak = np.max(np.abs(with_bdft[signal]))
    ref = np.max(np.abs(without_bdft[signal]))
    if peak > 20 * ref:
        axes[1].set_yscale("symlog", linthresh=max(ref, 1e-12))
        axes[1].text(
            0.01,
            0.9,
            "symlog scale: response grows without bound",
            transform=axes[1].transAxes,
            fontsize=8,
        )
    axes[1].set_ylabel(f"cylinder {signal}")
    axes[1].set_xlabel("time [s]")
    axes[1].legend(fontsize=8, loc="lower left")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[0].set_title(title)
    fig.tight_layout()
    return fig


def ratio_figure(freqs_hz: np.ndarray, study: dict, *, title: str):
    """|Y_bdft / Y_nobdft| in dB versus frequency for each workspace factor (Figure 13).

    Parameters
    ----------
    freqs_hz : ndarray, shape (F,)
        Frequency grid of the study, Hz.
    study : dict
        Workspace factor to a row with ``ratio_db`` (shape (F,)) and ``stable``, as
        :func:`backhoe.analysis.claims.ratio_study` returns; unstable members are
        dotted.
    title : str
        Plot title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    cmap = plt.get_cmap("viridis")
    facs = sorted(study)
    for i, fac in enumerate(facs):
        row = study[fac]
        style = "-" if row["stable"] else ":"
        ax.semilogx(
            freqs_hz,
            row["ratio_db"],
            style,
            color=cmap(i / max(1, len(facs) - 1)),
            label=f"x{fac} ({71 * fac} mm){'' if row['stable'] else ' unstable'}",
        )
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|Y with / Y without BDFT| [dB]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(title)
    fig.tight_layout()
    return fig


def loop_gain_figure(
    freqs_hz: np.ndarray, curves: list[tuple[str, np.ndarray]], *, title: str, mark_hz=()
):
    """Magnitude of the BDFT loop gain (broken at the handle) for several models.

    Parameters
    ----------
    freqs_hz : ndarray
        Frequencies, Hz.
    curves : list of (str, ndarray)
        ``(legend label, complex loop gain at freqs_hz)`` pairs, e.g. the ``"loop"``
        entry of :func:`backhoe.analysis.loops.bdft_loop_gain`.
    title : str
        Plot title.
    mark_hz : sequence of float
        Frequencies marked by dashed vertical lines, Hz.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    for label, L in curves:
        ax.loglog(freqs_hz, np.abs(L), label=label)
    for f in mark_hz:
        ax.axvline(f, color="0.5", ls="--", lw=0.8)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|BDFT loop gain|")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    return fig
