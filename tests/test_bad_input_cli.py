"""Bad input on the command line: every command checks its arguments first, answers with one
named line (exit 2), and keeps the user's files.

Each case asserts the exit code, that standard error is exactly one line
``bdft CMD: error: ...`` naming the culprit, and, where a path is involved, that
nothing was written or replaced. Commands that must really run use a handful of
members.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import backhoe.sysid.model_file
import designs.registry
import reports.designs
import uncertainty
from backhoe import RANGES, default_family
from backhoe.sysid import ChirpProtocol, paper_experiment
from bdft import main
from bdft.args import (
    BYTES_PER_BATCH_MEMBER,
    BYTES_PER_MEMBER,
    MAX_FAMILY_PARAMETERS,
    max_batch,
    max_members,
)
from reports.html import REPORT_MARKER
from robust.sysid import save_experiment

ROOT = Path(__file__).resolve().parents[1]


def _listing(path: Path) -> list[str]:
    """Every file and folder under ``path`` with its content (files), for before/after checks."""
    out = []
    for p in sorted(path.rglob("*")):
        rel = str(p.relative_to(path))
        out.append(rel + (":" + p.read_bytes().hex()[:200] if p.is_file() else "/"))
    return out


def _one_error(capsys, command: str) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"bdft {command}: error: "), lines[0]
    assert "Traceback" not in captured.err
    assert captured.out == ""
    return lines[0]


@pytest.fixture(scope="module")
def chirp(tmp_path_factory) -> Path:
    """A small structure chirp file (3 records of 8 s): channels y (input) and c (output)."""
    exp = paper_experiment(
        "structure", ChirpProtocol(n_records=3, duration=8.0, f0_hz=0.5), noise=0.02, seed=5
    )
    return save_experiment(exp, tmp_path_factory.mktemp("data") / "d.csv")


def _identify(data, *extra, out=None, form="structure", band=("2", "15")):
    argv = ["identify", str(data), "--input", "y", "--output", "c", "--fs", "1000"]
    argv += ["--form", form, "--band", *band]
    if out is not None:
        argv += ["--out", str(out)]
    return argv + list(extra)


# --------------------------------------------------------------------------------------
# options: type and range, checked before any work
# --------------------------------------------------------------------------------------

BIG = str(10**12)

OPTION_CASES = [
    # (argv, command, culprit, what the message must also say)
    (["validate", "--samples", "0"], "validate", "--samples", "expected an integer from 1 to"),
    (["validate", "--samples", "-5"], "validate", "--samples", "got -5"),
    (["validate", "--samples", "abc"], "validate", "--samples", "got 'abc'"),
    (["validate", "--samples", "1.5"], "validate", "--samples", "got '1.5'"),
    (["validate", "--samples", BIG], "validate", "--samples", "memory budget"),
    (["validate", "--samples", "1e13"], "validate", "--samples", "bytes per member"),
    (["validate", "--chunk", "0"], "validate", "--chunk", "got 0"),
    (["validate", "--chunk", "1000000000"], "validate", "--chunk", "memory budget"),
    (["validate", "--seed", "-1"], "validate", "--seed", "from 0 to 2**63-1"),
    (["validate", "--seed", str(2**63)], "validate", "--seed", "signed 64-bit"),
    (["validate", "--workspace-factor", "0"], "validate", "--workspace-factor", "positive"),
    (["validate", "--workspace-factor", "-1"], "validate", "--workspace-factor", "got -1"),
    (["validate", "--workspace-factor", "nan"], "validate", "--workspace-factor", "got nan"),
    (["validate", "--workspace-factor", "inf"], "validate", "--workspace-factor", "got inf"),
    (["validate", "--method", "sobol"], "validate", "--method", "got 'sobol' (invalid choice)"),
    (["validate", "--human", "robot"], "validate", "--human", "got 'robot' (invalid choice)"),
    (["validate", "--bogus"], "validate", "--bogus", "unrecognized arguments"),
    (["sweep", "workspace", "--points", "-3"], "sweep", "--points", "got -3"),
    (["sweep", "workspace", "--points", "0"], "sweep", "--points", "from 2 to 200; got 0"),
    (["sweep", "workspace", "--points", "1"], "sweep", "--points", "got 1"),
    (["sweep", "workspace", "--points", "201"], "sweep", "--points", "got 201"),
    (["sweep", "workspace", "--points", "x"], "sweep", "--points", "got 'x'"),
    (["sweep", "nope"], "sweep", "name", "got 'nope' (invalid choice)"),
    (["sweep", "workspace", "--workspace-factor", "-2"], "sweep", "--workspace-factor", "-2"),
    (["sweep", "frequency-damping", "--pair", "leg"], "sweep", "--pair", "'leg'"),
    (["sweep", "workspace", "--samples", BIG], "sweep", "--samples", "memory budget"),
    (["report", "--samples", "0"], "report", "--samples", "got 0"),
    (["report", "--samples", BIG], "report", "--samples", "memory budget"),
    (["report", "--seed", "-3"], "report", "--seed", "got -3"),
    (["report", "--scheduled-samples", "-1"], "report", "--scheduled-samples", "got -1"),
    (["design", "scheduled", "--border-samples", "x"], "design", "--border-samples", "got 'x'"),
    (["design", "cancellation", "--samples", "0"], "design", "--samples", "got 0"),
    (["design", "cancellation", "--samples", BIG], "design", "--samples", "memory budget"),
    (["design"], "design", "NAME", "expected a design name or --list"),
    (["design", "magic"], "design", "NAME", "unknown design 'magic'"),
    (["design", "cancellation", "--method", "sobol"], "design", "--method", "'sobol'"),
    (["reproduce", "--human", "robot"], "reproduce", "--human", "got 'robot' (invalid choice)"),
]


@pytest.mark.parametrize(
    "argv, command, culprit, detail",
    OPTION_CASES,
    ids=[" ".join(c[0])[:60] for c in OPTION_CASES],
)
def test_bad_option_is_one_named_line(capsys, argv, command, culprit, detail):
    assert main(argv) == 2
    line = _one_error(capsys, command)
    assert culprit in line and detail in line, line
    if culprit.startswith("--"):
        assert "expected" in line and "got" in line, line


IDENTIFY_CASES = [
    # (extra argv or replacements, culprit, detail)
    (dict(fs="0"), "--fs", "positive finite number (Hz); got 0"),
    (dict(fs="-1000"), "--fs", "got -1000"),
    (dict(fs="nan"), "--fs", "got nan"),
    (dict(band=("15", "2")), "--band", "expected LO < HI; got LO=15 Hz, HI=2 Hz"),
    (dict(band=("2", "700")), "--band", "beyond the Nyquist frequency"),
    (dict(band=("0", "15")), "--band", "got 0"),
    (dict(band=("2", "x")), "--band", "got 'x'"),
    (dict(form="seat"), "--form", "got 'seat'"),
    (dict(form="5/2"), "--form", "M=5, N=2"),
    (dict(form="2/40"), "--form", "N <= 20; got '2/40'"),
    (dict(form="2/4", extra=["--save-model", "m.json"]), "--save-model", "needs a fixed form"),
    (dict(output="y"), "--input, --output", "two different channels; got 'y' for both"),
    (dict(input=""), "--input", "expected a channel name"),
    (dict(extra=["--nperseg", "1"]), "--nperseg", "got 1"),
    (dict(extra=["--min-coherence", "1.5"]), "--min-coherence", "[0, 1]; got 1.5"),
    (dict(extra=["--significance", "0"]), "--significance", "(0, 1]; got 0"),
    (dict(extra=["--confidence", "1"]), "--confidence", "(0, 1); got 1"),
    (dict(extra=["--window", "nosuchwindow"]), "--window", "'nosuchwindow'"),
    (dict(extra=["--detrend", "cubic"]), "--detrend", "got 'cubic' (invalid choice)"),
    (dict(drop="--fs"), "--fs", "expected a value (required); got none"),
    (dict(data="missing.csv"), "DATA", "which does not exist"),
    (dict(data="DIR"), "DATA", "a folder"),
    (dict(data="data.xlsx"), "DATA", "name ending in .csv or .txt or .mat"),
]


@pytest.mark.parametrize(
    "change, culprit, detail",
    IDENTIFY_CASES,
    ids=[f"identify-{c[1]}-{'-'.join(map(str, c[0].values()))}"[:60] for c in IDENTIFY_CASES],
)
def test_bad_identify_option_writes_nothing(tmp_path, capsys, chirp, change, culprit, detail):
    data = {"missing.csv": tmp_path / "missing.csv", "DIR": tmp_path}.get(
        change.get("data"), change.get("data", chirp)
    )
    if change.get("data") == "data.xlsx":
        data = tmp_path / "data.xlsx"
        data.write_bytes(b"PK\x03\x04")
    argv = ["identify", str(data)]
    opts = {
        "--input": change.get("input", "y"),
        "--output": change.get("output", "c"),
        "--fs": change.get("fs", "1000"),
        "--form": change.get("form", "structure"),
    }
    for k, v in opts.items():
        if k != change.get("drop"):
            argv += [k, v]
    argv += ["--band", *change.get("band", ("2", "15")), "--out", str(tmp_path / "out")]
    extra = [str(tmp_path / x) if x.endswith(".json") else x for x in change.get("extra", [])]
    before = _listing(tmp_path)
    assert main(argv + extra) == 2
    line = _one_error(capsys, "identify")
    assert culprit in line and detail in line, line
    assert _listing(tmp_path) == before


def test_memory_budget_is_documented_and_follows_the_environment(capsys, monkeypatch):
    # the limit is the budget over the bytes per member, stated in --help
    assert max_members() == 4 * 2**30 // BYTES_PER_MEMBER == 11_184_810
    assert max_batch() == 4 * 2**30 // BYTES_PER_BATCH_MEMBER
    with pytest.raises(SystemExit) as exc:
        main(["validate", "--help"])
    assert exc.value.code == 0
    helptext = " ".join(capsys.readouterr().out.split())
    assert "at most 11,184,810 (4 GiB memory budget at 384 bytes per member" in helptext
    # a smaller budget refuses what the default allows, naming the variable's limit
    monkeypatch.setenv("BDFT_MEMORY_BUDGET_GIB", "0.001")
    assert main(["validate", "--samples", "5000"]) == 2
    line = _one_error(capsys, "validate")
    assert f"from 1 to {int(0.001 * 2**30) // BYTES_PER_MEMBER:,}" in line
    monkeypatch.setenv("BDFT_MEMORY_BUDGET_GIB", "lots")
    assert main(["validate", "--samples", "5"]) == 2
    assert "BDFT_MEMORY_BUDGET_GIB: expected a positive number of GiB; got 'lots'" in _one_error(
        capsys, "validate"
    )


def test_bytes_per_member_covers_every_family():
    widest = max(
        len(default_family(h, **({"ranges": r} if h == "physical" else {})).names)
        for h in ("physical", "literal")
        for r in RANGES
    )
    assert widest <= MAX_FAMILY_PARAMETERS


@pytest.mark.parametrize(
    "argv, detail",
    [([], "COMMAND: expected a value (required); got none"), (["frobnicate"], "'frobnicate'")],
    ids=["no-command", "unknown-command"],
)
def test_top_level_errors_are_one_line(capsys, argv, detail):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bdft: error: ") and detail in err[0]


# --------------------------------------------------------------------------------------
# output paths: never a file or folder of the user's
# --------------------------------------------------------------------------------------


def _user_file(tmp_path):
    p = tmp_path / "thesis.txt"
    p.write_text("three years of work\n")
    return p


def _user_dir(tmp_path):
    d = tmp_path / "mydata"
    d.mkdir()
    (d / "keep.csv").write_text("1,2,3\n")
    return d


def _report_with_extra(tmp_path):
    d = tmp_path / "rep"
    d.mkdir()
    (d / REPORT_MARKER).write_text(json.dumps({"kind": "bdft-report", "files": ["index.html"]}))
    (d / "index.html").write_text("<html></html>")
    (d / "notes.txt").write_text("mine")
    return d


def _under_file(tmp_path):
    return _user_file(tmp_path) / "sub"


OUT_CASES = [
    # (command argv before --out, make the target, expected in the message)
    (["reproduce"], _user_file, "an existing file (not replaced)"),
    (["reproduce"], _user_dir, "is not a bdft report"),
    (["reproduce"], _report_with_extra, "files bdft did not write (notes.txt)"),
    (["reproduce"], _under_file, "is a file"),
    (["sweep", "workspace"], _user_file, "an existing file (not replaced)"),
    (["sweep", "workspace"], _user_dir, "is not a bdft report"),
    (["report"], _user_file, "an existing file (not replaced)"),
    (["report"], _user_dir, "is not a bdft report"),
    (["design", "cancellation"], _user_file, "expected a folder"),
    (["design", "cancellation"], _under_file, "is a file"),
]


@pytest.mark.parametrize(
    "argv, make, detail",
    OUT_CASES,
    ids=[f"{' '.join(c[0])}-{c[1].__name__.strip('_')}" for c in OUT_CASES],
)
def test_out_never_replaces_user_files(tmp_path, capsys, argv, make, detail):
    target = make(tmp_path)
    before = _listing(tmp_path)
    assert main([*argv, "--out", str(target)]) == 2
    line = _one_error(capsys, argv[0])
    assert "--out" in line and detail in line, line
    assert _listing(tmp_path) == before


@pytest.mark.parametrize(
    "where", ["dot", "root", "proc"], ids=["cwd-dot", "filesystem-root", "unwritable"]
)
def test_report_out_must_be_a_writable_named_folder(tmp_path, capsys, monkeypatch, where):
    monkeypatch.chdir(tmp_path)
    target = {"dot": ".", "root": "/", "proc": "/proc/bdft-report"}[where]
    before = _listing(tmp_path)
    assert main(["report", "--out", target]) == 2
    line = _one_error(capsys, "report")
    assert "--out" in line and repr(target) in line, line
    assert _listing(tmp_path) == before


@pytest.mark.parametrize("suffix", [".json", ".mat"], ids=["json", "mat"])
def test_design_out_keeps_a_users_file_of_the_artifacts_name(tmp_path, capsys, suffix):
    folder = tmp_path / "arts"
    folder.mkdir()
    (folder / f"cancellation{suffix}").write_text("my own notes\n")
    before = _listing(tmp_path)
    assert main(["design", "cancellation", "--out", str(folder)]) == 2
    line = _one_error(capsys, "design")
    assert f"cancellation{suffix}" in line and "not a bdft controller artifact" in line
    assert _listing(tmp_path) == before


def test_design_out_is_checked_before_the_computation(tmp_path, capsys, monkeypatch):
    calls = []
    # (bdft design imports run_design when it runs: patched where it is defined)
    monkeypatch.setattr(designs.registry, "run_design", lambda *a, **k: calls.append(a))
    target = _user_file(tmp_path)
    assert main(["design", "hinf-robust", "--out", str(target)]) == 2
    assert calls == []
    assert "--out" in _one_error(capsys, "design")


def test_report_checks_its_artifact_folder_before_the_computation(tmp_path, capsys, monkeypatch):
    calls = []
    monkeypatch.setattr(reports.designs, "run_designs_with", lambda *a, **k: calls.append(a))
    (tmp_path / "page-artifacts").write_text("not a folder")
    before = _listing(tmp_path)
    assert main(["report", "--out", str(tmp_path / "page")]) == 2
    assert calls == []
    line = _one_error(capsys, "report")
    assert "page-artifacts" in line and "an existing file" in line
    assert _listing(tmp_path) == before


SAVE_MODEL_CASES = [
    ("user-json", "an existing file of another kind (not replaced)"),
    ("folder", "a folder"),
    ("txt", "a file name ending in .json"),
    ("impossible", "files cannot be created in"),
    ("under-file", "is a file"),
    ("same-as-output", "apart from the outputs in --out"),
]


@pytest.mark.parametrize("case, detail", SAVE_MODEL_CASES, ids=[c[0] for c in SAVE_MODEL_CASES])
def test_identify_save_model_fails_before_any_output(tmp_path, capsys, chirp, case, detail):
    out = tmp_path / "out"
    target = {
        "user-json": tmp_path / "mine.json",
        "folder": tmp_path,
        "txt": tmp_path / "model.txt",
        "impossible": Path("/proc/bdft-no-such-dir/model.json"),
        "under-file": tmp_path / "mine.json" / "model.json",
        "same-as-output": out / "d_structure_fit.json",
    }[case]
    (tmp_path / "mine.json").write_text(json.dumps({"my": "numbers"}))
    before = _listing(tmp_path)
    assert main(_identify(chirp, "--save-model", str(target), out=out)) == 2
    line = _one_error(capsys, "identify")
    assert "--save-model" in line and detail in line, line
    assert _listing(tmp_path) == before  # --out was not even created


def test_identify_out_keeps_a_users_file_of_an_output_name(tmp_path, capsys, chirp):
    out = tmp_path / "out"
    out.mkdir()
    (out / "d_structure_bode.png").write_text("not a picture")
    before = _listing(tmp_path)
    assert main(_identify(chirp, out=out)) == 2
    line = _one_error(capsys, "identify")
    assert "d_structure_bode.png" in line and "not replaced" in line
    assert _listing(tmp_path) == before


def test_identify_out_that_is_a_file(tmp_path, capsys, chirp):
    target = _user_file(tmp_path)
    before = _listing(tmp_path)
    assert main(_identify(chirp, out=target)) == 2
    assert "an existing file (not replaced)" in _one_error(capsys, "identify")
    assert _listing(tmp_path) == before


# --------------------------------------------------------------------------------------
# input files given on the command line
# --------------------------------------------------------------------------------------

DEEP = b"[" * 100_000 + b"]" * 100_000

INPUT_CASES = [
    ("--controller", "missing", None, "which does not exist"),
    ("--controller", "folder", None, "a folder"),
    ("--controller", "bytes", b"\xff\xfe\x00\x81garbage", "not UTF-8 text (byte 0xff at offset 0)"),
    ("--controller", "empty", b"", "is not valid JSON"),
    ("--controller", "deep", DEEP, "nested too deeply"),
    ("--controller", "array", b"[1, 2, 3]", "holding a JSON array"),
    ("--controller", "big", b"{}", "of at most 100 bytes"),
    ("--controller", "huge-int", b'{"A": [[1' + b"0" * 400 + b"]]}", "integer of 401 digits"),
    ("--plant-file", "bytes", b"\x00\x01\x02\x9c", "not UTF-8 text"),
    ("--plant-file", "folder", None, "a folder"),
    ("--plant-file", "string", b'"structure"', "holding a JSON string"),
]


@pytest.mark.parametrize(
    "option, case, content, detail",
    INPUT_CASES,
    ids=[f"{c[0]}-{c[1]}" for c in INPUT_CASES],
)
def test_bad_input_file_is_named(tmp_path, capsys, monkeypatch, option, case, content, detail):
    path = tmp_path / "input.json"
    if case == "folder":
        path = tmp_path
    elif content is not None:
        path.write_bytes(content if case != "big" else b" " * 200 + b"{}")
    if case == "big":
        monkeypatch.setattr("bdft.args.MAX_JSON_BYTES", 100)
    assert main(["validate", "--samples", "5", option, str(path)]) == 2
    line = _one_error(capsys, "validate")
    assert option in line and str(path) in line and detail in line, line


# --------------------------------------------------------------------------------------
# commands that run: markers, determinism, dead channels, internal errors
# --------------------------------------------------------------------------------------


def test_report_folder_is_marked_and_replaced_only_while_it_is_ours(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", "workspace", "--samples", "3", "--points", "2", "--out", str(out)]
    assert main(argv) == 0
    marker = json.loads((out / REPORT_MARKER).read_text())
    assert marker["kind"] == "bdft-report" and marker["version"]
    assert "index.html" in marker["files"] and "workspace.csv" in marker["files"]
    assert (out.stat().st_mode & 0o777) == (0o777 & ~_umask())
    assert main(argv) == 0  # a previous report of ours is replaced
    capsys.readouterr()
    (out / "notes.txt").write_text("mine")
    before = _listing(tmp_path)
    assert main(argv) == 2
    assert "notes.txt" in _one_error(capsys, "sweep")
    assert _listing(tmp_path) == before


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_validate_json_is_the_same_bytes_for_the_same_seed(tmp_path):
    cmd = [sys.executable, "-m", "bdft", "validate", "--samples", "20", "--seed", "3", "--json"]
    outs = []
    for hashseed in ("1", "2"):
        env = dict(os.environ, PYTHONHASHSEED=hashseed)
        proc = subprocess.run(cmd, capture_output=True, cwd=ROOT, env=env, check=True)
        outs.append(proc.stdout)
        assert b"members in" in proc.stderr  # the timing goes to stderr only
    assert outs[0] == outs[1]
    obj = json.loads(outs[0])
    assert obj["samples"] == 20 and obj["seed"] == 3
    assert not [k for k in obj if "elapsed" in k or "time" in k]


def _dead(chirp: Path, tmp_path: Path, column: int, records=None) -> Path:
    lines = chirp.read_text().splitlines()
    out = lines[:2]
    for ln in lines[2:]:
        parts = ln.split(",")
        if records is None or int(parts[0]) in records:
            parts[column] = "0.25"
        out.append(",".join(parts))
    path = tmp_path / "dead.csv"
    path.write_text("\n".join(out) + "\n")
    return path


@pytest.mark.parametrize(
    "column, records, detail",
    [
        (2, None, "input channel 'y' is dead: constant, with zero power, in every record"),
        (3, None, "output channel 'c' is dead"),
        (2, {1}, "input channel 'y' is dead: constant, with zero power, in record(s) [1] of 3"),
    ],
    ids=["dead-input", "dead-output", "one-dead-record"],
)
def test_identify_names_a_dead_channel(tmp_path, capsys, chirp, column, records, detail):
    data = _dead(chirp, tmp_path, column, records)
    out = tmp_path / "out"
    assert main(_identify(data, out=out)) == 2
    line = _one_error(capsys, "identify")
    assert detail in line and "coherence" not in line, line
    assert not out.exists()


def test_identify_write_failure_leaves_no_output(tmp_path, capsys, chirp, monkeypatch):
    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(backhoe.sysid.model_file, "save_component_fit", boom)
    monkeypatch.setenv("BDFT_LOG_DIR", str(tmp_path))
    out = tmp_path / "out"
    assert main(_identify(chirp, "--save-model", str(tmp_path / "m.json"), out=out)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "internal error: OSError: disk full" in err[0]
    assert not out.exists() and not (tmp_path / "m.json").exists()


def test_internal_error_is_one_line_naming_the_traceback_file(tmp_path, capsys, monkeypatch):
    def broken(*a, **k):
        raise ZeroDivisionError("the bug")

    monkeypatch.setattr(uncertainty, "validate_family", broken)
    monkeypatch.setenv("BDFT_LOG_DIR", str(tmp_path))
    assert main(["validate", "--samples", "5"]) == 1
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and captured.out == ""
    assert lines[0].startswith("bdft validate: internal error: ZeroDivisionError: the bug")
    (log,) = tmp_path.glob("bdft-validate-*.log")
    assert str(log) in lines[0]
    text = log.read_text()
    assert "Traceback (most recent call last)" in text and "ZeroDivisionError: the bug" in text


def test_validate_with_good_inputs_still_runs(tmp_path, capsys):
    # the checks let a good run through, and the numbers are real
    assert main(["validate", "--samples", "1e1", "--seed", "2", "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["samples"] == 10 and 0.0 <= obj["fraction_stable"] <= 1.0
    assert np.isfinite(obj["max_real_pole"])
