import json

import control as ct
import numpy as np
import pytest
import scipy.io

from robust.errors import ArtifactError
from robust.export import ControllerArtifact, discretize, load_artifact, write_artifact


@pytest.fixture
def artifact():
    K = ct.ss(
        [[-5.0, 1.0], [0.0, -40.0]],
        [[1.0, 0.0], [0.0, 1.0]],
        [[1.0, 2.0]],
        [[0.0, 0.1]],
        inputs=["x", "c"],
        outputs=["f"],
        name="K",
    )
    return ControllerArtifact(
        "test", K, discretize(K, 0.001, prewarp_hz=6.4), 6.4, weights={"w": 1.0}, family={"seed": 7}
    )


def test_round_trip(tmp_path, artifact):
    paths = write_artifact(artifact, tmp_path / "k.json")
    art = load_artifact(paths["json"])
    np.testing.assert_allclose(art.continuous.A, artifact.continuous.A)
    np.testing.assert_allclose(art.discrete.B, artifact.discrete.B)
    assert art.inputs == ["x", "c"] and art.outputs == ["f"]
    assert art.discrete.dt == 0.001 and art.family == {"seed": 7}
    m = scipy.io.loadmat(paths["mat"])
    np.testing.assert_allclose(m["Ad"], artifact.discrete.A)
    assert float(m["Ts"][0, 0]) == 0.001
    assert [str(s[0]) for s in m["inputs"].ravel()] == ["x", "c"]


def test_prewarped_tustin_matches_at_prewarp_frequency(artifact):
    K, Kd = artifact.continuous, artifact.discrete
    w = 2 * np.pi * 6.4
    np.testing.assert_allclose(
        np.asarray(Kd(np.exp(1j * w * 0.001), squeeze=False)),
        np.asarray(K(1j * w, squeeze=False)),
        rtol=1e-9,
    )


def _corrupt(tmp_path, artifact, change):
    p = write_artifact(artifact, tmp_path / "k.json", mat=False)["json"]
    d = json.loads(p.read_text())
    change(d)
    p.write_text(json.dumps(d))
    return p


@pytest.mark.parametrize(
    "change,match",
    [
        (lambda d: d.update(kind="other"), r"'kind' must be 'bdft-controller'"),
        (lambda d: d.update(format_version=99), r"format_version must be 1; got 99"),
        (lambda d: d["continuous"].update(A=[[1.0, "nan"], [0, 1]]), r"continuous.A: contains NaN"),
        (
            lambda d: d["continuous"].update(B=[[1.0, 2.0, 3.0]]),
            r"continuous.B: expected shape \(2, 2\)",
        ),
        (lambda d: d["discrete"].update(dt=-0.001), r"discrete.dt must be a positive sample time"),
        (lambda d: d["discrete"]["A"][0].__setitem__(0, 0.5), r"not the Tustin transform"),
        (lambda d: d.update(inputs=["x", "x"]), r"field 'inputs' names a signal twice"),
    ],
    ids=["kind", "version", "nan", "shape", "dt", "tampered", "signal"],
)
def test_load_rejects_bad_artifacts(tmp_path, artifact, change, match):
    with pytest.raises(ArtifactError, match=match):
        load_artifact(_corrupt(tmp_path, artifact, change))


def test_load_missing_and_not_json(tmp_path):
    with pytest.raises(ArtifactError, match="does not exist"):
        load_artifact(tmp_path / "none.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ArtifactError, match="not valid JSON"):
        load_artifact(bad)


def test_failed_write_leaves_nothing(tmp_path, artifact, monkeypatch):
    import robust.export as ex

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(scipy.io, "savemat", boom)
    with pytest.raises(OSError, match="disk full"):
        ex.write_artifact(artifact, tmp_path / "k.json")
    # the pair is written together: neither file, and no temporary file, remains
    assert sorted(p.name for p in tmp_path.iterdir()) == []
