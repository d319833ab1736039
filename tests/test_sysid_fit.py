"""Structured fits: exact recovery on exact data, stated tolerances on noisy simulated chirps."""

import dataclasses

import control as ct
import numpy as np
import pytest

from backhoe import (
    LiteralHuman,
    LiteralHumanParams,
    StructureParams,
    ValveCylinderParams,
    structure,
    valve_cylinder,
)
from backhoe.sysid import (
    ChirpProtocol,
    RationalParams,
    coherence_threshold,
    fit_frequency_response,
    form_system,
    levy_sk,
    paper_experiment,
    parse_form,
)
from robust import InfeasibleError, ParameterError
from robust.sysid import FrequencyResponseEstimate, estimate_frequency_response

TRUTH = {
    "valve": ValveCylinderParams(),
    "structure": StructureParams(),
    "human": LiteralHumanParams(),
}
SYSTEMS = {
    "valve": valve_cylinder,
    "structure": structure,
    "human": lambda p: LiteralHuman(p).system(),
}
#: Fit bands: where each component's chirp experiment is coherent (the paper's Figures 6, 7, 9).
BANDS = {"valve": (0.5, 20.0), "structure": (2.0, 15.0), "human": (0.15, 20.0)}

#: Stated recovery tolerances (relative) at 2 % white noise on both channels plus engine tones
#: (2 % of RMS at 30 and 60 Hz) on the accelerometer, 8 records of 25 s at 1 kHz. Over seeds
#: 0-11 the largest errors were about a third of these (valve p1 1.3 %, human p1 3.2 %).
#: p1 of the valve (50 Hz) lies outside the band and is extrapolated; the human's p1
#: (0.25 Hz) sits where the seat acceleration, filtered by the structure's s^2, is weakest.
TOLERANCES = {
    "valve": {"k_vc": 0.01, "p1": 0.05, "wn_hz": 0.01, "zeta": 0.01},
    "structure": {"k_s": 0.01, "zeta1": 0.03, "zeta2": 0.03, "f1_hz": 0.01, "f2_hz": 0.01},
    "human": {"k_h": 0.05, "z1": 0.05, "p1": 0.10},
}


def _exact_estimate(system, f_hz, fs=1000.0) -> FrequencyResponseEstimate:
    """An 'estimate' holding the exact response and unit coherence (tests the fit alone)."""
    n = f_hz.size
    h = np.ones(n, dtype=complex)  # the DC bin is never fitted (a free integrator has no DC value)
    h[1:] = np.asarray(system(2j * np.pi * f_hz[1:])).ravel()
    return FrequencyResponseEstimate(
        f_hz=f_hz,
        h1=h,
        coherence=np.ones(n),
        g_uu=np.ones(n),
        g_yy=np.abs(h) ** 2,
        g_uy=h,
        fs=fs,
        nperseg=round(fs / (f_hz[1] - f_hz[0])),
        noverlap=0,
        window="boxcar",
        detrend="none",
        n_segments=10,
        n_effective=10.0,
        n_records=10,
    )


@pytest.mark.parametrize("form", list(TRUTH), ids=list(TRUTH))
def test_fixed_form_recovered_exactly_from_exact_response(form):
    f = np.arange(0, 50.0001, 0.05)
    est = _exact_estimate(SYSTEMS[form](TRUTH[form]), f)
    fit = fit_frequency_response(est, form, BANDS[form])
    assert isinstance(fit.params, type(TRUTH[form]))
    for name, true in dataclasses.asdict(TRUTH[form]).items():
        assert getattr(fit.params, name) == pytest.approx(true, rel=1e-6), name
    assert fit.fit_error_db < 1e-5 and fit.fit_error_deg < 1e-4


@pytest.mark.parametrize("form", list(TRUTH), ids=list(TRUTH))
def test_fixed_form_recovered_from_noisy_chirp_experiment(form):
    proto = ChirpProtocol(n_records=8)
    exp = paper_experiment(form, proto, noise=0.02, engine_tone=0.02, seed=2024)
    est = estimate_frequency_response(exp.u, exp.y, exp.fs)
    fit = fit_frequency_response(est, form, BANDS[form])
    got = fit.params_dict()
    for name, true in dataclasses.asdict(TRUTH[form]).items():
        assert got[name] == pytest.approx(true, rel=TOLERANCES[form][name]), name
        if form != "human":
            # the linearised standard error is honest to within a few sigma. Not for the human:
            # noise on its measured input (the seat accelerometer) biases H1 low where the seat
            # acceleration is weak (errors in variables), a bias std_errors does not include.
            assert abs(got[name] - true) <= 5.0 * fit.std_errors[name], name
    assert fit.fit_error_db < 1.0
    assert fit.band_errors[0].band_hz[0] == pytest.approx(BANDS[form][0])


@pytest.mark.slow
def test_paper_protocol_dimensions_recover_every_component():
    # the paper's protocol: 20 records of 25 s at 1 kHz
    proto = ChirpProtocol()
    assert (proto.n_records, proto.duration, proto.fs) == (20, 25.0, 1000.0)
    for form, truth in TRUTH.items():
        exp = paper_experiment(form, proto, noise=0.02, engine_tone=0.02, seed=7)
        est = estimate_frequency_response(exp.u, exp.y, exp.fs)
        fit = fit_frequency_response(est, form, BANDS[form])
        for name, true in dataclasses.asdict(truth).items():
            assert getattr(fit.params, name) == pytest.approx(true, rel=TOLERANCES[form][name]), (
                form,
                name,
            )


def test_structure_modes_are_ordered_and_their_coupling_reported():
    # start the refinement with the modes swapped: the fit must still return f1 <= f2
    f = np.arange(0, 30.0001, 0.05)
    truth = StructureParams(f1_hz=6.3, f2_hz=6.5)
    est = _exact_estimate(structure(truth), f)
    swapped = StructureParams(k_s=150.0, zeta1=0.2, zeta2=0.1, f1_hz=7.0, f2_hz=5.5)
    fit = fit_frequency_response(est, "structure", (2.0, 15.0), initial=swapped)
    assert fit.params.f1_hz <= fit.params.f2_hz
    assert fit.params.f1_hz == pytest.approx(6.3, rel=1e-5)
    assert any("modes are" in n and "apart" in n for n in fit.notes)
    assert fit.correlation.shape == (5, 5)


def test_levy_sk_recovers_exact_rational_model():
    g = ct.tf([3.0, 40.0, 500.0], np.polymul([1.0, 4.0, 900.0], [1.0, 30.0, 200.0]))
    w = np.geomspace(0.5, 300.0, 200)
    h = np.asarray(g(1j * w)).ravel()
    num, den = levy_sk(w, h, 2, 4)
    np.testing.assert_allclose(num, g.num[0][0], rtol=1e-7)
    np.testing.assert_allclose(den, g.den[0][0], rtol=1e-7)


def test_rational_form_returns_coefficients_and_system():
    g = ct.tf([2.0, 50.0], [1.0, 6.0, 400.0])
    f = np.arange(0, 40.0001, 0.05)
    est = _exact_estimate(g, f)
    fit = fit_frequency_response(est, "1/2", (0.5, 30.0))
    assert isinstance(fit.params, RationalParams)
    np.testing.assert_allclose(fit.params.num, [2.0, 50.0], rtol=1e-6)
    np.testing.assert_allclose(fit.params.den, [1.0, 6.0, 400.0], rtol=1e-6)
    assert set(fit.params_dict()) == {"b1", "b0", "a2", "a1", "a0"}
    assert isinstance(fit.system, ct.TransferFunction)
    assert fit.fit_error_db < 1e-5


@pytest.mark.parametrize("form", list(TRUTH), ids=list(TRUTH))
def test_form_system_matches_the_plant_blocks(form):
    w = 2 * np.pi * np.array([0.3, 3.0, 6.4, 30.0])
    a = np.asarray(form_system(form, TRUTH[form])(1j * w)).ravel()
    b = np.asarray(SYSTEMS[form](TRUTH[form])(1j * w)).ravel()
    np.testing.assert_allclose(a, b, rtol=1e-9)


@pytest.mark.parametrize(
    "form, match",
    [
        ("valves", r"form must be one of"),
        ("3/2", r"M <= N \(proper\); got M=3, N=2"),
        ("2/0", r"1 <= N"),
        ("2:4", r"'M/N'"),
    ],
    ids=["unknown-name", "improper", "zero-denominator", "bad-syntax"],
)
def test_bad_forms(form, match):
    with pytest.raises(ParameterError, match=match):
        parse_form(form)


def test_too_few_coherent_points_is_infeasible():
    f = np.arange(0, 30.0001, 0.05)
    est = _exact_estimate(structure(), f)
    est = dataclasses.replace(est, coherence=np.where((f > 6.0) & (f < 6.1), 0.9, 0.1))
    with pytest.raises(InfeasibleError, match=r"only 1 usable frequencies .* has 5 parameters"):
        fit_frequency_response(est, "structure", (2.0, 15.0), min_coherence=0.5)


def test_initial_of_wrong_class_is_rejected():
    f = np.arange(0, 30.0001, 0.05)
    est = _exact_estimate(structure(), f)
    with pytest.raises(ParameterError, match=r"initial must be a StructureParams"):
        fit_frequency_response(est, "structure", (2.0, 15.0), initial=ValveCylinderParams())


def test_coherence_threshold_has_its_false_alarm_rate():
    # independent white input and output: true coherence 0; with n_d = 8 independent
    # (rectangular, non-overlapping) averages a fraction alpha of bins exceeds the threshold
    rng = np.random.default_rng(8)
    u = rng.standard_normal((8, 4096))
    y = rng.standard_normal((8, 4096))
    est = estimate_frequency_response(u, y, 1000.0, window="boxcar")
    assert est.n_effective == pytest.approx(8.0)
    coh = est.coherence[1:-1]
    for alpha in (0.05, 0.2):
        rate = np.mean(coh > coherence_threshold(est.n_effective, alpha))
        assert rate == pytest.approx(alpha, abs=4 * np.sqrt(alpha * (1 - alpha) / coh.size))


def test_noise_only_data_have_no_usable_frequencies():
    rng = np.random.default_rng(9)
    est = estimate_frequency_response(
        rng.standard_normal((8, 4096)), rng.standard_normal((8, 4096)), 1000.0
    )
    with pytest.raises(InfeasibleError, match=r"only \d usable frequencies in band \[1, 100\] Hz"):
        fit_frequency_response(est, "valve", (1.0, 100.0))


def test_single_mode_structure_is_reported_as_merged_modes():
    # one mode written twice: the data cannot separate f1 from f2, and the fit must say so
    f = np.arange(0, 30.0001, 0.05)
    truth = StructureParams(k_s=200.0, zeta1=0.15, zeta2=0.15, f1_hz=6.4, f2_hz=6.4)
    fit = fit_frequency_response(_exact_estimate(structure(truth), f), "structure", (2.0, 15.0))
    assert fit.params.f1_hz <= fit.params.f2_hz
    assert fit.fit_error_db < 0.01
    assert any("modes merged" in n for n in fit.notes), fit.notes


@pytest.mark.parametrize("form", list(TRUTH), ids=list(TRUTH))
def test_inverted_sensor_is_reported(form):
    # a backwards-mounted sensor: the physical form (positive gain) cannot fit a sign flip
    # and says so
    f = np.arange(0, 50.0001, 0.05)
    est = _exact_estimate(SYSTEMS[form](TRUTH[form]), f)
    est = dataclasses.replace(est, h1=-est.h1)
    fit = fit_frequency_response(est, form, BANDS[form])
    assert any("data look inverted" in n for n in fit.notes), fit.notes
