"""Uncertain parameters: validation at construction, quantile maps, default family ranges."""

import math

import numpy as np
import pytest
from scipy import stats

from backhoe.families.family import MODEL_PARAMETERS, Family
from backhoe.families.family_ranges import default_family
from backhoe.model.literature import published_box
from robust.errors import ParameterError
from uncertainty.parameters import UncertainParameter


def P(**kw):
    base = dict(
        name="human.k_arm",
        nominal=200.0,
        low=100.0,
        high=400.0,
        distribution="uniform",
        units="N/m",
        source="test",
    )
    base.update(kw)
    return UncertainParameter(**base)


@pytest.mark.parametrize(
    "changes, match",
    [
        (dict(low=500.0), r"'human.k_arm'.*low < high"),
        (
            dict(nominal=50.0),
            r"'human.k_arm'.*nominal must lie in \[low, high\] = \[100.0, 400.0\]; got 50.0",
        ),
        (dict(nominal=float("nan")), r"'human.k_arm'.nominal must be a finite value"),
        (dict(high=float("inf")), r"'human.k_arm'.high must be a finite value"),
        (
            dict(low=0.0, nominal=1.0, distribution="loguniform"),
            r"'human.k_arm'.*log-uniform parameter needs low > 0",
        ),
        (dict(low=-5.0, nominal=1.0, distribution="loguniform"), r"'human.k_arm'.*log-uniform"),
        (dict(distribution="normal"), r"'human.k_arm'.*distribution must be one of"),
        (dict(std=1.0), r"'human.k_arm'.*std applies only to 'truncnormal'"),
        (dict(distribution="truncnormal", std=-1.0), r"'human.k_arm'.std must be"),
        (dict(name=""), r"name must be a non-empty string"),
        (dict(nominal="200"), r"'human.k_arm'.nominal must be a real number"),
    ],
    ids=[
        "inverted",
        "nominal-outside",
        "nan-nominal",
        "inf-bound",
        "log-zero-bound",
        "log-negative-bound",
        "unknown-distribution",
        "std-not-truncnormal",
        "negative-std",
        "empty-name",
        "string-value",
    ],
)
def test_invalid_definitions_raise_value_error_naming_the_parameter(changes, match):
    with pytest.raises(ValueError, match=match) as info:
        P(**changes)
    assert isinstance(info.value, ParameterError)


def test_values_are_normalised_to_float_and_frozen():
    p = P(nominal=200, low=100, high=400)
    assert isinstance(p.nominal, float)
    with pytest.raises(AttributeError):
        p.nominal = 3.0


@pytest.mark.parametrize("dist", ["uniform", "loguniform", "truncnormal"])
def test_ppf_maps_the_unit_interval_onto_the_bounds(dist):
    p = P(distribution=dist)
    x = p.ppf(np.array([0.0, 0.5, 1.0]))
    assert x[0] == pytest.approx(p.low) and x[-1] == pytest.approx(p.high)
    median = {"uniform": 250.0, "loguniform": math.sqrt(100.0 * 400.0), "truncnormal": None}[dist]
    if median is None:
        a, b = (p.low - p.nominal) / p.sigma, (p.high - p.nominal) / p.sigma
        median = stats.truncnorm.median(a, b, loc=p.nominal, scale=p.sigma)
    assert x[1] == pytest.approx(median, rel=1e-12)


@pytest.mark.parametrize("human", ["physical", "literal"])
def test_default_family_ranges(human):
    fam = default_family(human)
    assert fam.names == tuple(p.name for p in fam.parameters)
    assert set(fam.names) <= set(MODEL_PARAMETERS[human])
    for p in fam.parameters:
        assert p.source and p.units, p.name
    f1 = fam.parameter("struct.f1_hz")
    assert f1.high == pytest.approx(6.3) and f1.low <= 3.0
    if human == "physical":
        # every human parameter spans its published range and cites it
        box = published_box(fam.posture)
        for name, r in box.items():
            q = fam.parameter(f"human.{name}")
            assert (q.low, q.high, q.distribution, q.source) == (
                r.low,
                r.high,
                r.distribution,
                r.source,
            )
            assert r.low <= q.nominal <= r.high
        assert "STRESS" not in " ".join(p.source for p in fam.parameters)
        stress = default_family(human, ranges="stress")
        assert stress.name.startswith("stress-")
        assert stress.parameter("human.zeta_arm").low == pytest.approx(0.1)
        assert all("STRESS VARIANT" in stress.parameter(f"human.{n}").source for n in box)


def test_nominal_member_is_the_nominal_loop():
    fam = default_family("physical")
    loop = fam.member(fam.nominal_values())
    assert loop.human.params == fam.physical
    assert loop.struct == fam.struct


def test_family_rejects_parameters_of_the_other_variant():
    lit = default_family("literal").parameter("human.k_h")
    with pytest.raises(
        ParameterError, match="'human.k_h' is not a parameter of the physical variant"
    ):
        Family(parameters=(lit,), human="physical")
    with pytest.raises(ParameterError, match="unknown parameters"):
        default_family().member({"human.nope": 1.0})
