"""Robust margins of uncertain systems (``uncertainty.robust_margin`` on a ``uss``) against
margins derived by hand.

Each case is a small system whose margin follows from a closed-form condition (Routh-Hurwitz,
the real part or damping ratio of a second-order pair) worked out below; the certified
lower bound must hold at most the exact margin and at least 0.9 of it, the upper bound at
least the exact margin and within 1.5e-3 of it (the critical member's scale is refined along
its segment from the nominal to 1e-3, not a step of the search's bisection), and the
critical member must break the region. The scale ``k`` moves each parameter from its
nominal towards its range's ends: ``low(k) = nominal - k (nominal - low)``,
``high(k) = nominal + k (high - nominal)`` (in log coordinates for log-uniform parameters).
"""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from scipy.optimize import brentq

from robust.errors import ModelStructureError, ParameterError
from uncertainty import (
    Region,
    margin_lower_bound,
    robust_margin,
    sample,
    scaled_bounds,
    ureal,
    uss,
    validate_family,
    worst_member,
)
from uncertainty.boxcert import certify_box
from uncertainty.testing import assert_robust_margin


def _check(res, exact):
    assert res.lower <= exact <= res.upper
    assert res.lower >= 0.9 * exact, (res.lower, exact)
    assert res.upper <= (1 + 1.5e-3) * exact, (res.upper, exact)
    assert res.critical is not None and res.critical["violation"] > 0
    assert res.critical["checked_with"] == "python-control poles of the member system"


def _second_order(a1, a0):
    return uss([[0, 1], [-a0, -a1]], [[0], [1]], [[1, 0]], [[0]])


def test_face_interior_worst_member():
    # s^2 + (c - q (2 - q)) s + 4: stable iff c > q (2 - q). Over q in [1 - k, 1 + k] the
    # product q (2 - q) is largest at q = 1, the nominal, inside the range: the worst member
    # lies inside a face of the box, not at a vertex. c(k) >= 1.5 - k, so the loop breaks
    # where 1.5 - k = 1: k_m = 0.5.
    q = ureal("q", 1.0, 0.0, 2.0)
    c = ureal("c", 1.5, 0.5, 2.5)
    res = robust_margin(_second_order(c - q * (2 - q), 4.0))
    _check(res, 0.5)
    assert res.critical["parameters"]["q"] == pytest.approx(1.0, abs=0.05)


def test_routh_boundary_with_asymmetric_ranges():
    # s^3 + p s^2 + 3 s + r: stable iff p, r > 0 and 3 p > r (Routh). p(k) >= 2 - 0.5 k,
    # r(k) <= 2 + 6 k: 3 (2 - 0.5 k) = 2 + 6 k gives k_m = 8 / 15.
    p = ureal("p", 2.0, 1.5, 4.0)
    r = ureal("r", 2.0, 1.0, 8.0)
    A = [[0, 1, 0], [0, 0, 1], [-r, -3.0, -p]]
    res = robust_margin(uss(A, [[0], [0], [1]], [[1, 0, 0]], [[0]]))
    _check(res, 8 / 15)


def test_rational_entries_in_log_coordinates():
    # m x'' + c x' + 4 x = 0 with m log-uniform in [0.5, 2] (nominal 1): m(k) <= 2^k; c(k) >=
    # 1 - 0.5 k. The poles are complex on the box (4 / m > (c / 2m)^2) with real part
    # -c / (2 m); a decay rate of 0.2 needs c > 0.4 m: 1 - 0.5 k = 0.4 * 2^k.
    m = ureal("m", 1.0, 0.5, 2.0, distribution="loguniform")
    c = ureal("c", 1.0, 0.5, 1.5)
    exact = brentq(lambda k: 1 - 0.5 * k - 0.4 * 2.0**k, 0.0, 2.0)
    res = robust_margin(_second_order(c / m, 4.0 / m), region=Region(decay_rate=0.2))
    _check(res, exact)


def test_damping_region():
    # s^2 + 2 z w s + w^2, w in [pi, 4 pi] rad/s (0.5-2 Hz, inside the band), z in
    # [0.2, 0.8] about 0.5: the damping ratio is z, at least 0.3 while 0.5 - 0.3 k >= 0.3,
    # k_m = 2 / 3 (the frequency does not matter).
    w = ureal("w", 2 * math.pi, math.pi, 4 * math.pi)
    z = ureal("z", 0.5, 0.2, 0.8)
    region = Region(min_damping=0.3, band_hz=(0.1, 10.0))
    res = robust_margin(_second_order(2 * z * w, w**2), region=region)
    _check(res, 2 / 3)
    # the automatic method takes mu (the cone's edge over the band, and the band's edges)
    assert res.certificate["method"] == "mu"
    # the eigenvalue enclosures certify the band's region itself
    eig = robust_margin(_second_order(2 * z * w, w**2), region=region, method="eigenvalues")
    _check(eig, 2 / 3)
    assert eig.certificate["method"] == "eigenvalues"


def test_uncertain_plant_closed_by_a_python_control_controller():
    # g / (s (s + 1)) with the lag 1 / (s + 1) in its feedback path: s^3 + 2 s^2 + s + g,
    # stable iff 0 < g < 2 (Routh); g(k) <= 1 + 2 k gives k_m = 0.5.
    g = ureal("g", 1.0, 0.5, 3.0)
    plant = uss([[0, 1], [0, -1]], [[0], [g]], [[1, 0]], [[0]])
    controller = ct.ss(ct.tf([1.0], [1.0, 1.0]))
    res = robust_margin(plant, controller=controller)
    _check(res, 0.5)
    assert res.critical["parameters"]["g"] == pytest.approx(2.0, rel=0.02)
    # the member the margin reports is the python-control loop's
    member = ct.feedback(plant.at({"g": res.critical["parameters"]["g"]}), controller)
    assert np.sort_complex(ct.poles(member)) == pytest.approx(
        np.array([p["re"] + 1j * p["im"] for p in res.to_json()["critical"]["poles"]]), abs=1e-9
    )


def test_scaled_bounds_and_worst_member_of_a_system():
    m = ureal("m", 1.0, 0.5, 2.0, distribution="loguniform")
    c = ureal("c", 1.0, 0.5, 1.5)
    G = _second_order(c / m, 4.0 / m)
    lo, hi = scaled_bounds(G, 0.5)
    assert list(G.parameters) == ["m", "c"]  # in the order they first appear
    assert lo == pytest.approx([2**-0.5, 0.75]) and hi == pytest.approx([2**0.5, 1.25])
    v, row = worst_member(G, 1.0, region=Region(decay_rate=0.2))
    # the worst member has c low and m high: real part -0.5 / 4 = -0.125, violation 0.075
    assert v == pytest.approx(0.075, abs=1e-6)
    assert row == pytest.approx([2.0, 0.5])


def test_validation_of_a_system_counts_the_unstable_members():
    # s^2 + c s + 1 with c uniform in [-1, 3]: unstable exactly when c <= 0, a quarter
    c = ureal("c", 1.0, -1.0, 3.0)
    G = _second_order(c, 1.0)
    members = sample(list(G.parameters.values()), 20_000, method="mc", seed=3)
    res = validate_family(G, members)
    expected = float(np.mean(members.values[:, 0] >= 0))
    assert res.fraction_stable == pytest.approx(expected, abs=1e-12)
    assert 0.24 < 1 - res.fraction_stable < 0.26
    assert res.worst["c"] == pytest.approx(-1.0, abs=1e-3)
    with pytest.raises(ParameterError, match="sample names"):
        validate_family(_second_order(ureal("d", 1, 0, 2), 1.0), members)


def test_bad_systems_are_refused_with_the_reason():
    with pytest.raises(ParameterError, match="no uncertain real"):
        robust_margin(uss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]))
    with pytest.raises(ParameterError, match="expected an uncertain system .* or a family"):
        robust_margin(ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]))
    g = ureal("g", 1.0, 0.5, 2.0)
    with pytest.raises(ModelStructureError, match="no state"):
        robust_margin(uss([], [], [], [[g]]))
    # a divisor whose range reaches 0 on the box
    d = ureal("d", 1.0, -1.0, 2.0)
    res = certify_box(_second_order(1.0 / d, 1.0), [-1.0], [2.0])
    assert not res["certified"] and res["centre_violates"]
    assert "contains 0 on the box d in [-1, 2]" in res["reason"]
    # ... which the margin never meets: members with d < 0 are unstable, and the margin
    # stops short of the box where the range of d reaches 0 (k = 0.5)
    res = robust_margin(_second_order(1.0 / d, 1.0))
    assert res.lower <= 0.5 <= res.upper <= 0.505 and res.lower > 0.45


def test_a_nominal_outside_the_region_has_both_bounds_zero():
    # the nominal itself violates: no scale is certified and the critical member is the
    # nominal, at scale 0 (not -0.0, not a step of the search)
    a = ureal("a", 0.5, -1.0, 1.0)
    res = robust_margin(uss([[a]], [[1.0]], [[1.0]], [[0.0]]), samples=50)
    assert res.lower == 0.0 and res.upper == 0.0 and math.copysign(1.0, res.upper) == 1.0
    assert res.critical["parameters"]["a"] == pytest.approx(0.5, abs=1e-12)
    assert res.critical["violation"] == pytest.approx(0.5, abs=1e-9)


def test_the_mu_route_certifies_a_decay_rate_margin():
    # s^2 + c s + 4, c in [0.2, 3] about 1: decays faster than 0.3 1/s while c > 0.6, the
    # scale 0.5; the state matrix's LFT shifted by 0.3, mu below 1 at every frequency
    c = ureal("c", 1.0, 0.2, 3.0)
    G = uss([[0, 1], [-4, -c]], [[0], [1]], [[1, 0]], [[0]])
    res = robust_margin(G, region=Region(decay_rate=0.3), method="mu")
    _check(res, 0.5)
    cert = res.certificate
    assert cert["method"] == "mu" and "Popov" in res.method["lower"]
    last = [h for h in cert["history"] if h["certified"]][-1]
    assert last["frequencies"] >= 1 and last["peak_mu_upper"] < 1.0
    # just above the exact margin (c down to 0.584) the cover meets the frequency where mu's
    # bound reaches 1 (the shifted pair crosses the axis near 2 rad/s): not certified
    with pytest.raises(AssertionError, match="out of reach") as err:
        assert_robust_margin(G, region=Region(decay_rate=0.3), at_least=0.52, method="mu")
    assert "main loop theorem" in str(err.value)


@pytest.mark.parametrize(
    "f_hz, low_hz, high_hz, edge_hz",
    [(12.0, 8.0, 16.0, 10.0), (0.3, 0.1, 0.7, 0.5)],
    ids=["from-above", "from-below"],
)
def test_the_mu_route_certifies_damping_asked_in_a_band(f_hz, low_hz, high_hz, edge_hz):
    # s^2 + 2 z w s + w^2 with z = 0.05 and w/(2 pi) in [low, high] Hz about f: damping 0.1
    # asked in 0.5-10 Hz only. The centre's poles lie outside the band, less damped than
    # it asks; a member breaks the region when its damped frequency w sqrt(1 - z^2) reaches
    # the band's edge (by the band's edge |Im s| = w0, not by the cone): w = edge / sqrt(1 -
    # z^2), at the scale |w - f| / (f - low) (or high - f). The cone of every pole would
    # certify nothing (the centre is outside it).
    z = 0.05
    w = ureal("w", 2 * math.pi * f_hz, 2 * math.pi * low_hz, 2 * math.pi * high_hz)
    region = Region(min_damping=0.1, band_hz=(0.5, 10.0))
    crossing = edge_hz / math.sqrt(1 - z**2)
    side = (f_hz - low_hz) if crossing < f_hz else (high_hz - f_hz)
    exact = abs(crossing - f_hz) / side
    res = robust_margin(_second_order(2 * z * w, w**2), region=region, method="mu")
    _check(res, exact)
    assert res.certificate["method"] == "mu"
    every = Region(min_damping=0.1, band_hz=(0.0, np.inf))
    assert robust_margin(_second_order(2 * z * w, w**2), region=every, method="mu").lower == 0


def test_the_mu_route_certifies_the_family_loop():
    # the default family's open loop (15 parameters, 30 repeated real channels in its
    # reduced LFT, gains from 1e-3 to 1e4 between channels): before the channels were
    # balanced the D-G LMI found no feasible point and the bound stayed at the largest
    # singular value (18.6 at 0 Hz for the workspace design at scale 0.05), so mu certified
    # nothing. The value sets certify 0.0671 of the box and an unstable member lies at
    # 0.0701; mu certifies 0.03 (each certified box is also checked on seeded members)
    from backhoe import default_family

    cert = assert_robust_margin(default_family(), at_least=0.03, method="mu")
    stats = cert["certified_stats"]
    assert stats["method"] == "mu" and stats["frequencies"] >= 1
    assert stats["peak_mu_upper"] < 1.0
    assert sum(b[0] for b in stats["blocks"]) == 30


def test_the_mu_route_on_an_observer_based_noncollocated_loop():
    # two unit masses on a spring k in [0.5, 2] about 1, lightly damped (0.01), force on the
    # first, position of the second measured, closed by an observer-based controller (LQR
    # and Kalman gains) designed for the nominal spring. The exact margin is the smaller of
    # the scales where a stiffer and a softer spring first destabilise the loop, each found
    # by a root of the closed loop's spectral abscissa along k.
    k = ureal("k", 1.0, 0.5, 2.0)
    c = 0.01
    A = [[0, 0, 1, 0], [0, 0, 0, 1], [-k, k, -c, c], [k, -k, c, -c]]
    S = uss(A, [[0], [0], [1], [0]], [[0, 1, 0, 0]], [[0]])
    P0 = S.nominal()
    Kc, _, _ = ct.lqr(P0.A, P0.B, np.diag([1, 1, 0.1, 0.1]), [[1.0]])
    L, _, _ = ct.lqe(P0.A, np.eye(4), P0.C, np.eye(4) * 0.1, [[0.01]])
    K = ct.ss(P0.A - P0.B @ Kc - L @ P0.C, L, Kc, [[0.0]])
    closed = S.feedback(K)

    def abscissa(kv):
        return float(np.linalg.eigvals(closed.at({"k": kv}).A).real.max())

    up = brentq(abscissa, 1.0 + 1e-6, 2.0)  # 1.427
    scales = [up - 1.0]
    grid = np.linspace(1.0, 0.5, 201)
    bad = [x for x in grid if abscissa(x) >= 0]
    if bad:
        scales.append((1.0 - brentq(abscissa, bad[0], bad[0] + 0.0025)) / 0.5)
    exact = min(scales)
    # the automatic method for an uncertain system's loop in the open left half-plane
    lower, cert = margin_lower_bound(S, controller=K)
    assert cert["method"] == "mu"
    assert 0.9 * exact <= lower <= exact, (lower, exact)


def test_a_margin_prints_as_one_readable_line():
    c = ureal("c", 1.0, 0.2, 3.0)
    res = robust_margin(_second_order(c, 4.0), region=Region(decay_rate=0.3))
    text = str(res)
    assert "\n" not in text and len(text) < 200
    assert text.startswith(f"robust margin in [{res.lower:.4g}, {res.upper:.4g}] for the real")
    assert "critical member c=0.5996" in text and "rightmost pole -0.2998" in text


def test_the_mu_route_certifies_a_damping_ratio_of_every_pole():
    # the damping cone by mu: s^2 + 2 z w s + w^2 as in test_damping_region, the damping
    # asked of every pole (the default band of an uncertain system): k_m = 2 / 3 again
    w = ureal("w", 2 * math.pi, math.pi, 4 * math.pi)
    z = ureal("z", 0.5, 0.2, 0.8)
    res = robust_margin(_second_order(2 * z * w, w**2), region=Region(min_damping=0.3))
    _check(res, 2 / 3)
    assert res.certificate["method"] == "mu" and "rotated by the cone" in res.method["lower"]


@pytest.mark.parametrize("zeta, binding", [(0.2, "damping"), (0.1, "decay")])
def test_the_mu_route_certifies_a_decay_rate_and_a_damping_ratio_together(zeta, binding):
    # m x'' + c x' + 4 x = 0, m log-uniform in [0.5, 2], c in [0.5, 1.5]: complex poles with
    # real part -c / (2 m) and damping ratio c / (4 sqrt(m)); at scale k the worst member
    # has m = 2^k, c = 1 - 0.5 k. A decay rate of 0.2 needs c > 0.4 m (k = 0.70); a damping
    # ratio zeta needs c > 4 zeta sqrt(m): k = 0.25 for 0.2, 0.93 for 0.1. The margin is
    # the smaller of the two, each map binding once.
    m = ureal("m", 1.0, 0.5, 2.0, distribution="loguniform")
    c = ureal("c", 1.0, 0.5, 1.5)
    decay = brentq(lambda k: 1 - 0.5 * k - 0.4 * 2.0**k, 0.0, 2.0)
    damping = brentq(lambda k: 1 - 0.5 * k - 4 * zeta * 2.0 ** (k / 2), 0.0, 2.0)
    assert (damping < decay) == (binding == "damping")
    region = Region(decay_rate=0.2, min_damping=zeta)
    res = robust_margin(_second_order(c / m, 4.0 / m), region=region)
    _check(res, min(decay, damping))
    assert res.certificate["method"] == "mu"


def test_every_edge_of_a_band_region_is_on_some_maps_axis():
    # the mu route's soundness: a pole anywhere on the boundary of the violating set of
    # "decay 0.1, damping 0.1 in 0.5-10 Hz" (the cone's upper edge between the band's
    # moduli, the band's edges from the cone to the decay line) is an imaginary eigenvalue
    # of one of the maps, inside that map's band; a pole well inside the region is on none
    from uncertainty.margins import _region_maps

    region = Region(decay_rate=0.1, min_damping=0.1, band_hz=(0.5, 10.0))
    sin_t, cos_t = region.cone
    w_lo, w_hi = 2 * math.pi * 0.5, 2 * math.pi * 10.0

    def hits(p):
        A = np.array([[p.real, p.imag], [-p.imag, p.real]])  # poles p and its conjugate
        out = set()
        for name, Am, _, band in _region_maps(A, np.eye(2), region, 0.1):
            for e in np.linalg.eigvals(Am):
                if abs(e.real) < 1e-9 and band[0] - 1e-9 <= e.imag <= band[1] + 1e-9:
                    out.add(name)
        return out

    for r in np.linspace(w_lo / sin_t, w_hi / sin_t, 7):
        assert "damping" in hits(r * complex(-cos_t, sin_t))
    for w0, name in ((w_lo, "damping at 0.5 Hz"), (w_hi, "damping at 10 Hz")):
        for x in np.linspace(-cos_t * w0 / sin_t, -0.1, 5):
            assert name in hits(complex(x, w0))
    for y in np.linspace(-100.0, 100.0, 9):
        assert "decay rate" in hits(complex(-0.1, y))
    # inside: well damped in the band, and lightly damped above and below it
    for p in (complex(-20.0, 30.0), complex(-0.5, 80.0), complex(-0.2, 1.0)):
        assert hits(p) == set()
