"""H1, coherence and confidence bounds against their theory (Bendat & Piersol, Ch. 9)."""

import control as ct
import numpy as np
import pytest
import scipy.signal as sps

from backhoe import structure
from backhoe.sysid import ChirpProtocol, simulate_experiment, simulate_response
from robust import DataError, ParameterError
from robust.sysid import (
    effective_averages,
    estimate_frequency_response,
    estimate_frequency_responses,
    spectral,
)

FS = 1000.0


def _first_order(f_c=5.0):
    return ct.ss(ct.tf([1.0], [1.0 / (2 * np.pi * f_c), 1.0]), inputs="u", outputs="y", name="lp")


def _foh_response(system, f_hz, fs=FS):
    """Exact frequency response of the first-order-hold discretisation the simulator uses."""
    sysd = ct.sample_system(ct.ss(system), 1.0 / fs, method="foh")
    return np.asarray(sysd(np.exp(2j * np.pi * f_hz / fs))).ravel()


def test_h1_equals_true_response_on_noise_free_chirps():
    # Records start at rest and end rung down (3 s tail >> 1/(zeta w) = 0.2 s), so each
    # whole record's DFT obeys Y = G U exactly: H1 must equal G on the DFT grid.
    proto = ChirpProtocol(n_records=3, duration=12.0, f0_hz=0.5, f1_hz=40.0, tail_s=3.0)
    exp = simulate_experiment(structure(), proto)
    est = estimate_frequency_response(exp.u, exp.y, exp.fs)
    assert est.window == "boxcar" and est.nperseg == proto.n_samples
    band = est.band_mask((1.0, 30.0))
    g_d = _foh_response(exp.system, est.f_hz[band])
    np.testing.assert_allclose(est.h1[band], g_d, rtol=1e-6)
    # and the continuous Eqn 4 within the hold's (pi f / fs)^2 / 3 < 0.3 % at 30 Hz
    g_c = np.asarray(exp.system(2j * np.pi * est.f_hz[band])).ravel()
    np.testing.assert_allclose(est.h1[band], g_c, rtol=3e-3)
    np.testing.assert_allclose(est.coherence[band], 1.0, atol=1e-9)


def test_welch_leakage_on_noise_free_random_data_shrinks_with_segment_length():
    # Segments cut from a random record carry the response to input before the segment:
    # the H1 error is leakage, and it shrinks as segments grow relative to the 32 ms time constant.
    rng = np.random.default_rng(5)
    proto = ChirpProtocol(n_records=4, duration=32.0)
    u = rng.standard_normal((proto.n_records, proto.n_samples))
    exp = simulate_experiment(_first_order(), proto, excitation=u)
    errors = []
    for nperseg in (500, 2000, 8000):
        est = estimate_frequency_response(exp.u, exp.y, FS, nperseg=nperseg)
        assert est.window == "hann"
        band = est.band_mask((2.0, 50.0))
        g = _foh_response(exp.system, est.f_hz[band])
        errors.append(float(np.median(np.abs(est.h1[band] / g - 1))))
        assert est.coherence[band].min() > 0.95
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 5e-3


def test_coherence_falls_with_noise_as_theory_says():
    # White input (variance 1) and white output noise (variance s^2), both one-sided PSD 2 var / fs:
    # gamma^2 = |G|^2 / (|G|^2 + s^2); E[estimate] ~ gamma^2 + (1 - gamma^2)^2 / n_d (bias).
    # An 8 ms time constant in 2 s segments keeps leakage far below the random error.
    rng = np.random.default_rng(17)
    proto = ChirpProtocol(n_records=8, duration=16.384)
    u = rng.standard_normal((proto.n_records, proto.n_samples))
    lp = _first_order(20.0)
    means = []
    for s in (0.3, 1.0, 3.0):
        exp = simulate_experiment(lp, proto, excitation=u, output_noise=s, seed=int(1000 * s))
        est = estimate_frequency_response(exp.u, exp.y, FS, nperseg=2048, window="hann")
        band = est.band_mask((1.0, 100.0))
        g2 = np.abs(_foh_response(lp, est.f_hz[band])) ** 2
        theory = g2 / (g2 + s * s)
        nd = est.n_effective
        expected = theory + (1 - theory) ** 2 / nd
        # random error of one bin: sqrt(2) (1 - g^2) |g| / sqrt(n_d)
        # (absolute, from the normalised error)
        sd = np.sqrt(2.0) * (1 - theory) * np.sqrt(theory) / np.sqrt(nd)
        z = (est.coherence[band] - expected) / sd
        # neighbouring Hann bins are correlated, so the mean's spread is wider than 1/sqrt(n)
        assert abs(np.mean(z)) < 0.3, f"{s=}: mean z {np.mean(z):.3f}"
        assert 0.6 < np.std(z) < 1.4, f"{s=}: std z {np.std(z):.3f}"
        means.append(float(np.mean(est.coherence[band])))
    assert means[0] > means[1] > means[2]


def test_confidence_disc_covers_truth_at_its_level():
    rng = np.random.default_rng(23)
    proto = ChirpProtocol(n_records=6, duration=16.384)
    u = rng.standard_normal((proto.n_records, proto.n_samples))
    lp = _first_order(5.0)
    exp = simulate_experiment(lp, proto, excitation=u, output_noise=0.5, seed=3)
    est = estimate_frequency_response(exp.u, exp.y, FS, nperseg=1024)
    band = est.band_mask((1.0, 60.0))
    g = _foh_response(lp, est.f_hz[band])
    inside = np.abs(est.h1[band] - g) <= est.error_radius(0.95)[band]
    assert 0.92 <= inside.mean() <= 0.985, inside.mean()
    mlo, mhi = est.magnitude_bounds(0.95)
    assert np.all(mlo <= np.abs(est.h1)) and np.all(np.abs(est.h1) <= mhi)


@pytest.mark.parametrize(
    "window, overlap, k, expected",
    [
        ("boxcar", 0, 10, 10.0),
        ("hann", 0, 10, 10.0),
        # Hann at 50 % overlap: rho_1 = 1/6 (Harris 1978, Table 1: 16.7 %), rho_2 = 0
        ("hann", 512, 1000, 1000 / (1 + 2 * (1 - 1 / 1000) * (1 / 6) ** 2)),
    ],
    ids=["boxcar-no-overlap", "hann-no-overlap", "hann-50pct"],
)
def test_effective_averages(window, overlap, k, expected):
    w = sps.get_window(window, 1024)
    assert effective_averages(w, 1024, overlap, k) == pytest.approx(expected, rel=2e-3)


def test_simulate_response_matches_python_control():
    proto = ChirpProtocol(n_records=1, duration=3.0)
    u = proto.excitation()
    ref = ct.forced_response(structure(), T=proto.time(), U=u).outputs
    np.testing.assert_allclose(
        simulate_response(structure(), u, FS), ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max()
    )


# --- bad data ---------------------------------------------------------------------------------
def _records(n=2, m=4000):
    rng = np.random.default_rng(0)
    return rng.standard_normal((n, m)), rng.standard_normal((n, m))


def test_nan_is_rejected():
    u, y = _records()
    y[1, 17] = np.nan
    with pytest.raises(DataError, match=r"output record 1 contains 1 non-finite"):
        estimate_frequency_response(u, y, FS)


def test_mismatched_lengths_are_rejected():
    u, y = _records()
    with pytest.raises(DataError, match=r"record 0: input has 4000 samples but output has 3999"):
        estimate_frequency_response(list(u), [y[0, :-1], y[1]], FS)


def test_too_short_records_are_rejected():
    u, y = _records(m=100)
    with pytest.raises(DataError, match=r"records too short: the shortest has 100 samples"):
        estimate_frequency_response(u, y, FS, nperseg=256)


def test_one_average_is_rejected():
    u, y = _records(n=1)
    with pytest.raises(DataError, match=r"need at least 2 averages"):
        estimate_frequency_response(u, y, FS, nperseg=4000)


@pytest.mark.parametrize(
    "band, match",
    [
        ((10.0, 600.0), r"beyond the Nyquist frequency fs/2 = 500 Hz"),
        ((0.1, 20.0), r"below the frequency resolution fs/nperseg = 0\.25 Hz"),
        ((20.0, 10.0), r"lo < hi"),
        ((100.0, 100.3), r"holds 2 frequencies"),
    ],
    ids=["above-nyquist", "below-resolution", "inverted", "too-narrow"],
)
def test_band_outside_data(band, match):
    u, y = _records()
    est = estimate_frequency_response(u, y, FS)
    with pytest.raises(DataError, match=match):
        est.band_mask(band)


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"detrend": "quadratic"}, r"detrend must be one of"),
        ({"nperseg": 4}, r"nperseg must be an integer >= 8"),
        ({"nperseg": 256, "noverlap": 256}, r"noverlap=256"),
        ({"window": "nonsense"}, r"window 'nonsense' is not a scipy.signal window"),
        ({"window": ["hann"]}, r"window \['hann'\] .* must be a tuple, a string or a float"),
    ],
    ids=["detrend", "nperseg", "noverlap", "window", "window-list"],
)
def test_bad_options(kw, match):
    u, y = _records()
    with pytest.raises(ParameterError, match=match):
        estimate_frequency_response(u, y, FS, **kw)


@pytest.mark.parametrize("detrend, ok", [("linear", True), ("none", False)], ids=["linear", "none"])
def test_linear_detrend_removes_sensor_drift(detrend, ok):
    # a slowly drifting output sensor (a ramp) leaks through the Hann window into every low bin
    # unless each segment is detrended
    rng = np.random.default_rng(4)
    proto = ChirpProtocol(n_records=4, duration=16.384)
    u = rng.standard_normal((proto.n_records, proto.n_samples))
    exp = simulate_experiment(_first_order(20.0), proto, excitation=u)
    drift = 50.0 * np.arange(proto.n_samples) / FS
    est = estimate_frequency_response(exp.u, exp.y + drift, FS, nperseg=2048, detrend=detrend)
    assert est.detrend == detrend
    band = est.band_mask((2.0, 10.0))
    err = np.median(np.abs(est.h1[band] / _foh_response(exp.system, est.f_hz[band]) - 1))
    assert bool(err < 0.01) is ok, err


@pytest.mark.parametrize(
    "n, nperseg, detrend",
    [
        (60000, 16384, "constant"),
        (5000, 256, "linear"),
        (4097, 255, "constant"),
        (3000, 100, "none"),
    ],
)
def test_several_outputs_equal_scipy_welch_and_csd(n, nperseg, detrend):
    # each signal transformed once; the spectra are scipy's (odd and even segment lengths,
    # every detrend), and each output's estimate is the one-output call's
    rng = np.random.default_rng(n)
    u = rng.standard_normal(n)
    y1 = np.convolve(u, [1.0, 0.5, 0.2], "same") + 0.1 * rng.standard_normal(n)
    y2 = np.cumsum(u) * 0.01 + rng.standard_normal(n)
    win = sps.get_window("hann", nperseg)
    kw = dict(fs=FS, window=win, nperseg=nperseg, noverlap=nperseg // 2)
    kw["detrend"] = False if detrend == "none" else detrend
    e1, e2 = estimate_frequency_responses(u, [y1, y2], FS, nperseg=nperseg, detrend=detrend)
    f, puu = sps.welch(u, **kw)
    np.testing.assert_array_equal(e1.f_hz, f)
    np.testing.assert_allclose(e1.g_uu, puu, rtol=1e-13, atol=0)
    for est, y in ((e1, y1), (e2, y2)):
        np.testing.assert_allclose(est.g_yy, sps.welch(y, **kw)[1], rtol=1e-13, atol=0)
        np.testing.assert_allclose(est.g_uy, sps.csd(u, y, **kw)[1], rtol=1e-13, atol=0)
        one = estimate_frequency_response(u, y, FS, nperseg=nperseg, detrend=detrend)
        for name in ("h1", "coherence", "g_uu", "g_yy", "g_uy"):
            np.testing.assert_array_equal(getattr(est, name), getattr(one, name))
        assert est.n_effective == one.n_effective and est.n_segments == one.n_segments


def test_several_outputs_need_matching_records():
    u = np.zeros(2048)
    with pytest.raises(ParameterError, match="outputs must be a non-empty sequence"):
        estimate_frequency_responses(u, [], FS)
    with pytest.raises(DataError, match="input has 2048 samples but output has 1000"):
        estimate_frequency_responses(u, [np.zeros(2048), np.zeros(1000)], FS)


def test_kept_transform_gives_a_fresh_transforms_bits():
    # the window and transform of a setting are kept for the next call; interleaved settings
    # and a cleared store give the same bits
    rng = np.random.default_rng(11)
    u = rng.standard_normal(20000)
    y = np.convolve(u, [1.0, -0.3, 0.1], "same") + 0.2 * rng.standard_normal(20000)

    def arrays(**kw):
        e = estimate_frequency_response(u, y, FS, **kw)
        return [e.h1, e.coherence, e.g_uu, e.g_yy, e.g_uy, e.n_effective]

    spectral._short_time_fft.cache_clear()
    fresh = arrays(nperseg=1024, window="hann")
    other = arrays(nperseg=1024, window=("tukey", 0.25))
    assert not np.array_equal(other[1], fresh[1])
    kept = arrays(nperseg=1024, window="hann")
    assert spectral._short_time_fft.cache_info().hits >= 1
    for a, b in zip(fresh, kept):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("detrend", ["constant", "none", "linear"])
def test_several_outputs_get_the_numbers_of_one_output_calls(detrend):
    # the input and the outputs of a record are transformed together (one array, its rows
    # the signals); every estimate is the one-output call's to the bit
    rng = np.random.default_rng(9)
    u = rng.standard_normal(9000)
    ys = [rng.standard_normal(9000) * s for s in (1e-3, 1.0, 250.0)]
    many = estimate_frequency_responses(u, ys, 500.0, nperseg=1024, detrend=detrend)
    for y, est in zip(ys, many):
        one = estimate_frequency_responses(u, [y], 500.0, nperseg=1024, detrend=detrend)[0]
        for name in ("h1", "coherence", "g_uu", "g_yy", "g_uy"):
            assert getattr(est, name).tobytes() == getattr(one, name).tobytes()
