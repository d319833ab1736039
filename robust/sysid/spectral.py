"""Welch-averaged spectra, the H1 frequency response and coherence, with confidence bounds.

The paper's Eqn 1 and Eqn 2 in one-sided auto- and cross-spectra ``G``:

* H1 estimate:           ``H1(f) = G_uy(f) / G_uu(f)``;
* magnitude-squared coherence: ``gamma^2(f) = |G_uy(f)|^2 / (G_uu(f) G_yy(f))``.

Spectra are those of :func:`scipy.signal.csd` and :func:`scipy.signal.welch`
(windowed, optionally detrended, overlapping segments), averaged over segments
and over records, formed from each signal's segment transforms
(:class:`scipy.signal.ShortTimeFFT`) computed once, so that one input and several
outputs (:func:`estimate_frequency_responses`) transform the input once.
``scipy.signal.csd(u, y)`` computes ``conj(U) Y``, the convention under which
``G_uy / G_uu`` is the response from ``u`` to ``y``.

H1 is unbiased for noise on the output only. Noise on the measured input (the
paper's seat accelerometer on a running tractor) biases it low by the factor
``G_uu,true / (G_uu,true + G_nn,input)``, most where the input is weak; the
coherence falls there too, which is how the fits notice.

Random errors and confidence bounds follow

    J. S. Bendat and A. G. Piersol, *Random Data: Analysis and Measurement
    Procedures*, 4th ed., Wiley, 2010, Ch. 9 (statistical errors of frequency
    response and coherence estimates, single input/output).

With ``n_d`` independent averages, the estimate's error disc in the complex plane
at confidence ``1 - alpha`` has radius ``r`` with

    r^2 = F(2, 2 n_d - 2; 1 - alpha) * (1 - gamma^2) / ((n_d - 1) gamma^2) * |H1|^2,

(the F-distribution interval of Bendat & Piersol, written with ``n = 2 n_d``
real degrees of freedom), so ``|H1| +- r`` bounds the magnitude and
``+- arcsin(r / |H1|)`` the phase. The normalised random error of the coherence
estimate is ``sqrt(2) (1 - gamma^2) / (|gamma| sqrt(n_d))`` and its bias is about
``(1 - gamma^2)^2 / n_d``. Overlapping segments are not independent: ``n_d`` is the
effective number of averages of Welch (1967),
``K / (1 + 2 sum_j (1 - j/K) rho_j^2)`` per record, with ``rho_j`` the
correlation of the window with itself shifted by ``j`` hops.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence

import numpy as np
import scipy.signal as sps
import scipy.stats

from robust.checks import POSITIVE, Spec, check_scalar
from robust.errors import DataError, ParameterError

__all__ = [
    "FrequencyResponseEstimate",
    "default_nperseg",
    "effective_averages",
    "estimate_frequency_response",
    "estimate_frequency_responses",
]

_DETRENDS = {"none": False, "constant": "constant", "linear": "linear"}


@dataclasses.dataclass(frozen=True)
class FrequencyResponseEstimate:
    """Averaged spectra and the H1 estimate at the Welch frequencies.

    Attributes
    ----------
    f_hz : numpy.ndarray, shape (n_f,)
        Frequencies in Hz (``0 .. fs/2`` in steps of ``fs / nperseg``).
    h1 : numpy.ndarray of complex, shape (n_f,)
        H1 estimate ``G_uy / G_uu`` (output units per input unit).
    coherence : numpy.ndarray, shape (n_f,)
        Magnitude-squared coherence in [0, 1].
    g_uu, g_yy : numpy.ndarray, shape (n_f,)
        One-sided auto-spectral densities (units^2 / Hz).
    g_uy : numpy.ndarray of complex, shape (n_f,)
        One-sided cross-spectral density.
    fs : float
        Sampling rate in Hz.
    nperseg, noverlap : int
        Segment length and overlap in samples.
    window : str
        Window name (``scipy.signal.get_window``), e.g. ``"boxcar"`` or ``"hann"``.
    detrend : str
        ``"none"``, ``"constant"`` or ``"linear"`` (applied to each segment).
    n_segments : int
        Number of segments averaged (over all records).
    n_effective : float
        Effective number of independent averages ``n_d`` (see the module notes).
    n_records : int
        Number of records.
    """

    f_hz: np.ndarray
    h1: np.ndarray
    coherence: np.ndarray
    g_uu: np.ndarray
    g_yy: np.ndarray
    g_uy: np.ndarray
    fs: float
    nperseg: int
    noverlap: int
    window: str
    detrend: str
    n_segments: int
    n_effective: float
    n_records: int

    @property
    def magnitude_db(self) -> np.ndarray:
        """``20 log10 |H1|`` in dB, shape (n_f,)."""
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(np.abs(self.h1))

    @property
    def phase_deg(self) -> np.ndarray:
        """Unwrapped phase of H1 in degrees, shape (n_f,).

        Unwrapped from the first nonzero frequency.
        """
        ph = np.angle(self.h1)
        out = ph.copy()
        out[1:] = np.unwrap(ph[1:])
        return np.degrees(out)

    def error_radius(self, confidence: float = 0.95) -> np.ndarray:
        """Radius ``r`` of the confidence disc around H1 (Bendat & Piersol, Ch. 9), shape (n_f,)."""
        conf = check_scalar("confidence", confidence, _UNIT_OPEN)
        nd = self.n_effective
        if nd <= 1.0:
            return np.full_like(self.f_hz, np.inf)
        fq = scipy.stats.f.ppf(conf, 2.0, 2.0 * nd - 2.0)
        g2 = np.clip(self.coherence, 1e-300, 1.0)
        return np.abs(self.h1) * np.sqrt(fq * (1.0 - g2) / ((nd - 1.0) * g2))

    def magnitude_bounds(self, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper confidence bounds of ``|H1|`` (linear units), each shape (n_f,)."""
        r = self.error_radius(confidence)
        mag = np.abs(self.h1)
        return np.maximum(mag - r, 0.0), mag + r

    def phase_bounds(self, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper confidence bounds of the (unwrapped) phase in degrees."""
        r = self.error_radius(confidence)
        mag = np.abs(self.h1)
        with np.errstate(divide="ignore", invalid="ignore"):
            half = np.where(r < mag, np.degrees(np.arcsin(np.clip(r / mag, 0.0, 1.0))), 180.0)
        ph = self.phase_deg
        return ph - half, ph + half

    def coherence_random_error(self) -> np.ndarray:
        """Normalised random error of the coherence estimate, ``sqrt(2)(1-g^2)/(|g| sqrt(n_d))``."""
        g2 = np.clip(self.coherence, 1e-300, 1.0)
        return (
            math.sqrt(2.0) * (1.0 - g2) / (np.sqrt(g2) * math.sqrt(max(self.n_effective, 1e-300)))
        )

    def band_mask(self, band_hz: tuple[float, float]) -> np.ndarray:
        """Boolean mask of the frequencies in ``[lo, hi]`` Hz, checking the band lies in the data.

        Raises
        ------
        DataError
            If the band is inverted, reaches DC, or extends beyond the Nyquist
            frequency or holds fewer than 3 frequencies.
        """
        lo, hi = check_band(band_hz)
        df = self.fs / self.nperseg
        nyq = self.fs / 2.0
        if hi > nyq:
            raise DataError(
                f"band upper edge {hi:g} Hz lies beyond the Nyquist frequency fs/2 = {nyq:g} Hz"
            )
        if lo < df:
            raise DataError(
                f"band lower edge {lo:g} Hz lies below the frequency resolution "
                f"fs/nperseg = {df:g} Hz; use longer segments (nperseg) or raise the band's "
                "lower edge"
            )
        mask = (self.f_hz >= lo) & (self.f_hz <= hi)
        if np.count_nonzero(mask) < 3:
            raise DataError(
                f"band [{lo:g}, {hi:g}] Hz holds {np.count_nonzero(mask)} frequencies at "
                f"resolution {df:g} Hz; need at least 3. Widen the band or use longer segments"
            )
        return mask

    def table(self, confidence: float = 0.95) -> dict[str, np.ndarray]:
        """Columns for a CSV table: frequency, H1 (re, im, dB, deg), bounds and coherence."""
        mlo, mhi = self.magnitude_bounds(confidence)
        plo, phi = self.phase_bounds(confidence)
        with np.errstate(divide="ignore"):
            return {
                "f_hz": self.f_hz,
                "h1_re": self.h1.real,
                "h1_im": self.h1.imag,
                "mag_db": self.magnitude_db,
                "phase_deg": self.phase_deg,
                "coherence": self.coherence,
                f"mag_lo_db_{round(confidence * 100)}": 20.0 * np.log10(mlo),
                f"mag_hi_db_{round(confidence * 100)}": 20.0 * np.log10(mhi),
                f"phase_lo_deg_{round(confidence * 100)}": plo,
                f"phase_hi_deg_{round(confidence * 100)}": phi,
                "g_uu": self.g_uu,
                "g_yy": self.g_yy,
            }


_UNIT_OPEN = Spec(low=0.0, high=1.0, low_open=True, high_open=True)


def check_band(band_hz) -> tuple[float, float]:
    """Return ``(lo, hi)`` in Hz as floats, checking ``0 < lo < hi``.

    Parameters
    ----------
    band_hz : (float, float)
        Band edges in Hz.

    Raises
    ------
    ParameterError
        A non-finite or non-positive edge.
    DataError
        Not a pair, or ``lo >= hi``.
    """
    try:
        lo, hi = band_hz
    except (TypeError, ValueError):
        raise DataError(f"band must be a pair (lo, hi) in Hz; got {band_hz!r}") from None
    lo = check_scalar("band lower edge (Hz)", lo, POSITIVE)
    hi = check_scalar("band upper edge (Hz)", hi, POSITIVE)
    if not lo < hi:
        raise DataError(f"band must satisfy lo < hi; got lo={lo:g} Hz, hi={hi:g} Hz")
    return lo, hi


def effective_averages(window: np.ndarray, nperseg: int, noverlap: int, n_segments: int) -> float:
    """Welch's effective number of independent averages for ``n_segments`` overlapping segments.

    ``K / (1 + 2 sum_{j=1}^{K-1} (1 - j/K) rho_j^2)`` with
    ``rho_j = sum_n w[n] w[n + j*hop] / sum_n w[n]^2`` (P. D. Welch, "The use of the
    fast Fourier transform for the estimation of power spectra", IEEE Trans.
    Audio Electroacoustics 15(2), 1967, pp. 70-73).

    Parameters
    ----------
    window : array_like, shape (nperseg,)
        Window samples.
    nperseg, noverlap : int
        Segment length and overlap in samples.
    n_segments : int
        Number of segments ``K`` in one record.

    Returns
    -------
    float
        Effective number of independent averages, ``<= K``.
    """
    k = int(n_segments)
    if k <= 1:
        return float(k)
    w = np.asarray(window, dtype=float)
    hop = nperseg - noverlap
    e = float(np.dot(w, w))
    acc = 0.0
    for j in range(1, k):
        shift = j * hop
        if shift >= nperseg:
            break
        rho = float(np.dot(w[: nperseg - shift], w[shift:])) / e
        acc += (1.0 - j / k) * rho * rho
    return k / (1.0 + 2.0 * acc)


def default_nperseg(record_lengths: Sequence[int]) -> int:
    """Default segment length: the shortest record, so one segment holds one whole chirp.

    A chirp sweeps its band once per record; a segment cut from it sees only part
    of the sweep and the response's ring-in and ring-out leak into the estimate.
    Averaging is then over records (the paper's 20-50). With a single record, a
    quarter of it (at least 256 samples) so that Welch still averages 7 segments.

    Parameters
    ----------
    record_lengths : sequence of int
        Samples in each record.
    """
    lengths = [int(n) for n in record_lengths]
    shortest = min(lengths)
    if len(lengths) >= 2:
        return shortest
    return int(min(shortest, max(256, shortest // 4)))


def as_records(name: str, x) -> list[np.ndarray]:
    """A signal's records as a list of 1-D float arrays.

    Parameters
    ----------
    name : str
        The signal's name, for error messages.
    x : array_like or sequence of array_like
        One record (1-D), records x samples (2-D), or a sequence of records of any lengths.

    Raises
    ------
    DataError
        If ``x`` is not one of those shapes.
    """
    if (
        isinstance(x, np.ndarray)
        or not isinstance(x, Sequence)
        or (len(x) > 0 and np.isscalar(x[0]))
    ):
        arr = np.asarray(x, dtype=float)
        if arr.ndim == 1:
            rows = [arr]
        elif arr.ndim == 2:
            rows = list(arr)
        else:
            raise DataError(
                f"{name} must be 1-D (one record) or 2-D (records x samples); got shape {arr.shape}"
            )
    else:
        rows = [np.asarray(r, dtype=float) for r in x]
    for i, r in enumerate(rows):
        if r.ndim != 1:
            raise DataError(f"{name} record {i} must be 1-D; got shape {r.shape}")
        if not np.all(np.isfinite(r)):
            n_bad = int(r.size - np.count_nonzero(np.isfinite(r)))
            raise DataError(f"{name} record {i} contains {n_bad} non-finite value(s) (NaN or inf)")
    if not rows:
        raise DataError(f"{name} holds no records")
    return rows


def estimate_frequency_response(
    u,
    y,
    fs: float,
    *,
    nperseg: int | None = None,
    noverlap: int | None = None,
    window: str | None = None,
    detrend: str = "constant",
) -> FrequencyResponseEstimate:
    """H1 and coherence from records of input ``u`` and output ``y`` (paper's Eqns 1-2).

    Parameters
    ----------
    u, y : array_like, shape (n_samples,) or (n_records, n_samples), or lists of 1-D records
        Measured input and output, sampled at ``fs``; records may differ in length
        but each input record must match its output record.
    fs : float
        Sampling rate in Hz.
    nperseg : int, optional
        Segment length in samples; default :func:`default_nperseg` (one segment
        per record when there are several records).
    noverlap : int, optional
        Overlap in samples; default ``nperseg // 2`` (0 when segments are whole records).
    window : str, optional
        Window name for :func:`scipy.signal.get_window`. Default: ``"boxcar"``
        (no taper) when each segment is a whole record, else ``"hann"``. A chirp
        record that starts at rest and ends with the response rung down satisfies
        ``Y = G U`` exactly on its DFT grid, so a taper would only bias H1 (it
        weights the sweep's start and end, where a slowly decaying response is
        still building up); a segment cut from a record needs the taper.
    detrend : str
        ``"none"``, ``"constant"`` (default) or ``"linear"``, applied to each segment;
        ``"linear"`` suits outputs drifting through free integrators.

    Returns
    -------
    FrequencyResponseEstimate

    Raises
    ------
    DataError
        NaN/inf, mismatched input/output lengths, a record shorter than a segment,
        or fewer than 2 segments in all (coherence of one average is always 1).
    ParameterError
        Bad ``fs``, ``nperseg``, ``noverlap``, ``window`` or ``detrend``.
    """
    return estimate_frequency_responses(
        u, [y], fs, nperseg=nperseg, noverlap=noverlap, window=window, detrend=detrend
    )[0]


def estimate_frequency_responses(
    u,
    outputs: Sequence,
    fs: float,
    *,
    nperseg: int | None = None,
    noverlap: int | None = None,
    window: str | None = None,
    detrend: str = "constant",
) -> list[FrequencyResponseEstimate]:
    """:func:`estimate_frequency_response` from one input to several outputs, at once.

    Each signal's segments are transformed once (:class:`scipy.signal.ShortTimeFFT`, as
    :func:`scipy.signal.csd` and :func:`scipy.signal.welch` transform them) and every
    auto- and cross-spectrum is formed from those transforms, in the operations and
    order those functions use, so each estimate equals the one-output call's.

    Parameters
    ----------
    u : array_like
        Measured input (records as in :func:`estimate_frequency_response`).
    outputs : sequence of array_like
        Measured outputs, each with records matching ``u``'s.
    fs : float
        Sampling rate in Hz.
    nperseg, noverlap, window, detrend
        As in :func:`estimate_frequency_response`.

    Returns
    -------
    list of FrequencyResponseEstimate
        One per output, in order.

    Raises
    ------
    DataError, ParameterError
        As :func:`estimate_frequency_response`, for any output.
    """
    fs = check_scalar("fs", fs, POSITIVE)
    us = as_records("input", u)
    if isinstance(outputs, (str, bytes)) or not isinstance(outputs, Sequence) or not outputs:
        raise ParameterError("outputs must be a non-empty sequence of output records")
    yss = [as_records("output", y) for y in outputs]
    for ys in yss:
        if len(us) != len(ys):
            raise DataError(
                f"input has {len(us)} record(s) but output has {len(ys)}; they must match"
            )
        for i, (a, b) in enumerate(zip(us, ys)):
            if a.size != b.size:
                raise DataError(
                    f"record {i}: input has {a.size} samples but output has {b.size}; "
                    "channels must be sampled together"
                )
    if detrend not in _DETRENDS:
        raise ParameterError(f"detrend must be one of {sorted(_DETRENDS)}; got {detrend!r}")
    shortest = min(r.size for r in us)
    if nperseg is None:
        nperseg = default_nperseg([r.size for r in us])
    if isinstance(nperseg, bool) or not isinstance(nperseg, (int, np.integer)) or nperseg < 8:
        raise ParameterError(f"nperseg must be an integer >= 8; got {nperseg!r}")
    nperseg = int(nperseg)
    if shortest < nperseg:
        raise DataError(
            f"records too short: the shortest has {shortest} samples ({shortest / fs:g} s) "
            f"but a segment needs nperseg={nperseg} ({nperseg / fs:g} s); "
            "use shorter segments or longer records"
        )
    if noverlap is None:
        noverlap = 0 if all(r.size == nperseg for r in us) else nperseg // 2
    if (
        isinstance(noverlap, bool)
        or not isinstance(noverlap, (int, np.integer))
        or not 0 <= noverlap < nperseg
    ):
        raise ParameterError(
            f"noverlap must be an integer in [0, {nperseg}); got {noverlap=}, {nperseg=}"
        )
    if window is None:
        window = "boxcar" if all(r.size == nperseg for r in us) else "hann"
    noverlap = int(noverlap)
    hop = nperseg - noverlap
    try:
        hash(window)
    except TypeError:  # not a window scipy knows (an array, a list): scipy's own message
        make = _short_time_fft.__wrapped__
    else:
        make = _short_time_fft
    try:
        win, sft = make(window, nperseg, hop, fs)
    except (ValueError, TypeError) as exc:
        raise ParameterError(f"window {window!r} is not a scipy.signal window: {exc}") from None
    detr = None if _DETRENDS[detrend] is False else _DETRENDS[detrend]
    n_out = len(yss)
    acc_uu = 0.0
    acc_yy = [0.0] * n_out
    acc_uy = [0.0j] * n_out
    n_seg_total = 0
    n_eff = 0.0
    for r, a in enumerate(us):
        k = 1 + (a.size - nperseg) // hop

        S = _transforms(sft, [a, *(ys[r] for ys in yss)], detr, noverlap, hop, nperseg)
        Su = S[0]
        acc_uu = acc_uu + k * _averaged(Su.real**2 + Su.imag**2, nperseg).real
        for j in range(n_out):
            Sy = S[1 + j]
            acc_yy[j] = acc_yy[j] + k * _averaged(Sy.real**2 + Sy.imag**2, nperseg).real
            # csd(u, y) is conj(U) Y, formed as scipy does: Y conj(U)
            acc_uy[j] = acc_uy[j] + k * _averaged(Sy * Su.conj(), nperseg)
        n_seg_total += k
        n_eff += effective_averages(win, nperseg, noverlap, k)
    if n_seg_total < 2:
        raise DataError(
            f"only {n_seg_total} segment (nperseg={nperseg}, {len(us)} record(s)): "
            "coherence and confidence bounds need at least 2 averages; "
            "give more records or a shorter nperseg"
        )
    f = sft.f
    g_uu = acc_uu / n_seg_total
    out = []
    for j in range(n_out):
        g_yy = acc_yy[j] / n_seg_total
        g_uy = acc_uy[j] / n_seg_total
        with np.errstate(divide="ignore", invalid="ignore"):
            h1 = np.where(g_uu > 0, g_uy / g_uu, np.nan + 0j)
            coh = np.where((g_uu > 0) & (g_yy > 0), np.abs(g_uy) ** 2 / (g_uu * g_yy), 0.0)
        coh = np.clip(coh, 0.0, 1.0)
        arrays = [f.copy(), h1, coh, g_uu.copy(), g_yy, g_uy]
        for arr in arrays:
            arr.setflags(write=False)
        out.append(
            FrequencyResponseEstimate(
                f_hz=arrays[0],
                h1=h1,
                coherence=coh,
                g_uu=arrays[3],
                g_yy=g_yy,
                g_uy=g_uy,
                fs=fs,
                nperseg=nperseg,
                noverlap=noverlap,
                window=str(window),
                detrend=detrend,
                n_segments=n_seg_total,
                n_effective=float(n_eff),
                n_records=len(us),
            )
        )
    return out


@functools.lru_cache(maxsize=16)
def _short_time_fft(window, nperseg: int, hop: int, fs: float):
    """The window and the PSD-scaled :class:`scipy.signal.ShortTimeFFT` of one setting.

    Kept for the next call with the same setting (a calibration run estimates thousands of
    records alike): building it (the scaling's sum over the window is a Python loop in
    scipy) took a sixth of the estimate of a minute's record at 1 kHz. The window is read-only, and
    the transform is only read (its own caches aside).
    """
    win = sps.get_window(window, nperseg)
    win.setflags(write=False)
    sft = sps.ShortTimeFFT(
        win, hop, fs, fft_mode="onesided", mfft=nperseg, scale_to="psd", phase_shift=None
    )
    return win, sft


def _transforms(sft, signals: list, detr, noverlap: int, hop: int, nperseg: int) -> np.ndarray:
    """The segment transforms of signals of one length, shape ``(signals, f, segments)``.

    Without detrending or with the constant one, all signals go through one transform as the
    rows of an array: scipy's loop over the segments runs once, not once per signal, and
    each row gets the numbers its own transform would (the mean and the FFT of a row are
    those of the row alone; tested). The linear detrend fits the rows together (another
    rounding), so there each signal is transformed alone.
    """
    k = (signals[0].size - noverlap) // hop

    def transform(x):
        return sft.stft_detrend(x, detr, 0, k, k_offset=nperseg // 2, axis=-1)

    if detr in (None, "constant"):
        return transform(np.stack(signals))
    return np.stack([transform(x) for x in signals])


def _averaged(P: np.ndarray, nfft: int) -> np.ndarray:
    """A segment spectrogram (frequencies x segments) made one-sided and averaged over the
    segments, as :func:`scipy.signal.csd` does (complex result)."""
    P = np.moveaxis(P, -2, -1)
    P[..., 1 : -1 if nfft % 2 == 0 else None] *= 2
    P = np.moveaxis(P, -1, -2)
    P = P.mean(axis=-1) if P.shape[-1] > 1 else np.reshape(P, P.shape[:-1])
    return P.astype(np.complex128)
