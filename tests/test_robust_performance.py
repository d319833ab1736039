"""uncertainty.performance: robust performance margins against hand-derived exact values.

Each case is small enough that the exact margin follows on paper:

* ``1 / (s + a)``, ``a`` in ``[0.5, 3.5]`` about 2, bound 1: the DC gain ``1/a`` reaches 1
  at ``a = 1``, the scale ``(2 - 1) / 1.5 = 2/3``;
* ``1 / (s^2 + c s + 1)``, ``c = 2 zeta`` in ``[0.2, 1.8]`` about 1, bound 2: the resonant
  peak ``1 / (2 zeta sqrt(1 - zeta^2))`` reaches 2 at ``zeta = sin 15 deg``, the scale
  ``(1 - 2 sin 15 deg) / 0.8``;
* the loop ``b / (s + a)`` under unit feedback, ``a`` in ``[0.5, 1.5]`` about 1, ``b`` in
  ``[1, 3]`` about 2, bound 0.75 on ``b / (s + a + b)``: the worst corner ``(1 - k/2,
  2 + k)`` reaches ``b = 3 a`` at the scale 0.4 (two real parameters and the performance
  block: the D-G bound is not exact by theory there);
* ``1.5 / (s + a)`` (an output weight 1.5), bound 1: ``a = 1.5``, the scale 1/3.
"""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

from robust.errors import ModelStructureError, ParameterError
from uncertainty import (
    certify_performance,
    performance_system,
    robust_performance,
    scaled_bounds,
    ureal,
    uss,
)
from uncertainty.mucover import _crossings, _negative


def _lag():
    a = ureal("a", 2.0, 0.5, 3.5)
    return dict(system=uss([[-a]], [[1.0]], [[1.0]], [[0.0]])), 2.0 / 3.0


def _resonance():
    c = ureal("c", 1.0, 0.2, 1.8)
    system = uss([[0, 1], [-1, -c]], [[0], [1]], [[1, 0]], [[0]])
    return dict(system=system, gamma=2.0), (1.0 - 2.0 * math.sin(math.radians(15))) / 0.8


def _loop():
    a = ureal("a", 1.0, 0.5, 1.5)
    b = ureal("b", 2.0, 1.0, 3.0)
    system = uss([[-a]], [[b]], [[1.0]], [[0.0]])
    return dict(system=system, controller=ct.ss([], [], [], [[1.0]]), gamma=0.75), 0.4


def _weighted():
    a = ureal("a", 2.0, 0.5, 3.5)
    return dict(system=uss([[-a]], [[1.0]], [[1.0]], [[0.0]]), output_weight=1.5), 1.0 / 3.0


CASES = {"lag": _lag, "resonance": _resonance, "loop": _loop, "weighted": _weighted}


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    kwargs, exact = CASES[request.param]()
    return request.param, kwargs, exact, robust_performance(**kwargs)


def test_the_bounds_bracket_the_exact_margin_tightly(case):
    _, _, exact, res = case
    assert res.lower <= exact <= res.upper
    assert res.lower >= 0.99 * exact
    assert res.upper <= 1.01 * exact


def test_the_worst_member_breaks_the_bound_by_two_norm_algorithms(case):
    _, _, _, res = case
    w = res.worst
    assert w["norm"] >= 1.0
    assert w["grid_norm"] == pytest.approx(w["norm"], rel=1e-6)
    assert w["scale"] == pytest.approx(res.upper)


def test_members_of_the_certified_box_meet_the_bound(case):
    # independent of the certificate: random members of the box scaled to the lower bound
    _, kwargs, _, res = case
    P = performance_system(**kwargs)
    lo, hi = scaled_bounds(P, res.lower)
    rng = np.random.default_rng(7)
    rows = np.vstack([lo, hi, lo + rng.random((60, lo.size)) * (hi - lo)])
    names = list(P.parameters)
    worst = max(ct.norm(P.at(dict(zip(names, r))), "inf") for r in rows)
    assert worst < 1.0


def test_the_certificate_covers_every_frequency(case):
    _, _, _, res = case
    cert = res.certificate
    assert cert["certified"] and cert["scale"] == res.lower
    ivs = sorted(f["interval_hz"] for f in cert["frequencies"])
    assert ivs[0][0] == 0.0
    reach = 0.0
    for a, b in ivs:
        assert a <= reach * (1 + 1e-12) or a == pytest.approx(reach)
        reach = max(reach, b)
    assert math.isinf(reach)
    assert all(f["mu_upper"] < 1.0 for f in cert["frequencies"])


def test_a_scale_beyond_the_exact_margin_is_not_certified():
    kwargs, exact = _resonance()
    cert = certify_performance(performance_system(**kwargs), 1.02 * exact)
    assert not cert["certified"]
    assert "mu upper bound" in cert["reason"]
    # the resonance: the failing frequency is near the undamped 1 rad/s
    assert 0.1 < cert["frequency_hz"] < 0.2


def test_a_nominal_beyond_the_bound_gives_zero():
    a = ureal("a", 0.8, 0.5, 3.5)  # nominal gain 1.25
    res = robust_performance(uss([[-a]], [[1.0]], [[1.0]], [[0.0]]))
    assert res.lower == 0.0 and res.upper == 0.0
    assert res.nominal_norm == pytest.approx(1.25)
    assert res.worst["found_by"] == "the nominal member"


def test_the_crossings_are_where_an_eigenvalue_of_the_scaled_matrix_changes_sign():
    # F(w) = M^H D M + j (G M - M^H G) - D for fixed scalings: the pencil's imaginary
    # eigenvalues must be exactly the frequencies where F's inertia changes
    rng = np.random.default_rng(11)
    A = rng.standard_normal((5, 5))
    A -= (np.linalg.eigvals(A).real.max() + 0.3) * np.eye(5)
    B, C, D = rng.standard_normal((5, 3)), rng.standard_normal((3, 5)), rng.standard_normal((3, 3))
    R = rng.standard_normal((3, 3)) + 1j * rng.standard_normal((3, 3))
    Dsc = R @ R.conj().T + np.eye(3)
    H = rng.standard_normal((3, 3)) + 1j * rng.standard_normal((3, 3))
    Gsc = 0.3 * (H + H.conj().T)
    Dsc *= 0.5 / np.linalg.norm(D @ D.T + np.eye(3), 2)
    cross = _crossings(A, B, C, D, Dsc, Gsc)
    w = np.geomspace(1e-3, 1e3, 20001)
    MH = lambda M: M.conj().T  # noqa: E731

    def negatives(x):
        M = D + C @ np.linalg.solve(1j * x * np.eye(5) - A, B)
        F = MH(M) @ Dsc @ M + 1j * (Gsc @ M - MH(M) @ Gsc) - Dsc
        return int(np.sum(np.linalg.eigvalsh(0.5 * (F + MH(F))) < 0))

    inertia = np.array([negatives(x) for x in w])
    changes = w[1:][inertia[1:] != inertia[:-1]]
    assert changes.size == 3  # (the case is chosen to have some)
    inside = cross[(cross > w[0]) & (cross < w[-1])]
    assert inside.size == changes.size
    assert np.allclose(inside, changes, rtol=1e-3)
    # and F's sign test agrees with the inertia
    assert all(_negative(A, B, C, D, Dsc, Gsc, x) == (negatives(x) == 3) for x in w[::500])


def test_bad_input_names_the_parameter():
    kwargs, _ = _lag()
    with pytest.raises(ParameterError, match="inputs must name signals"):
        performance_system(kwargs["system"], inputs=["nope"])
    with pytest.raises(ParameterError, match="gamma must be a finite value > 0"):
        performance_system(kwargs["system"], gamma=0.0)
    k = ureal("k", 1.0, 0.5, 2.0)
    with pytest.raises(ModelStructureError, match="output_weight must not be uncertain"):
        performance_system(kwargs["system"], output_weight=uss([[-k]], [[1.0]], [[1.0]], [[0]]))
    with pytest.raises(ModelStructureError, match="expected an uncertain system"):
        performance_system(ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]))
    with pytest.raises(ParameterError, match="k must be a finite scale"):
        certify_performance(performance_system(kwargs["system"]), -1.0)
