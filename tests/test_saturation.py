"""The loop with the handle force saturated and the controller sampled at 1 kHz.

Without saturation the sampled simulation must match python-control's continuous
response (the 1 kHz loop is close to the continuous one); with the Omni's peak force a
stabilising controller must settle; a member whose loop is unstable must be flagged as
diverging even though the force is bounded.
"""

import control as ct
import numpy as np
import pytest
from numba_builds import outputs_here_and_generic

from designs.virtual_damping import virtual_damping_controller
from robust.analysis.sampled import open_plant
from robust.analysis.saturation import _steps, saturated_response
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
    terms = 0.0  # the largest |Ck| |xk| + |Dk| |meas| of the force's sum
    for k, uk in enumerate(uu):
        z0 = Cp @ xp + Dp[:, :1] @ [uk]
        meas = z0[rows]
        v = Ck @ xk + Dk @ meas
        terms = max(terms, float(np.abs(Ck[jf]) @ np.abs(xk) + np.abs(Dk[jf]) @ np.abs(meas)))
        v[jf] = np.clip(v[jf], -peak, peak)
        y[k], force[k] = (z0 + Dp[:, 1:] @ v)[iy], v[jf]
        xk = Ak @ xk + Bk @ meas
        xp = Ap @ xp + Bp @ np.concatenate([[uk], v])
    return y, force, terms


def test_saturated_steps_are_the_literal_equations(setup):
    """The compiled steps are the equations stepped in numpy, to rounding: the same clipped
    samples, the position within 1e-12 of its largest value, the force within 8 eps of the
    terms of its sum (the controller's terms reach 1e5 N where the force is clipped at 3.3:
    summed in another order, the force moves by their rounding)."""
    _, m, _, Kd = setup
    u = 0.5 * np.sin(2 * np.pi * 0.5 * T[:3000])
    peak = DeviceLimits().peak_force_n
    r = saturated_response(m, Kd, u, peak_force_n=peak, settle_s=2.0)
    assert not r.delayed and r.saturated_fraction > 0.1
    y, force, terms = _literal_steps(m, Kd, u, peak, settle_s=2.0)
    assert terms > 1e4 * peak
    np.testing.assert_allclose(r.y, y, rtol=0, atol=1e-12 * np.max(np.abs(y)))
    np.testing.assert_allclose(r.force, force, rtol=0, atol=8 * np.finfo(float).eps * terms)
    assert np.array_equal(np.abs(r.force) == peak, np.abs(force) == peak)
    assert r.peak_request_n > peak


def _reference_steps(mats, meas_rows, y_row, f_idx, peak, uu, delayed):
    """The loop of :func:`_steps` written with numpy products, as the module notes read."""
    Ap, Bp, Cp, Dp, Ak, Bk, Ck, Dk = mats
    xp, xk, v = np.zeros(Ap.shape[0]), np.zeros(Ak.shape[0]), np.zeros(Ck.shape[0])
    y, force, requests = np.zeros(uu.size), np.zeros(uu.size), np.zeros(uu.size)
    clipped = 0
    for k, uk in enumerate(uu):
        w = np.concatenate([[uk], v])
        z = Cp @ xp + (Dp @ w if delayed else Dp[:, 0] * uk)
        meas = z[meas_rows]
        req = Ck @ xk + Dk @ meas
        v_new = req.copy()
        requests[k] = req[f_idx]
        v_new[f_idx] = np.clip(req[f_idx], -peak, peak)
        clipped += abs(req[f_idx]) > peak
        if not delayed:
            v = v_new
            z = z + Dp[:, 1:] @ v
        y[k], force[k] = z[y_row], v[f_idx]
        xk = Ak @ xk + Bk @ meas
        xp = Ap @ xp + Bp @ np.concatenate([[uk], v])
        if delayed:
            v = v_new
    return y, force, requests, clipped


def _random_loop(rng, n_p=6, n_k=3, n_v=2):
    """A stable sampled plant and controller with feedthrough on every path."""
    Ap = rng.normal(size=(n_p, n_p))
    Ap *= 0.9 / np.max(np.abs(np.linalg.eigvals(Ap)))
    Ak = rng.normal(size=(n_k, n_k))
    Ak *= 0.5 / np.max(np.abs(np.linalg.eigvals(Ak)))
    n_z, n_m = 4, 2
    return (
        Ap,
        0.3 * rng.normal(size=(n_p, 1 + n_v)),
        rng.normal(size=(n_z, n_p)),
        0.1 * rng.normal(size=(n_z, 1 + n_v)),
        Ak,
        0.3 * rng.normal(size=(n_k, n_m)),
        0.3 * rng.normal(size=(n_v, n_k)),
        0.1 * rng.normal(size=(n_v, n_m)),
    )


@pytest.mark.parametrize("delayed", [False, True])
def test_compiled_steps_match_numpy_products(delayed):
    rng = np.random.default_rng(7 + delayed)
    for _ in range(5):
        mats = _random_loop(rng)
        uu = np.concatenate([np.sin(np.arange(400) / 7.0), np.zeros(200)])
        rows, peak = np.array([3, 1]), 0.05
        y, force, norms, requests, clipped = _steps(*mats, rows, 2, 1, peak, uu, delayed)
        ry, rforce, rreq, rclipped = _reference_steps(mats, rows, 2, 1, peak, uu, delayed)
        assert clipped == rclipped and 0 < clipped < uu.size
        for got, want in ((y, ry), (force, rforce), (requests, rreq)):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.max(np.abs(want)))
        assert np.all(np.abs(force) <= peak) and np.all(np.isfinite(norms))


def test_compiled_steps_stop_at_a_diverging_state():
    mats = list(_random_loop(np.random.default_rng(3)))
    mats[0] = 3.0 * np.eye(6)  # the plant state triples at each sample
    uu = np.ones(1000)
    y, force, norms, _, _ = _steps(*mats, np.array([3, 1]), 2, 1, 0.05, uu, False)
    k = int(np.argmax(~np.isfinite(norms)))
    # stopped at the first state whose norm is not finite: its square overflows at 1.34e154
    assert 100 < k and 1e150 < norms[k - 1] < 1.35e154
    assert np.all(norms[k:] == np.inf) and np.all(np.isnan(y[k:]))
    assert np.all(np.isfinite(y[:k])) and np.all(np.abs(force) <= 0.05)


_HASH_SCRIPT = """
import hashlib
import numpy as np
from robust.analysis.saturation import _steps
rng = np.random.default_rng(5)
h = hashlib.sha256()
for delayed in (False, True):
    Ap = rng.normal(size=(7, 7)); Ap *= 0.95 / np.max(np.abs(np.linalg.eigvals(Ap)))
    Ak = rng.normal(size=(3, 3)); Ak *= 0.5 / np.max(np.abs(np.linalg.eigvals(Ak)))
    mats = (Ap, rng.normal(size=(7, 3)), rng.normal(size=(4, 7)), 0.1 * rng.normal(size=(4, 3)),
            Ak, rng.normal(size=(3, 2)), rng.normal(size=(2, 3)), 0.1 * rng.normal(size=(2, 2)))
    out = _steps(*mats, np.array([0, 2]), 1, 0, 0.2, np.sin(np.arange(3000) / 9.0), delayed)
    for a in out[:4]:
        h.update(a.tobytes())
    h.update(str(out[4]).encode())
print(h.hexdigest())
"""


def test_same_bits_for_a_generic_cpu_build(tmp_path):
    """The compiled steps give the same bits built for a generic x86-64 (no AVX, no FMA)."""
    here, generic = outputs_here_and_generic(_HASH_SCRIPT, tmp_path)
    assert len(here) == 64 and here == generic
