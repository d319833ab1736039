"""Zero exclusion on value sets: the factorisation, the enclosures, the certified margin."""

from __future__ import annotations

import control as ct
import numpy as np
import pytest

from backhoe import default_family
from backhoe.families.batched import closed_loop_matrices, interconnection, loop_blocks
from backhoe.families.valueset import ValueSetLoop
from robust.errors import ParameterError
from uncertainty import Region, robust_margin
from uncertainty.enclosure import margin_loop
from uncertainty.margins import _perron_bound, margin_lower_bound
from uncertainty.search import _scaled_t, _to_values, worst_member


@pytest.fixture(scope="module")
def family():
    return default_family()


@pytest.fixture(scope="module")
def vloop(family):
    return ValueSetLoop(family)


def _members(family, k, n, seed):
    loop = margin_loop(family, None)
    lo_t, hi_t = _scaled_t(loop, k)
    T = lo_t + np.random.default_rng(seed).random((n, len(lo_t))) * (hi_t - lo_t)
    return T, _to_values(loop, T)


def _fr(block, i, s):
    A, B, C, D = (m[min(i, len(m) - 1)] for m in (block.A, block.B, block.C, block.D))
    return C @ np.linalg.solve(s * np.eye(A.shape[0]) - A, B) + D


def _loop_gain(family, rows, w):
    """``L(j w)`` per member from the blocks' state-space matrices (numpy), independently of
    the certificate's polynomial forms; and each member's tracking loop (its own valve)."""
    blocks = loop_blocks(family, rows, check_bounds=False)
    by = {b.name: b for b in blocks}
    kappa = -interconnection(family, blocks, None)[0, 4]
    pi, valve = by["pi"], by["valve"]
    out = np.zeros((len(rows), len(w)), complex)
    tracking = []
    for i in range(len(rows)):
        v = [m[min(i, len(m) - 1)] for m in (valve.A, valve.B, valve.C, valve.D)]
        T = ct.feedback(ct.ss(*v) * ct.ss(pi.A[0], pi.B[0], pi.C[0], pi.D[0]), 1)
        tracking.append(T)
        for j, wj in enumerate(w):
            s = 1j * wj
            h = _fr(by["human"], i, s)[0, 0]
            c = _fr(by["structure"], i, s)[1, 0]
            out[i, j] = kappa * complex(T(s)) * h * c
    return out, tracking


def test_characteristic_polynomial_factors_through_one_plus_the_loop_gain(family, vloop):
    # det(sI - A_cl) = det(sI - A_T) det(sI - A_S) det(sI - A_H) (1 + L(s)) on the axis
    T_, rows = _members(family, 0.5, 4, seed=3)
    w = np.array([0.3, 2.0, 8.0, 39.0, 120.0])
    L, tracking = _loop_gain(family, rows, w)
    A = closed_loop_matrices(family, rows, check_bounds=False)
    by = {b.name: b for b in loop_blocks(family, rows, check_bounds=False)}
    # the members' valves differ (the family varies them)
    assert len({float(x) for x in by["valve"].A[:, 3, 2]}) == len(rows)
    for i in range(len(rows)):
        T = tracking[i]
        for j, wj in enumerate(w):
            s = 1j * wj
            ratio = np.linalg.det(s * np.eye(A.shape[1]) - A[i]) / (
                np.linalg.det(s * np.eye(T.nstates) - T.A)
                * np.linalg.det(s * np.eye(4) - by["structure"].A[i])
                * np.linalg.det(s * np.eye(4) - by["human"].A[i])
            )
            assert abs(ratio - (1 + L[i, j])) <= 1e-8 * abs(ratio)
        # the certificate's own forms at degenerate cells (a point, one frequency) agree
        cells = np.repeat(T_[i][None], len(w), 0)
        m_lo, m_hi, a_lo, a_hi, _ = vloop.factors(cells, cells, w, w)
        assert np.allclose(np.exp(m_lo + 1j * a_lo), L[i], rtol=1e-9)
        assert np.all(m_hi - m_lo < 1e-9) and np.all(a_hi - a_lo < 1e-9)


def _inside_zonotope(zc, zg, zr, p):
    """Whether ``p`` lies in ``zc + sum [-1, 1] zg_i + [-zr, zr]`` (exact in the plane)."""
    normals = np.vstack([np.stack([-zg[:, 1], zg[:, 0]], axis=1), np.eye(2)])
    support = np.abs(normals @ zg.T).sum(axis=1) + np.abs(normals) @ zr
    return bool(np.all(np.abs(normals @ (p - zc)) <= support * (1 + 1e-9) + 1e-12))


@pytest.mark.parametrize("k", [0.05, 0.3])
def test_cells_enclose_every_sampled_member_and_frequency(family, vloop, k):
    # random cells (a sub-box of the scaled box times a frequency interval); members and
    # frequencies drawn inside each cell have their loop gain, computed independently from
    # the blocks, inside the cell's log-polar rectangle and zonotope
    rng = np.random.default_rng(11)
    loop = margin_loop(family, None)
    lo_t, hi_t = _scaled_t(loop, k)
    n_cells, d = 6, len(lo_t)
    a = lo_t + rng.random((n_cells, d)) * (hi_t - lo_t)
    b = lo_t + rng.random((n_cells, d)) * (hi_t - lo_t)
    c_lo, c_hi = np.minimum(a, b), np.maximum(a, b)
    w_lo = np.array([0.5, 6.0, 7.5, 30.0, 37.0, 60.0])
    w_hi = w_lo * 1.08
    m_lo, m_hi, a_lo, a_hi, _ = vloop.factors(c_lo, c_hi, w_lo, w_hi)
    zc, zg, zr, z_ok = vloop.zonotope
    assert z_ok.any()
    for i in range(n_cells):
        T = c_lo[i] + rng.random((30, d)) * (c_hi[i] - c_lo[i])
        T[0], T[1] = c_lo[i], c_hi[i]
        w = w_lo[i] + rng.random(30) * (w_hi[i] - w_lo[i])
        for t, wj in zip(T, w):
            L = _loop_gain(family, _to_values(loop, t)[None], [wj])[0][0, 0]
            u, phi = np.log(abs(L)), np.angle(L)
            assert m_lo[i] <= u <= m_hi[i]
            turns = np.round((a_lo[i] + a_hi[i]) / 2 / (2 * np.pi) - phi / (2 * np.pi))
            assert a_lo[i] <= phi + 2 * np.pi * turns <= a_hi[i]
            if z_ok[i]:
                turns = np.round((zc[i, 1] - phi) / (2 * np.pi))
                p = np.array([u, phi + 2 * np.pi * turns])
                assert _inside_zonotope(zc[i], zg[i], zr[i], p)


def test_perron_bound_covers_every_member_eigenvalue(family):
    loop = margin_loop(family, None)
    lo_t, hi_t = _scaled_t(loop, 0.5)
    w_max = _perron_bound(loop.enclosure(_to_values(loop, lo_t), _to_values(loop, hi_t), False))
    _, rows = _members(family, 0.5, 200, seed=5)
    eig = np.linalg.eigvals(closed_loop_matrices(family, rows, check_bounds=False))
    assert np.abs(eig).max() <= w_max


@pytest.fixture(scope="module")
def margin(family):
    return robust_margin(family)


#: A scale at which a wider worst-case search than the margin's own (2000 samples, 10 local
#: searches, seed 3) finds an unstable member of the default family (its 6 Hz mode; checked
#: with python-control below): the true margin lies below it.
UNSTABLE_SCALE = 0.08


def test_open_loop_margin_certified_within_a_twentieth_of_an_unstable_member(family, margin):
    # bdft margin's default: the value-set route for the family's open loop. Measured with
    # the valve's spread (15 parameters): 0.0671 certified; the margin's own search (1000
    # samples, 3 local searches) misses the 6 Hz mode below 0.094, but the certificate's
    # probe of its surviving cells finds an unstable member at 0.0702 (refined along its
    # segment to 0.07012): 0.0671 / 0.0701 = 0.957. A wider search (below) finds one at 0.08.
    # Without the valve's spread (11 parameters) it certified 0.0870 against 0.0898.
    assert margin.certificate["method"] == "valueset"
    assert margin.lower <= margin.upper < 0.075
    assert margin.lower >= 0.9 * margin.upper
    assert "zero exclusion" in margin.method["lower"]
    crit = margin.critical
    assert crit["found_by"].startswith("the lower bound's probe")
    assert crit["checked_with"].startswith("python-control")
    assert crit["violation"] > 0 and crit["scale"] == margin.upper
    row = np.array([crit["parameters"][n] for n in family.names])
    poles = ct.poles(family.member(row, check_bounds=False).system())
    assert poles.real.max() > 0
    violation, row = worst_member(family, UNSTABLE_SCALE, samples=2000, seed=3, starts=10)
    assert violation > 0
    poles = ct.poles(family.member(row, check_bounds=False).system())
    assert poles.real.max() > 0.05
    # an independent search inside the certified box (another seed, more local searches)
    # finds every member stable, with room: the worst member's largest real part
    violation, _ = worst_member(family, margin.lower, samples=600, seed=7, starts=6)
    assert violation < -1e-3


def test_the_critical_member_is_the_first_unstable_one_on_its_segment(family, margin):
    # the upper bound is not quantised: 0.1 % closer to the nominal along the critical
    # member's segment the member is stable, and the critical member's own scale is the bound
    from uncertainty.search import _coords, _member_scale, _to_values

    logs, tn, *_ = _coords(family)
    row = np.array([margin.critical["parameters"][n] for n in family.names])
    assert _member_scale(family, row) == pytest.approx(margin.upper, rel=1e-12)
    t = np.where(logs, np.log(row), row)
    inside = _to_values(family, (tn + (1 - 2e-3) * (t - tn))[None])[0]
    assert ct.poles(family.member(inside, check_bounds=False).system()).real.max() < 0


def test_value_sets_refuse_a_box_holding_an_unstable_member(family, margin):
    # past the critical member's scale the box holds an unstable member: never certified
    low, cert = margin_lower_bound(
        family,
        k_hint=margin.critical["scale"] * 1.02,
        max_boxes=40,
        ladder=0,
        iterations=0,
        method="valueset",
    )
    assert low == 0.0 and not cert["history"][-1]["certified"]
    # the probe of the surviving cells found an unstable member, inside the box tried
    last = cert["history"][-1]
    assert last["max_real"] > 0
    assert last["unstable_scale"] <= margin.critical["scale"] * 1.02 * (1 + 1e-9)
    member = family.member(np.array(last["unstable_member"]), check_bounds=False)
    assert ct.poles(member.system()).real.max() > 0


def test_value_sets_apply_only_to_the_open_loop_and_the_half_plane(family):
    assert ValueSetLoop.applies(family)
    assert not ValueSetLoop.applies(default_family("literal"))
    with pytest.raises(ParameterError, match="physical human"):
        ValueSetLoop(default_family("literal"))
    K = ct.ss([[-10.0]], [[1.0]], [[1.0]], [[0.0]], inputs="x", outputs="f")
    with pytest.raises(ParameterError, match="compensator"):
        margin_lower_bound(family, controller=K, method="valueset", ladder=0, iterations=0)
    with pytest.raises(ParameterError, match="half-plane"):
        margin_lower_bound(
            family, region=Region(decay_rate=0.1), method="valueset", ladder=0, iterations=0
        )
    # where the route does not apply, auto takes mu on the loop's LFT (the family gives its
    # uncertain system)
    _, cert = margin_lower_bound(
        family, region=Region(decay_rate=0.1), k_hint=0.01, ladder=0, iterations=0, max_boxes=8
    )
    assert cert["method"] == "mu"
