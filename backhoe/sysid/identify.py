"""From measured records to a fitted model: the path ``bdft identify`` runs.

Data -> checks -> Welch H1 and coherence (:mod:`.spectral`) -> structured fit
(:mod:`.fit`). Nothing here writes files; the CLI saves plots, tables and models.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from backhoe.sysid.fit import FitResult, fit_frequency_response
from robust.errors import DataError
from robust.sysid.datafile import load_channels, select_channels
from robust.sysid.spectral import (
    FrequencyResponseEstimate,
    as_records,
    check_band,
    estimate_frequency_response,
)

__all__ = ["MIN_PERIODS", "Identification", "identify_file", "identify_records"]

#: A record must hold at least this many periods of the band's lowest frequency.
MIN_PERIODS = 2.0
#: A record whose peak-to-peak spread is at most this fraction of its largest magnitude
#: is constant: it carries no power at any frequency above DC.
_CONSTANT_RTOL = 1e-12


def _check_not_constant(records, role: str, name: str) -> None:
    """Name a dead (constant, zero-power) channel instead of letting the fit blame coherence."""
    recs = as_records(role, records)
    dead = []
    for k, r in enumerate(recs):
        scale = float(np.max(np.abs(r))) if r.size else 0.0
        if r.size == 0 or float(np.ptp(r)) <= _CONSTANT_RTOL * scale:
            dead.append(k)
    if not dead:
        return
    value = float(recs[dead[0]][0]) if recs[dead[0]].size else 0.0
    which = "every record" if len(dead) == len(recs) else f"record(s) {dead} of {len(recs)}"
    expected = (
        "an excitation (a chirp) with power across the band"
        if role == "input"
        else "a measured response that varies"
    )
    raise DataError(
        f"{role} channel {name!r} is dead: constant, with zero power, in {which} "
        f"(record {dead[0]} holds {value:g} throughout); expected {expected}. "
        "Check the channel name, the sensor and its cable"
    )


@dataclasses.dataclass(frozen=True)
class Identification:
    """H1 estimate and fit of one input/output pair.

    Attributes
    ----------
    estimate : FrequencyResponseEstimate
    fit : FitResult
    input_name, output_name : str
        Channel names.
    fs : float
        Sampling rate in Hz.
    seed : int or None
        Seed of simulated data, if the data file states one.
    source : str
        Data file (empty for in-memory records).
    """

    estimate: FrequencyResponseEstimate
    fit: FitResult
    input_name: str
    output_name: str
    fs: float
    seed: int | None = None
    source: str = ""

    def to_dict(self) -> dict:
        """JSON-ready summary: the fit plus data provenance and spectral settings."""
        est = self.estimate
        return {
            **self.fit.to_dict(),
            "input": self.input_name,
            "output": self.output_name,
            "fs": self.fs,
            "seed": self.seed,
            "source": self.source,
            "spectral": {
                "n_records": est.n_records,
                "n_segments": est.n_segments,
                "n_effective": est.n_effective,
                "nperseg": est.nperseg,
                "noverlap": est.noverlap,
                "window": est.window,
                "detrend": est.detrend,
                "resolution_hz": est.fs / est.nperseg,
            },
        }


def identify_records(
    u,
    y,
    fs: float,
    form: str,
    band_hz: tuple[float, float],
    *,
    nperseg: int | None = None,
    window: str | None = None,
    detrend: str = "constant",
    weighting: str = "coherence",
    min_coherence: float = 0.0,
    significance: float | None = 0.05,
    input_name: str = "u",
    output_name: str = "y",
    seed: int | None = None,
    source: str = "",
) -> Identification:
    """Estimate H1 and coherence from records and fit ``form`` over ``band_hz``.

    Parameters
    ----------
    u, y : array_like
        Input and output records (see :func:`~robust.sysid.spectral.estimate_frequency_response`).
    fs : float
        Sampling rate in Hz.
    form : str
        ``"valve"``, ``"structure"``, ``"human"`` or ``"M/N"``.
    band_hz : (float, float)
        Fit band in Hz.
    nperseg : int, optional
        Segment length in samples (option of
        :func:`~robust.sysid.spectral.estimate_frequency_response`).
    window : str, optional
        Window name (option of :func:`~robust.sysid.spectral.estimate_frequency_response`).
    detrend : str
        Detrending (option of :func:`~robust.sysid.spectral.estimate_frequency_response`).
    weighting : str
        Fit weighting (option of :func:`~backhoe.sysid.fit.fit_frequency_response`).
    min_coherence : float
        Coherence below which frequencies are dropped (option of
        :func:`~backhoe.sysid.fit.fit_frequency_response`).
    significance : float or None
        Significance of the zero-coherence test (option of
        :func:`~backhoe.sysid.fit.fit_frequency_response`).
    input_name, output_name : str
        Channel names, kept in the result.
    seed : int or None
        Seed of simulated data, kept in the result.
    source : str
        Data file, kept in the result.

    Returns
    -------
    Identification

    Raises
    ------
    DataError
        Bad records (see the estimator), a constant (zero-power) input or output
        record (the message names the channel and the records), or a band outside
        the data.
    InfeasibleError, SolverError
        If the fit cannot be made.
    """
    check_band(band_hz)
    _check_not_constant(u, "input", input_name)
    _check_not_constant(y, "output", output_name)
    est = estimate_frequency_response(u, y, fs, nperseg=nperseg, window=window, detrend=detrend)
    fit = fit_frequency_response(
        est,
        form,
        band_hz,
        weighting=weighting,
        min_coherence=min_coherence,
        significance=significance,
    )
    return Identification(est, fit, input_name, output_name, float(fs), seed, source)


def identify_file(
    path: str | os.PathLike,
    input_name: str,
    output_name: str,
    fs: float,
    form: str,
    band_hz: tuple[float, float],
    **options,
) -> Identification:
    """:func:`identify_records` on two channels of a CSV or ``.mat`` file.

    Records shorter than :data:`MIN_PERIODS` periods of the band's lower edge are
    rejected with :class:`~robust.errors.DataError`.

    Parameters
    ----------
    path : str or path-like
        CSV or ``.mat`` file (see :mod:`robust.sysid.datafile`).
    input_name, output_name : str
        Channel names.
    fs : float
        Sampling rate in Hz (checked against the file's time column and stated rate).
    form : str
        Model form.
    band_hz : (float, float)
        Fit band in Hz.
    **options
        Passed to :func:`identify_records`.

    Returns
    -------
    Identification
    """
    lo, _ = check_band(band_hz)
    data = load_channels(path)
    u, y = select_channels(data, input_name, output_name, fs, min_duration_s=MIN_PERIODS / lo)
    return identify_records(
        u,
        y,
        fs,
        form,
        band_hz,
        input_name=input_name,
        output_name=output_name,
        seed=data.seed,
        source=str(path),
        **options,
    )
