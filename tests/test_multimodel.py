"""Multi-model tuning pieces: exact eigenvalue and force-response gradients, sampled-data check."""

import math

import control as ct
import numpy as np
import pytest

from backhoe import default_family
from backhoe.analysis.sampled import sampled_data_check
from designs.multimodel import (
    _eigen_gradients,
    _omega,
    _stalled,
    force_response,
    open_loop_data,
    tune_spectral_abscissa,
)
from designs.virtual_damping import virtual_damping_controller
from robust.errors import ModelStructureError, ParameterError
from robust.export import discretize
from uncertainty import sample


@pytest.fixture(scope="module")
def setup():
    fam = default_family()
    rows = [fam.nominal_values()] + list(sample(fam.parameters, 3, method="lhs", seed=3).values)
    members = [fam.member(r) for r in rows]
    nominal = members[0]
    K = ct.ss(virtual_damping_controller(nominal, 5.0, 50.0, rolloff_hz=20.0))
    K = ct.ss(K.A, K.B, K.C, K.D, inputs=["x"], outputs=["f"], name="k")
    return fam, members, K


def test_closed_loop_eigenvalues_match_the_interconnected_loop(setup):
    fam, members, K = setup
    data = open_loop_data(members, K)
    w, _ = _eigen_gradients(data, _omega(K), K.nstates)
    for i, m in enumerate(members):
        ref = np.linalg.eigvals(m.system(bdft=True, controller=K).A)
        assert np.sort(w[i].real)[-1] == pytest.approx(np.sort(ref.real)[-1], abs=1e-8)


def test_lagged_plants_equal_the_loop_with_a_lagged_controller(setup):
    # the lag at the plant's controller inputs is the same loop as the controller followed
    # by 1/(1 + s tau), closed through python-control's interconnection
    fam, members, K = setup
    tau = 0.5e-3
    data = open_loop_data(members, K, lag_s=tau)
    assert data.A.shape[1] == open_loop_data(members, K).A.shape[1] + 1
    w, _ = _eigen_gradients(data, _omega(K), K.nstates)
    lag = ct.ss(-1 / tau, 1 / tau, 1.0, 0.0)
    KL = lag * ct.ss(K.A, K.B, K.C, K.D)
    KL = ct.ss(KL.A, KL.B, KL.C, KL.D, inputs=["x"], outputs=["f"], name="kl")
    for i, m in enumerate(members):
        ref = np.linalg.eigvals(m.system(bdft=True, controller=KL).A)
        # the two realisations agree to 1e-6 relative (the pair near -0.9 rad/s is the
        # least well conditioned), far below what the lag itself moves
        np.testing.assert_allclose(np.sort(w[i].real)[-3:], np.sort(ref.real)[-3:], rtol=1e-5)
    # a half-sample lag moves the three slowest poles by 1e-3 to 1e-2 rad/s
    w0, _ = _eigen_gradients(open_loop_data(members, K), _omega(K), K.nstates)
    shift = np.abs(np.sort(w0.real, axis=1)[:, -3:] - np.sort(w.real, axis=1)[:, -3:])
    assert shift.max() > 5e-3


def test_eigenvalue_gradient_against_finite_differences(setup):
    _, members, K = setup
    data = open_loop_data(members, K)
    Om = _omega(K)
    w, g = _eigen_gradients(data, Om, K.nstates)
    D = np.random.default_rng(0).standard_normal(Om.shape) * np.abs(Om)
    # a step of 1e-4 (relative to each entry): truncation error O(h^2) stays near 1e-7
    # relative, while at 1e-6 the eigenvalue solver's rounding error divided by h reaches
    # 3e-4 relative on some CPUs' BLAS kernels
    h = 1e-4
    wp, _ = _eigen_gradients(data, Om + h * D, K.nstates)
    wm, _ = _eigen_gradients(data, Om - h * D, K.nstates)
    k = np.argmax(w.real, axis=1)
    idx = np.arange(len(k))
    # central differences of the same eigenvalue (the one nearest the unperturbed rightmost)
    lam = w[idx, k]
    near_p = wp[idx, np.argmin(np.abs(wp - lam[:, None]), axis=1)]
    near_m = wm[idx, np.argmin(np.abs(wm - lam[:, None]), axis=1)]
    fd = (near_p.real - near_m.real) / (2 * h)
    an = np.einsum("nij,ij->n", g[idx, k], D)
    np.testing.assert_allclose(an, fd, rtol=1e-4, atol=1e-6 * np.abs(an).max())


def test_gradients_above_a_floor_are_the_full_ones(setup):
    # the tuning asks only for the eigenvalues above its margin: the same eigenvalues and
    # the same gradients as the full decomposition, with the others' vectors never formed
    _, members, K = setup
    data = open_loop_data(members, K)
    Om = _omega(K)
    w, g = _eigen_gradients(data, Om, K.nstates)
    top = np.sort(w.real, axis=1)[:, -3]
    floor = float(np.median(top))  # some members above it, some entirely below
    assert (w.real > floor).any(axis=1).sum() not in (0, len(members))
    wf, gf = _eigen_gradients(data, Om, K.nstates, floor=floor)
    above = w.real > floor
    np.testing.assert_array_equal(wf.real > floor, above)
    np.testing.assert_allclose(np.sort_complex(wf[above]), np.sort_complex(w[above]), rtol=1e-12)
    assert gf.shape == (above.sum(),) + Om.shape
    np.testing.assert_allclose(gf, g[above], rtol=1e-9, atol=1e-12 * np.abs(g).max())
    # a floor above every eigenvalue: nothing to differentiate
    w_none, g_none = _eigen_gradients(data, Om, K.nstates, floor=float(w.real.max()) + 1.0)
    assert g_none.shape == (0,) + Om.shape
    np.testing.assert_allclose(np.sort(w_none.real, axis=1), np.sort(w.real, axis=1), atol=1e-9)


def test_force_response_and_its_gradient(setup):
    _, members, K = setup
    data = open_loop_data(members[:2], K)
    Om = _omega(K)
    w = 2 * np.pi * np.array([0.3, 2.0, 7.0])
    T, g = force_response(data, Om, K.nstates, w, grad=True)
    cl = members[0].system(bdft=True, controller=K, outputs=["f"])
    ref = ct.frequency_response(cl[0, list(cl.input_labels).index("u")], w).complex.ravel()
    np.testing.assert_allclose(T[0], ref, rtol=1e-8)
    D = np.random.default_rng(1).standard_normal(Om.shape) * np.abs(Om)
    h = 1e-7
    T2, _ = force_response(data, Om + h * D, K.nstates, w)
    fd = (np.abs(T2) ** 2 - np.abs(T) ** 2) / h
    np.testing.assert_allclose(np.einsum("nwij,ij->nw", g, D), fd, rtol=1e-4)


def test_sampled_data_check_converges_with_the_sample_rate(setup):
    fam, members, K = setup
    pw = math.sqrt(fam.struct.f1_hz * fam.struct.f2_hz)
    fast = sampled_data_check(members[0], K, discretize(K, 1e-3, prewarp_hz=pw))
    slow = sampled_data_check(members[0], K, discretize(K, 2e-2, prewarp_hz=pw))
    assert fast.stable_continuous and fast.stable_discrete and fast.agree
    assert fast.max_response_deviation_db < 0.5
    assert slow.max_response_deviation_db > 2 * fast.max_response_deviation_db
    assert abs(fast.max_real_discrete - fast.max_real_continuous) < 0.05


def test_sampled_data_check_refuses_a_continuous_kd(setup):
    _, members, K = setup
    with pytest.raises(ModelStructureError, match="Kd must be a discrete-time controller"):
        sampled_data_check(members[0], K, K)


def test_enlargement_stops_after_rounds_without_a_better_one():
    # history entries: (design members, worst sampled abscissa, fraction stable)
    rising = [(1, 4.0, 0.2), (13, 1.0, 0.9), (25, 0.5, 0.9), (37, 0.4, 0.95)]
    assert not _stalled(rising, 3)
    # hinf-robust-corr's rounds: the same controller from the fourth round on
    stuck = [(1, 4.6, 0.204), (13, 1.45, 0.932), (25, 1.04, 0.984)] + [(37, -0.061, 1.0)] * 4
    assert not _stalled(stuck[:6], 3)  # two repeats after the best: not yet
    assert _stalled(stuck, 3)
    # a lower worst abscissa at the same fraction is an improvement; a higher one is not
    assert not _stalled([(1, 1.0, 0.9), (2, 2.0, 0.9), (3, 0.9, 0.9)], 1)
    assert _stalled([(1, 1.0, 0.9), (2, 2.0, 0.9), (3, 1.0, 0.9)], 2)
    assert not _stalled(stuck, 0)  # 0 never stops early


@pytest.mark.parametrize("patience", [-1, 1.5, True, "3"])
def test_patience_must_be_a_non_negative_integer(setup, patience):
    fam, samples, K0 = setup[0], None, setup[-1]
    with pytest.raises(ParameterError, match="patience must be an integer >= 0"):
        tune_spectral_abscissa(fam, samples, K0, patience=patience)
