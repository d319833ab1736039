"""The calibrated handle-force design: the member it is built for, its box and its certificate."""

import json

import numpy as np
import pytest

from backhoe import default_family
from backhoe.families.batched import closed_loop_matrices
from backhoe.model.blocks import VALVE_FIELDS, block_of
from bdft import main
from designs.calibrated_force import (
    BOX_MEMBERS,
    DESIGN_DAMPINGS,
    calibrate_operator,
    calibrated_force_certificates,
    design_for,
    force_operator_family,
)
from designs.force_calibration import FORCE_IDENTIFIED
from designs.mu_synthesis import scaled_family
from designs.spec import check_specification
from designs.specification import Specification
from uncertainty import sample


@pytest.fixture(scope="module")
def fam():
    return default_family()


@pytest.fixture(scope="module")
def row(fam):
    # a member the design covers (the sixth of 60 drawn with the coverage sample's seed)
    return np.asarray(sample(fam.parameters, 60, seed=2).values, float)[5]


@pytest.fixture(scope="module")
def cal(fam, row):
    # the records' seed the certificates give their first operator (coverage seed 2)
    return calibrate_operator(fam, row, seed=2 * 100_003)


def test_the_identified_member_carries_both_records_and_the_machines_valve(fam, row, cal):
    names = fam.names
    for k in FORCE_IDENTIFIED:
        assert cal.row[names.index(k)] == cal.force.values[k]
    truth = dict(zip(names, row))
    inside = cal.force.contains(truth)
    assert all(inside.values()), (inside, cal.force.values, cal.force.bounds)
    # the arm's mass within a per cent, the body mass held at the nominal
    i = names.index("human.m_arm")
    assert abs(cal.row[i] / row[i] - 1) < 0.01
    assert cal.row[names.index("human.body_mass")] == fam.body_mass
    loop = fam.member(row)
    np.testing.assert_array_equal(cal.valve, [getattr(loop.valve, f) for f in VALVE_FIELDS])


def test_the_operators_box_is_the_calibrations_bounds_with_the_machines_valve(fam, cal):
    box = force_operator_family(fam, cal)
    p = {q.name: q for q in box.parameters}
    assert not any(block_of(n) == "valve" for n in p)
    for k in FORCE_IDENTIFIED:
        lo, hi = cal.force.bounds[k]
        assert (p[k].low, p[k].high) == (pytest.approx(lo), pytest.approx(hi))
        assert p[k].low <= p[k].nominal <= p[k].high
    valve = box.member(np.array([q.nominal for q in box.parameters])).valve
    np.testing.assert_array_equal([getattr(valve, f) for f in VALVE_FIELDS], cal.valve)


def test_the_design_is_certified_on_a_fraction_of_its_box_and_broken_just_beyond(fam, row, cal):
    spec = Specification()
    res, K, choice = design_for(fam, cal, spec, seed=2 * 100_003)
    assert K is not None and choice["damping"] in DESIGN_DAMPINGS
    assert res.verified and res.required_force <= 1.0
    assert check_specification([fam.member(row)], K, spec).holds
    # the first certified scale (15/16 of the upper bound or below), no bisection after it,
    # and a short search for the upper bound
    cert = calibrated_force_certificates(
        fam, rows=row[None, :], time_limit_s=120.0, iterations=0, search_samples=32
    )
    (m,) = cert["members"]
    assert m["designed"] and m["choice"]["damping"] == choice["damping"]
    # tight: mu's lower bound within 5 % of the breaking member's scale; and small: the
    # certainty-equivalent design holds on a few per cent of the calibration's box
    assert 0 < m["lower"] <= m["upper"] <= 1.05 * m["lower"] / 0.95
    assert m["upper"] < 0.2 and cert["certified_whole_bound"] == 0
    # independently: members of the box scaled to the lower bound keep the region, and
    # the calibration's whole box holds members that leave it
    box = force_operator_family(fam, cal)
    region = spec.region()
    for k, want in ((m["lower"], True), (1.0, False)):
        sub = scaled_family(box, k)
        rows = np.asarray(sample(sub.parameters, 64, seed=3).values, float)
        A = closed_loop_matrices(sub, rows, controller=K, check_bounds=False)
        ok = region.violation(np.linalg.eigvals(A)) <= 0
        assert ok.all() if want else not ok.all(), (k, ok.mean())
    assert choice["box_members"] == BOX_MEMBERS and choice["box_held"] < BOX_MEMBERS


def test_cli_reports_the_coverage_against_the_members_own_limits(tmp_path, capsys):
    code = main(
        [
            "design",
            "calibrated-force",
            "--coverage-samples",
            "1",
            "--limit-samples",
            "1",
            "--certify-samples",
            "0",
            "--jobs",
            "1",
            "--out",
            str(tmp_path),
            "--json",
        ]
    )
    assert code == 0
    obj = json.loads(capsys.readouterr().out)
    cov = obj["coverage"]
    assert cov["coverage"]["samples"] == 1 and cov["limit"]["samples"] == 1
    assert sum(cov["dampings"].values()) == 1
    assert cov["coverage"]["failures"] == sum(cov["binding"].values())
    assert obj["certificates"] is None
    art = json.loads((tmp_path / "calibrated-force.json").read_text())
    assert art["kind"] == "bdft-calibrated-design" and art["coverage"] == cov
