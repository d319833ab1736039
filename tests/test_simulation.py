import numpy as np
import pytest
import scipy.signal as ss

from backhoe import (
    DEFAULT_CALIBRATION,
    K_PSF_STABLE,
    BDFTLoop,
    SweptSine,
    simulate,
    simulate_swept_sine,
)
from backhoe.analysis.simulation import foh_response, lifted_response
from robust import ParameterError

CAL = DEFAULT_CALIBRATION


def test_unstable_nominal_loop_grows():
    w, wo = simulate_swept_sine(BDFTLoop(), SweptSine(duration_s=20.0))
    early = np.abs(w["y"][w.t < 5]).max()
    late = np.abs(w["y"][w.t > 19]).max()
    assert late > 100 * early  # exponential growth, not clipped
    assert np.abs(wo["y"]).max() < 0.2  # without BDFT the cylinder tracks K_PSF*u (amplitude 1)


def test_stable_halved_k_psf_stays_bounded():
    w, wo = simulate_swept_sine(BDFTLoop(k_psf=K_PSF_STABLE))
    assert np.all(np.isfinite(w["y"]))
    assert np.abs(w["y"]).max() < 5 * np.abs(wo["y"]).max()


def test_simulation_matches_scipy_lsim_of_the_formula():
    # independent: scipy lsim on the transfer function from the characteristic polynomial
    t = np.arange(0, 5, 1e-3)
    u = np.sin(2 * np.pi * 1.3 * t)
    resp = simulate(BDFTLoop(k_psf=K_PSF_STABLE), t, u)
    P = np.polynomial.Polynomial
    wn = 2 * np.pi * 5.0
    nv = P([36.0 * 314.0 * wn**2])
    dv = P([0, 314.0, 1]) * P([wn**2, 2 * 0.45 * wn, 1])
    npi, dpi = P([CAL.ki, CAL.kp]), P([0, 1])
    w1, w2 = 2 * np.pi * 6.3, 2 * np.pi * 6.5
    ns = 200.0 * P([w1**2, 2 * 0.126 * w1]) * P([w2**2, 2 * 0.223 * w2])
    ds = P([w1**2, 2 * 0.126 * w1, 1]) * P([w2**2, 2 * 0.223 * w2, 1])
    nh, dh = 5.0 * P([50.3, 1]) ** 2, P([1.57, 1]) ** 2
    k = K_PSF_STABLE
    num = k * npi * nv * ds * dh
    den = (
        dpi * dv + npi * nv
    ) * ds * dh - CAL.handle_sign * CAL.loop_scale * k * npi * nv * ns * nh
    _, y, _ = ss.lsim((num.coef[::-1], den.coef[::-1]), u, t)
    np.testing.assert_allclose(resp["y"], y, atol=1e-6 * np.abs(y).max())


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"f0_hz": 5.0, "f1_hz": 1.0}, r"f1_hz must exceed"),
        ({"duration_s": -1.0}, r"SweptSine\.duration_s"),
        ({"f1_hz": 600.0}, r"Nyquist"),
    ],
    ids=["inverted", "negative-duration", "above-nyquist"],
)
def test_bad_sweep(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        SweptSine(**kwargs)


def test_lifted_simulation_equals_dlsim():
    rng = np.random.default_rng(4)
    A = rng.normal(size=(30, 30))
    A -= (np.abs(np.linalg.eigvals(A)).max() + 0.5) * np.eye(30)
    B, C = rng.normal(size=(30, 1)), rng.normal(size=(1, 30))
    Ad, Bd, Cd, Dd, _ = ss.cont2discrete((A, B, C, np.zeros((1, 1))), 1e-3, method="foh")
    u = rng.normal(size=5003)
    y = lifted_response(Ad, Bd[:, 0], Cd[0], float(Dd[0, 0]), u)
    _, ref, _ = ss.dlsim((Ad, Bd, Cd, Dd, 1e-3), u)
    np.testing.assert_allclose(y, ref[:, 0], rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    # several output rows in one call: the same numbers as one call per row (the
    # calibration's record relies on it)
    C2 = np.vstack([Cd[0], rng.normal(size=30)])
    both = lifted_response(Ad, Bd[:, 0], C2, np.array([Dd[0, 0], 0.3]), u)
    np.testing.assert_array_equal(both[0], y)
    np.testing.assert_array_equal(both[1], lifted_response(Ad, Bd[:, 0], C2[1], 0.3, u))


def test_first_order_hold_response_equals_control_forced_response():
    # the loop's own realisation, with and without feedthrough, input not starting at zero
    import control as ct

    rng = np.random.default_rng(7)
    sys = BDFTLoop(k_psf=K_PSF_STABLE).system()
    iu = sys.input_labels.index("u")
    A, B, C, D = sys.A, sys.B[:, iu], sys.C, sys.D[:, iu]
    t = np.arange(7001) / 1000.0
    u = 0.4 + np.sin(2 * np.pi * 2.1 * t) + 0.2 * rng.normal(size=t.size)
    ref = np.atleast_2d(ct.forced_response(ct.ss(A, B[:, None], C, D[:, None]), T=t, U=u).outputs)
    for block in (1, 37, 200, 1000):
        y = foh_response(A, B, C, D, 1e-3, u, block=block)
        assert y.shape == ref.shape
        np.testing.assert_allclose(y, ref, rtol=0, atol=1e-11 * np.abs(ref).max())
    # a feedthrough-only system, and the loop's outputs through simulate
    none = (np.zeros((0, 0)), np.zeros(0), np.zeros((2, 0)))
    y = foh_response(*none, np.array([2.0, -1.0]), 1e-3, u)
    np.testing.assert_array_equal(y, np.vstack([2.0 * u, -u]))
    resp = simulate(BDFTLoop(k_psf=K_PSF_STABLE), t, u)
    for name in sys.output_labels:
        i = sys.output_labels.index(name)
        np.testing.assert_allclose(resp[name], ref[i], rtol=0, atol=1e-9 * np.abs(ref).max())
