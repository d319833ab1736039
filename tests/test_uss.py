"""Uncertain state-space systems: evaluation and combination against python-control's own."""

import control as ct
import numpy as np
import pytest

from robust.errors import ModelStructureError, ParameterError
from uncertainty import ureal, uss

W = 1j * np.array([0.3, 1.0, 2.7, 9.0])


def _plant():
    k = ureal("k", 4.0, 2.0, 6.0, unit="N/m")
    m = ureal("m", 1.0, 0.8, 1.5, unit="kg")
    c = ureal("c", 0.2, 0.1, 0.4)
    A = [[0, 1], [-k / m, -c / m]]
    return uss(A, [[0], [1 / m]], [[1, 0]], [[0]])


def _resp(sys):
    return np.array([sys(s) for s in W]).reshape(len(W), -1)


def test_nominal_at_and_batched_matrices():
    G = _plant()
    assert list(G.parameters) == ["k", "m", "c"] and G.nstates == 2
    nom = G.nominal()
    np.testing.assert_allclose(nom.A, [[0, 1], [-4.0, -0.2]])
    np.testing.assert_allclose(G.at({"m": 1.5, "k": 3.0}).B, [[0], [1 / 1.5]])
    A, B, C, D = G.matrices({"k": [2.0, 6.0], "m": [1.0, 1.0]})
    assert A.shape == (2, 2, 2) and D.shape == (2, 1, 1)
    np.testing.assert_allclose(A[:, 1, 0], [-2.0, -6.0])
    np.testing.assert_allclose(A[:, 1, 1], [-0.2, -0.2])  # c nominal


@pytest.mark.parametrize("values", [{}, {"k": 2.5, "m": 1.4, "c": 0.35}])
def test_series_parallel_feedback_agree_with_python_control(values):
    G = _plant()
    K = ct.ss([[-5.0]], [[1.0]], [[-8.0]], [[3.0]])  # a lead-like controller
    H = ct.tf([1.0], [0.1, 1.0])
    g = G.at(values)
    cases = [
        (G * K, g * K),
        (K * G, K * g),
        (G + H, ct.parallel(g, ct.ss(H))),
        (G - 2.0, ct.parallel(g, ct.ss([], [], [], [[-2.0]]))),
        (-G, -g),
        (G.feedback(K), ct.feedback(g, K)),
        (G.feedback(K, sign=1), ct.feedback(g, K, sign=1)),
        ((K * G).feedback(), ct.feedback(K * g, 1)),
        (G.feedback(G), ct.feedback(g, g)),
    ]
    for u, ref in cases:
        np.testing.assert_allclose(_resp(u.at(values)), _resp(ref), rtol=1e-10, atol=1e-12)
    # the closed loop's poles from the batched matrices, member by member
    loop = (K * G).feedback()
    A = loop.matrices({"k": [2.0, 6.0]})[0]
    for i, kv in enumerate((2.0, 6.0)):
        ref = ct.feedback(K * G.at({"k": kv}), 1).poles()
        np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(A[i])), np.sort_complex(ref))


def test_errors():
    G = _plant()
    k = ureal("k2", 1.0, 0.5, 2.0)
    with pytest.raises(ModelStructureError, match="conformal"):
        uss([[0, 1], [1, 0]], [[1]], [[1, 0]], [[0]])
    with pytest.raises(ModelStructureError, match="cannot drive"):
        G * ct.ss([], [], [], np.ones((2, 2)))
    with pytest.raises(ModelStructureError, match="algebraic loop"):
        uss([], [], [], [[k]]).feedback(uss([], [], [], [[1.0]]))
    with pytest.raises(ParameterError, match="not parameters"):
        G.at({"z": 1.0})
    with pytest.raises(ParameterError, match="sign"):
        G.feedback(1, sign=2)
    with pytest.raises(ModelStructureError, match="continuous-time"):
        G * ct.ss([[0.5]], [[1]], [[1]], [[0]], 0.01)


def test_interconnect_by_names_matches_python_control():
    from uncertainty import interconnect

    k = ureal("k", 4.0, 2.0, 6.0)
    c = ureal("c", 0.4, 0.1, 0.8)
    P = uss([[0, 1], [-k, -c]], [[0], [1]], [[1, 0]], [[0]], inputs="u", outputs="y")
    K = ct.ss(ct.tf([2.0, 1.0], [0.1, 1.0]))
    K = ct.ss(K.A, K.B, K.C, K.D, inputs=["e"], outputs=["u"], name="K")
    S = uss([], [], [], [[1.0, -1.0]], inputs=["r", "y"], outputs="e")
    T = interconnect([P, K, S], inputs="r", outputs=["y", "u"])
    assert T.inputs == ["r"] and T.outputs == ["y", "u"] and T.nstates == 3
    for vals in ({}, {"k": 2.0, "c": 0.1}, {"k": 6.0, "c": 0.8}):
        Pn = P.at(vals)
        Pn = ct.ss(Pn.A, Pn.B, Pn.C, Pn.D, inputs=["u"], outputs=["y"], name="P")
        Sn = ct.summing_junction(inputs=["r", "-y"], output="e", name="S")
        ref = ct.interconnect([Pn, K, Sn], inplist=["r"], outlist=["y", "u"])
        got = T.at(vals)
        w = np.array([0.1, 1.0, 3.0, 20.0])
        assert np.allclose(
            ct.frequency_response(got, w).complex, ct.frequency_response(ref, w).complex
        )
        assert np.sort_complex(got.poles()) == pytest.approx(np.sort_complex(ref.poles()))


def test_interconnect_solves_a_constant_algebraic_loop_and_refuses_bad_wiring():
    from uncertainty import interconnect

    a = ureal("a", 1.0, 0.5, 2.0)
    P = uss([[-a]], [[1.0]], [[1.0]], [[0.5]], inputs="u", outputs="y")
    # u = r - 0.5 y with y = x + 0.5 u: a constant loop through both feed-throughs
    G = uss([], [], [], [[1.0, -0.5]], inputs=["r", "y"], outputs="u")
    T = interconnect([P, G], inputs="r", outputs="y")
    m = T.at({"a": 2.0})
    # x' = -a x + u, u = r - 0.5 (x + 0.5 u) -> u = (r - 0.5 x) / 1.25
    assert m.A[0, 0] == pytest.approx(-2.0 - 0.5 / 1.25)
    assert m.D[0, 0] == pytest.approx(0.5 / 1.25)
    with pytest.raises(ModelStructureError, match="driven by no output"):
        interconnect([P], inputs="r", outputs="y")
    with pytest.raises(ModelStructureError, match="is no block's output"):
        interconnect([P, G], inputs="r", outputs="z")
    Pa = uss([[-1.0]], [[1.0]], [[1.0]], [[a]], inputs="u", outputs="y")
    with pytest.raises(ModelStructureError, match="depends on\\s+uncertain reals"):
        interconnect([Pa, G], inputs="r", outputs="y")
