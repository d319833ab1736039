"""uncertainty.testing: the certified-margin assertion users put in their own test suites."""

from __future__ import annotations

import math
import re

import control as ct
import pytest

from robust.errors import ParameterError
from uncertainty import Region, ureal, uss
from uncertainty.testing import assert_robust_margin, assert_robust_performance

REGION = Region(decay_rate=0.02)


@pytest.fixture(scope="module")
def two_mass():
    """The README's two masses on an uncertain spring under a PD controller: certified
    1.533 and broken at 1.582 (the softest spring, the heaviest second mass) for a decay
    rate of 0.02 1/s."""
    k = ureal("k", 1.0, 0.5, 2.0)
    m2 = ureal("m2", 1.0, 0.8, 1.5)
    c = 0.05
    A = [[0, 0, 1, 0], [0, 0, 0, 1], [-k, k, -c, c], [k / m2, -k / m2, c / m2, -c / m2]]
    system = uss(A, [[0], [0], [1], [0]], [[1, 0, 0, 0]], [[0]])
    return system, ct.tf([4.0, 2.0], [0.05, 1.0])


def test_a_requirement_the_certificate_reaches_passes(two_mass):
    system, K = two_mass
    cert = assert_robust_margin(system, controller=K, region=REGION, at_least=1.0)
    # an uncertain system's loop and a decay rate: mu is the automatic method
    assert cert["certified_scale"] >= 1.0 and cert["method"] == "mu"
    # one scale certified, no search
    assert [h["scale"] for h in cert["history"]] == [0.0, 1.0]


def test_a_requirement_beyond_a_violating_member_fails_with_both_bounds(two_mass):
    system, K = two_mass
    with pytest.raises(AssertionError) as err:
        assert_robust_margin(system, controller=K, region=REGION, at_least=2.0, samples=300)
    msg = str(err.value)
    assert "the box scaled by 2 is not certified for the real parts below -0.02 rad/s" in msg
    lower, upper = (
        float(x) for x in re.search(r"lower bound ([\d.]+), upper bound ([\d.]+)", msg).groups()
    )
    assert 1.4 < lower <= upper < 1.7
    assert "out of reach: a member inside the required box" in msg
    # the critical member: the softest spring and the heaviest second mass of its box
    crit = dict(re.findall(r"(k|m2)=([\d.]+)", msg.split("critical member:")[1].splitlines()[0]))
    assert float(crit["k"]) < 0.3 and float(crit["m2"]) > 1.7
    assert "rightmost pole" in msg and "python-control" in msg
    assert "main loop theorem" in msg and "worst-case search" in msg


def test_a_requirement_the_certificate_cannot_settle_says_so(two_mass):
    # between the bounds, with too small a budget of boxes: neither shown nor refuted
    system, K = two_mass
    with pytest.raises(AssertionError, match="not shown either way"):
        assert_robust_margin(
            system, controller=K, region=REGION, at_least=1.5, max_boxes=1, samples=300
        )


def test_a_requirement_must_be_a_positive_scale(two_mass):
    system, K = two_mass
    with pytest.raises(ParameterError, match="assert_robust_margin.at_least"):
        assert_robust_margin(system, controller=K, at_least=0.0)


def test_robust_performance_passes_when_the_certificate_reaches_the_requirement():
    a = ureal("a", 2.0, 1.5, 3.0)  # gain 1/a <= 2/3 on the whole box
    cert = assert_robust_performance(uss([[-a]], [[1.0]], [[1.0]], [[0.0]]), at_least=1.0)
    assert cert["certified"] and cert["scale"] == 1.0
    assert cert["frequencies"][0]["mu_upper"] < 1.0


def test_robust_performance_failure_gives_both_bounds_and_the_worst_member():
    # 1 / (s^2 + c s + 1) under the bound 2: broken at zeta = sin 15 deg, scale 0.603
    c = ureal("c", 1.0, 0.2, 1.8)
    system = uss([[0, 1], [-1, -c]], [[0], [1]], [[1, 0]], [[0]])
    with pytest.raises(AssertionError) as err:
        assert_robust_performance(system, gamma=2.0, at_least=1.0)
    msg = str(err.value)
    assert "the box scaled by 1 is not certified" in msg and "below 2" in msg
    lower, upper = (
        float(x) for x in re.search(r"lower bound ([\d.]+), upper bound ([\d.]+)", msg).groups()
    )
    assert 0.59 < lower <= 0.60295 <= upper < 0.61
    assert "out of reach" in msg
    c_worst = float(re.search(r"worst member: c=([\d.]+)", msg).group(1))
    assert c_worst == pytest.approx(2 * math.sin(math.radians(15)), rel=2e-3)
    hz = float(re.search(r"at ([\d.]+) Hz", msg).group(1))
    assert 0.13 < hz < 0.16  # near the 1 rad/s resonance
    assert "mu upper bound" in msg and "Popov" in msg and "worst-case search" in msg
