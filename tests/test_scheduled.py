"""The per-operator scheduled bank: cells, selection rule, coverage, command line."""

import json

import numpy as np
import pytest

from bdft import main
from designs.calibration import IDENTIFIED, operator_row
from designs.cancellation import cancellation_controller
from designs.scheduled import (
    LIMIT_SET,
    bank_coverage,
    build_bank,
    cab_damper,
    calibrate_members,
    continuous_coverage,
)
from robust.errors import ParameterError
from uncertainty import default_family, sample

FAM = default_family()


@pytest.fixture(scope="module")
def calibrated():
    rows = sample(FAM.parameters, 24, method="mc", seed=2).values
    est, truth, inside = calibrate_members(FAM, rows, seed=1002)
    return rows, est, truth, inside


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
    rows, est, truth, inside = calibrated
    bank = build_bank(FAM, 2)
    cov = bank_coverage(bank, FAM, rows, est, truth, inside, seed=2)
    # the selection agrees with the rule applied by hand
    assert cov.right_cell == pytest.approx(np.mean(bank.select(est) == bank.select(truth)))
    assert cov.bound.samples == 24 and cov.cells == 16
    assert sum(cov.binding.values()) == cov.bound.failures
    # a cancellation needs the operator's modes to within a few percent: the 16-cell bank
    # covers almost nobody (measured 1 of these 24; 3 % of 400 in bdft design scheduled),
    # the compensator built from each operator's own estimate most (19 of 24; 74 % of 400)
    cont = continuous_coverage(FAM, rows, est)
    assert cov.bound.fraction <= 0.25
    assert cont.mean() >= 0.5
    assert cont.mean() > cov.bound.fraction + 0.2


def test_cli_design_scheduled_json_and_artifact(tmp_path, capsys):
    out = tmp_path / "designs"
    argv = ["design", "scheduled", "--coverage-samples", "8", "--cells", "1"]
    argv += ["--limit-samples", "1", "--damped-samples", "1", "--jobs", "1"]
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
    assert obj["coverage_by_cells"][-1]["samples"] == 1
    art = json.loads((out / "scheduled.json").read_text())
    assert art["kind"] == "bdft-controller-bank" and len(art["cells"]) == 1
    # a second run (without the limit map) replaces its own artifact
    argv[argv.index("--limit-samples") + 1] = "0"
    argv[argv.index("--coverage-samples") + 1] = "2"
    argv[argv.index("--damped-samples") + 1] = "0"
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["limit"] is None
    assert "scheduled" in [*map(str.strip, _listed(capsys))]


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
    # cancellation of the identified human alone leaves that mode and fails; with the
    # damper designed from the same record (identified cab, phase and gain picked on the
    # identified member) the whole specification holds on the true member (measured: 3 of 3)
    rows = sample(FAM.parameters, 300, method="mc", seed=5).values
    rows = rows[rows[:, FAM.names.index("struct.zeta1")] < 0.09][:3]
    est, _, _, cabs = calibrate_members(FAM, rows, seed=77, cab=True)
    plain = continuous_coverage(FAM, rows, est)
    damped, binding = continuous_coverage(FAM, rows, est, cabs=cabs, binding=True)
    assert not plain.any()
    assert damped.sum() >= 2
    # the damper is the band-pass at its mode: unit gain and zero phase there
    D = cab_damper(4.0, 1.0, 0.0)
    g = complex(D(2j * np.pi * 4.0))
    assert abs(g - 1.0) < 1e-12
    g = complex(cab_damper(4.0, 1.0, -1.0)(2j * np.pi * 4.0))
    assert abs(abs(g) - 1.0) < 1e-12 and abs(np.angle(g) + 1.0) < 1e-12
