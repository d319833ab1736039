"""The LFT form of an uncertain system closes back to the system, member by member."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

from backhoe import default_family, family_uss
from robust.errors import ParameterError
from uncertainty import lft_form, ureal, uss


def _members_agree(system, n=5, seed=0, rtol=1e-12, reduce=True):
    F = lft_form(system, reduce=reduce)
    rng = np.random.default_rng(seed)
    for _ in range(n):
        d = {name: rng.uniform(-1, 1) for name in system.parameters}
        vals = {name: F.centre[name] + F.half_width[name] * d[name] for name in d}
        got, want = F.close(d), system.at(vals)
        for X, Y in zip((got.A, got.B, got.C, got.D), (want.A, want.B, want.C, want.D)):
            if np.size(Y) == 0:
                assert np.size(X) == 0
                continue
            assert np.abs(np.asarray(X) - np.asarray(Y)).max() <= rtol * max(
                1.0, np.abs(np.asarray(Y)).max()
            )
    return F


def test_rational_entries_with_a_controller():
    k = ureal("k", 1.0, 0.5, 2.0)
    m2 = ureal("m2", 1.0, 0.8, 1.5)
    c = 0.05
    A = [[0, 0, 1, 0], [0, 0, 0, 1], [-k, k, -c, c], [k / m2, -k / m2, c / m2, -c / m2]]
    G = uss(A, [[0], [0], [1], [0]], [[1, 0, 0, 0]], [[0]])
    loop = G.feedback(ct.ss(ct.tf([4.0, 2.0], [0.05, 1.0])))
    # one channel per occurrence: k appears in four entries, m2 in four divisions
    F = _members_agree(loop, reduce=False)
    assert F.blocks == [("k", 4), ("m2", 4)] and F.mu_blocks == [(4, "real"), (4, "real")]
    assert F.M.ninputs == 8 + 1 and F.M.noutputs == 8 + 1 and F.M.nstates == 5
    # reduced: k and m2 act on the spring's stretch and the second row only (x1 - x2 feeds
    # k in rows 3 and 4; 1 / m2 scales row 4's stiffness and damping terms), two each
    F = _members_agree(loop)
    assert F.blocks == [("k", 2), ("m2", 2)] and F.mu_blocks == [(2, "real"), (2, "real")]
    assert F.M.ninputs == 4 + 1 and F.M.noutputs == 4 + 1 and F.M.nstates == 5
    # the centre of the box is delta = 0
    assert F.centre == {"k": 1.25, "m2": 1.15} and F.half_width["k"] == pytest.approx(0.75)


def test_powers_products_and_uncertain_input_output_matrices():
    w = ureal("w", 2 * math.pi, math.pi, 4 * math.pi)
    z = ureal("z", 0.5, 0.2, 0.8)
    g = ureal("g", 1.0, 0.5, 3.0)
    G = uss([[0, 1], [-(w**2), -2 * z * w]], [[0], [g * w**2]], [[1 / g, 0]], [[g - 1]])
    F = _members_agree(G)
    assert [b[0] for b in F.blocks] == ["w", "z", "g"]


def test_the_bdft_family_in_lft_form():
    # unreduced, the repetitions are the parameters' occurrences in the blocks' one
    # definition (with the valve's spread 51 and 162; without it the structure's scaled
    # sections took 38 and 152, where the sections in w^2 took 47 and 182); the n-D Kalman
    # reduction leaves 18 and 30, every parameter kept, and closes to the same members
    for human, repeats, reduced in (("literal", 51, 18), ("physical", 162, 30)):
        loop = family_uss(default_family(human))
        F = _members_agree(loop, n=3, rtol=1e-12, reduce=False)
        assert len(F.blocks) == len(default_family(human).names)
        assert sum(r for _, r in F.blocks) == repeats
        F = _members_agree(loop, n=3, rtol=1e-9)
        assert [b[0] for b in F.blocks] == list(default_family(human).names)
        assert sum(r for _, r in F.blocks) == reduced


def test_a_divisor_at_the_centre_is_refused():
    d = ureal("d", 1.0, -1.0, 1.0)  # centre 0
    with pytest.raises(ParameterError, match="divisor is 0 at the centre"):
        lft_form(uss([[-1.0 / d]], [[1.0]], [[1.0]], [[0.0]]))


def test_the_lft_feeds_mussv_with_the_exact_margin():
    # s^2 + c s + 4, c in [0.2, 3]: centre 1.6, half-width 1.4; the loop loses stability at
    # c = 0 (poles +-2j), delta = -1.6 / 1.4, so mu of M_zw(j2) is 1.4 / 1.6 and a real
    # parameter gives mu 0 where M_zw is not real
    from uncertainty import mussv

    c = ureal("c", 1.0, 0.2, 3.0)
    F = lft_form(uss([[0, 1], [-4, -c]], [[0], [1]], [[1, 0]], [[0]]))
    A, B, C, D = (np.asarray(x) for x in (F.M.A, F.M.B, F.M.C, F.M.D))

    def mzw(w):
        return D[:1, :1] + C[:1] @ np.linalg.solve(1j * w * np.eye(2) - A, B[:, :1])

    at2 = mussv(mzw(2.0), F.mu_blocks)
    assert at2.lower == pytest.approx(1.4 / 1.6, rel=1e-6)
    assert at2.upper == pytest.approx(1.4 / 1.6, rel=1e-3) and at2.upper >= at2.lower
    assert mussv(mzw(1.0), F.mu_blocks).upper < 0.05


def test_a_parameter_with_a_tiny_range_keeps_its_channels():
    # b's range is 1e-12 of a's: normalised by the ranges, its channel sat below the
    # reduction's threshold set by a's, and the reduced LFT left b out (a box scaled to 1e-4
    # about a loop with controller gains of 1e7 lost its operator's parameters that way,
    # and mu certified a box with a member outside the region)
    a, b = ureal("a", 1.0, 0.5, 1.5), ureal("b", 2.0, 1.0, 3.0)
    G = uss([[-a, 1.0], [0.0, -b]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]])
    for width in (1e-12, 1e-6, 1.0):
        F = lft_form(G, bounds={"a": (0.5, 1.5), "b": (2.0 - width, 2.0 + width)})
        assert F.blocks == [("a", 1), ("b", 1)], width
        # the member at b's upper end, closed from the reduced form, is the system's
        A = np.asarray(F.close({"b": 1.0}).A)
        np.testing.assert_allclose(np.sort(np.linalg.eigvals(A).real), [-(2.0 + width), -1.0])
    # the block structure does not depend on the box's size (the family's loop as well)
    loop = family_uss(default_family())
    sizes = {
        k: lft_form(
            loop,
            bounds={
                n: (p.nominal - k * (p.nominal - p.low), p.nominal + k * (p.high - p.nominal))
                for n, p in loop.parameters.items()
            },
        ).blocks
        for k in (1.0, 1e-3, 1e-6)
    }
    assert sizes[1.0] == sizes[1e-3] == sizes[1e-6]
