"""Uncertain transfer functions: members against the hand-written transfer function,
combination with numbers, expressions, python-control and uncertain systems."""

import control as ct
import numpy as np
import pytest

from robust.errors import ModelStructureError, ParameterError
from uncertainty import USS, UTF, interconnect, lft_form, tf, ureal, uss

W = np.array([0.05, 0.7, 2.0, 5.3, 40.0])  # rad/s


def _params():
    m = ureal("m", 1.0, 0.6, 1.6, unit="kg")
    c = ureal("c", 0.4, 0.1, 0.9, unit="N s/m")
    k = ureal("k", 4.0, 2.0, 7.0, unit="N/m")
    return m, c, k


def _members(n=4, seed=12):
    rng = np.random.default_rng(seed)
    lo, hi = np.array([0.6, 0.1, 2.0]), np.array([1.6, 0.9, 7.0])
    return [dict(zip("mck", lo + (hi - lo) * rng.random(3))) for _ in range(n)]


def _response(sys, w=W):
    return np.array([complex(np.squeeze(sys(1j * x))) for x in w])


def _close(got, ref):
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=0.0)


@pytest.mark.parametrize(
    "values", _members(), ids=lambda v: "-".join(f"{n}{x:.3g}" for n, x in v.items())
)
def test_members_equal_the_hand_written_transfer_functions(values):
    m, c, k = _params()
    s = tf("s")
    G = k / (m * s**2 + c * s + k)  # the leading coefficient m is uncertain
    H = 1 / (s**2 + c * s + k)
    mv, cv, kv = values["m"], values["c"], values["k"]
    jw = 1j * W
    _close(_response(uss(G).at(values)), kv / (mv * jw**2 + cv * jw + kv))
    _close(_response(G.at(values)), kv / (mv * jw**2 + cv * jw + kv))
    sub = {"c": cv, "k": kv}
    _close(_response(uss(H).at(sub)), 1 / (jw**2 + cv * jw + kv))
    # a lead controller from python-control in series, and the unit-feedback loop
    K = ct.tf([2.0, 3.0], [0.05, 1.0])
    kj = (2.0 * jw + 3.0) / (0.05 * jw + 1.0)
    g = kv / (mv * jw**2 + cv * jw + kv)
    for L in (G * K, K * G, uss(G) * K, K * uss(G)):
        _close(_response(uss(L).at(values)), g * kj)
    for T in ((G * K).feedback(), (K * G).feedback(1), uss(G * K).feedback()):
        _close(_response(uss(T).at(values)), g * kj / (1 + g * kj))
    _close(_response(uss(G.feedback(K)).at(values)), g / (1 + g * kj))
    _close(_response(uss(G + K).at(values)), g + kj)
    _close(_response(uss(K - G).at(values)), kj - g)
    _close(_response(uss(2 * G - k / m).at(values)), 2 * g - kv / mv)
    _close(_response(uss(G**2).at(values)), g**2)


def test_realisation_is_the_controllable_canonical_form_divided_by_the_leading_coefficient():
    m, c, k = _params()
    s = tf("s")
    P = uss((2 * s + k) / (m * s**2 + c * s + k))
    v = {"m": 1.3, "c": 0.5, "k": 3.0}
    A, B, C, D = P.matrices(v)
    np.testing.assert_allclose(A, [[-0.5 / 1.3, -3.0 / 1.3], [1.0, 0.0]], rtol=1e-14)
    np.testing.assert_allclose(B, [[1.0], [0.0]])
    np.testing.assert_allclose(C, [[2.0 / 1.3, 3.0 / 1.3]], rtol=1e-14)
    np.testing.assert_allclose(D, [[0.0]])
    # biproper: the direct feedthrough b0/a0 and the remainder in C
    Q = uss((k * s**2 + 1) / (m * s**2 + c * s + k))
    A, B, C, D = Q.matrices(v)
    np.testing.assert_allclose(D, [[3.0 / 1.3]], rtol=1e-14)
    np.testing.assert_allclose(C, [[-3.0 / 1.3 * 0.5 / 1.3, 1 / 1.3 - 3.0 / 1.3 * 3.0 / 1.3]])


def test_lft_form_and_interconnection_with_a_state_space_system():
    m, c, k = _params()
    s = tf("s")
    G = tf(k / (m * s**2 + c * s + k), inputs="u", outputs="y")
    F = lft_form(uss(G))
    assert sorted(name for name, _ in F.blocks) == ["c", "k", "m"]
    v = {"m": 0.7, "c": 0.8, "k": 6.5}
    # the LFT closed at the member's normalised deltas gives the member
    p = uss(G).parameters
    delta = {n: (v[n] - 0.5 * (p[n].low + p[n].high)) / (0.5 * (p[n].high - p[n].low)) for n in v}
    _close(_response(F.close(delta)), _response(uss(G).at(v)))
    # joined by names with a python-control state-space controller and a summing junction
    K = ct.ss([[-20.0]], [[1.0]], [[-40.0]], [[3.0]], inputs="e", outputs="u")
    E = uss([], [], [], [[1, -1]], inputs=["r", "y"], outputs="e")
    T = interconnect([G, K, E], inputs="r", outputs="y")
    jw = 1j * W
    g = v["k"] / (v["m"] * jw**2 + v["c"] * jw + v["k"])
    kj = 3.0 - 40.0 / (jw + 20.0)
    _close(_response(T.at(v)), g * kj / (1 + g * kj))
    # an uncertain state-space system and a transfer function combine in both orders
    P = uss([[-k]], [[1]], [[1]], [[0]])
    for sys in (P * G, G * P, P + G, G.feedback(P), P.feedback(G)):
        assert isinstance(sys, USS)
    _close(_response((G * P).at(v)), g / (1j * W + v["k"]))
    _close(_response(G.feedback(P).at(v)), g / (1 + g / (1j * W + v["k"])))


def test_numbers_expressions_and_python_control_systems_on_either_side():
    m, c, k = _params()
    s = tf("s")
    G = k / (m * s**2 + c * s + k)
    assert isinstance(np.float64(2.0) * G, UTF) and isinstance(k * G, UTF)
    assert isinstance(ct.tf([1.0], [1.0, 1.0]) * G, UTF)
    assert isinstance(ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]) * G, UTF)
    mimo = ct.ss([[-1.0]], [[1.0]], [[1.0], [2.0]], [[0.0], [0.0]])
    assert isinstance(mimo * G, USS) and (mimo * G).noutputs == 2
    # k * P for an uncertain state-space P is a uss now (k as a static gain in series)
    P = uss([[-1.0]], [[1.0]], [[1.0]], [[0.0]])
    _close(_response((k * P).at({"k": 3.0})), 3.0 / (1j * W + 1.0))
    # a python-control system is lifted by tf(sys) / uss(sys), its signal names kept
    Gc = ct.tf([1.0], [1.0, 2.0], inputs="f", outputs="x")
    assert (tf(Gc).inputs, tf(Gc).outputs) == (["f"], ["x"])
    assert (uss(Gc).inputs, uss(Gc).outputs, uss(Gc).nstates) == (["f"], ["x"], 1)
    _close(_response(uss(k * tf(Gc)).at({"k": 3.0})), 3.0 / (1j * W + 2.0))
    assert uss(G).at({}).input_labels == ["u[0]"]


def test_bad_input_is_refused_with_what_was_expected():
    m, c, k = _params()
    s = tf("s")
    with pytest.raises(
        ModelStructureError, match="improper .*degree 2 over a denominator of degree 1"
    ):
        uss(s**2 / (s + k))
    with pytest.raises(ModelStructureError, match="leading coefficient .* is 0 at the nominal"):
        uss(1 / ((m - 1.0) * s + 1))
    with pytest.raises(ModelStructureError, match=r"is 0.2 at the nominal and -0.2 at m=0.6"):
        uss(1 / ((m - 0.8) * s + 1))
    with pytest.raises(ParameterError, match="the Laplace variable is 's'"):
        tf("z")
    with pytest.raises(ParameterError, match="exponent must be an integer"):
        s**0.5
    with pytest.raises(ParameterError, match="division by zero"):
        s / (s - s)
    with pytest.raises(ParameterError, match="lift a python-control system first"):
        k * ct.tf([1.0], [1.0, 1.0])
    with pytest.raises(ModelStructureError, match="continuous-time"):
        s * ct.tf([1.0], [1.0, 0.5], dt=0.1)
    with pytest.raises(ModelStructureError, match="lift it with uncertainty.uss"):
        tf(ct.ss([[-1.0]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]]))
    with pytest.raises(ParameterError, match="a matrix alone is not a system"):
        uss([[1.0, 2.0]])
    with pytest.raises(ParameterError, match="four matrices A, B, C, D"):
        uss([[1.0]], [[1.0]])
    with pytest.raises(ParameterError, match="num must be a non-empty sequence"):
        tf([[1.0, 2.0]], [1.0])
