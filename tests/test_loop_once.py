"""The BDFT loop is written once: its batched, interval and uncertain-system evaluations agree."""

from __future__ import annotations

import control as ct
import numpy as np
import pytest

from uncertainty import (
    Region,
    closed_loop_matrices,
    default_family,
    family_uss,
    sample,
    validate_family,
    worst_member,
)
from uncertainty.margins import certify_box, closed_loop_enclosure, scaled_bounds


def _controller(output):
    # a small strictly proper compensator from the handle and the cylinder to the force (or
    # to the cylinder reference's correction)
    A, B = [[-30.0, 5.0], [-5.0, -20.0]], [[1.0, -0.5], [0.3, 0.8]]
    return ct.ss(A, B, [[0.02, -0.01]], [[0, 0]], inputs=["x", "c"], outputs=[output], name="K")


@pytest.mark.parametrize("human", ["literal", "physical"])
@pytest.mark.parametrize("with_controller", [False, True])
def test_three_evaluations_agree_on_seeded_members(human, with_controller):
    fam = default_family(human)
    output = "f" if human == "physical" else "r_corr"
    K = _controller(output) if with_controller else None
    loop = family_uss(fam, K)
    assert list(loop.parameters) == list(fam.names)
    rows = sample(fam.parameters, 64, method="mc", seed=11).values
    batched = closed_loop_matrices(fam, rows, controller=K)
    from_uss = loop.state_matrices(rows)
    assert from_uss.shape == batched.shape
    scale = np.abs(batched).max(axis=(1, 2))[:, None, None]
    assert np.abs(from_uss - batched).max() <= 1e-12 * scale.max()
    for r, A in zip(rows[:8], batched[:8]):
        enc = closed_loop_enclosure(fam, r, r, controller=K)  # a point box
        assert np.all((enc.lo <= A) & (A <= enc.hi))
        assert np.abs(enc.mid - A).max() <= 1e-12 * np.abs(A).max()
    # python-control's poles of one member's uncertain-system form
    poles = np.sort_complex(ct.poles(loop.at(dict(zip(fam.names, rows[0])))))
    assert poles == pytest.approx(np.sort_complex(np.linalg.eigvals(batched[0])), rel=1e-9)


def test_the_family_and_its_uncertain_system_give_the_same_answers():
    fam = default_family("physical")
    loop = family_uss(fam)
    members = sample(fam.parameters, 3000, method="mc", seed=5)
    a, b = validate_family(fam, members), validate_family(loop, members)
    assert b.fraction_stable == a.fraction_stable and b.worst == a.worst
    assert b.max_real_pole == pytest.approx(a.max_real_pole, rel=1e-12)
    # the same worst-case search on both (same coordinates, same seed)
    region = Region(decay_rate=0.1)
    va, ra = worst_member(fam, 0.05, region=region, samples=100, seed=2)
    vb, rb = worst_member(loop, 0.05, region=region, samples=100, seed=2)
    assert vb == pytest.approx(va, abs=1e-9) and rb == pytest.approx(ra, rel=1e-9)
    # a small box about the nominal is certified through either form
    lo, hi = scaled_bounds(fam, 0.01)
    assert certify_box(fam, lo, hi)["certified"]
    assert certify_box(loop, lo, hi)["certified"]
