"""Synthesis for an uncertain plant written as a transfer-function expression, through the
public API, and the controller checked independently: closed-loop poles of the nominal and
of seeded members, the weighted closed-loop norm by two norm algorithms, the robust margin."""

import control as ct
import numpy as np
import pytest

from robust import hinf_norm
from robust.errors import ModelStructureError, ParameterError
from uncertainty import (
    Region,
    UncertainPlant,
    augw,
    hinfsyn_members,
    hinfsyn_nominal,
    lft_form,
    robust_margin,
    robust_performance,
    sample,
    tf,
    ureal,
    uss,
    validate_family,
)

W1 = ct.tf([0.5, 1.0], [1.0, 0.01])  # |S| below 1/100 at DC, up to 2 at high frequency
W2 = 0.1  # the control effort
W = np.array([0.01, 0.3, 1.0, 2.2, 7.0, 60.0])  # rad/s


def _plant():
    """A mass on a spring and a damper, force to position, each uncertain."""
    m = ureal("m", 1.0, 0.8, 1.25, unit="kg")
    c = ureal("c", 0.2, 0.1, 0.3, unit="N s/m")
    k = ureal("k", 4.0, 3.0, 5.0, unit="N/m")
    s = tf("s")
    return k / (m * s**2 + c * s + k)


def _freq(sys, w=W):
    return np.stack([np.asarray(sys(1j * x)).reshape(sys.noutputs, sys.ninputs) for x in w])


def _norms(cl):
    """The H-infinity norm by Bruinsma-Steinbuch (robust) and by SLICOT's AB13DD."""
    return hinf_norm(cl), float(ct.norm(cl, p="inf"))


@pytest.mark.filterwarnings("ignore:connect\\(\\) is deprecated:FutureWarning")  # control.augw's
def test_augw_members_are_python_controls_augw_of_the_member():
    G = _plant()
    P = augw(G, w1=W1, w2=W2, w3=ct.tf([1.0, 0.5], [0.01, 1.0]))
    assert (P.w, P.u, P.z, P.y) == (("w",), ("u",), ("z1", "z2", "z3"), ("v",))
    for values in ({}, {"m": 1.2, "c": 0.12, "k": 3.3}):
        g = G.at(values)
        ref = ct.augw(
            ct.ss(g), ct.ss(W1), ct.ss([], [], [], [[W2]]), ct.ss(ct.tf([1.0, 0.5], [0.01, 1.0]))
        )
        got, want = _freq(P.at(values).sys), _freq(ref)
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


def test_nominal_synthesis_from_a_transfer_function_expression():
    G = _plant()
    P = augw(G, w1=W1, w2=W2)
    res = hinfsyn_nominal(P)
    K = res.K
    # nominal closed loop, G.feedback(K) (u = K (w - y)): poles strictly in the left half-plane
    nominal_poles = uss(G).feedback(K).nominal().poles()
    assert nominal_poles.real.max() < -1e-3
    # the weighted closed loop at the nominal, by two norm algorithms, from the plant and
    # from the uncertain closed loop's nominal member
    bb, ab13dd = _norms(P.nominal().closed_loop(K))
    assert bb == pytest.approx(res.gamma, rel=1e-6)
    assert ab13dd == pytest.approx(res.gamma, rel=1e-5)
    assert _norms(P.closed_loop(K).nominal())[0] == pytest.approx(res.gamma, rel=1e-6)
    assert res.gamma <= res.gamma_bound * (1 + 1e-6) and res.gamma < 1.0
    # seeded members: the uncertain loop's poles are those of the hand-written member's
    # loop (python-control). The nominal design cancels the plant's lightly damped poles,
    # so members far from the nominal need not be stable: hinfsyn_members is for them.
    members = sample(G, 6, seed=7)
    for i in range(len(members)):
        v = members.row(i)
        ref = ct.feedback(ct.ss(ct.tf([v["k"]], [v["m"], v["c"], v["k"]])), K).poles()
        got = uss(G).feedback(K).at(v).poles()
        np.testing.assert_allclose(np.sort_complex(got), np.sort_complex(ref), rtol=1e-7)


def test_multi_model_synthesis_on_sampled_members_and_its_robust_margin():
    G = _plant()
    P = augw(G, w1=W1, w2=W2)
    members = sample(P, 3, seed=3)
    res = hinfsyn_members(P, members, max_iter=3)
    K = res.K
    assert len(res.gammas) == 4  # the nominal, then the three members
    plants = [P.nominal()] + P.members(members)
    for gp, gamma in zip(plants, res.gammas):
        cl = gp.closed_loop(K)
        assert np.linalg.eigvals(cl.A).real.max() < 0
        bb, ab13dd = _norms(cl)
        assert bb == pytest.approx(gamma, rel=1e-6)
        assert ab13dd == pytest.approx(gamma, rel=1e-5)
        assert bb <= res.gamma_bound * (1 + 1e-6)
    fresh = sample(G, 2000, seed=11)
    assert validate_family(uss(G), fresh, controller=K).fraction_stable == 1.0
    margin = robust_margin(uss(G), controller=K, region=Region(), samples=200, seed=1, max_boxes=50)
    assert 0.0 < margin.lower <= margin.upper
    assert margin.upper > 1.0  # the search finds no unstable member in the box itself
    # robust performance of the weighted closed loop (||[W1 S; W2 K S]|| < 1), certified by
    # mu on its reduced LFT (m, k and c once or twice each, not 9 and 8 times): a tight
    # bracket, the worst member's exact norm at the upper end
    cl = P.closed_loop(K)
    assert lft_form(cl).blocks == [("c", 1), ("m", 2), ("k", 1)]
    perf = robust_performance(cl, gamma=1.0)
    assert perf.lower is not None and 0.5 < perf.lower <= perf.upper <= 1.01 * perf.lower
    assert hinf_norm(cl.at(perf.worst["parameters"])) >= 1.0 - 1e-6


def test_bad_input_names_the_parameter():
    G = _plant()
    with pytest.raises(ModelStructureError, match="at least one weight"):
        augw(G)
    with pytest.raises(ModelStructureError, match="w1 must have one input and one output"):
        augw(G, w1=ct.ss([[-1.0]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]]))
    with pytest.raises(ModelStructureError, match="augw: G: .*improper"):
        augw(G * tf("s") ** 3, w1=W1)
    with pytest.raises(ParameterError, match="plant must be an uncertain generalized plant"):
        hinfsyn_nominal(uss(G))
    P = augw(G, w1=W1, w2=W2)
    with pytest.raises(ParameterError, match="sample names .* must be the plant's parameters"):
        P.members(sample([ureal("q", 1.0, 0.5, 2.0).parameters["q"]], 2))
    with pytest.raises(ModelStructureError, match=r"outputs \['z2'\] are in no partition"):
        UncertainPlant(P.sys, w=("w",), u=("u",), z=("z1",), y=("v",))
    with pytest.raises(ModelStructureError, match="K must map the 1 measurements to the 1"):
        P.closed_loop(ct.ss([], [], [], [[1.0, 2.0]]))
