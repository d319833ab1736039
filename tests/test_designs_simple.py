import numpy as np
import pytest

from backhoe import default_family
from backhoe.analysis.loops import loop_poles
from designs.cancellation import cancellation_controller
from designs.evaluate import evaluate_design, frequency_metrics, intended_motion
from designs.virtual_damping import virtual_damping_controller
from designs.workspace import design_workspace
from uncertainty import sample


@pytest.fixture(scope="module")
def family():
    return default_family()


@pytest.fixture(scope="module")
def members(family):
    return sample(family.parameters, 300, method="lhs", seed=11)


def test_cancellation_is_exact_on_the_member_it_is_built_for(family):
    # the nominal operator on a machine with 3x the cab-motion gain (on its tyres): the
    # uncompensated loop has four unstable poles
    member = family.member({"struct.k_s": family.parameter("struct.k_s").high})
    K = cancellation_controller(member)
    assert loop_poles(member).n_unstable == 4
    assert loop_poles(member, controller=K).stable
    sup, trk = frequency_metrics(member, K)
    assert sup < 1e-6 and trk < 1e-6


def test_virtual_damping_damps_the_arm(family):
    # with the handle rendering damping b, the hand's arm mode gains damping b/(2 sqrt(k m))
    import control as ct

    nominal = family.member(family.nominal_values())
    p = nominal.human.params
    H = nominal.human.system()
    per_m = nominal.handle_units_per_m(signed=True)
    K = virtual_damping_controller(nominal, 20.0, 0.0, rolloff_hz=1e4)
    # close f = K(x) with x = per_m * h_m = per_m * h / h_gain on the human alone
    hx = ct.ss([], [], [], [[per_m / p.h_gain]], inputs="h", outputs="x")
    cl = ct.interconnect([H, hx, K], inputs="c", outputs="h")
    z_open = min(-np.real(H.poles()) / np.abs(H.poles()))
    z_closed = min(
        -np.real(cl.poles()[np.abs(cl.poles()) < 1e3])
        / np.abs(cl.poles()[np.abs(cl.poles()) < 1e3])
    )
    assert z_closed > z_open + 0.05


def test_workspace_search_reports_the_fraction_honestly(family, members):
    res = design_workspace(family, members, factors=(1.0, 2.0, 10.0), refine=3)
    assert res.fraction_stable[0] < res.fraction_stable[-1]
    assert res.stabilises_family == (max(res.fraction_stable) == 1.0)


def test_evaluation_of_virtual_damping_reports_force(family, members):
    nominal = family.member(family.nominal_values())
    K = virtual_damping_controller(nominal, 20.0, 100.0)
    ev = evaluate_design("vd", family, members, K)
    assert ev.seed == 11 and ev.samples == 300 and ev.order == 1
    assert 0.0 <= ev.fraction_stable <= 1.0
    assert ev.peak_force_n > 0 and ev.rms_force_n > 0
    assert ev.force_within_limits == (ev.peak_force_n <= 3.3 and ev.rms_force_n <= 0.88)


def test_intended_motion_is_seeded_and_scaled():
    t = np.arange(0, 10, 1e-3)
    a = intended_motion(t, 2.0, 2.0, seed=3)
    b = intended_motion(t, 2.0, 2.0, seed=3)
    c = intended_motion(t, 2.0, 2.0, seed=4)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert np.sqrt(np.mean(a**2)) == pytest.approx(2.0 / np.sqrt(2), rel=1e-12)
    # the noise through the intent filter, as control.forced_response computes it
    import control as ct

    from backhoe.synthesis.forcefb import intent_filter

    w = np.random.default_rng(3).standard_normal(t.size)
    ref = np.ravel(ct.forced_response(intent_filter(2.0, 1.0), T=t, U=w).outputs)
    ref *= 2.0 / np.sqrt(2) / np.sqrt(np.mean(ref**2))
    np.testing.assert_allclose(a, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
