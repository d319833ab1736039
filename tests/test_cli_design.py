import json

import numpy as np
import pytest
import scipy.io

from bdft import main
from designs.registry import design_names
from robust.export import load_artifact


def test_design_list(capsys):
    assert main(["design", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = [line.split()[0] for line in lines]
    assert names == [*design_names(), "scheduled", "calibrated-force"]
    # each line says what the design is, the descriptions aligned in one column
    column = {len(line) - len(line[len(name) :].lstrip()) for line, name in zip(lines, names)}
    assert len(column) == 1
    assert "cancellation of the hand's motion" in lines[names.index("cancellation")]


def test_design_list_json(capsys):
    assert main(["design", "--list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["designs"]
    assert [r["name"] for r in rows] == [*design_names(), "scheduled", "calibrated-force"]
    assert all(set(r) == {"name", "description"} and len(r["description"]) > 30 for r in rows)


def test_design_cancellation_json_and_artifact(tmp_path, capsys):
    assert (
        main(
            [
                "design",
                "cancellation",
                "--samples",
                "200",
                "--seed",
                "5",
                "--coverage-samples",
                "60",
                "--margin-boxes",
                "60",
                "--jobs",
                "2",
                "--out",
                str(tmp_path),
                "--json",
            ]
        )
        == 0
    )
    obj = json.loads(capsys.readouterr().out)
    for key in (
        "name",
        "fraction_stable",
        "max_real_pole",
        "min_damping",
        "peak_force_N",
        "rms_force_N",
        "order",
        "artifact",
    ):
        assert key in obj
    assert obj["seed"] == 5 and obj["samples"] == 200 and obj["order"] == 4
    cov = obj["coverage"]
    # fresh Monte Carlo members, seed 5 + 2. The feedforward cancellation of the nominal
    # arm's feedthrough misses the tracking requirement on every member (the cancelled
    # path is the nominal one) and leaves the unstable members unstable
    assert cov["samples"] == 60 and cov["seed"] == 7 and cov["confidence"] == 0.999
    assert cov["failures"] == 60 and cov["fraction"] == 0.0 and cov["epsilon"] == 1.0
    assert cov["violations"]["tracking"] == 60
    assert 10 < cov["violations"]["decay rate"] < 60
    assert sum(cov["binding"].values()) == 60
    # the certified robust margin for the specification's pole region (its damping in
    # 0.5-10 Hz) by mu on the loop's LFT: within a tenth of the upper bound, a member
    # outside the region there
    margin = obj["details"]["robust_margin"]
    assert 0.9 * margin["upper"] <= margin["lower"] <= margin["upper"] < 1.0
    assert margin["certificate"]["method"] == "mu" and margin["critical"]["violation"] > 0
    # the tracking bound's robust performance margin: the cancellation is exact on the
    # nominal member only, so the bound holds on a sliver of the box (2 % of its scale),
    # and no fresh member of the coverage sample lies that close to the nominal
    perf = obj["details"]["robust_performance"]
    assert 0.0 < perf["lower"] <= perf["upper"] < 0.05 and perf["nominal_norm"] < 1.0
    assert perf["certificate"]["certified"] and perf["certificate"]["scale"] == perf["lower"]
    assert perf["worst"]["norm"] >= 1.0 and perf["worst"]["found_by"] == "worst-case search"
    assert "operator's band" in perf["requirement"]
    art = load_artifact(obj["artifact"])
    assert art.inputs == ["c"] and art.outputs == ["r_corr"] and art.discrete.dt == 0.001
    m = scipy.io.loadmat(tmp_path / "cancellation.mat")
    np.testing.assert_allclose(m["Ac"], art.continuous.A)
    assert art.family["seed"] == 5


def test_unknown_design(capsys):
    assert main(["design", "magic"]) == 2
    assert "unknown design 'magic'" in capsys.readouterr().err


@pytest.mark.parametrize("script", ["workspace", "virtual-damping", "cancellation"])
def test_design_scripts_run(script, tmp_path, capsys, monkeypatch):
    import runpy
    import sys

    monkeypatch.setattr(
        sys,
        "argv",
        [
            "designs",
            script,
            "--samples",
            "150",
            "--seed",
            "2",
            "--coverage-samples",
            "0",
            "--out",
            str(tmp_path),
        ],
    )
    with pytest.raises(SystemExit) as exc:
        runpy.run_module("designs", run_name="__main__")
    assert exc.value.code == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["name"] == script and obj["samples"] == 150 and obj["seed"] == 2
    assert 0.0 <= obj["fraction_stable"] <= 1.0
