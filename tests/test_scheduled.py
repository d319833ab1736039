"""The per-operator scheduled bank: cells, selection rule, coverage, command line."""

import json

import control as ct
import numpy as np
import pytest
from family_rows import rows_with_valves

from backhoe import default_family, member_metrics
from bdft import main
from designs.calibration import CAB_IDENTIFIED, IDENTIFIED, operator_row
from designs.cancellation import cancellation_controller
from designs.coverage import member_verdicts
from designs.scheduled import (
    LIMIT_SET,
    _damper_candidates,
    _identified_row,
    _utilisations,
    bank_coverage,
    border_check,
    build_bank,
    cab_damper,
    calibrate_members,
    continuous_coverage,
    damped_cancellation,
    member_valve,
    operator_family,
)
from designs.spec import CONSTRAINTS, Specification, check_specification
from robust.errors import ParameterError

FAM = default_family()


@pytest.fixture(scope="module")
def calibrated():
    # the operators and cabs measured below, each machine with its own valve
    rows = rows_with_valves(FAM, 24, method="mc", seed=2)
    return rows, calibrate_members(FAM, rows, seed=1002)


def test_bank_cells_and_selection_rule():
    bank = build_bank(FAM, 2)
    # 2^4 grid cells; with the frequencies' common range split at its geometric middle, no
    # lower-mode interval lies wholly above an upper-mode one, so all 16 are kept; with 3
    # per axis the lower mode's top third above the upper's bottom third is dropped
    assert len(bank.cells) == 16
    assert len(build_bank(FAM, 3).cells) == 81 - 9
    # every centre selects its own cell; estimates beyond the grid are clipped into it
    assert list(bank.select(bank.centres)) == list(range(len(bank.cells)))
    far = bank.centres[[0]] * np.array([[0.1, 0.1, 0.1, 0.1]])
    assert bank.select(far)[0] == bank.select(bank.centres[[0]])[0]
    # each cell's compensator is the cancellation of its centre's human
    i = 5
    K = cancellation_controller(
        FAM.member(operator_row(FAM, dict(zip(IDENTIFIED, bank.centres[i]))), check_bounds=False)
    )
    np.testing.assert_array_equal(bank.controllers[i].C, K.C)
    obj = bank.to_json()
    assert obj["set"] == LIMIT_SET and len(obj["cells"]) == 16
    assert set(obj["edges"]) == set(IDENTIFIED)
    with pytest.raises(ParameterError, match="select"):
        bank.select([[1.0, np.nan, 2.0, 0.3]])
    with pytest.raises(ParameterError, match="cells_per_axis"):
        build_bank(FAM, 0)


def test_bank_coverage_against_the_continuous_schedule(calibrated):
    rows, cal = calibrated
    est, truth, inside = cal.estimates, cal.truth, cal.operator_inside
    bank = build_bank(FAM, 2)
    cov = bank_coverage(bank, FAM, rows, est, truth, inside, seed=2)
    # the selection agrees with the rule applied by hand
    assert cov.right_cell == pytest.approx(np.mean(bank.select(est) == bank.select(truth)))
    assert cov.bound.samples == 24 and cov.cells == 16
    assert sum(cov.binding.values()) == cov.bound.failures
    # under the specification at every frequency with the valve's limits, no cancellation of
    # the hand's motion through the cylinder reference holds: built from each operator's own
    # estimate it asks more than half the valve's flow (the reference effort binds on every
    # member); the bank's cells, a wrong cell's cancellation, also break the loop or tracking
    cont, why = continuous_coverage(FAM, rows, est, binding=True)
    assert cov.bound.fraction == 0.0 and not cont.any()
    assert set(why) == {"reference effort"}
    assert "reference effort" in cov.binding


@pytest.mark.slow
def test_cli_design_scheduled_json_and_artifact(tmp_path, capsys):
    out = tmp_path / "designs"
    argv = ["design", "scheduled", "--coverage-samples", "8", "--cells", "1"]
    argv += ["--limit-samples", "1", "--border-samples", "1", "--certify-samples", "1"]
    argv += ["--jobs", "1"]
    argv += ["--out", str(out), "--json"]
    assert main(argv) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["limit_set"] == LIMIT_SET and obj["force_scale"] == 1.0
    cov = obj["coverage"]
    assert {"fraction", "samples", "failures", "epsilon", "confidence"} <= set(cov)
    assert cov["samples"] == 8 and cov["seed"] == 2
    assert obj["limit"]["samples"] == 1 and LIMIT_SET in obj["limit"]["coverage_by_set"]
    cells = [r["cells"] for r in obj["coverage_by_cells"]]
    assert cells[-2:] == ["continuous", "continuous with the cab damper"]
    assert obj["coverage_by_cells"][-1]["samples"] == 8
    # the coverage is the damped design's, the last entry of the comparison on all 8
    assert obj["coverage_by_cells"][-1]["fraction"] == cov["fraction"]
    assert obj["bank"]["cells"] == 1 and obj["bank"]["samples"] == 8
    assert obj["wrong_within_bound"]["members"] == 1
    assert obj["wrong_within_bound"]["designs"] == 16
    assert obj["wrong_within_bound"]["construction"] == "confidence"
    assert obj["wrong_within_box"]["construction"] == "box"
    assert obj["wrong_within_box"]["designs"] == 16
    assert 0.0 <= cov["estimate_within_confidence_region"] <= 1.0
    assert cov["confidence_region_samples"] == 8
    assert "damped_cancellation" in obj["design"]
    cert = obj["certified_over_bound"]
    assert cert["members"] == 1 and 0.0 <= cert["lower"][0] <= cert["upper"][0]
    art = json.loads((out / "scheduled.json").read_text())
    assert art["kind"] == "bdft-controller-bank" and len(art["cells"]) == 1
    # a second run (without the limit map) replaces its own artifact
    argv[argv.index("--limit-samples") + 1] = "0"
    argv[argv.index("--coverage-samples") + 1] = "2"
    argv[argv.index("--border-samples") + 1] = "0"
    argv[argv.index("--certify-samples") + 1] = "0"
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["limit"] is None
    assert "scheduled" in [line.split()[0] for line in _listed(capsys)]


def _listed(capsys):
    assert main(["design", "--list"]) == 0
    return capsys.readouterr().out.splitlines()


def test_cli_design_scheduled_bad_options(tmp_path, capsys):
    assert main(["design", "scheduled", "--coverage-samples", "0", "--out", str(tmp_path)]) == 2
    assert "--coverage-samples" in capsys.readouterr().err
    assert main(["design", "scheduled", "--cells", "9"]) == 2
    assert "--cells" in capsys.readouterr().err
    (tmp_path / "scheduled.json").write_text("{}")
    argv = ["design", "scheduled", "--coverage-samples", "2", "--out", str(tmp_path)]
    assert main(argv) == 2
    assert "refusing to replace" in capsys.readouterr().err


def test_the_cab_damper_designed_at_calibration_rescues_lightly_damped_cabs():
    # three machines whose cab's first mode is damped below the specification's 0.1: the
    # cancellation of the identified human alone leaves that mode and fails the damping; with
    # the damper designed from the same record (identified cab, phase and gain picked on the
    # identified member) the damping holds on the true member (measured: 3 of 3). The whole
    # specification does not: the reference effort binds (see the bank's test)
    rows = rows_with_valves(FAM, 300, method="mc", seed=5)
    rows = rows[rows[:, FAM.names.index("struct.zeta1")] < 0.09][:3]
    cal = calibrate_members(FAM, rows, seed=77)
    spec = Specification()
    k = CONSTRAINTS.index("damping")
    plain, damped = [], []
    for row, e, cb in zip(rows, cal.estimates, cal.cabs, strict=True):
        h, c = dict(zip(IDENTIFIED, e)), dict(zip(CAB_IDENTIFIED, cb))
        Kc = _damper_candidates(FAM, h, c, spec).cancellation
        # the damper made with the machine's own valve (its rig knows its cylinder loop)
        K = damped_cancellation(FAM, h, c, spec, valve=member_valve(FAM, row))
        plain.append(member_verdicts(FAM, row[None, :], Kc, spec).violated[0, k])
        damped.append(member_verdicts(FAM, row[None, :], K, spec).violated[0, k])
    assert all(plain)
    assert sum(damped) <= 1
    # the damper is the band-pass at its mode: unit gain and zero phase there
    D = cab_damper(4.0, 1.0, 0.0)
    g = complex(D(2j * np.pi * 4.0))
    assert abs(g - 1.0) < 1e-12
    g = complex(cab_damper(4.0, 1.0, -1.0)(2j * np.pi * 4.0))
    assert abs(abs(g) - 1.0) < 1e-12 and abs(np.angle(g) + 1.0) < 1e-12


def test_damper_candidates_evaluated_as_the_specification_defines_them(calibrated):
    # the batched closed loops that pick the damper agree with check_specification (the
    # python-control loop, minimal realisation, its own frequency responses) on every
    # fourth candidate of two identified members, and the damper adds its three states
    rows, cal = calibrated
    spec = Specification()
    keys = ("decay rate", "damping", "tracking", "feedthrough")
    for i in (0, 5):
        h, c = dict(zip(IDENTIFIED, cal.estimates[i])), dict(zip(CAB_IDENTIFIED, cal.cabs[i]))
        cand = _damper_candidates(FAM, h, c, spec)
        U = _utilisations(cand.open_loop, spec, cand.cancellation, cand.w, cand.gain, cand.phase)
        hat = FAM.member(_identified_row(FAM, h, c), check_bounds=False)
        Kc = cand.cancellation
        finite = 0
        for k in range(0, len(cand.gain), 4):
            D = cab_damper(cand.w / (2 * np.pi), cand.gain[k], cand.phase[k])
            K = ct.parallel(ct.ss(Kc.A, Kc.B, Kc.C, Kc.D), D)
            K = ct.ss(K.A, K.B, K.C, K.D, inputs="c", outputs="r_corr")
            ref = check_specification([hat], K, spec, simulate_peak=0)
            ref = np.array([r.utilisation for r in ref.constraints if r.name in keys])
            np.testing.assert_array_equal(np.isinf(U[k]), np.isinf(ref))
            ok = np.isfinite(ref)
            # the poles' figures exactly; the frequency-wise bounds on the design grid, whose
            # values are those of the exact check at the grid's frequencies: at most its
            # supremum (measured within 40 % of it; the choice among candidates is made on
            # the grid, the verdict by the exact check)
            np.testing.assert_allclose(U[k][:2][ok[:2]], ref[:2][ok[:2]], rtol=1e-6, atol=1e-9)
            assert np.all(U[k][2:][ok[2:]] <= ref[2:][ok[2:]] * (1 + 1e-9))
            assert np.all(U[k][2:][ok[2:]] >= 0.5 * ref[2:][ok[2:]])
            finite += int(ok.all())
        assert finite >= 3  # stable candidates were compared, not only unstable ones
        K = damped_cancellation(FAM, h, c, spec)
        assert K.nstates in (Kc.nstates, Kc.nstates + 3)


def test_calibration_places_the_operator_within_its_bound_for_95_percent(calibrated):
    # the design's "cell" is the box the calibration bounds: the operator's true modes lie
    # in it for 97.7 % of the 2000 seeded operators of `bdft design scheduled` (97.8 % of
    # 400 in benchmarks/bench_calibration.py); of these 24, 22 (an arm mode near 1 Hz is
    # the usual miss); the cab's for 91.8 % of the 2000 (its bound is two bins of the
    # frequency resolution)
    rows, cal = calibrated
    assert cal.operator_inside.sum() >= 21
    assert cal.cab_inside.sum() >= 20
    # the bounds bracket their estimates
    assert np.all(cal.bounds[..., 0] <= cal.estimates) and np.all(
        cal.estimates <= cal.bounds[..., 1]
    )
    sub = cal[3:5]
    assert len(sub) == 2 and np.array_equal(sub.cab_bounds, cal.cab_bounds[3:5])


def test_border_check_counts_what_a_hand_built_design_shows(calibrated):
    # two of the seeded operators: a wrong estimate at the bound's edge destabilises the
    # loop in 8 and 1 of their 16 designs (measured; the first in each of the operator's
    # eight, the second only with the trunk's damping low): the cancellation needs the
    # operator's modes to within about a percent
    rows, cal = calibrated
    idx = [3, 5]
    out = border_check(FAM, rows[idx], cal[idx], construction="box")
    assert out["members"] == 2 and out["designs"] == 32 and out["construction"] == "box"
    assert len(out["unstable_by_case"]) == 16
    assert sum(out["unstable_by_case"].values()) == round(32 * (1 - out["stable"]))
    assert out["specification"] <= out["stable"] < 1.0
    # the count of two cases by hand: the arm's frequency low by the bound's half-width (a
    # factor), the trunk's damping low by it, the cab as it is
    for label, j in (("f_low_hz-", 0), ("zeta_high-", 3)):
        unstable = 0
        for i in idx:
            t = cal.truth[i].copy()
            lo, hi = cal.bounds[i, j]
            t[j] = t[j] / np.sqrt(hi / lo) if j == 0 else max(t[j] - 0.5 * (hi - lo), 0.01)
            h, c = dict(zip(IDENTIFIED, t)), dict(zip(CAB_IDENTIFIED, cal.cab_truth[i]))
            K = damped_cancellation(FAM, h, c, valve=cal.valves[i])
            unstable += int(not member_metrics(FAM, rows[i : i + 1], controller=K)[0][0] < 0)
        assert out["unstable_by_case"][label] == unstable
    assert out["unstable_by_case"]["f_low_hz-"] >= 1


def test_the_calibration_bounds_the_operator_for_95_percent_of_seeded_operators():
    # the design's cell is the box its calibration bounds: 200 seeded operators, each with
    # its own record; the true modes inside the bound for 196 of them (measured), the
    # issue's floor 95 % (190)
    rows = rows_with_valves(FAM, 200, method="mc", seed=2)
    cal = calibrate_members(FAM, rows, seed=1002, regions=0)
    assert cal.operator_inside.sum() >= 190
    assert np.isnan(cal.region_distance).all() and cal.within_confidence_region.size == 0


def test_border_check_on_the_joint_error_region_keeps_the_loop_stable(calibrated):
    # the estimates a record can return: the noise-free estimate moved along each principal
    # axis of the estimate's covariance until the hand's response has moved 4.03 standard
    # deviations (the 99.73 % region); with them every design on these three operators stays
    # stable, the first two destabilised by the box construction above, the third (member
    # 13: a 2.8 kg arm) unstable even with its exact modes paired with nominal masses
    # (measured: every design stable on 200 members)
    rows, cal = calibrated
    idx = [3, 5, 13]
    out = border_check(FAM, rows[idx], cal[idx])
    assert out["construction"] == "confidence" and out["radius"] == pytest.approx(4.0313, abs=1e-4)
    assert out["designs"] == 48
    assert out["stable"] == 1.0
    assert set(out["unstable_by_case"]) >= {"axis1+", "axis1-", "axis4+", "axis4-"}
    # the largest axis's design by hand: stable on the true member
    h = cal.region_points[13, 0]
    K = damped_cancellation(
        FAM,
        dict(zip(IDENTIFIED, h)),
        dict(zip(CAB_IDENTIFIED, cal.cab_truth[13])),
        valve=cal.valves[13],
    )
    assert member_metrics(FAM, rows[13:14], controller=K)[0][0] < -1e-3
    # the true modes with the nominal masses are not what the record tells member 13
    t = dict(zip(IDENTIFIED, cal.truth[13]))
    K = damped_cancellation(
        FAM, t, dict(zip(CAB_IDENTIFIED, cal.cab_truth[13])), valve=cal.valves[13]
    )
    assert member_metrics(FAM, rows[13:14], controller=K)[0][0] > 0
    with pytest.raises(ParameterError, match="construction"):
        border_check(FAM, rows[:1], cal[:1], construction="corners")
    # without the regions (computed for the first member only) the check says so
    part = calibrate_members(FAM, rows[:2], seed=1002, regions=1)
    assert np.isnan(part.noise_free[1]).all() and np.isfinite(part.noise_free[0]).all()
    np.testing.assert_array_equal(part.region_points[0], cal.region_points[0])
    assert part.within_confidence_region.shape == (1,)
    with pytest.raises(ParameterError, match="error region"):
        border_check(FAM, rows[:2], part)
    border_check(FAM, rows[:1], part[:1])  # the member with its region


def test_operator_family_is_the_calibrations_box(calibrated):
    rows, cal = calibrated
    fam, h, c = operator_family(FAM, cal, 4)
    p = {q.name: q for q in fam.parameters}
    # the operator's estimate is the nominal, its bound the range; the masses keep the
    # family's whole ranges (the record does not tell them)
    assert p["human.f_arm_hz"].nominal == pytest.approx(h["f_low_hz"])
    assert (p["human.f_arm_hz"].low, p["human.f_arm_hz"].high) == tuple(cal.bounds[4, 0])
    assert p["human.zeta_trunk"].high == cal.bounds[4, 3, 1]
    assert p["struct.k_s"].nominal == pytest.approx(c["k_s"])
    ref = {q.name: q for q in FAM.parameters}
    assert p["human.m_arm"] == ref["human.m_arm"]
    # the machine's valve is its own (the rig knows its cylinder loop), not a range
    assert not any(name.startswith("valve.") for name in p)
    assert fam.valve.k_vc == cal.valves[4, 0] and fam.valve.zeta == cal.valves[4, 3]
    assert cal.valves[4, 0] == rows[4, FAM.names.index("valve.k_vc")] != FAM.valve.k_vc


def test_cab_damper_keeps_the_realisation_of_its_transfer_function_product():
    # the certified margins over a damped cancellation depend on the controller's
    # coordinates: the damper's matrices are python-control's realisation of the product of
    # the band-pass and the all-pass, to the bit
    for f, g, ph in [(4.0, 0.1, -1.0), (2.7, 0.4, 2.5), (11.3, 0.05, 0.0), (6.1, 1.3, -2.9)]:
        w = 2 * np.pi * f
        K = ct.tf([g * w, 0.0], [1.0, w, w * w])
        if ph != 0.0:
            a = w / np.tan(abs(ph) / 2)
            K = K * ct.tf([-1.0, a], [1.0, a]) * (-1.0 if ph > 0 else 1.0)
        ref, got = ct.ss(K), cab_damper(f, g, ph)
        for x, y in zip((ref.A, ref.B, ref.C, ref.D), (got.A, got.B, got.C, got.D)):
            assert x.shape == y.shape and x.tobytes() == y.tobytes()
