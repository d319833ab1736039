"""Verified eigenvalue enclosures over parametric boxes (robust.analysis.eigen_enclosure).

Closed-form cases: an interval polynomial (Kharitonov's four polynomials give the largest
stable scaling of its coefficients), a mass-spring-damper whose damping crosses zero, and
an oscillator whose frequency is uncertain far beyond its damping (the real part of its
poles does not move; a certificate that treated the perturbation as complex would fail).
Random parametric matrices: every eigenvalue of every sampled member lies in the
enclosures.
"""

import math

import numpy as np
import pytest
import scipy.linalg as sla

import robust.analysis.eigen_enclosure as ee
from robust.analysis.eigen_enclosure import (
    certify_affine_family,
    enclose_eigenvalues,
    subdivide,
)


def _inside(res, lam):
    c, rr, ri = res["centre"], res["rad_re"], res["rad_im"]
    hit = (np.abs(lam.real[:, None] - c.real[None]) <= rr[None]) & (
        np.abs(lam.imag[:, None] - c.imag[None]) <= ri[None]
    )
    return hit.any(axis=1).all()


@pytest.mark.parametrize("basis", ["modal", "balanced"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_members_lie_in_the_enclosures(seed, basis):
    rng = np.random.default_rng(seed)
    n, d = 7, 3
    Ac = rng.standard_normal((n, n))
    J = rng.standard_normal((d, n, n))
    h = np.full(d, 3e-4)
    E_rad = np.full((n, n), 1e-7)
    res = enclose_eigenvalues(Ac, J, h, E_rad, basis=basis)
    assert res["ok"], "a box this small around distinct eigenvalues must verify"
    for _ in range(300):
        delta = rng.uniform(-1, 1, d)
        A = Ac + np.einsum("p,pab->ab", delta * h, J) + rng.uniform(-1, 1, (n, n)) * E_rad
        assert _inside(res, np.linalg.eigvals(A))
    # the enclosures are tight: of the order of the first-order movement
    assert res["rad_re"].max() < 50 * (res["sensitivity"].sum(axis=1).max() + 1e-6)


def _kharitonov_scale(nom):
    """Largest k with every s^3 + a2 s^2 + a1 s + a0, a_i in nom_i (1 +- k), stable."""

    def hurwitz(a0, a1, a2):
        return a0 > 0 and a1 > 0 and a2 > 0 and a2 * a1 > a0

    def ok(k):
        lo, hi = nom * (1 - k), nom * (1 + k)
        picks = [(0, 0, 1), (1, 1, 0), (1, 0, 0), (0, 1, 1)]  # the four Kharitonov polynomials
        return all(hurwitz(*[(lo, hi)[p[i]][i] for i in range(3)]) for p in picks)

    a, b = 0.0, 1.0
    while b - a > 1e-12:
        m = (a + b) / 2
        a, b = (m, b) if ok(m) else (a, m)
    return a


def test_interval_polynomial_matches_kharitonov():
    nom = np.array([8.0, 4.8, 2.4])  # (s + 2)(s^2 + 0.4 s + 4)
    k_star = _kharitonov_scale(nom)
    assert k_star == pytest.approx(0.11862458, rel=1e-6)
    A0 = np.diag([1.0, 1.0], k=1)
    J = np.zeros((3, 3, 3))
    for p in range(3):
        J[p, 2, p] = -1.0  # companion form: last row -a0, -a1, -a2
    ok, stats = certify_affine_family(A0, J, nom * (1 - 0.95 * k_star), nom * (1 + 0.95 * k_star))
    assert ok and stats["worst_check"] < 0
    for f in (1.02, 1.2):  # boxes that hold an unstable polynomial are refused
        ok, _ = certify_affine_family(A0, J, nom * (1 - f * k_star), nom * (1 + f * k_star))
        assert not ok


@pytest.mark.parametrize(
    "c_lo, certified", [(0.2, True), (0.05, True), (-0.05, False)], ids=["in", "edge", "past"]
)
def test_mass_spring_damper_damping_crossing(c_lo, certified):
    # x'' = -4 x - c x', c in [c_lo, 2]: stable exactly while c > 0
    A0 = np.array([[0.0, 1.0], [-4.0, 0.0]])
    J = np.array([[[0.0, 0.0], [0.0, -1.0]]])
    ok, _ = certify_affine_family(A0, J, [c_lo], [2.0], max_boxes=2000)
    assert ok is certified


def test_frequency_uncertainty_does_not_move_the_real_part():
    # x'' + 2 zeta w x' + w^2 x = 0 with w^2 in [0.5, 1.5] w0^2 and 2 zeta w fixed at 0.02:
    # the real part of the poles is -0.01 for every member
    A0 = np.array([[0.0, 1.0], [0.0, -0.02]])
    J = np.array([[[0.0, 0.0], [-1.0, 0.0]]])
    ok, stats = certify_affine_family(A0, J, [0.5], [1.5], decay_rate=0.005)
    assert ok
    assert stats["boxes"] < 200


def test_coalescing_eigenvalues_get_block_enclosures():
    # a double eigenvalue of the centre: the simple-eigenvalue enclosures cannot separate
    # the pair; the block route encloses both in discs about -1
    res = enclose_eigenvalues(
        np.array([[-1.0, 1.0], [0.0, -1.0]]), np.zeros((1, 2, 2)), np.zeros(1), np.zeros((2, 2))
    )
    assert res["ok"] and res["route"] == "blocks" and not res["disjoint"]
    np.testing.assert_allclose(res["centre"], [-1.0, -1.0], atol=1e-12)
    assert np.all(res["rad_re"] < 1e-6)


@pytest.mark.parametrize("delta", [1e-6, 1e-3, 1e-1], ids=["d1e-6", "d1e-3", "d1e-1"])
def test_block_discs_hold_the_eigenvalues_through_an_exceptional_point(delta):
    # A(t) = [[-1, 1], [t, -1]], |t| <= delta: eigenvalues -1 +- sqrt(t) meet at t = 0
    # (a defective double eigenvalue); the discs must grow like sqrt(delta)
    Ac = np.array([[-1.0, 1.0], [0.0, -1.0]])
    J = np.array([[[0.0, 0.0], [1.0, 0.0]]])
    res = enclose_eigenvalues(Ac, J, np.array([delta]), np.zeros((2, 2)))
    assert res["ok"] and res["route"] == "blocks"
    r = res["rad_re"].max()
    assert math.sqrt(delta) <= r <= 3 * math.sqrt(delta) + 1e-6
    for t in np.linspace(-delta, delta, 21):
        for lam in np.linalg.eigvals(Ac + t * J[0]):
            d = np.abs(lam - res["centre"])
            assert np.any(d <= res["rad_re"] * (1 + 1e-12) + 1e-15)


def test_cluster_operator_encloses_two_close_modes_and_their_neighbours():
    # two lightly damped modes 0.01 rad/s apart (the structure's pair in a tuned loop)
    # and a well separated one; a box that moves the pair by about their separation
    rng = np.random.default_rng(4)
    blocks = [(-6.5, 39.0), (-6.49, 39.01), (-1.4, 6.9)]
    D = np.zeros((6, 6))
    for i, (a, b) in enumerate(blocks):
        D[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[a, b], [-b, a]]
    T = rng.normal(size=(6, 6)) + 4 * np.eye(6)
    Ac = T @ D @ np.linalg.inv(T)
    J = 0.01 * rng.normal(size=(2, 6, 6))
    h = np.array([0.5, 0.5])
    res = enclose_eigenvalues(Ac, J, h, np.zeros((6, 6)))
    assert res["ok"] and res["route"] in ("clusters", "krawczyk")
    for d1 in np.linspace(-1, 1, 5):
        for d2 in np.linspace(-1, 1, 5):
            A = Ac + h[0] * d1 * J[0] + h[1] * d2 * J[1]
            for lam in np.linalg.eigvals(A):
                inside = (np.abs(lam.real - res["centre"].real) <= res["rad_re"] + 1e-12) & (
                    np.abs(lam.imag - res["centre"].imag) <= res["rad_im"] + 1e-12
                )
                assert inside.any()
    # the well separated pair keeps a tight enclosure
    far = np.abs(res["centre"] - complex(-1.4, 6.9)) < 0.5
    assert far.any() and res["rad_re"][far].max() < 0.2


@pytest.mark.parametrize("bad", [None, (0.9, 0.1)])
def test_subdivision_verdict_does_not_depend_on_the_wave(bad):
    # a box of the plane is "certified" when it is narrower than 1/8 in both coordinates
    # and far from the bad point; the tree of sub-boxes is the same whatever the order
    def certify(a, b):
        w = b - a
        near = bad is not None and np.all(a - 0.01 <= bad) and np.all(bad <= b + 0.01)
        small = bool(np.all(w <= 0.125 + 1e-12))
        return {
            "certified": small and not near,
            "centre_violates": small and near,
            "check": -float(w.max()),
            "split": int(np.argmax(w)),
        }

    lo, hi = np.zeros(2), np.ones(2)
    calls = []

    def many(boxes):
        calls.append(len(boxes))
        return [certify(a, b) for a, b in boxes]

    for budget in (200, 40):
        runs = [
            subdivide(certify, lo, hi, max_boxes=budget, wave=w, certify_many=many)
            for w in (1, 3, 8)
        ]
        verdicts = {ok for ok, _ in runs}
        assert len(verdicts) == 1
        if bad is None and budget == 200:
            # 64 leaves of width 1/8 and the 63 boxes above them, on every wave
            assert runs[0][0] and all(st["boxes"] == 127 for _, st in runs)
            assert all(st["certified_boxes"] == 64 for _, st in runs)
        else:
            assert not runs[0][0]
        assert all(st["boxes"] <= budget for _, st in runs)
    assert max(calls) == 8


@pytest.mark.parametrize("wave", [1, 3, 8])
def test_subdivision_stops_when_the_tree_cannot_fit_the_budget(wave):
    # the tree of the unit square down to boxes of width 1/8 holds 127 boxes: a budget of
    # 127 certifies, 126 cannot, and the search gives up once the boxes tried and those
    # waiting exceed the budget
    def certify(a, b, limit=0.125):
        w = b - a
        small = bool(np.all(w <= limit + 1e-12))
        return {
            "certified": small,
            "centre_violates": False,
            "check": -1.0,
            "split": int(np.argmax(w)),
        }

    def run(budget, limit=0.125):
        return subdivide(
            lambda a, b: certify(a, b, limit),
            np.zeros(2),
            np.ones(2),
            max_boxes=budget,
            wave=wave,
        )

    ok, st = run(127)
    assert ok and st["boxes"] == 127 and st["certified_boxes"] == 64
    for budget in (126, 100, 40):
        ok, st = run(budget)
        assert not ok and st["reason"] == "box budget"
        assert st["boxes"] <= budget and st["boxes"] + st["pending"] > budget
    # no box certifies: each failed box leaves one more waiting, so about half the budget
    # is tried before the verdict (all of it before the early stop)
    ok, st = run(400, limit=-1.0)
    assert not ok and st["certified_boxes"] == 0
    assert 200 <= st["boxes"] <= 200 + wave


@pytest.mark.parametrize("wave", [1, 8])
def test_subdivision_tries_the_larger_boxes_first(wave):
    # the right half of the square certifies in boxes of width 1/64 (a subtree of thousands
    # of boxes), the left half never: a budget of 400 cannot hold the tree, and breadth
    # first the search finds that out on the large boxes, before any of the small certified
    # ones (depth first it would dive to the certified boxes of one corner and try them)
    def certify(a, b):
        w = b - a
        small = a[0] >= 0.5 and bool(np.all(w <= 1 / 64 + 1e-12))
        return {
            "certified": small,
            "centre_violates": False,
            "check": -1.0,
            "split": int(np.argmax(w)),
        }

    ok, st = subdivide(certify, np.zeros(2), np.ones(2), max_boxes=400, wave=wave)
    assert not ok and st["reason"] == "box budget"
    assert st["certified_boxes"] == 0
    assert 200 <= st["boxes"] <= 200 + wave and st["boxes"] + st["pending"] > 400


@pytest.mark.parametrize(
    "complex_r, complex_j", [(True, False), (True, True), (False, True), (False, False)]
)
def test_weighted_product_moduli_are_the_sum_of_the_moduli_of_each_product(complex_r, complex_j):
    # sum_p h_p |R_i J_p| from products in blocks of rows and in real and imaginary parts,
    # against each product formed on its own; 81 rows of the stacked R: two blocks
    rng = np.random.default_rng(3)
    n, d = 9, 4
    R = rng.standard_normal((n, n, n)) * np.logspace(-8, 8, n)[:, None, None]
    J = rng.standard_normal((d, n, n))
    if complex_r:
        R = R + 1j * rng.standard_normal((n, n, n))
    if complex_j:
        J = J - 2j * rng.standard_normal((d, n, n))
    h = rng.uniform(0.0, 1.0, d)
    want = np.zeros((n, n, n))
    for i in range(n):
        for p in range(d):
            want[i] += h[p] * np.abs(R[i] @ J[p])
    got = ee._weighted_product_moduli(R, J, h)
    assert got.shape == (n, n, n)
    np.testing.assert_allclose(got, want, rtol=1e-13)


def test_block_norms_are_numpys_norm_of_each_block():
    """The norms of 1 x 1 blocks taken as magnitudes are numpy's norms to the bit, also for
    entries whose square under- or overflows (those are computed as numpy computes them)."""
    rng = np.random.default_rng(12)
    for _ in range(300):
        n = int(rng.integers(1, 30))
        sizes = []
        while sum(sizes) < n:
            sizes.append(int(min(rng.choice([1, 1, 1, 2, 3]), n - sum(sizes))))
        starts = np.cumsum([0, *sizes])
        F = np.abs(rng.standard_normal((n, n))) * 10.0 ** rng.uniform(-200, 200, (n, n))
        F[rng.random((n, n)) < 0.2] = 0.0
        blocks = list(zip(starts[:-1], starts[1:]))
        with np.errstate(over="ignore"):
            want = np.array([[np.linalg.norm(F[a:b, c:e]) for c, e in blocks] for a, b in blocks])
            got = ee._block_norms(F, starts)
        assert got.tobytes() == want.tobytes()


def test_pseudo_radius_stops_where_the_bisection_stands_still():
    # the bisection ends once a step changes nothing (every later step repeats it): the
    # radius is the 200-step bisection's to the bit, and it solves its equation
    def reference(eps, nu, k):
        def g(r):
            return sum(nu**m / r ** (m + 1) for m in range(k)) - 1.0 / eps

        lo, hi = eps, eps + k * max(nu, eps)
        while g(hi) > 0:
            hi *= 2
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if g(mid) > 0 else (lo, mid)
        return hi

    rng = np.random.default_rng(7)
    cases = [(1e-3, 1e-30, 2), (1e-3, 1e-12, 3), (1.0, 1e3, 4), (1e-8, 1.0, 2)]
    cases += [
        (10 ** rng.uniform(-9, 0), 10 ** rng.uniform(-12, 3), int(rng.integers(2, 6)))
        for _ in range(200)
    ]
    for eps, nu, k in cases:
        r = ee._pseudo_radius(eps, nu, k)
        assert r == reference(eps, nu, k)
        total = sum(nu**m / r ** (m + 1) for m in range(k))
        assert total <= 1.0 / eps * (1 + 1e-12)
        assert r >= eps


def test_one_by_one_blocks_take_their_entry_as_schur_form():
    # a 1 x 1 block is its own Schur form (what zgees returns) unless LAPACK scales it first
    # (entries below about 7e-139 or above 1e138): there the form comes from LAPACK
    rng = np.random.default_rng(11)
    n = 4000
    mag = 10.0 ** rng.integers(-300, 300, n)
    entries = list(rng.standard_normal(n) * mag)
    entries += list(rng.standard_normal(n) * mag + 1j * rng.standard_normal(n))
    entries += [0.0, -0.0, 1e-320, 1e-130, 1e130, 2e-140, 5e140, complex(0, 1e-200)]
    differ = 0
    for x in entries:
        B = np.array([[x]])
        T, _ = sla.schur(B, output="complex")
        ev, nu = ee._block_schur(B)
        assert ev.dtype == np.complex128 and ev.tobytes() == np.diag(T).tobytes()
        assert nu == 0.0
        differ += T[0, 0] != B[0, 0]
    assert differ > 100  # the scaled range is exercised: there the entry is not the form
    for k in (2, 3):
        B = rng.standard_normal((k, k))
        T, _ = sla.schur(B, output="complex")
        ev, nu = ee._block_schur(B)
        assert ev.tobytes() == np.diag(T).tobytes()
        assert nu == np.linalg.norm(np.triu(T, 1), 2) > 0
