"""Data files (CSV, .mat) and component-fit files: round trips and the errors bad input raises."""

import json

import numpy as np
import pytest

from backhoe import StructureParams
from backhoe.sysid import (
    ChirpProtocol,
    identify_file,
    load_component_fit,
    paper_experiment,
    read_component_fit,
    save_component_fit,
)
from robust import ArtifactError, DataError, ParameterError
from robust.sysid import load_channels, save_experiment, select_channels

FS = 1000.0


@pytest.fixture(scope="module")
def experiment():
    return paper_experiment(
        "structure", ChirpProtocol(n_records=3, duration=8.0, f0_hz=0.5), noise=0.02, seed=99
    )


@pytest.mark.parametrize("suffix", [".csv", ".mat"], ids=["csv", "mat"])
def test_round_trip(tmp_path, experiment, suffix):
    path = save_experiment(experiment, tmp_path / f"data{suffix}")
    data = load_channels(path)
    assert data.seed == 99 and data.fs == FS
    assert set(data.names) == {"y", "c"}
    u, y = select_channels(data, "y", "c", FS)
    assert len(u) == 3
    np.testing.assert_allclose(np.array(u), experiment.u, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.array(y), experiment.y, rtol=1e-9, atol=1e-12)


def _write_csv(path, header, rows, comment="# fs=1000"):
    lines = [comment, ",".join(header)] + [",".join(str(v) for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _rows(n=50, records=1, dt=1e-3):
    out = []
    for r in range(records):
        for k in range(n):
            out.append([r, k * dt, np.sin(0.1 * k), np.cos(0.1 * k)])
    return out


def test_nan_names_channel_record_and_sample(tmp_path):
    rows = _rows(records=2)
    rows[50 + 7][3] = "nan"
    data = load_channels(_write_csv(tmp_path / "d.csv", ["record", "t", "e", "y"], rows))
    with pytest.raises(
        DataError, match=r"channel 'y' record 1 has 1 NaN/inf value\(s\), first at sample 7"
    ):
        select_channels(data, "e", "y", FS)


def test_non_uniform_sampling(tmp_path):
    rows = _rows()
    for r in rows[30:]:
        r[1] += 0.0005
    data = load_channels(_write_csv(tmp_path / "d.csv", ["record", "t", "e", "y"], rows))
    with pytest.raises(
        DataError, match=r"non-uniform sampling in record 0: .* between samples 29 and 30"
    ):
        select_channels(data, "e", "y", FS)


@pytest.mark.parametrize(
    "comment, dt, match",
    [
        ("# fs=500", 1e-3, r"the file states fs=500 Hz but fs=1000 Hz was given"),
        ("# data", 2e-3, r"time column gives 500 Hz but fs=1000 Hz was given"),
    ],
    ids=["stated-rate", "time-column"],
)
def test_mismatched_sampling_rate(tmp_path, comment, dt, match):
    data = load_channels(
        _write_csv(tmp_path / "d.csv", ["record", "t", "e", "y"], _rows(dt=dt), comment)
    )
    with pytest.raises(DataError, match=match):
        select_channels(data, "e", "y", FS)


def test_mismatched_channel_lengths_in_mat(tmp_path):
    import scipy.io

    path = tmp_path / "d.mat"
    scipy.io.savemat(path, {"e": np.zeros(100), "y": np.zeros(99), "fs": 1000.0})
    data = load_channels(path)
    with pytest.raises(
        DataError, match=r"mismatched sampling: record 0 has 100 samples of 'e' but 99 of 'y'"
    ):
        select_channels(data, "e", "y", FS)


def test_too_short_record_for_band(tmp_path, experiment):
    path = save_experiment(experiment, tmp_path / "d.csv")
    with pytest.raises(DataError, match=r"record 0 of 'y'/'c' lasts 8 s .* expected at least 20 s"):
        identify_file(path, "y", "c", FS, "structure", (0.1, 15.0))


def test_band_outside_data(tmp_path, experiment):
    path = save_experiment(experiment, tmp_path / "d.csv")
    with pytest.raises(DataError, match=r"beyond the Nyquist frequency fs/2 = 500 Hz"):
        identify_file(path, "y", "c", FS, "structure", (2.0, 700.0))


@pytest.mark.parametrize(
    "content, match",
    [
        ("record,t,e,y\n0,0,1,x\n", r"non-numeric or missing value"),
        ("1,2,3\n4,5,6\n", r"looks numeric; the first row must name the channels"),
        ("record,t,e,y\n0,0,1,2\n1,0.001,1,2\n0,0.002,1,2\n", r"record ids repeat"),
        ("e,e\n1,2\n", r"header must name every column once"),
    ],
    ids=["non-numeric", "no-header", "non-contiguous-records", "duplicate-channel"],
)
def test_malformed_csv(tmp_path, content, match):
    path = tmp_path / "d.csv"
    path.write_text(content)
    with pytest.raises(DataError, match=match):
        load_channels(path)


def test_unknown_channel_lists_available(tmp_path, experiment):
    data = load_channels(save_experiment(experiment, tmp_path / "d.csv"))
    with pytest.raises(
        DataError, match=r"channel 'acc' not found in d.csv; available: \['y', 'c'\]"
    ):
        select_channels(data, "acc", "c", FS)


def test_missing_file_and_bad_suffix(tmp_path):
    with pytest.raises(DataError, match=r"does not exist"):
        load_channels(tmp_path / "nope.csv")
    (tmp_path / "d.xlsx").write_text("x")
    with pytest.raises(DataError, match=r"expected a .csv, .txt or .mat file; got suffix '.xlsx'"):
        load_channels(tmp_path / "d.xlsx")


# --- component-fit files ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def structure_fit(experiment):
    from backhoe.sysid import fit_frequency_response
    from robust.sysid import estimate_frequency_response

    est = estimate_frequency_response(experiment.u, experiment.y, experiment.fs)
    return fit_frequency_response(est, "structure", (2.0, 15.0))


def test_component_fit_round_trip(tmp_path, structure_fit):
    path = save_component_fit(tmp_path / "m.json", structure_fit, fs=FS, seed=99, source="d.csv")
    params = load_component_fit(path)
    assert isinstance(params, StructureParams)
    assert params == structure_fit.params
    rec = read_component_fit(path)
    assert (rec.form, rec.seed, rec.source, rec.band) == ("structure", 99, "d.csv", (2.0, 15.0))
    obj = json.loads(path.read_text())
    assert obj["kind"] == "bdft-component-fit" and obj["params_class"] == "StructureParams"


def _edit(obj, path, **changes):
    bad = json.loads(json.dumps(obj))
    for k, v in changes.items():
        if k.startswith("params."):
            bad["params"][k.split(".", 1)[1]] = v
        else:
            bad[k] = v
    path.write_text(json.dumps(bad))
    return path


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"kind": "controller"}, r"field 'kind' must be 'bdft-component-fit'; got 'controller'"),
        (
            {"form": "valve"},
            r"form 'valve' needs params_class 'ValveCylinderParams'; got 'StructureParams'",
        ),
        ({"form": "cab"}, r"field 'form' must be one of"),
        (
            {"params.zeta1": -0.1},
            r"not physical: StructureParams.zeta1 must be a finite value in \(0, 1\)",
        ),
        ({"params.k_s": "big"}, r"field 'k_s' must be a finite number; got 'big'"),
        ({"params.extra": 1.0}, r"missing \[\], unexpected \['extra'\]"),
        ({"band": [15.0, 2.0]}, r"field 'band' must be \[lo, hi\]"),
        ({"fs": -1.0}, r"field 'fs' must be positive"),
        ({"seed": 1.5}, r"field 'seed' must be an integer or null"),
    ],
    ids=[
        "kind",
        "class-mismatch",
        "form",
        "unphysical",
        "non-numeric",
        "unexpected-param",
        "band",
        "fs",
        "seed",
    ],
)
def test_component_fit_validation(tmp_path, structure_fit, changes, match):
    good = save_component_fit(tmp_path / "m.json", structure_fit, fs=FS, seed=None, source="d.csv")
    obj = json.loads(good.read_text())
    path = _edit(obj, tmp_path / "bad.json", **changes)
    with pytest.raises(ArtifactError, match=match):
        load_component_fit(path)


def test_component_fit_unreadable(tmp_path):
    with pytest.raises(ArtifactError, match=r"cannot read component-fit file"):
        load_component_fit(tmp_path / "missing.json")
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(ArtifactError, match=r"not valid JSON"):
        load_component_fit(tmp_path / "x.json")


def test_rational_fit_cannot_be_saved_as_component(tmp_path, experiment):
    from backhoe.sysid import fit_frequency_response
    from robust.sysid import estimate_frequency_response

    est = estimate_frequency_response(experiment.u, experiment.y, experiment.fs)
    fit = fit_frequency_response(est, "4/4", (2.0, 15.0))
    with pytest.raises(
        ParameterError, match=r"only the forms .* can be saved as component models; got '4/4'"
    ):
        save_component_fit(tmp_path / "m.json", fit, fs=FS, seed=None, source="d.csv")
    assert not (tmp_path / "m.json").exists()


def test_unreadable_mat_file(tmp_path):
    (tmp_path / "d.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(DataError, match=r"d.mat: cannot read as a MATLAB .mat file"):
        load_channels(tmp_path / "d.mat")
