"""The mu-synthesis design's pieces: the family's force-feedback plant as an uncertain
system, the scaled design box, and the certificate of any controller's peak mu."""

import math

import control as ct
import numpy as np
import pytest

from backhoe import default_family
from backhoe.families.force_plant import force_feedback_uss
from backhoe.synthesis.forcefb import (
    FORCE_PLANT_SIGNALS,
    ForceFeedbackWeights,
    force_feedback_plant,
)
from designs.mu_synthesis import scaled_family
from robust.errors import ModelStructureError, ParameterError, VerificationError
from uncertainty import certified_mu_peak, dgk, musyn, sample, scaled_bounds, ureal, uss


@pytest.fixture(scope="module")
def family():
    return default_family()


def test_force_feedback_uss_is_each_members_plant(family):
    """Channel by channel, the uncertain plant at a member is that member's python-control
    force-feedback plant (the blocks' realisation against SLICOT's: 1.5e-8 measured), but
    for the intent's tracking error off the nominal, whose reference is the nominal's."""
    P = force_feedback_uss(family)
    assert P.inputs == FORCE_PLANT_SIGNALS["w"] + FORCE_PLANT_SIGNALS["u"]
    assert P.outputs == FORCE_PLANT_SIGNALS["z"] + FORCE_PLANT_SIGNALS["y"]
    assert set(P.parameters) == set(family.names)
    w = np.logspace(-1, 3, 40)
    rows = [family.nominal_values(), *sample(family.parameters, 2, method="mc", seed=5).values]
    for j, row in enumerate(rows):
        ours = P.at(dict(zip(family.names, row)))
        theirs = force_feedback_plant(family.member(row)).sys
        for i in P.inputs:
            for o in P.outputs:
                if j and (o, i) == ("z_e", "w_u"):
                    continue  # the BDFT-free reference is the nominal member's (documented)
                a, b = ours[o, i](1j * w), theirs[o, i](1j * w)
                scale = max(np.max(np.abs(b)), 1e-8)  # structural zeros: rounding
                assert np.max(np.abs(a - b)) <= 1e-6 * scale, (o, i)


def test_force_feedback_uss_refuses_what_it_cannot_build(family):
    with pytest.raises(ModelStructureError, match="bdft_weight must be 0"):
        force_feedback_uss(family, ForceFeedbackWeights(bdft_weight=0.5))
    with pytest.raises(ModelStructureError, match="force port"):
        force_feedback_uss(default_family("literal"))


def test_scaled_family_is_the_scaled_box(family):
    lo, hi = scaled_bounds(family, 0.1)
    small = scaled_family(family, 0.1)
    np.testing.assert_allclose(
        [p.low for p in small.parameters], np.minimum(lo, small.nominal_values())
    )
    np.testing.assert_allclose(
        [p.high for p in small.parameters], np.maximum(hi, small.nominal_values())
    )
    np.testing.assert_array_equal(small.nominal_values(), family.nominal_values())
    # a tenth of the box is narrower than the box in every parameter, and the whole box is itself
    widths = [(p.high - p.low, q.high - q.low) for p, q in zip(small.parameters, family.parameters)]
    assert all(a < b for a, b in widths)
    whole = scaled_family(family, 1.0)
    np.testing.assert_allclose(
        [p.low for p in whole.parameters], [p.low for p in family.parameters], rtol=1e-12
    )
    np.testing.assert_allclose(
        [p.high for p in whole.parameters], [p.high for p in family.parameters], rtol=1e-12
    )


# -- certified_mu_peak on a small problem ----------------------------------------------------------
def _plant():
    """A lightly damped mode, stiffness known to +-30 %, position measured (musyn's example)."""
    k = ureal("k", 1.0, 0.7, 1.3, unit="N/m")
    return uss(
        [[0, 1, 0], [-k, -0.2, 0], [-1, 0, -0.01]],
        [[0, 0], [0, 1], [1, 0]],
        [[0, 0, 0.5], [0, 0, 0], [-1, 0, 0]],
        [[0.5, 0], [0, 0.1], [1, 0]],
    )


@pytest.fixture(scope="module")
def small():
    grid = np.logspace(-2, 2, 17)
    return musyn(_plant(), 1, 1, method="dk", max_iter=1, orders=(0, 1, 2), frequencies=grid)


def test_certified_mu_peak_reproduces_musyns_own(small):
    """The same controller certified again from outside gives musyn's figure (the same
    ladder from the same start), and a controller that does worse certifies higher."""
    assert small.history[0]["start"] in ("identity", "balanced")
    assert small.stopped in ("converged", "max_iter")
    start = small.mu_peak_grid * (1 + dgk.CERT_RTOL)  # musyn's first rung
    b, record = certified_mu_peak(_plant(), small.controller, 1, 1, start=start)
    assert math.isclose(b, small.mu_peak_certified, rel_tol=1e-9)
    assert record["certified"] and record["seconds"] >= 0
    # half the gain: still stabilising, a higher certified peak
    K = small.controller
    half = ct.ss(K.A, K.B, 0.5 * K.C, 0.5 * K.D)
    b_half, _ = certified_mu_peak(_plant(), half, 1, 1, start=start)
    assert b_half > b * 1.01


def test_certified_mu_peak_bad_input(small):
    with pytest.raises(ModelStructureError, match="1 inputs and 1 outputs"):
        certified_mu_peak(_plant(), ct.ss([], [], [], np.zeros((2, 1))), 1, 1, start=1.0)
    with pytest.raises(ParameterError, match="start must be > 0"):
        certified_mu_peak(_plant(), small.controller, 1, 1, start=math.nan)
    # the measurement is minus the position: this gain is a negative stiffness of 50 N/m
    with pytest.raises(VerificationError, match="does not stabilise"):
        certified_mu_peak(_plant(), ct.ss([], [], [], [[-50.0]]), 1, 1, start=1.0)


def test_musyn_is_registered_and_runs_on_demand_only():
    from designs.registry import design_names, get_design, report_design_names

    assert get_design("musyn").in_report is False
    assert "musyn" in design_names() and "musyn" not in report_design_names()
    assert report_design_names() == [n for n in design_names() if n != "musyn"]
