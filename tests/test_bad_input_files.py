"""Bad files: the artifact and controller loaders, the artifact pair, report folders, sample time.

A malformed file of any kind (random bytes, a folder, a field of the wrong type)
raises :class:`robust.errors.ArtifactError` naming the file and the field; writers
write all of their files or none, with the usual mode, and never replace a file of
the user's. The hypothesis tests feed the parsers random bytes and random JSON.
"""

from __future__ import annotations

import copy
import json
import math
import os
import warnings
from pathlib import Path

import control as ct
import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import robust.jsonio
from backhoe.families.files import load_controller
from backhoe.sysid.identify import identify_records
from reports.html import REPORT_MARKER, HtmlPage, is_report_dir, write_report_dir
from robust.errors import ArtifactError, DataError, ParameterError
from robust.export import (
    ControllerArtifact,
    discretize,
    is_artifact_file,
    load_artifact,
    write_artifact,
)
from robust.jsonio import atomic_write_group


def _controller():
    return ct.ss(
        [[-5.0, 1.0], [0.0, -40.0]],
        [[1.0, 0.0], [0.0, 1.0]],
        [[1.0, 2.0]],
        [[0.0, 0.1]],
        inputs=["x", "c"],
        outputs=["f"],
        name="K",
    )


@pytest.fixture(scope="module")
def artifact():
    K = _controller()
    return ControllerArtifact(
        "test", K, discretize(K, 0.001, prewarp_hz=6.4), 6.4, weights={"w": 1.0}, family={"seed": 7}
    )


@pytest.fixture(scope="module")
def document(artifact):
    """The JSON document of a valid artifact."""
    return artifact.to_dict()


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


# --------------------------------------------------------------------------------------
# load_artifact: whole-file problems
# --------------------------------------------------------------------------------------

FILE_CASES = [
    ("random-bytes", b"\x89\xfe\x00\x13\x9c\xff garbage", "not UTF-8 text"),
    ("empty", b"", "is not valid JSON"),
    ("truncated", b'{"kind": "bdft-controller", "inputs": [', "is not valid JSON"),
    ("deep", b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
    ("long-integer", b'{"kind": ' + b"9" * 5000 + b"}", "is not valid JSON"),
    ("array", b"[1, 2]", "got a JSON array"),
    ("string", b'"bdft-controller"', "got a JSON string"),
    ("null", b"null", "got a JSON null"),
    ("number", b"3.5", "got a JSON number"),
]


@pytest.mark.parametrize("name, content, detail", FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_load_artifact_rejects_bad_bytes(tmp_path, name, content, detail):
    path = tmp_path / f"{name}.json"
    path.write_bytes(content)
    with pytest.raises(ArtifactError) as exc:
        load_artifact(path)
    msg = str(exc.value)
    assert str(path) in msg and detail in msg, msg


def test_load_artifact_rejects_a_folder_and_a_missing_file(tmp_path):
    with pytest.raises(ArtifactError, match=r"is a directory; expected a JSON file") as exc:
        load_artifact(tmp_path)
    assert str(tmp_path) in str(exc.value)
    with pytest.raises(ArtifactError, match=r"none\.json does not exist"):
        load_artifact(tmp_path / "none.json")


def test_load_artifact_rejects_an_oversized_file(tmp_path, monkeypatch, artifact):
    path = write_artifact(artifact, tmp_path / "k.json", mat=False)["json"]
    monkeypatch.setattr("robust.export.MAX_ARTIFACT_BYTES", 100)
    with pytest.raises(ArtifactError, match=r"k\.json has \d+ bytes; expected .* at most 100"):
        load_artifact(path)


# --------------------------------------------------------------------------------------
# load_artifact: one field of the wrong type or value
# --------------------------------------------------------------------------------------


def _set(path: tuple, value):
    def change(d):
        target = d
        for key in path[:-1]:
            target = target[key]
        if value is _DELETE:
            del target[path[-1]]
        else:
            target[path[-1]] = value

    return change


_DELETE = object()

FIELD_CASES = [
    # (id, path of the field, new value, the message names ...)
    ("kind-list", ("kind",), ["bdft-controller"], r"'kind' must be 'bdft-controller'"),
    ("kind-missing", ("kind",), _DELETE, r"'kind' must be 'bdft-controller'; got None"),
    ("version-string", ("format_version",), "1", r"format_version must be 1; got '1'"),
    ("version-bool", ("format_version",), True, r"format_version must be 1; got True"),
    ("version-float", ("format_version",), 1.0, r"format_version must be 1; got 1.0"),
    ("inputs-string", ("inputs",), "x", r"field 'inputs' must be a non-empty list"),
    ("inputs-numbers", ("inputs",), [1, 2], r"field 'inputs' must be a non-empty list"),
    ("inputs-empty-name", ("inputs",), ["x", ""], r"field 'inputs' must be a non-empty list"),
    ("inputs-twice", ("inputs",), ["x", "x"], r"field 'inputs' names a signal twice"),
    ("outputs-empty", ("outputs",), [], r"field 'outputs' must be a non-empty list"),
    ("outputs-dict", ("outputs",), {"f": 1}, r"field 'outputs' must be a non-empty list"),
    ("continuous-list", ("continuous",), [1, 2], r"field 'continuous' must be an object"),
    ("discrete-missing", ("discrete",), _DELETE, r"field 'discrete' must be an object"),
    ("A-string", ("continuous", "A"), "[[1]]", r"continuous\.A: expected a numeric matrix"),
    ("A-dict", ("continuous", "A"), {"a": 1}, r"continuous\.A: expected a numeric matrix"),
    ("A-none", ("continuous", "A"), [[None, 1.0], [0, 1]], r"continuous\.A: expected a numeric"),
    ("A-text", ("continuous", "A"), [["one", 1.0], [0, 1]], r"continuous\.A: expected a numeric"),
    ("A-ragged", ("continuous", "A"), [[1.0], [0, 1]], r"continuous\.A: expected a numeric"),
    ("A-huge-int", ("continuous", "A"), [[10**400, 0], [0, 1]], r"continuous\.A: expected a num"),
    ("A-bool", ("continuous", "A"), [[True, 0], [0, 1]], r"got an entry True \(a JSON boolean\)"),
    ("A-3d", ("continuous", "A"), [[[1.0]]], r"continuous\.A: expected a 2-D matrix"),
    ("A-scalar", ("continuous", "A"), 5, r"continuous\.A: expected a numeric matrix"),
    ("A-missing", ("continuous", "A"), _DELETE, r"continuous: missing matrix 'A'"),
    ("A-inf", ("continuous", "A"), [[1e999, 0], [0, 1]], r"continuous\.A: contains NaN or inf"),
    ("B-shape", ("continuous", "B"), [[1.0, 2.0, 3.0]], r"continuous\.B: expected shape \(2, 2\)"),
    ("D-shape", ("discrete", "D"), [[0.0]], r"discrete\.D: expected shape \(1, 2\)"),
    ("dt-string", ("discrete", "dt"), "0.001", r"discrete\.dt must be a positive sample time"),
    ("dt-bool", ("discrete", "dt"), True, r"discrete\.dt must be a positive sample time"),
    ("dt-zero", ("discrete", "dt"), 0, r"discrete\.dt must be a positive sample time"),
    ("dt-negative", ("discrete", "dt"), -0.001, r"discrete\.dt .*; got -0\.001"),
    ("dt-inf", ("discrete", "dt"), 1e999, r"discrete\.dt .*; got inf"),
    ("dt-missing", ("discrete", "dt"), _DELETE, r"discrete\.dt .*; got None"),
    ("prewarp-string", ("discrete", "prewarp_hz"), "6.4", r"discrete\.prewarp_hz must be null"),
    ("prewarp-above-nyquist", ("discrete", "prewarp_hz"), 600.0, r"prewarp_hz .*\(0, 500\) Hz"),
    ("prewarp-negative", ("discrete", "prewarp_hz"), -1.0, r"discrete\.prewarp_hz .*; got -1\.0"),
    ("prewarp-list", ("discrete", "prewarp_hz"), [6.4], r"discrete\.prewarp_hz must be null"),
    ("name-number", ("name",), 5, r"field 'name' must be a string; got 5"),
    ("weights-list", ("weights",), [1, 2], r"field 'weights' must be a JSON object"),
    ("family-string", ("family",), "default", r"field 'family' must be a JSON object"),
    ("extra-null", ("extra",), None, r"field 'extra' must be a JSON object"),
    ("tampered", ("discrete", "A"), [[0.5, 0.0], [0.0, 0.5]], r"not the Tustin transform"),
]


@pytest.mark.parametrize(
    "field, value, match", [c[1:] for c in FIELD_CASES], ids=[c[0] for c in FIELD_CASES]
)
def test_load_artifact_names_the_bad_field(tmp_path, document, field, value, match):
    d = copy.deepcopy(document)
    _set(field, value)(d)
    path = tmp_path / "k.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ArtifactError, match=match) as exc:
        load_artifact(path)
    assert "k.json" in str(exc.value)


@pytest.mark.parametrize(
    "field, value, match",
    [
        (("discrete", "dt"), "fast", r"discrete\.dt must be a positive sample time"),
        (("continuous", "C"), {"rows": 1}, r"continuous\.C: expected a numeric matrix"),
        (("outputs",), ["r_corr", 7], r"field 'outputs' must be a non-empty list"),
    ],
    ids=["dt", "C", "outputs"],
)
def test_load_controller_reports_artifact_fields(tmp_path, document, field, value, match):
    # backhoe.families.files.load_controller reads artifacts through load_artifact
    d = copy.deepcopy(document)
    _set(field, value)(d)
    path = tmp_path / "k.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ArtifactError, match=match) as exc:
        load_controller(path)
    assert "k.json" in str(exc.value)


def test_a_valid_artifact_still_loads(tmp_path, artifact):
    art = load_artifact(write_artifact(artifact, tmp_path / "k.json")["json"])
    np.testing.assert_allclose(art.discrete.A, artifact.discrete.A)
    assert art.prewarp_hz == 6.4 and art.weights == {"w": 1.0} and art.name == "test"
    np.testing.assert_allclose(load_controller(tmp_path / "k.json").A, artifact.continuous.A)


# --------------------------------------------------------------------------------------
# discretize: the sample time and the prewarping frequency
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "dt",
    [0, 0.0, -0.001, math.nan, math.inf, -math.inf, True, "0.001", None],
    ids=["zero", "zero-float", "negative", "nan", "inf", "-inf", "bool", "string", "none"],
)
def test_discretize_rejects_a_bad_sample_time(dt):
    with pytest.raises(ParameterError, match=r"discretize: dt must be a positive, finite"):
        discretize(_controller(), dt)


@pytest.mark.parametrize(
    "prewarp",
    [0.0, -6.0, math.nan, 500.0, 1e6, "6"],
    ids=["zero", "negative", "nan", "nyquist", "far-above", "string"],
)
def test_discretize_rejects_a_bad_prewarp_frequency(prewarp):
    with pytest.raises(ParameterError, match=r"discretize: prewarp_hz must be a frequency in"):
        discretize(_controller(), 0.001, prewarp_hz=prewarp)


def test_discretize_accepts_numpy_numbers():
    Kd = discretize(_controller(), np.float64(0.002), prewarp_hz=np.float32(6.0))
    assert Kd.dt == 0.002 and Kd.nstates == 2


# --------------------------------------------------------------------------------------
# write_artifact: a pair, the usual mode, never a user's file
# --------------------------------------------------------------------------------------


def test_artifact_pair_gets_the_usual_mode(tmp_path, artifact):
    old = os.umask(0o027)
    try:
        paths = write_artifact(artifact, tmp_path / "k.json")
    finally:
        os.umask(old)
    for p in paths.values():
        assert (p.stat().st_mode & 0o777) == 0o640, p
    assert is_artifact_file(paths["json"]) and is_artifact_file(paths["mat"])


@pytest.mark.parametrize("failing", ["mat-write", "second-rename"], ids=["mat", "rename"])
def test_artifact_pair_is_both_or_neither(tmp_path, artifact, monkeypatch, failing):
    first = write_artifact(artifact, tmp_path / "k.json")
    before = {p.name: p.read_bytes() for p in first.values()}
    art2 = ControllerArtifact("other", artifact.continuous, artifact.discrete, artifact.prewarp_hz)
    if failing == "mat-write":

        def boom(*a, **k):
            raise OSError("disk full")

        monkeypatch.setattr(scipy.io, "savemat", boom)
    else:
        real_replace = os.replace
        calls = []

        def replace(src, dst):
            calls.append(dst)
            if len(calls) == 2:
                raise OSError("disk full")
            return real_replace(src, dst)

        monkeypatch.setattr(robust.jsonio.os, "replace", replace)
    with pytest.raises(OSError, match="disk full"):
        write_artifact(art2, tmp_path / "k.json")
    # the previous pair is as it was, and no temporary file remains
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


@pytest.mark.parametrize(
    "occupied, match",
    [
        ("k.json", r"refusing to replace .*k\.json.*not a bdft controller artifact"),
        ("k.mat", r"refusing to replace .*k\.mat.*not a bdft controller artifact"),
        ("folder", r"k\.json' is a directory"),
    ],
    ids=["user-json", "user-mat", "folder"],
)
def test_write_artifact_never_replaces_a_users_file(tmp_path, artifact, occupied, match):
    if occupied == "folder":
        (tmp_path / "k.json").mkdir()
    else:
        (tmp_path / occupied).write_text("my own data\n")
    before = sorted(tmp_path.iterdir())
    with pytest.raises(ParameterError, match=match):
        write_artifact(artifact, tmp_path / "k.json")
    assert sorted(tmp_path.iterdir()) == before
    if occupied != "folder":
        assert (tmp_path / occupied).read_text() == "my own data\n"


def test_write_artifact_needs_a_json_name(tmp_path, artifact):
    with pytest.raises(ParameterError, match=r"artifact path must end in \.json; got"):
        write_artifact(artifact, tmp_path / "k.mat")
    assert list(tmp_path.iterdir()) == []


def test_group_write_failure_removes_the_folders_it_made(tmp_path):
    def ok(tmp):
        Path(tmp).write_text("a")

    def boom(tmp):
        raise OSError("no space")

    with pytest.raises(OSError, match="no space"):
        atomic_write_group([(tmp_path / "a" / "b" / "x.txt", ok), (tmp_path / "a" / "y.txt", boom)])
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------------
# report folders
# --------------------------------------------------------------------------------------


def _page(title="t"):
    page = HtmlPage(title)
    page.p("hello")
    page.attach("table.csv", "a,b\n1,2\n")
    return page


@pytest.mark.parametrize(
    "target, match",
    [
        ("file", r"an existing file \(not replaced\)"),
        ("user-folder", r"is not a bdft report"),
        ("report-plus-notes", r"files bdft did not write \(notes\.txt\)"),
        ("report-plus-subfolder", r"files bdft did not write \(sub\)"),
    ],
    ids=["file", "user-folder", "report-plus-notes", "report-plus-subfolder"],
)
def test_write_report_dir_refuses_what_is_not_ours(tmp_path, target, match):
    out = tmp_path / "out"
    if target == "file":
        out.write_text("mine")
    elif target == "user-folder":
        out.mkdir()
        (out / "data.csv").write_text("1\n")
    else:
        write_report_dir(_page(), out)
        if target == "report-plus-notes":
            (out / "notes.txt").write_text("mine")
        else:
            (out / "sub").mkdir()
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    with pytest.raises(ParameterError, match=match):
        write_report_dir(_page("new"), out)
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before


def test_write_report_dir_replaces_its_own_reports(tmp_path):
    out = tmp_path / "out"
    write_report_dir(_page("first"), out, command="bdft test")
    marker = json.loads((out / REPORT_MARKER).read_text())
    assert marker["kind"] == "bdft-report" and marker["command"] == "bdft test"
    assert marker["files"] == ["index.html", "table.csv"] and marker["title"] == "first"
    assert is_report_dir(out)
    write_report_dir(_page("second"), out)
    assert "second" in (out / "index.html").read_text()
    assert (out.stat().st_mode & 0o777) == 0o777 & ~_umask()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_report_written_before_the_marker_is_still_ours(tmp_path):
    out = tmp_path / "old"
    out.mkdir()
    legacy = _page("legacy")
    legacy.raw('<img src="plot.png">')
    (out / "index.html").write_text(legacy.render())
    (out / "plot.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    (out / "claims.json").write_text("{}")
    assert is_report_dir(out)
    (out / "mine.csv").write_text("1\n")  # not named by the page: the user's
    assert not is_report_dir(out)
    with pytest.raises(ParameterError, match=r"files bdft did not write \(mine\.csv\)"):
        write_report_dir(_page("new"), out)
    (out / "mine.csv").unlink()
    write_report_dir(_page("new"), out)
    assert (out / REPORT_MARKER).exists() and not (out / "plot.png").exists()
    assert not is_report_dir(tmp_path)  # a folder of the user's


def test_design_artifacts_in_the_report_folder_are_kept(tmp_path, artifact):
    out = tmp_path / "designs"
    paths = write_artifact(artifact, out / "cancellation.json")  # bdft design's default folder
    before = {p.name: p.read_bytes() for p in paths.values()}
    assert is_report_dir(out)  # a folder of artifacts only
    write_report_dir(_page("report"), out)
    write_report_dir(_page("again"), out)
    assert {n: (out / n).read_bytes() for n in before} == before
    assert "again" in (out / "index.html").read_text()


def test_failed_replacement_keeps_the_previous_report(tmp_path, monkeypatch):
    out = tmp_path / "out"
    write_report_dir(_page("first"), out)
    real_replace = os.replace
    calls = []

    def replace(src, dst):
        calls.append(dst)
        if len(calls) == 2:  # the new folder into place
            raise OSError("disk full")
        return real_replace(src, dst)

    monkeypatch.setattr("reports.html.os.replace", replace)
    with pytest.raises(OSError, match="disk full"):
        write_report_dir(_page("second"), out)
    assert "first" in (out / "index.html").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("fname", ["../x.csv", "sub/x.csv", "index.html", REPORT_MARKER, ".."])
def test_report_file_names_stay_inside_the_folder(tmp_path, fname):
    page = _page()
    page.files[fname] = b"x"
    with pytest.raises(ParameterError, match=r"report file name: expected a plain file name"):
        write_report_dir(page, tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------------
# identification: a dead channel is named
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "dead, match",
    [
        ("u", r"input channel 'e' is dead: constant, with zero power, in every record"),
        ("y", r"output channel 'y' is dead"),
        ("zeros", r"input channel 'e' is dead.*record 0 holds 0 throughout"),
    ],
    ids=["input", "output", "all-zero-input"],
)
def test_identify_records_names_the_dead_channel(dead, match):
    t = np.arange(4000) / 1000.0
    u = np.sin(2 * np.pi * (0.5 + 2.0 * t) * t)
    y = 0.5 * np.roll(u, 3)
    if dead == "u":
        u = np.full_like(u, 0.7)
    elif dead == "y":
        y = np.full_like(y, -2.0)
    else:
        u = np.zeros_like(u)
    with pytest.raises(DataError, match=match):
        identify_records([u, u], [y, y], 1000.0, "2/2", (1.0, 10.0), input_name="e")


# --------------------------------------------------------------------------------------
# property tests: the parsers raise ArtifactError and nothing else
# --------------------------------------------------------------------------------------

json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(10**30), max_value=10**30)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8)
    | st.sampled_from(["x", "c", "y", "f", "r_corr", "bdft-controller"]),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4)
    ),
    max_leaves=12,
)


def _paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, (*prefix, i))


def _loads_or_artifact_error(loader, path):
    try:
        loader(path)
    except ArtifactError as exc:
        assert str(path) in str(exc) or path.name in str(exc), str(exc)


PROPERTY = settings(
    max_examples=120,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


@PROPERTY
@given(data=st.binary(max_size=300))
def test_random_bytes_raise_only_artifact_errors(tmp_path_factory, data):
    path = tmp_path_factory.getbasetemp() / "random-bytes.json"
    path.write_bytes(data)
    _loads_or_artifact_error(load_artifact, path)


@PROPERTY
@given(value=json_values)
def test_random_json_raises_only_artifact_errors(tmp_path_factory, value):
    path = tmp_path_factory.getbasetemp() / "random-json.json"
    path.write_text(json.dumps(value))
    _loads_or_artifact_error(load_artifact, path)


@PROPERTY
@given(data=st.data())
def test_mutated_artifacts_raise_only_artifact_errors(tmp_path_factory, document, data):
    d = copy.deepcopy(document)
    paths = [p for p in _paths(d) if p]
    field = data.draw(st.sampled_from(paths), label="field")
    value = data.draw(json_values, label="value")
    target = d
    for key in field[:-1]:
        target = target[key]
    target[field[-1]] = value
    path = tmp_path_factory.getbasetemp() / "mutated.json"
    path.write_text(json.dumps(d))
    _loads_or_artifact_error(load_artifact, path)
    # the controller loader reads the same file through load_artifact
    _loads_or_artifact_error(load_controller, path)


finite = st.floats(allow_nan=False, allow_infinity=False) | st.sampled_from([0.0, 2000.0, 1e308])


@PROPERTY
@given(data=st.data())
def test_random_matrices_raise_only_artifact_errors(tmp_path_factory, document, data):
    # numbers of any size in any matrix, any sample time and prewarping: no other
    # exception and no warning (a singular Tustin transform is an ArtifactError too)
    d = copy.deepcopy(document)
    section = data.draw(st.sampled_from(["continuous", "discrete"]), label="section")
    key = data.draw(st.sampled_from("ABCD"), label="matrix")
    shape = np.array(d[section][key]).shape
    size = int(np.prod(shape))
    entries = data.draw(st.lists(finite, min_size=size, max_size=size), label="entries")
    d[section][key] = np.array(entries).reshape(shape).tolist()
    d["discrete"]["dt"] = data.draw(st.sampled_from([0.001, 0.02, 1e-7]), label="dt")
    d["discrete"]["prewarp_hz"] = data.draw(st.none() | st.floats(1e-6, 499.0), label="prewarp")
    path = tmp_path_factory.getbasetemp() / "numbers.json"
    path.write_text(json.dumps(d))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _loads_or_artifact_error(load_artifact, path)


@PROPERTY
@given(data=st.binary(max_size=300))
def test_random_bytes_raise_only_artifact_errors_in_the_controller_loader(tmp_path_factory, data):
    path = tmp_path_factory.getbasetemp() / "random-controller.json"
    path.write_bytes(data)
    _loads_or_artifact_error(load_controller, path)


@PROPERTY
@given(data=st.data())
def test_mutated_bare_controllers_raise_only_artifact_errors(tmp_path_factory, data):
    # a bare state-space controller file (no kind) with one field replaced by anything
    bare = {
        "A": [[-1.0, 0.0], [0.0, -2.0]],
        "B": [[1.0], [0.5]],
        "C": [[1.0, 1.0]],
        "D": [[0.0]],
        "inputs": ["x"],
        "outputs": ["f"],
    }
    field = data.draw(st.sampled_from(sorted(bare)), label="field")
    bare[field] = data.draw(json_values, label="value")
    path = tmp_path_factory.getbasetemp() / "bare.json"
    path.write_text(json.dumps(bare))
    _loads_or_artifact_error(load_controller, path)
