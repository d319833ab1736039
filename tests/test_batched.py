"""Batched closed-loop poles against python-control, and the family metrics."""

import control as ct
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from backhoe.constants import DAMPING_BAND_HZ
from backhoe.families.batched import batched_poles, closed_loop_matrices
from backhoe.families.family_ranges import default_family
from robust.errors import ModelStructureError, ParameterError
from uncertainty.sampling import sample
from uncertainty.validation import validate_family

N_MEMBERS = 6


def _max_matched_error(ref, got):
    """Largest |ref - got| / max(1, |ref|) over the best one-to-one matching of two pole sets."""
    assert len(ref) == len(got)
    d = np.abs(ref[:, None] - got[None, :])
    r, c = linear_sum_assignment(d)
    return float(np.max(d[r, c] / np.maximum(1.0, np.abs(ref[r]))))


def _stable_controller(inputs, outputs, seed, scale):
    rng = np.random.default_rng(seed)
    n = 2
    A = rng.normal(size=(n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + 1.0 + rng.random()) * np.eye(n)  # stable
    B = rng.normal(size=(n, len(inputs)))
    C = scale * rng.normal(size=(len(outputs), n))
    D = scale * 0.1 * rng.normal(size=(len(outputs), len(inputs)))
    return ct.ss(A, B, C, D, inputs=inputs, outputs=outputs, name="K")


CONTROLLERS = {
    "none": None,
    "force-from-c": _stable_controller(["c"], ["f"], 1, 0.5),
    "force-and-reference-from-x-y": _stable_controller(["x", "y"], ["f", "r_corr"], 2, 0.05),
    "all-inputs-all-outputs": _stable_controller(["x", "c", "y"], ["f", "r_corr"], 3, 0.01),
}


@pytest.mark.parametrize("ctrl", list(CONTROLLERS), ids=list(CONTROLLERS))
@pytest.mark.parametrize("method", ["mc", "vertices"])
def test_physical_batched_poles_equal_python_control_poles(ctrl, method):
    K = CONTROLLERS[ctrl]
    fam = default_family("physical")
    S = sample(fam.parameters, N_MEMBERS, method=method, seed=17)
    assert np.unique(S.column("valve.k_vc")).size > 1  # each member its own valve
    P = batched_poles(fam, S.values, controller=K)
    for i in range(N_MEMBERS):
        ref = ct.poles(fam.member(S.values[i]).system(controller=K))
        assert _max_matched_error(ref, P[i]) < 1e-9, (ctrl, i)


@pytest.mark.parametrize("ctrl", ["none", "reference-from-c"])
def test_literal_batched_poles_equal_python_control_poles_without_the_hidden_modes(ctrl):
    """Eqn 4's s^2 zero cancels Eqn 5's s^2 pole: python-control keeps two hidden modes at s = 0."""
    K = None if ctrl == "none" else _stable_controller(["c"], ["r_corr"], 4, 0.01)
    fam = default_family("literal")
    S = sample(fam.parameters, N_MEMBERS, method="mc", seed=23)
    P = batched_poles(fam, S.values, controller=K)
    for i in range(N_MEMBERS):
        ref = ct.poles(fam.member(S.values[i]).system(controller=K))
        order = np.argsort(np.abs(ref))
        hidden, rest = ref[order[:2]], ref[order[2:]]
        assert np.all(np.abs(hidden) < 1e-4), hidden  # the double mode at s = 0, split by rounding
        assert np.min(np.abs(rest)) > 1e-2
        assert _max_matched_error(rest, P[i]) < 1e-8, (ctrl, i)


def test_literal_nominal_matches_the_minimal_realisation():
    from robust.analysis.realization import minimal_realization

    fam = default_family("literal")
    sys = fam.member(fam.nominal_values()).system()
    mr = minimal_realization(sys.A, sys.B, sys.C, sys.D)
    assert mr.nstates == 11
    P = batched_poles(fam, fam.nominal_values()[None])[0]
    assert _max_matched_error(np.linalg.eigvals(mr.A), P) < 1e-8


def test_validation_metrics_agree_with_per_member_poles():
    fam = default_family("physical")
    S = sample(fam.parameters, 300, method="lhs", seed=5)
    res = validate_family(fam, S, chunk=70)  # several chunks, last one partial
    P = batched_poles(fam, S.values)
    max_real = P.real.max(axis=1)
    np.testing.assert_allclose(res.max_real, max_real, rtol=0, atol=1e-12)
    assert res.max_real_pole == pytest.approx(max_real.max())
    assert res.fraction_stable == pytest.approx(np.mean(max_real < res.stability_threshold))
    assert res.n_unstable == int(np.sum(max_real >= res.stability_threshold))
    f = np.abs(P.imag) / (2 * np.pi)
    band = (f >= DAMPING_BAND_HZ[0]) & (f <= DAMPING_BAND_HZ[1])
    assert res.min_damping == pytest.approx(np.min((-P.real / np.abs(P))[band]))
    assert res.worst == S.row(int(np.argmax(max_real)))
    assert res.seed == 5 and res.method == "lhs" and res.samples == 300


def test_workspace_factor_matches_the_loops_workspace_factor():
    fam = default_family("physical")
    nominal = fam.nominal_values()
    for factor in (1.0, 2.0, 10.0):
        ref = ct.poles(fam.member(nominal).with_workspace_factor(factor).system())
        got = batched_poles(fam.with_workspace_factor(factor), nominal[None])[0]
        assert _max_matched_error(ref, got) < 1e-9


def test_bad_inputs_raise():
    fam = default_family("physical")
    S = sample(default_family("literal").parameters, 4, method="mc", seed=0)
    with pytest.raises(ParameterError, match="do not match the family's"):
        validate_family(fam, S)
    with pytest.raises(ModelStructureError, match="no force port"):
        closed_loop_matrices(
            default_family("literal"), S.values, controller=CONTROLLERS["force-from-c"]
        )
    bad = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], inputs=["u"], outputs=["f"])
    with pytest.raises(ModelStructureError, match="controller inputs must be"):
        closed_loop_matrices(fam, fam.nominal_values()[None], controller=bad)


def test_results_do_not_depend_on_the_chunk_size():
    fam = default_family("physical")
    S = sample(fam.parameters, 257, method="mc", seed=8)
    a = validate_family(fam, S, chunk=257)
    b = validate_family(fam, S, chunk=16)
    np.testing.assert_array_equal(a.max_real, b.max_real)
    assert a.to_json() == b.to_json()


_PHYS = default_family("physical")


@settings(max_examples=15, deadline=None)
@given(
    st.lists(st.floats(0.0, 1.0), min_size=len(_PHYS.parameters), max_size=len(_PHYS.parameters))
)
def test_property_any_member_of_the_box_matches_python_control(u):
    row = np.array([p.ppf(x) for p, x in zip(_PHYS.parameters, u)])
    ref = ct.poles(_PHYS.member(row).system())
    assert _max_matched_error(ref, batched_poles(_PHYS, row[None])[0]) < 1e-9
