"""The result cache returns a stored result only for the same inputs and code."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from bdft import main
from bdft.kernels import _cpu_flags
from robust import cache
from robust.cache import CACHE_ENV, cache_dir, cache_key, cached, code_version


@pytest.fixture
def store(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "c"))
    return tmp_path / "c"


def test_a_result_is_computed_once_per_inputs(store):
    calls = []

    def compute(x):
        calls.append(x)
        return {"x": x, "squares": [i * i for i in range(x)]}

    v1, hit1 = cached("t", {"x": 3}, lambda: compute(3))
    v2, hit2 = cached("t", {"x": 3}, lambda: compute(3))
    v3, hit3 = cached("t", {"x": 4}, lambda: compute(4))
    assert (hit1, hit2, hit3) == (False, True, False)
    assert v1 == v2 == {"x": 3, "squares": [0, 1, 4]} and v3["x"] == 4
    assert calls == [3, 4]
    assert len(list((store / "t").glob("*.pkl"))) == 2
    # disabled: computed every time, nothing written
    v4, hit4 = cached("u", {"x": 3}, lambda: compute(3), enabled=False)
    assert not hit4 and calls == [3, 4, 3] and not (store / "u").exists()


def test_a_damaged_entry_is_recomputed_and_replaced(store):
    cached("t", {"a": 1}, lambda: 41)
    (entry,) = (store / "t").glob("*.pkl")
    entry.write_bytes(b"not a pickle")
    assert cached("t", {"a": 1}, lambda: 42) == (42, False)
    assert cached("t", {"a": 1}, lambda: 43) == (42, True)
    assert not list((store / "t").glob(".tmp-*"))  # no half-written entry left


def test_the_key_holds_the_inputs_and_the_code(monkeypatch, store):
    k = cache_key("design", {"seed": 0})
    assert k == cache_key("design", {"seed": 0}) != cache_key("design", {"seed": 1})
    assert k != cache_key("limit-map", {"seed": 0})
    assert len(code_version()) == 64
    monkeypatch.setattr(cache, "_VERSION", "another code version")
    assert cache_key("design", {"seed": 0}) != k


def test_the_code_version_holds_the_kernels(monkeypatch):
    # this process's kernels, and those of a bdft process (fixed by bdft.kernels)
    here = cache.numeric_kernels()
    assert here.startswith("openblas=") and ";numpy=" in here
    code = "import bdft\nfrom robust.cache import numeric_kernels\nprint(numeric_kernels())"
    env = {k: v for k, v in os.environ.items() if k != "BDFT_NATIVE_KERNELS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    if {"avx2", "fma"} <= _cpu_flags():
        assert out.stdout.strip() == "openblas=Haswell;numpy=X86_V3"
    # other kernels, another key
    monkeypatch.setattr(cache, "_VERSION", None)
    k = cache_key("design", {"seed": 0})
    monkeypatch.setattr(cache, "_VERSION", None)
    monkeypatch.setattr(cache, "numeric_kernels", lambda: "openblas=Sandybridge;numpy=X86_V3")
    assert cache_key("design", {"seed": 0}) != k
    monkeypatch.setattr(cache, "_VERSION", None)


def test_the_folder_comes_from_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "x"))
    assert cache_dir() == tmp_path / "x"
    monkeypatch.delenv(CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "bdft"


def test_a_design_rerun_comes_from_the_cache_with_its_artifact(store, tmp_path, capsys):
    args = ["design", "cancellation", "--samples", "40", "--coverage-samples", "0"]
    args += ["--margin-boxes", "0", "--json"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    first = json.loads(capsys.readouterr().out)
    assert len(list((store / "design").glob("*.pkl"))) == 1
    assert main(args + ["--out", str(tmp_path / "b")]) == 0
    second = json.loads(capsys.readouterr().out)
    assert (tmp_path / "b" / "cancellation.json").is_file()  # written again from the entry
    assert second.pop("artifact") != first.pop("artifact")
    assert second == first
    assert len(list((store / "design").glob("*.pkl"))) == 1


def test_no_cache_computes_afresh_and_stores_nothing(store, tmp_path, capsys):
    args = ["design", "workspace", "--samples", "60", "--coverage-samples", "0"]
    args += ["--margin-boxes", "0", "--json", "--out", str(tmp_path)]
    assert main(args) == 0
    first = json.loads(capsys.readouterr().out)
    assert main(args + ["--no-cache"]) == 0
    assert json.loads(capsys.readouterr().out) == first
    assert len(list((store / "design").glob("*.pkl"))) == 1
