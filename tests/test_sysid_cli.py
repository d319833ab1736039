"""``bdft identify`` end to end, in-process: simulated noisy data -> fitted component -> loop."""

import dataclasses
import json
import re
from pathlib import Path

import pytest

from backhoe import BDFTLoop, LiteralHuman, LiteralHumanParams, StructureParams, ValveCylinderParams
from backhoe.sysid import ChirpProtocol, load_component_fit, paper_experiment
from bdft import main
from robust.jsonio import round_significant
from robust.sysid import save_experiment

TRUTH = {
    "valve": ValveCylinderParams(),
    "structure": StructureParams(),
    "human": LiteralHumanParams(),
}
CHANNELS = {"valve": ("e", "y"), "structure": ("y", "c"), "human": ("c", "h")}
BANDS = {"valve": ("0.5", "20"), "structure": ("2", "15"), "human": ("0.15", "20")}
# the stated tolerances of tests/test_sysid_fit.py (same protocol and noise)
TOLERANCES = {
    "valve": {"k_vc": 0.01, "p1": 0.05, "wn_hz": 0.01, "zeta": 0.01},
    "structure": {"k_s": 0.01, "zeta1": 0.03, "zeta2": 0.03, "f1_hz": 0.01, "f2_hz": 0.01},
    "human": {"k_h": 0.05, "z1": 0.05, "p1": 0.10},
}


@pytest.fixture(scope="module")
def chirps(tmp_path_factory):
    """A folder of the simulated records, each written once for the module's tests."""
    return tmp_path_factory.mktemp("chirps")


def _data(chirps, form, suffix=".csv", seed=31):
    path = chirps / f"seed{seed}" / f"chirp_{form}{suffix}"
    if path.exists():  # the same form, noise and seed: the same records
        return path
    path.parent.mkdir(exist_ok=True)
    exp = paper_experiment(
        form, ChirpProtocol(n_records=6), noise=0.02, engine_tone=0.02, seed=seed
    )
    return save_experiment(exp, path)


def _identify(path, form, out, *extra, fit_form=None):
    ch_in, ch_out = CHANNELS[form]
    return main(
        [
            "identify",
            str(path),
            "--input",
            ch_in,
            "--output",
            ch_out,
            "--fs",
            "1000",
            "--form",
            fit_form or form,
            "--band",
            *BANDS[form],
            "--out",
            str(out),
            *extra,
        ]
    )


@pytest.mark.parametrize("form", list(TRUTH), ids=list(TRUTH))
def test_identify_recovers_component_and_model_drops_into_loop(tmp_path, capsys, form, chirps):
    data = _data(chirps, form)
    out = tmp_path / "out"
    model = tmp_path / f"{form}_model.json"
    assert _identify(data, form, out, "--json", "--save-model", str(model)) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["form"] == form
    assert summary["band"] == [float(b) for b in BANDS[form]]
    assert summary["seed"] == 31 and summary["fit_error_db"] < 1.0
    for name, true in dataclasses.asdict(TRUTH[form]).items():
        assert summary["params"][name] == pytest.approx(true, rel=TOLERANCES[form][name]), name
    for key in ("bode_png", "coherence_png", "h1_csv", "fit_json"):
        assert Path(summary["outputs"][key]).stat().st_size > 0, key
    table = (out / f"chirp_{form}_{form}_h1.csv").read_text().splitlines()
    assert table[0].startswith("# bdft identify:") and "seed=31" in table[0]
    assert table[1].split(",")[:3] == ["f_hz", "h1_re", "h1_im"]
    params = load_component_fit(model)
    assert isinstance(params, type(TRUTH[form]))
    field = {"valve": "valve", "structure": "struct"}.get(form)
    loop = BDFTLoop(**{field: params}) if field else BDFTLoop(human=LiteralHuman(params))
    assert loop.system().nstates > 0


def test_identify_text_output_and_mat_input(tmp_path, capsys, chirps):
    data = _data(chirps, "structure", suffix=".mat")
    assert _identify(data, "structure", tmp_path / "out") == 0
    text = capsys.readouterr().out
    assert "form structure (StructureParams)" in text and "f1_hz" in text and "seed: 31" in text


def test_identify_rational_form(tmp_path, capsys, chirps):
    data = _data(chirps, "structure")
    assert _identify(data, "structure", tmp_path / "out", "--json", fit_form="4/4") == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["form"] == "4/4" and summary["params_class"] == "RationalParams"
    assert set(summary["params"]) == {"b4", "b3", "b2", "b1", "b0", "a4", "a3", "a2", "a1", "a0"}
    assert summary["fit_error_db"] < 1.0
    assert (tmp_path / "out" / "chirp_structure_4-4_bode.png").exists()


def _listing(path):
    return sorted(p.name for p in path.rglob("*")) if path.exists() else []


@pytest.mark.parametrize(
    "case, match",
    [
        ("nan", r"channel 'c' record 2 has 1 NaN/inf value"),
        ("nyquist", r"beyond the Nyquist frequency"),
        ("rational-save", r"--save-model needs a fixed form"),
        ("channel", r"channel 'acc' not found"),
    ],
    ids=["nan", "band-above-nyquist", "rational-save-model", "unknown-channel"],
)
def test_identify_failure_writes_nothing(tmp_path, capsys, case, match):
    exp = paper_experiment(
        "structure", ChirpProtocol(n_records=3, duration=8.0, f0_hz=0.5), noise=0.02, seed=5
    )
    data = save_experiment(exp, tmp_path / "d.csv")
    if case == "nan":
        lines = data.read_text().splitlines()
        idx = next(i for i, ln in enumerate(lines) if ln.startswith("2,"))
        parts = lines[idx].split(",")
        parts[3] = "nan"
        lines[idx] = ",".join(parts)
        data.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    model = tmp_path / "model.json"
    args = [
        "identify",
        str(data),
        "--input",
        "acc" if case == "channel" else "y",
        "--output",
        "c",
        "--fs",
        "1000",
        "--form",
        "2/4" if case == "rational-save" else "structure",
        "--band",
        "2",
        "700" if case == "nyquist" else "15",
        "--out",
        str(out),
        "--save-model",
        str(model),
    ]
    before = _listing(tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "bdft identify: error:" in err
    assert re.search(match, err), err
    assert _listing(tmp_path) == before


def test_measured_csv_to_model_that_validate_accepts(tmp_path, capsys, chirps):
    # a CSV of 'measured' chirps (here simulated, with its seed in the file) -> identify -> validate
    data = _data(chirps, "structure", seed=77)
    model = tmp_path / "structure_model.json"
    assert _identify(data, "structure", tmp_path / "out", "--save-model", str(model)) == 0
    capsys.readouterr()
    assert main(["validate", "--samples", "8", "--plant-file", str(model), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["plant_files"] == [str(model)]
    params = json.loads(model.read_text())["params"]
    assert report["nominals"]["struct"] == round_significant(params)


def test_identify_spectral_and_fit_options_reach_the_estimate(tmp_path, capsys, chirps):
    data = _data(chirps, "structure")
    extra = ["--json", "--nperseg", "5000", "--window", "hann", "--detrend", "linear",
             "--significance", "1", "--min-coherence", "0.5"]  # fmt: skip
    assert _identify(data, "structure", tmp_path / "out", *extra) == 0
    summary = json.loads(capsys.readouterr().out)
    spec = summary["spectral"]
    assert (spec["nperseg"], spec["window"], spec["detrend"]) == (5000, "hann", "linear")
    assert spec["n_segments"] == 6 * 9  # 25 s records, 5 s segments, 50 % overlap
    assert summary["coherence_threshold"] == 0.5
    assert summary["params"]["f1_hz"] == pytest.approx(6.3, rel=0.02)
