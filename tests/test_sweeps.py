"""Sweeps: tables agree with direct validation; ``bdft sweep`` writes its page, plots and CSV."""

import csv
import json

import numpy as np
import pytest

from backhoe import default_family
from backhoe.families.sweeps import (
    frequency_damping_sweep,
    structure_frequency_sweep,
    workspace_sweep,
)
from bdft import main
from robust.errors import ParameterError
from uncertainty import validate_family
from uncertainty.sampling import SampleSet, sample


def test_workspace_sweep_rows_equal_direct_validation():
    fam = default_family("physical")
    res = workspace_sweep(fam, factors=[1.0, 2.0, 4.0], members=40, method="mc", seed=3)
    S = sample(fam.parameters, 40, method="mc", seed=3)
    for i, f in enumerate([1.0, 2.0, 4.0]):
        ref = validate_family(fam.with_workspace_factor(f), S)
        assert res.columns["fraction_stable"][i] == pytest.approx(ref.fraction_stable)
        assert res.columns["max_real_pole"][i] == pytest.approx(ref.max_real_pole)
    assert res.settings["seed"] == 3 and res.settings["members_per_point"] == 40


def test_frequency_damping_map_fixes_the_swept_pair():
    fam = default_family("physical").with_workspace_factor(2.0)
    res = frequency_damping_sweep(fam, n_f=3, n_z=2, members=10, seed=1)
    assert res.grid_shape == (3, 2) and len(res.columns["max_real_pole"]) == 6
    swept = ("human.f_arm_hz", "human.zeta_arm")
    base = [p for p in fam.parameters if p.name not in swept]
    S = sample(base, 10, method="lhs", seed=1)
    point = {n: res.columns[n][4] for n in swept}
    lo, hi = fam.parameter("human.f_arm_hz").low, fam.parameter("human.f_arm_hz").high
    assert point["human.f_arm_hz"] == pytest.approx(np.geomspace(lo, hi, 3)[2])
    vals = np.column_stack(
        [S.column(n) if n in S.names else np.full(10, point[n]) for n in fam.names]
    )
    ref = validate_family(fam, SampleSet(fam.names, vals, "lhs", 1, 10))
    assert res.columns["max_real_pole"][4] == pytest.approx(ref.max_real_pole)
    with pytest.raises(ParameterError, match="needs the physical human"):
        frequency_damping_sweep(default_family("literal"))


def test_structure_frequency_sweep_spans_tyres_to_stilts():
    res = structure_frequency_sweep(default_family("physical"), members=10)
    assert res.columns["f1_hz"][-1] == pytest.approx(6.3)
    assert res.columns["f1_hz"][0] == pytest.approx(0.4 * 6.3)


@pytest.mark.parametrize("name", ["workspace", "frequency-damping", "structure-frequency"])
def test_cli_sweep_writes_page_plots_and_csv(capsys, tmp_path, name):
    out = tmp_path / name
    assert (
        main(
            [
                "sweep",
                name,
                "--samples",
                "8",
                "--points",
                "3",
                "--seed",
                "5",
                "--out",
                str(out),
                "--json",
            ]
        )
        == 0
    )
    obj = json.loads(capsys.readouterr().out)
    assert obj["settings"]["seed"] == 5
    page = (out / "index.html").read_text()
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs and all(p in page for p in pngs)
    rows = list(csv.DictReader((out / f"{name}.csv").open()))
    assert len(rows) == (9 if name == "frequency-damping" else 3)
    assert float(rows[0]["fraction_stable"]) == pytest.approx(obj["columns"]["fraction_stable"][0])
    assert not list(out.glob(".*.tmp"))
