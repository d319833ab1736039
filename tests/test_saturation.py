"""The loop with the handle force saturated and the controller sampled at 1 kHz.

Without saturation the sampled simulation must match python-control's continuous
response (the 1 kHz loop is close to the continuous one); with the Omni's peak force a
stabilising controller must settle; a member whose loop is unstable must be flagged as
diverging even though the force is bounded.
"""

import control as ct
import numpy as np
import pytest

from designs.virtual_damping import virtual_damping_controller
from robust.analysis.sampled import open_plant
from robust.analysis.saturation import saturated_response
from robust.analysis.simulation import simulate
from robust.errors import ModelStructureError, ParameterError
from robust.export import discretize
from robust.model.device import DeviceLimits
from uncertainty import default_family

T = np.arange(0.0, 10.0, 1e-3)


@pytest.fixture(scope="module")
def setup():
    fam = default_family()
    m = fam.member(fam.nominal_values())
    K = virtual_damping_controller(m, 5.0, 50.0)
    return fam, m, K, discretize(K, DeviceLimits().sample_time_s)


def test_without_saturation_matches_the_continuous_loop(setup):
    _, m, K, Kd = setup
    u = 0.01 * np.sin(2 * np.pi * 0.5 * T)
    r = saturated_response(m, Kd, u, peak_force_n=1e9, settle_s=2.0)
    ref = simulate(m, T, u, controller=K)
    n = len(T)
    assert r.saturated_fraction == 0.0 and not r.delayed
    assert np.max(np.abs(r.y[:n] - ref["y"])) < 0.02 * np.max(np.abs(ref["y"]))
    assert np.max(np.abs(r.force[:n] - ref["f"])) < 0.02 * np.max(np.abs(ref["f"]))


def test_saturated_stabilising_controller_settles(setup):
    _, m, _, Kd = setup
    u = 0.5 * np.sin(2 * np.pi * 0.5 * T)
    r = saturated_response(m, Kd, u, peak_force_n=DeviceLimits().peak_force_n)
    assert r.saturated_fraction > 0.1  # the limit is active
    assert np.max(np.abs(r.force)) <= DeviceLimits().peak_force_n
    assert r.ok and r.decay_ratio < 0.1


def test_unstable_member_diverges_with_bounded_force(setup):
    _, _, _, Kd = setup
    fam3 = default_family(k_psf=3 * 0.1097)
    m3 = fam3.member(fam3.nominal_values())
    r = saturated_response(m3, Kd, 0.01 * np.sin(2 * np.pi * 0.5 * T), peak_force_n=3.3)
    assert r.diverged and not r.ok
    assert np.max(np.abs(r.force)) <= 3.3


def test_bad_input(setup):
    _, m, K, Kd = setup
    with pytest.raises(ModelStructureError, match="discrete"):
        saturated_response(m, K, np.zeros(10), peak_force_n=3.3)
    with pytest.raises(ParameterError, match="settle_s"):
        saturated_response(m, Kd, np.zeros(10), peak_force_n=3.3, settle_s=1.0)
    with pytest.raises(ParameterError, match="peak_force_n"):
        saturated_response(m, Kd, np.zeros(10), peak_force_n=0.0)
    with pytest.raises(ParameterError, match="u"):
        saturated_response(m, Kd, np.array([0.0, np.nan]), peak_force_n=3.3)


def _literal_steps(m, Kd, u, peak, settle_s=10.0):
    """The sampled loop stepped as the equations read (no algebraic loop): y and force."""
    P = ct.sample_system(open_plant(m, Kd), float(Kd.dt), method="zoh")
    Ap, Bp, Cp, Dp = (np.asarray(a, float) for a in (P.A, P.B, P.C, P.D))
    Ak, Bk, Ck, Dk = (np.asarray(a, float) for a in (Kd.A, Kd.B, Kd.C, Kd.D))
    rows = [list(P.output_labels).index(s) for s in Kd.input_labels]
    iy, jf = list(P.output_labels).index("y"), list(Kd.output_labels).index("f")
    uu = np.concatenate([u, np.zeros(int(round(settle_s / float(Kd.dt))))])
    xp, xk = np.zeros(Ap.shape[0]), np.zeros(Ak.shape[0])
    y, force = np.zeros(uu.size), np.zeros(uu.size)
    for k, uk in enumerate(uu):
        z0 = Cp @ xp + Dp[:, :1] @ [uk]
        meas = z0[rows]
        v = Ck @ xk + Dk @ meas
        v[jf] = np.clip(v[jf], -peak, peak)
        y[k], force[k] = (z0 + Dp[:, 1:] @ v)[iy], v[jf]
        xk = Ak @ xk + Bk @ meas
        xp = Ap @ xp + Bp @ np.concatenate([[uk], v])
    return y, force


def test_saturated_steps_are_the_literal_equations_bit_for_bit(setup):
    _, m, _, Kd = setup
    u = 0.5 * np.sin(2 * np.pi * 0.5 * T[:3000])
    peak = DeviceLimits().peak_force_n
    r = saturated_response(m, Kd, u, peak_force_n=peak, settle_s=2.0)
    assert not r.delayed and r.saturated_fraction > 0.1
    y, force = _literal_steps(m, Kd, u, peak, settle_s=2.0)
    np.testing.assert_array_equal(r.y, y)
    np.testing.assert_array_equal(r.force, force)
    assert r.peak_request_n > peak
