"""Figures of identification results, like the paper's Figures 6, 7 and 9.

Library code returns :class:`matplotlib.figure.Figure` objects and never saves
or shows them; the CLI saves them.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from backhoe.sysid.fit import FitResult
from robust.checks import Spec, check_scalar
from robust.errors import ParameterError
from robust.sysid.spectral import FrequencyResponseEstimate, check_band

__all__ = ["bode_figure", "coherence_figure"]


def _check_plot_args(where: str, estimate, band_hz, f_range_hz) -> None:
    if not isinstance(estimate, FrequencyResponseEstimate):
        raise ParameterError(
            f"{where}: estimate must be a FrequencyResponseEstimate; got {type(estimate).__name__}"
        )
    if band_hz is not None:
        check_band(band_hz)
    if f_range_hz is not None:
        check_band(f_range_hz)


def _plot_mask(est: FrequencyResponseEstimate, f_range):
    f = est.f_hz
    lo, hi = f_range if f_range is not None else (f[1], est.fs / 2)
    return (f >= lo) & (f <= hi) & (f > 0)


def bode_figure(
    estimate: FrequencyResponseEstimate,
    fit: FitResult | None = None,
    *,
    band_hz: tuple[float, float] | None = None,
    f_range_hz: tuple[float, float] | None = None,
    confidence: float = 0.95,
    title: str = "",
    truth=None,
) -> Figure:
    """Bode plot of the measured H1 (with its confidence band) and the fitted model.

    Parameters
    ----------
    estimate : FrequencyResponseEstimate
    fit : FitResult, optional
        Model to overlay.
    band_hz : (float, float), optional
        Fit band, shaded.
    f_range_hz : (float, float), optional
        Frequency axis limits in Hz (default: first bin to Nyquist).
    confidence : float
        Confidence level of the shaded bounds (Bendat & Piersol, Ch. 9).
    title : str
    truth : control.LTI, optional
        True system (simulated data), drawn dashed.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes: magnitude (dB) and phase (degrees) against frequency (Hz, log).
    """
    _check_plot_args("bode_figure", estimate, band_hz, f_range_hz)
    if fit is not None and not isinstance(fit, FitResult):
        raise ParameterError(
            f"bode_figure: fit must be a FitResult or None; got {type(fit).__name__}"
        )
    m = _plot_mask(estimate, f_range_hz)
    f = estimate.f_hz[m]
    fig = Figure(figsize=(7.5, 6.0), layout="constrained")
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    mag = estimate.magnitude_db[m]
    lo, hi = estimate.magnitude_bounds(confidence)
    plo, phi = estimate.phase_bounds(confidence)
    half = 0.5 * (phi - plo)[m]
    # Reference phase curve: the model's if there is one, else the truth's, else none.
    # Measured phase is drawn within +-180 deg of it, so noise cannot unwrap into turns.
    ref = None
    h_fit = h_true = None
    if fit is not None:
        h_fit = fit.frequency_response(f)
        ref = np.degrees(np.unwrap(np.angle(h_fit)))
    if truth is not None:
        h_true = np.asarray(truth(2j * np.pi * f)).ravel()
        if ref is None:
            ref = np.degrees(np.unwrap(np.angle(h_true)))
    meas = np.degrees(np.angle(estimate.h1[m]))
    if ref is not None:
        phase = ref + _wrap180(meas - ref)
    else:
        phase = meas
    with np.errstate(divide="ignore"):
        ax_m.fill_between(
            f,
            20 * np.log10(lo[m]),
            20 * np.log10(hi[m]),
            color="0.8",
            label=f"{confidence:.0%} bounds",
        )
    ax_m.semilogx(f, mag, ".", ms=2.5, color="C0", label="measured H1")
    ax_p.fill_between(f, phase - half, phase + half, color="0.8")
    ax_p.semilogx(f, phase, ".", ms=2.5, color="C0")
    lines_db = []
    if h_fit is not None:
        db = 20 * np.log10(np.abs(h_fit))
        lines_db.append(db)
        ax_m.semilogx(f, db, "-", color="C3", lw=1.5, label=f"fit ({fit.form})")
        ax_p.semilogx(f, ref, "-", color="C3", lw=1.5)
    if h_true is not None:
        db = 20 * np.log10(np.abs(h_true))
        lines_db.append(db)
        ph_t = np.degrees(np.unwrap(np.angle(h_true)))
        ph_t = ph_t - 360.0 * np.round(np.median(ph_t - phase) / 360.0)
        ax_m.semilogx(f, db, "--", color="k", lw=1.0, label="true system")
        ax_p.semilogx(f, ph_t, "--", color="k", lw=1.0)
    for ax in (ax_m, ax_p):
        if band_hz is not None:
            ax.axvspan(*band_hz, color="C2", alpha=0.07, lw=0)
        ax.grid(True, which="both", alpha=0.3)
    ax_m.set_ylim(*_db_limits(mag, lines_db, f, band_hz))
    ax_m.set_ylabel("magnitude (dB)")
    ax_p.set_ylabel("phase (deg)")
    ax_p.set_xlabel("frequency (Hz)")
    ax_m.legend(loc="best", fontsize=8)
    ax_m.set_title(title or "Frequency response: measured H1 and fitted model")
    return fig


def _wrap180(x):
    return (x + 180.0) % 360.0 - 180.0


def _db_limits(mag, lines_db, f, band_hz):
    """Axis limits: the measured data's 1-99.5 % range, widened to hold the model lines.

    Only the model lines within the band count.
    """
    sel = np.ones_like(f, dtype=bool) if band_hz is None else (f >= band_hz[0]) & (f <= band_hz[1])
    meas = mag[np.isfinite(mag)]
    lo, hi = (np.percentile(meas, 1.0), np.percentile(meas, 99.5)) if meas.size else (-20.0, 20.0)
    for d in lines_db:
        d = d[sel & np.isfinite(d)]
        if d.size:
            lo, hi = min(lo, d.min()), max(hi, d.max())
    return lo - 5.0, hi + 5.0


def coherence_figure(
    estimate: FrequencyResponseEstimate,
    *,
    band_hz: tuple[float, float] | None = None,
    f_range_hz: tuple[float, float] | None = None,
    title: str = "",
    threshold: float | None = None,
) -> Figure:
    """Magnitude-squared coherence against frequency (Hz, log), with the fit band shaded.

    Parameters
    ----------
    estimate : FrequencyResponseEstimate
    band_hz : (float, float), optional
        Fit band, shaded.
    f_range_hz : (float, float), optional
        Frequency axis limits in Hz.
    title : str
    threshold : float, optional
        Coherence below which the fit left frequencies out, drawn dashed.

    Returns
    -------
    matplotlib.figure.Figure
    """
    _check_plot_args("coherence_figure", estimate, band_hz, f_range_hz)
    if threshold is not None:
        check_scalar("coherence_figure: threshold", threshold, Spec(low=0.0, high=1.0))
    m = _plot_mask(estimate, f_range_hz)
    f = estimate.f_hz[m]
    fig = Figure(figsize=(7.5, 3.0), layout="constrained")
    ax = fig.subplots()
    ax.semilogx(f, estimate.coherence[m], ".", ms=2.5, color="C0")
    if band_hz is not None:
        ax.axvspan(*band_hz, color="C2", alpha=0.07, lw=0, label="fit band")
    if threshold is not None:
        ax.axhline(threshold, color="C3", ls="--", lw=1.0, label=f"fit threshold {threshold:.2f}")
    if band_hz is not None or threshold is not None:
        ax.legend(loc="lower left", fontsize=8)
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("coherence")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(title or f"Magnitude-squared coherence ({estimate.n_records} records)")
    return fig
