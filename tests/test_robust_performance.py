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


# -- a bound over a band ------------------------------------------------------------------------
# ``1 / (s + a)`` has the gain ``1 / sqrt(w^2 + a^2)``, largest at the band's lowest
# frequency ``w1``: the bound 1 holds on ``[w1, inf)`` while ``a^2 > 1 - w1^2``.
# * ``a`` in ``[0.5, 3.5]`` about 2, from 0.6 rad/s: ``a > 0.8``, the scale 0.8 (not the 2/3
#   of every frequency);
# * ``a`` in ``[-0.5, 2.5]`` about 1, from 2 rad/s: the gain is below 1/2 on every stable
#   member, so the margin is the box's stability, ``a > 0``, the scale 2/3, which only the
#   stability certificate can give.
BAND_CASES = {
    "from 0.6 rad/s": (0.6, 2.0, 0.5, 3.5, 0.8),
    "from 2 rad/s": (2.0, 1.0, -0.5, 2.5, 2 / 3),
}


def _band_lag(nominal, low, high):
    a = ureal("a", nominal, low, high)
    return dict(system=uss([[-a]], [[1.0]], [[1.0]], [[0.0]]))


@pytest.fixture(scope="module", params=sorted(BAND_CASES))
def band_case(request):
    w1, nominal, low, high, exact = BAND_CASES[request.param]
    band = (w1 / (2 * math.pi), math.inf)
    kwargs = _band_lag(nominal, low, high)
    return band, exact, (nominal, low, high), robust_performance(**kwargs, band_hz=band)


def test_a_band_bound_is_bracketed_tightly_around_its_exact_margin(band_case):
    band, exact, (nominal, low, _), res = band_case
    assert res.lower <= exact <= res.upper
    assert res.lower >= 0.99 * exact
    assert res.upper <= 1.01 * exact
    # the worst member: the box's low end at the upper bound, its band peak by two algorithms
    w = res.worst
    assert w["parameters"]["a"] == pytest.approx(nominal - (nominal - low) * res.upper, rel=1e-9)
    if math.isfinite(w["norm"]):
        assert w["norm"] >= 1.0
        assert w["grid_norm"] == pytest.approx(w["norm"], rel=1e-6)
        assert w["frequency_hz"] == pytest.approx(band[0], rel=1e-6)
    else:
        assert w["rightmost_pole"].real >= -1e-9


def test_a_band_certificate_covers_the_band_and_the_box_stability_every_frequency(band_case):
    band, _, _, res = band_case
    cert = res.certificate
    assert cert["certified"]
    ivs = sorted(f["interval_hz"] for f in cert["frequencies"])
    assert ivs[0][0] <= band[0] * (1 + 1e-12)
    reach = ivs[0][0]
    for a, b in ivs:
        assert a <= reach * (1 + 1e-12)
        reach = max(reach, b)
    assert math.isinf(reach)
    stab = sorted(f["interval_hz"] for f in cert["stability"]["frequencies"])
    assert cert["stability"]["certified"] and stab[0][0] == 0.0
    assert all(f["mu_upper"] < 1.0 for f in cert["frequencies"] + cert["stability"]["frequencies"])


def test_members_of_a_certified_band_box_meet_the_bound_on_a_dense_grid(band_case):
    band, _, box, res = band_case
    P = performance_system(**_band_lag(*box))
    lo, hi = scaled_bounds(P, res.lower)
    w = np.geomspace(2 * math.pi * band[0], 1e4, 2000)
    for a in np.concatenate([lo, hi, np.linspace(lo[0], hi[0], 30)]):
        assert a > 0  # stable
        assert np.max(1.0 / np.sqrt(w**2 + a**2)) < 1.0


def test_a_band_needs_a_siso_map_and_a_valid_band():
    kwargs, _ = _lag()
    with pytest.raises(ParameterError, match="band_hz must satisfy 0 <= low < high"):
        robust_performance(**kwargs, band_hz=(2.0, 1.0))
    with pytest.raises(ParameterError, match="band_hz must be a pair"):
        certify_performance(performance_system(**kwargs), 0.5, band_hz=3.0)
    a = ureal("a", 2.0, 0.5, 3.5)
    two = uss([[-a]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]])
    with pytest.raises(ModelStructureError, match="single-input single-output"):
        robust_performance(two, band_hz=(0.0, 1.0))
    with pytest.raises(ParameterError, match="fractions must be numbers in"):
        robust_performance(**kwargs, fractions=(1.5,))
