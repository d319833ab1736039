"""Coverage of a design over the population: member verdicts and the certificate."""

import control as ct
import numpy as np
import pytest
from scipy.linalg import block_diag

import designs.coverage as coverage_module
from backhoe import default_family
from backhoe.model.device import DeviceLimits
from designs.coverage import design_coverage, member_verdicts
from designs.registry import get_design
from designs.spec import (
    CONSTRAINTS,
    Specification,
    check_specification,
    unstable_member_check,
)
from robust.analysis.loops import closed_loop_poles
from robust.analysis.stability import damping_in_band
from robust.errors import ParameterError
from uncertainty import sample
from uncertainty.randomized import failure_bound


@pytest.fixture(scope="module")
def family():
    return default_family()


@pytest.fixture(scope="module")
def virtual_damping(family):
    res = get_design("virtual-damping").build(
        family, sample(family.parameters, 200, method="lhs", seed=0), DeviceLimits()
    )
    return res.controller


def test_member_verdicts_agree_with_the_specification_check(family, virtual_damping):
    # a handle-force controller: each member's verdict and binding constraint equal those of
    # check_specification on that member alone, which simulates its own peak force
    members = sample(family.parameters, 40, method="mc", seed=21)
    spec = Specification()
    v = member_verdicts(family, members.values, virtual_damping, spec, seed=100)
    assert v.violated.shape == (40, len(CONSTRAINTS))
    for i, row in enumerate(members.values):
        ref = check_specification(
            [family.member(row)], virtual_damping, spec, seed=100 + i, simulate_peak=1
        )
        assert bool(v.holds[i]) == ref.holds
        assert v.binding[i] == ref.binding
    # the sample exercises several binding constraints (unstable members bind on the decay
    # rate, stable ones on damping or tracking), so the agreement above means something
    assert {"decay rate", "damping", "tracking"} <= set(v.binding)
    assert 0 < v.violated[:, 0].sum() < 40


def test_unstable_members_settled_by_their_poles(family, virtual_damping, monkeypatch):
    # members whose batched poles say "unstable" beyond doubt are not assembled one by one:
    # their verdicts, binding constraints and utilisations equal the full check's
    rows = sample(family.parameters, 80, method="mc", seed=4).values
    spec = Specification()
    unstable, max_real, damping, n = coverage_module._screen(family, rows, virtual_damping, spec)
    assert 10 < unstable.sum() < 70  # both kinds, so the comparison below means something
    assert n == 13 + virtual_damping.nstates
    quick = member_verdicts(family, rows, virtual_damping, spec, seed=5)
    monkeypatch.setattr(coverage_module, "_screen", _no_screen)
    full = member_verdicts(family, rows, virtual_damping, spec, seed=5)
    _assert_same_verdicts(quick, full)
    # and for a screened member, the check from its own poles is check_specification's
    i = int(np.flatnonzero(unstable)[0])
    ref = check_specification([family.member(rows[i])], virtual_damping, spec, simulate_peak=0)
    ps = closed_loop_poles(family.member(rows[i]).system(bdft=True, controller=virtual_damping))
    assert not ps.stable and ps.max_real == pytest.approx(max_real[i], rel=1e-9)
    mine = unstable_member_check(
        ps.max_real, float(damping_in_band(ps.poles, spec.damping_band_hz)), spec, True
    )
    assert repr(mine) == repr(ref)


def _assert_same_verdicts(a, b):
    np.testing.assert_array_equal(a.violated, b.violated)
    assert a.binding == b.binding
    np.testing.assert_array_equal(a.utilisation, b.utilisation)


def _no_screen(family, rows, controller, spec):
    return np.zeros(len(rows), bool), None, None, 0


@pytest.mark.parametrize("hidden", ["unstable", "in band"])
def test_no_screen_where_the_loop_hides_a_mode(family, virtual_damping, hidden, monkeypatch):
    # a controller state wired to nothing is a mode of the full closed loop that the
    # check's minimal realisation drops: unstable, it would make every member look unstable;
    # lightly damped in the band, it would fail every member's damping. The screen must
    # stand aside, and the verdicts are the full check's (those of the controller without it)
    w = 2 * np.pi * 2.0
    H = np.array([[1.0]]) if hidden == "unstable" else np.array([[0.0, 1.0], [-w * w, -0.02 * w]])
    K = virtual_damping
    h = H.shape[0]
    K2 = ct.ss(
        block_diag(K.A, H),
        np.vstack([K.B, np.zeros((h, K.ninputs))]),
        np.hstack([K.C, np.zeros((K.noutputs, h))]),
        K.D,
        inputs=K.input_labels,
        outputs=K.output_labels,
    )
    rows = sample(family.parameters, 60, method="mc", seed=4).values
    spec = Specification()
    with_screen = member_verdicts(family, rows, K2, spec, seed=5)
    reference = member_verdicts(family, rows, K, spec, seed=5)
    monkeypatch.setattr(coverage_module, "_screen", _no_screen)
    without = member_verdicts(family, rows, K2, spec, seed=5)
    _assert_same_verdicts(with_screen, without)
    # the extra state changes the minimal realisation's rounding only
    np.testing.assert_array_equal(without.violated, reference.violated)
    assert without.binding == reference.binding
    np.testing.assert_allclose(without.utilisation, reference.utilisation, rtol=1e-8)
    # (the reference itself has unstable and stable members)
    assert 0 < (reference.binding.count("decay rate")) < 60


def test_parallel_verdicts_equal_serial(family, virtual_damping):
    rows = sample(family.parameters, 120, method="mc", seed=3).values
    a = member_verdicts(family, rows, virtual_damping, seed=9, n_jobs=1)
    b = member_verdicts(family, rows, virtual_damping, seed=9, n_jobs=2)
    _assert_same_verdicts(a, b)


def test_workspace_design_coverage(family):
    # the doubled workspace needs no force; it fails where a lightly damped mode is left in
    # the damping band (measured 61.7 % on 300 members, seed 2): asserted with room
    res = get_design("workspace").build(
        family, sample(family.parameters, 200, method="lhs", seed=0), DeviceLimits()
    )
    seen = []
    cov = design_coverage(
        res.family,
        res.controller,
        samples=200,
        seed=2,
        n_jobs=2,
        progress=lambda d, n: seen.append(d),
    )
    j = cov.to_json()
    assert j["samples"] == 200 and j["seed"] == 2 and j["method"] == "mc"
    assert 0.45 < j["fraction"] < 0.8
    assert j["epsilon"] == pytest.approx(failure_bound(200, j["failures"], 0.999))
    assert j["lower"] < j["fraction"]
    # damping is what fails, not force (the design exerts none). Measured with the valve's
    # spread: 52 %, damping binding on 85 of the 96 failures, tracking on 8, the decay rate
    # on 3; before the family varied the valve: 58.5 %, damping on 79 of 83, tracking on 4
    assert max(j["binding"], key=j["binding"].get) == "damping"
    assert j["binding"]["damping"] > 0.8 * j["failures"]
    assert j["violations"]["continuous force"] == 0 and j["violations"]["peak force"] == 0
    assert sum(j["binding"].values()) == j["failures"]
    assert seen[-1] == 200
    assert len(j["failing_members"]) == min(10, j["failures"])
    assert set(j["failing_members"][0]["parameters"]) == set(res.family.names)


def test_bad_input(family):
    with pytest.raises(ParameterError, match="max_real"):
        unstable_member_check(-1.0, 0.3, Specification(), True)
    with pytest.raises(ParameterError, match="spec"):
        member_verdicts(family, family.nominal_values()[None, :], None, spec="tight")
    with pytest.raises(ParameterError, match="n_jobs"):
        member_verdicts(family, family.nominal_values()[None, :], None, n_jobs=0)
    with pytest.raises(ParameterError, match="samples"):
        design_coverage(family, None, samples=0)
    bad = family.nominal_values()[None, :].copy()
    bad[0, 0] = np.nan
    with pytest.raises(ParameterError):
        member_verdicts(family, bad, None)
