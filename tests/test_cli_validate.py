"""``bdft validate``: JSON contract, seeds, controller and component-fit files, errors."""

import json

import control as ct
import numpy as np
import pytest

from backhoe import default_family
from backhoe.families.files import load_component_fit, load_controller
from bdft import main
from robust.jsonio import round_significant
from uncertainty import sample, validate_family

KEYS = {"samples", "seed", "method", "fraction_stable", "max_real_pole", "min_damping", "worst"}


def run_json(capsys, *argv):
    assert main(["validate", *argv, "--json"]) == 0
    out = capsys.readouterr().out
    return json.loads(out)


def run_bytes(capsys, *argv):
    assert main(["validate", *argv, "--json"]) == 0
    captured = capsys.readouterr()
    return captured.out, captured.err


@pytest.mark.parametrize("method", ["mc", "lhs", "grid", "vertices"])
def test_json_contract_and_agreement_with_the_library(capsys, method):
    obj = run_json(capsys, "--samples", "300", "--method", method, "--seed", "4")
    assert KEYS <= set(obj)
    fam = default_family("physical")
    ref = validate_family(fam, sample(fam.parameters, 300, method=method, seed=4))
    assert obj["samples"] == ref.samples and obj["seed"] == 4 and obj["method"] == method
    # the JSON's numbers are the library's to six significant digits
    assert obj["fraction_stable"] == round_significant(ref.fraction_stable)
    assert obj["max_real_pole"] == round_significant(ref.max_real_pole)
    assert obj["min_damping"] == round_significant(ref.min_damping)
    assert obj["worst"] == round_significant(ref.worst)
    assert set(obj["worst"]) == set(fam.names)


def test_same_seed_same_output_and_literal_variant(capsys):
    argv = ("--samples", "200", "--method", "mc", "--seed", "9", "--human", "literal")
    out_a, err_a = run_bytes(capsys, *argv)
    out_b, _ = run_bytes(capsys, *argv)
    assert out_a == out_b  # the same bytes: no wall-clock value in the result
    a = json.loads(out_a)
    assert "elapsed_s" not in a
    assert a["human"] == "literal" and "human.k_h" in a["worst"]
    assert "[bdft validate] 200 members in" in err_a  # the timing goes to stderr


def test_human_readable_output(capsys):
    assert main(["validate", "--samples", "50"]) == 0
    out = capsys.readouterr().out
    assert "fraction stable" in out and "worst member" in out


def _write(path, obj):
    path.write_text(json.dumps(obj))
    return str(path)


def test_controller_file_is_validated_like_the_library(capsys, tmp_path):
    A, B, C, D = [[-30.0, 0.0], [1.0, -20.0]], [[1.0], [0.0]], [[0.0, 0.4]], [[0.0]]
    path = _write(
        tmp_path / "k.json", {"A": A, "B": B, "C": C, "D": D, "inputs": ["c"], "outputs": ["f"]}
    )
    obj = run_json(capsys, "--samples", "200", "--controller", path)
    K = ct.ss(A, B, C, D, inputs=["c"], outputs=["f"])
    fam = default_family("physical")
    ref = validate_family(fam, sample(fam.parameters, 200, method="lhs", seed=0), controller=K)
    assert obj["controller_states"] == 2 and obj["nstates"] == 15
    assert obj["max_real_pole"] == round_significant(ref.max_real_pole)
    assert obj["controller"] == path
    K2 = load_controller(path)
    np.testing.assert_array_equal(K2.A, np.array(A))


@pytest.mark.parametrize(
    "content, match",
    [
        ("not json", "is not valid JSON"),
        (
            json.dumps({"A": [[-1]], "B": [[1]], "C": [[1]], "inputs": ["c"], "outputs": ["f"]}),
            "missing matrix 'D'",
        ),
        (
            json.dumps(
                {
                    "A": [[-1]],
                    "B": [[1, 2]],
                    "C": [[1]],
                    "D": [[0]],
                    "inputs": ["c"],
                    "outputs": ["f"],
                }
            ),
            "B must have shape",
        ),
        (
            json.dumps(
                {"A": [[-1]], "B": [[1]], "C": [[1]], "D": [[0]], "inputs": ["u"], "outputs": ["f"]}
            ),
            "controller inputs must be",
        ),
        (
            json.dumps(
                {
                    "A": [[-1]],
                    "B": [[1]],
                    "C": [["nan"]],
                    "D": [[0]],
                    "inputs": ["c"],
                    "outputs": ["f"],
                }
            ),
            "C contains NaN",
        ),
        (
            json.dumps(
                {
                    "A": [[-1]],
                    "B": [[1]],
                    "C": [[1]],
                    "D": [[0]],
                    "inputs": ["c"],
                    "outputs": ["f"],
                    "dt": 0.001,
                }
            ),
            "must be continuous-time",
        ),
    ],
    ids=["not-json", "missing-D", "bad-shape", "bad-signal", "nan", "discrete"],
)
def test_bad_controller_file_exits_2_with_message(capsys, tmp_path, content, match):
    path = tmp_path / "k.json"
    path.write_text(content)
    assert main(["validate", "--samples", "10", "--controller", str(path), "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "bdft validate: error:" in captured.err and match in captured.err


def _structure_fit(**params):
    p = {"k_s": 210.0, "zeta1": 0.12, "zeta2": 0.2, "f1_hz": 5.0, "f2_hz": 5.5}
    p.update(params)
    return {
        "kind": "bdft-component-fit",
        "form": "structure",
        "params_class": "StructureParams",
        "params": p,
        "fit_error_db": 0.1,
        "band": [2, 15],
        "fs": 1000.0,
        "seed": 7,
        "source": "rig.csv",
    }


def test_plant_file_replaces_the_nominal(capsys, tmp_path):
    path = _write(tmp_path / "s.json", _structure_fit())
    obj = run_json(capsys, "--samples", "100", "--plant-file", path, "--method", "vertices")
    assert obj["nominals"]["struct"]["f1_hz"] == 5.0
    assert obj["worst"]["struct.f1_hz"] <= 5.0 + 1e-12  # the range now ends at the fitted frequency
    assert obj["plant_files"] == [path]
    fit = load_component_fit(path)
    assert fit.form == "structure" and fit.params.k_s == 210.0 and fit.seed == 7


def test_literal_human_fit_needs_the_literal_variant(capsys, tmp_path):
    fit = {
        "kind": "bdft-component-fit",
        "form": "human",
        "params_class": "LiteralHumanParams",
        "params": {"k_h": 4.0, "z1": 50.0, "p1": 1.6},
        "fit_error_db": 0.5,
        "band": [1, 10],
        "fs": 1000.0,
        "seed": None,
        "source": "subject.csv",
    }
    path = _write(tmp_path / "h.json", fit)
    assert main(["validate", "--samples", "10", "--plant-file", path]) == 2
    assert "Use --human literal" in capsys.readouterr().err
    obj = run_json(capsys, "--samples", "10", "--plant-file", path, "--human", "literal")
    assert obj["nominals"]["human_nominal"]["k_h"] == 4.0


@pytest.mark.parametrize(
    "change, match",
    [
        (dict(kind="other"), "'kind' must be 'bdft-component-fit'; got 'other'"),
        (dict(form="seat"), "'form' must be one of"),
        (dict(params_class="ValveCylinderParams"), "needs params_class 'StructureParams'"),
        (dict(params={"k_s": 1.0}), "missing"),
        (
            dict(params={"k_s": -1.0, "zeta1": 0.1, "zeta2": 0.2, "f1_hz": 6.0, "f2_hz": 6.0}),
            "StructureParams.k_s",
        ),
    ],
    ids=["kind", "form", "class", "missing-params", "negative-gain"],
)
def test_malformed_plant_file_exits_2(capsys, tmp_path, change, match):
    obj = _structure_fit()
    obj.update(change)
    path = _write(tmp_path / "s.json", obj)
    assert main(["validate", "--samples", "10", "--plant-file", path]) == 2
    assert match in capsys.readouterr().err


def test_bad_options_are_rejected(capsys):
    assert main(["validate", "--samples", "0"]) == 2
    assert "bdft validate: error: --samples: expected" in capsys.readouterr().err
    assert main(["validate", "--method", "sobol"]) == 2
    err = capsys.readouterr().err
    assert "--method: expected one of 'mc', 'lhs', 'grid', 'vertices'; got 'sobol'" in err
    assert main(["validate", "--samples", "10", "--workspace-factor", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--workspace-factor: expected a positive finite number; got -1" in err
