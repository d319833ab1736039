"""A machine's own parametric family plugs into the generic core as the backhoe's does.

The core (:mod:`uncertainty`) knows no machine: a family type registers its loop with
``uncertainty.margin_loop`` and its batched validation with ``uncertainty.validate_family``,
and the margin and validation functions take it. Here a two-parameter mass-spring-damper
family, written in this file only, is registered and analysed; its figures are checked
against the same model written as an uncertain system and against the exact margin.

For ``x'' + c x' + k x = 0`` with ``k in [0.5, 2]`` and ``c in [0.1, 0.3]`` (nominal 1 and
0.2) every member is underdamped (``k >= 0.5 > c^2 / 4``), so its poles' real part is
``-c / 2``. A decay rate of 0.06 needs ``c > 0.12``; the box scaled by ``t`` about the
nominal reaches ``c = 0.2 - 0.1 t``, so the exact margin is ``t = 0.8``.
"""

from __future__ import annotations

import numpy as np
import pytest

from robust.analysis.intervals import imatrix
from robust.errors import ParameterError
from uncertainty import (
    Region,
    UncertainParameter,
    margin_loop,
    robust_margin,
    sample,
    ureal,
    uss,
    validate_family,
)
from uncertainty.enclosure import box_variables
from uncertainty.region import EVERY_FREQUENCY_HZ
from uncertainty.validation import validation_result

EXACT = 0.8
REGION = Region(decay_rate=0.06)


class SpringFamily:
    """A user's own family: its parameters and its members' state matrices."""

    def __init__(self):
        self.parameters = (
            UncertainParameter("k", 1.0, 0.5, 2.0, "uniform", "N/m", "a test's spring"),
            UncertainParameter("c", 0.2, 0.1, 0.3, "uniform", "N s/m", "a test's damper"),
        )
        self.names = tuple(p.name for p in self.parameters)

    def matrices(self, rows) -> np.ndarray:
        rows = np.atleast_2d(np.asarray(rows, float))
        A = np.zeros((rows.shape[0], 2, 2))
        A[:, 0, 1] = 1.0
        A[:, 1, 0] = -rows[:, 0]
        A[:, 1, 1] = -rows[:, 1]
        return A


class SpringLoop:
    """The family's loop as the margin sees it (the interface of uncertainty.enclosure)."""

    default_band_hz = EVERY_FREQUENCY_HZ
    prefers_mu = False

    def __init__(self, family: SpringFamily):
        self.family = family
        self.parameters = family.parameters
        self.names = family.names

    def matrices(self, rows):
        return self.family.matrices(rows)

    def enclosure(self, lo, hi, derivatives: bool):
        v = box_variables(self.parameters, lo, hi, derivatives)
        return imatrix([[0.0, 1.0], [-v["k"], -v["c"]]])

    def recheck(self, row):
        return np.linalg.eigvals(self.matrices(row)[0]), "numpy poles of the member"

    def valueset_why_not(self, region) -> str:
        return "needs the BDFT family's open loop"


@margin_loop.register
def _(family: SpringFamily, controller=None):
    if controller is not None:
        raise ParameterError("SpringFamily takes no controller")
    return SpringLoop(family)


@validate_family.register
def _(family: SpringFamily, samples, *, band_hz=EVERY_FREQUENCY_HZ, **_options):
    values = np.asarray(samples.values, float)
    poles = np.linalg.eigvals(family.matrices(values))
    max_real = poles.real.max(axis=1)
    damping = (-poles.real / np.abs(poles)).min(axis=1)
    return validation_result(samples, max_real, damping, 0.0, band_hz, 2, 0, None, None)


def _system():
    k = ureal("k", 1.0, 0.5, 2.0)
    c = ureal("c", 0.2, 0.1, 0.3)
    return uss([[0, 1], [-k, -c]], [[0], [1]], [[1, 0]], [[0]])


def test_the_registered_family_has_the_exact_margin_and_the_systems_figures():
    fam = SpringFamily()
    res = robust_margin(fam, region=REGION, method="eigenvalues")
    ref = robust_margin(_system(), region=REGION, method="eigenvalues")
    assert 0.9 * EXACT <= res.lower <= EXACT <= res.upper <= 1.01 * EXACT
    # the same model through the core's own route for an uncertain system
    assert res.upper == pytest.approx(ref.upper, rel=1e-3)
    assert res.lower == pytest.approx(ref.lower, rel=0.05)
    # the member that breaks the region is the softest damper
    assert res.critical["parameters"]["c"] == pytest.approx(0.2 - 0.1 * res.upper, rel=1e-6)


def test_the_registered_family_validates_member_by_member_as_the_system():
    fam, system = SpringFamily(), _system()
    members = sample(fam, 500, seed=3)
    mine = validate_family(fam, members)
    ref = validate_family(system, members)
    np.testing.assert_allclose(mine.max_real, ref.max_real, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(-mine.max_real, members.values[:, 1] / 2, rtol=1e-12)
    assert mine.fraction_stable == ref.fraction_stable == 1.0


def test_a_route_the_registered_loop_cannot_take_is_refused_by_name():
    # no uncertain system for mu, no value sets: each named, before any work
    with pytest.raises(ParameterError, match="method 'mu' needs the loop as an uncertain system"):
        robust_margin(SpringFamily(), region=REGION, method="mu")
    with pytest.raises(ParameterError, match="method 'valueset' needs the BDFT family's open"):
        robust_margin(SpringFamily(), region=REGION, method="valueset")


def test_an_unregistered_family_is_refused_by_name():
    class Unknown:
        parameters = ()

    with pytest.raises(ParameterError, match="registered with uncertainty.margin_loop"):
        robust_margin(Unknown(), region=REGION)
    with pytest.raises(ParameterError, match="registered with uncertainty.validate_family"):
        validate_family(Unknown(), None)
