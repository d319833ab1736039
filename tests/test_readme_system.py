"""The README's "Your own uncertain system" section runs as written, and says what it prints."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from bdft import main

README = Path(__file__).resolve().parents[1] / "README.md"
MARK = "<!-- own-system: tests/test_readme_system.py runs the next block -->"


def _blocks():
    text = README.read_text(encoding="utf-8")
    assert MARK in text, "the README lost its own-system section"
    after = text.split(MARK, 1)[1]
    code = re.search(r"```python\n(.*?)```", after, re.S).group(1)
    printed = re.search(r"prints \([^)]*\):\n\n```text\n(.*?)```", after, re.S).group(1)
    return code, printed


@pytest.fixture(scope="module")
def two_mass(tmp_path_factory):
    code, printed = _blocks()
    path = tmp_path_factory.mktemp("own") / "two_mass.py"
    path.write_text(code, encoding="utf-8")
    return path, printed


def test_the_example_prints_what_the_readme_says(two_mass):
    path, printed = two_mass
    out = subprocess.run(
        [sys.executable, str(path)], capture_output=True, text=True, check=True, timeout=120
    ).stdout
    assert out.strip().splitlines() == printed.strip().splitlines()
    lower, upper = (
        float(x) for x in re.findall(r"margin ([\d.]+) \(certified\) to ([\d.]+)", out)[0]
    )
    assert 0.9 * upper <= lower <= upper


def test_the_commands_take_the_file(two_mass, capsys):
    path, printed = two_mass
    assert main(["margin", "--system", str(path), "--region", "decay:0.02", "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert f"{obj['lower']:.3f}" in printed and f"{obj['upper']:.3f}" in printed
    assert obj["controller"] == "defined in the file"
    assert [p["name"] for p in obj["parameters"]] == ["k", "m2"]
    crit = obj["critical"]
    assert crit["checked_with"] == "python-control poles of the member system"
    assert max(p["re"] for p in crit["poles"]) > -0.02  # it breaks the region
    args = ["validate", "--system", str(path), "--samples", "20000", "--band", "0.01-10"]
    assert main(args + ["--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["fraction_stable"] == 1.0 and obj["samples"] == 20000
    assert obj["max_real_pole"] < -0.02  # inside the certified box: faster than 0.02
    assert set(obj["worst"]) == {"k", "m2"} and "human" not in obj


def test_bad_system_files_give_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.py"
    bad.write_text("system = 3\n", encoding="utf-8")
    assert main(["margin", "--system", str(bad)]) == 2
    assert (
        "`system` must be an uncertain system (uncertainty.uss); got int" in capsys.readouterr().err
    )
    broken = tmp_path / "broken.py"
    broken.write_text("import nothing_of_that_name\n", encoding="utf-8")
    assert main(["validate", "--system", str(broken)]) == 2
    assert "running it failed: ModuleNotFoundError" in capsys.readouterr().err
    assert main(["validate", "--system", str(tmp_path / "missing.py")]) == 2
    assert "--system" in capsys.readouterr().err
    assert main(["validate", "--system", str(bad), "--band", "5-1"]) == 2
    assert "--band: expected LO-HI" in capsys.readouterr().err
