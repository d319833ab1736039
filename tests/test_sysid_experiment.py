"""Chirp protocol and simulator: excitation, seeds, noise levels, the paper's chain of blocks."""

import control as ct
import numpy as np
import pytest

from backhoe import structure
from backhoe.sysid import (
    ENGINE_TONES_HZ,
    ChirpProtocol,
    MeasurementNoise,
    chirp_excitation,
    paper_experiment,
    simulate_experiment,
)
from robust import ModelStructureError, ParameterError
from robust.sysid import estimate_frequency_response


def test_protocol_defaults_are_the_papers():
    p = ChirpProtocol()
    assert (p.n_records, p.duration, p.fs, p.n_samples) == (20, 25.0, 1000.0, 25000)


def test_chirp_sweeps_its_band_and_starts_at_zero():
    t = np.arange(0, 20.0, 1e-3)
    x = chirp_excitation(t, f0_hz=0.5, f1_hz=20.0, amplitude=2.0)
    assert x[0] == pytest.approx(0.0, abs=1e-12)
    assert np.max(np.abs(x)) == pytest.approx(2.0, rel=1e-3)
    # the energy sits in the swept band
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(x.size, 1e-3)
    inside = (f >= 0.25) & (f <= 40.0)  # a sweep cut off at full amplitude splatters a little
    assert spec[inside].sum() / spec.sum() > 0.99
    assert (
        spec[(f >= 0.5) & (f <= 2.0)].sum() > 0.1 * spec.sum()
    )  # log sweep: same energy per decade


def test_tail_is_silent():
    p = ChirpProtocol(n_records=2, duration=5.0, tail_s=1.0)
    assert np.all(p.excitation()[4000:] == 0.0) and np.any(p.excitation()[:4000] != 0.0)


def test_same_seed_same_data_and_seed_is_recorded():
    p = ChirpProtocol(n_records=2, duration=4.0, f0_hz=0.5)
    a = simulate_experiment(structure(), p, output_noise=1.0, seed=42)
    b = simulate_experiment(structure(), p, output_noise=1.0, seed=42)
    c = simulate_experiment(structure(), p, output_noise=1.0, seed=43)
    assert a.seed == 42
    np.testing.assert_array_equal(a.y, b.y)
    assert not np.array_equal(a.y, c.y)
    assert not a.y.flags.writeable


def test_noise_level_is_what_was_asked():
    p = ChirpProtocol(n_records=4, duration=10.0)
    e = simulate_experiment(
        structure(), p, output_noise=MeasurementNoise(std=3.0), input_noise=0.5, seed=1
    )
    assert np.std(e.y - e.y_clean) == pytest.approx(3.0, rel=0.01)
    assert np.std(e.u - e.u_clean) == pytest.approx(0.5, rel=0.01)


def test_engine_tones_appear_at_their_frequencies():
    p = ChirpProtocol(n_records=4, duration=8.192, f0_hz=0.5, f1_hz=10.0)
    e = paper_experiment("human", p, noise=0.0, engine_tone=0.05, seed=3)
    est = estimate_frequency_response(e.u, e.y, e.fs, nperseg=2048)
    for f in ENGINE_TONES_HZ:
        k = int(np.argmin(np.abs(est.f_hz - f)))
        assert est.g_uu[k] > 100 * np.median(est.g_uu[(est.f_hz > 20) & (est.f_hz < 200)])


@pytest.mark.parametrize(
    "form, names",
    [("valve", ("e", "y")), ("structure", ("y", "c")), ("human", ("c", "h"))],
    ids=["valve", "structure", "human"],
)
def test_paper_experiment_channels_and_truth(form, names):
    e = paper_experiment(
        form, ChirpProtocol(n_records=2, duration=4.0, f0_hz=0.5), noise=0.01, seed=0
    )
    assert (e.input_name, e.output_name) == names
    assert e.seed == 0 and e.u.shape == (2, 4000)
    # the chain (loop -> structure -> human) cancels Eqn 4's s^2 against Eqn 5's 1/s^2: no drift
    assert np.all(np.isfinite(e.y_clean))
    assert np.abs(e.y_clean[:, -500:]).max() < 10 * np.abs(e.y_clean).std() + 1e-12


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"f1_hz": 600.0}, r"below the Nyquist frequency fs/2 = 500 Hz"),
        ({"f0_hz": 5.0, "f1_hz": 2.0}, r"f1_hz must exceed f0_hz"),
        ({"n_records": 0}, r"n_records must be a positive integer"),
        ({"duration": -1.0}, r"ChirpProtocol.duration must be a finite value in \(0, inf\]"),
        ({"tail_s": 30.0}, r"tail_s must be shorter than duration"),
        ({"method": "cubic"}, r"method must be one of"),
    ],
    ids=["above-nyquist", "inverted-sweep", "no-records", "negative-duration", "tail", "method"],
)
def test_bad_protocols(kw, match):
    with pytest.raises(ParameterError, match=match):
        ChirpProtocol(**kw)


def test_noisy_experiment_needs_a_seed():
    with pytest.raises(ParameterError, match=r"need a seed"):
        simulate_experiment(structure(), ChirpProtocol(n_records=1, duration=1.0), output_noise=1.0)


def test_mimo_system_needs_a_named_path():
    sys = ct.ss(
        np.eye(2) * -1.0,
        np.eye(2),
        np.eye(2),
        np.zeros((2, 2)),
        inputs=["a", "b"],
        outputs=["p", "q"],
    )
    with pytest.raises(
        ModelStructureError, match=r"must be SISO .* Name the path with input=/output="
    ):
        simulate_experiment(sys, ChirpProtocol(n_records=1, duration=1.0))
    with pytest.raises(
        ModelStructureError, match=r"path 'a' -> 'z' not found .* outputs \['p', 'q'\]"
    ):
        simulate_experiment(sys, ChirpProtocol(n_records=1, duration=1.0), input="a", output="z")


def test_path_of_the_closed_loop_is_identified_as_its_transfer_function():
    # any model of the workbench: the BDFT loop (stabilised by a doubled workspace), u -> y
    from backhoe import BDFTLoop
    from backhoe.sysid import select_path

    loop = BDFTLoop().with_workspace_factor(2.0).system()
    proto = ChirpProtocol(n_records=3, duration=20.0, f0_hz=0.2, f1_hz=30.0, tail_s=8.0)
    exp = simulate_experiment(loop, proto, input="u", output="y")
    assert (exp.input_name, exp.output_name) == ("u", "y")
    est = estimate_frequency_response(exp.u, exp.y, exp.fs)
    band = est.band_mask((0.5, 10.0))
    g = np.asarray(select_path(loop, "u", "y")(2j * np.pi * est.f_hz[band])).ravel()
    np.testing.assert_allclose(est.h1[band], g, rtol=3e-3)


def test_valve_experiment_runs_the_loop_with_the_true_valve():
    # y must be the closed loop's output with the true valve, and e its valve command
    from backhoe import ValveCylinderParams, pi_controller, valve_cylinder
    from backhoe.model.loop import DEFAULT_CALIBRATION

    truth = ValveCylinderParams(k_vc=20.0, p1=150.0, wn_hz=3.0, zeta=0.3)
    p = ChirpProtocol(n_records=1, duration=6.0, f0_hz=0.5)
    e = paper_experiment("valve", p, noise=0.0, seed=0, truth=truth)
    loop = ct.feedback(ct.series(pi_controller(DEFAULT_CALIBRATION.pi), valve_cylinder(truth)), 1)
    ref = ct.forced_response(loop, T=p.time(), U=p.excitation()).outputs
    np.testing.assert_allclose(e.y_clean[0], ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())
