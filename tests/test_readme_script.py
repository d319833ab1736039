"""The README's design script runs as written and produces what it says: a certified margin,
a validation, a specification verdict and an artifact that loads back."""

from __future__ import annotations

import ast
import importlib
import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest

from robust import load_artifact

README = Path(__file__).resolve().parents[1] / "README.md"
MARK = "<!-- design-script -->"


def _script() -> str:
    text = README.read_text(encoding="utf-8")
    assert MARK in text, "the README lost its design script (the design-script marker)"
    after = text.split(MARK, 1)[1]
    block = re.match(r"\s*```python\n(.*?)```", after, re.S)
    assert block, "the design-script marker must stand on the line before a ```python block"
    return block.group(1)


def test_the_script_imports_public_names_only():
    imports = [n for n in ast.walk(ast.parse(_script())) if isinstance(n, ast.ImportFrom)]
    project = [n for n in imports if n.module.split(".")[0] in ("robust", "uncertainty", "designs")]
    assert project, "the design script imports nothing from the workbench"
    for node in project:
        module = importlib.import_module(node.module)
        for alias in node.names:
            assert alias.name in module.__all__, f"{node.module}.{alias.name} is not public"


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """The script's namespace after running it in a temporary folder (its temporary output
    folder inside it too)."""
    tmp = tmp_path_factory.mktemp("readme")
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(tmp)
        mp.setattr(tempfile, "tempdir", str(tmp))
        namespace = {"__name__": "__main__"}
        exec(compile(_script(), f"{README}:design-script", "exec"), namespace)
    return tmp, namespace


def test_the_margin_is_certified_and_bracketed(ran):
    _, ns = ran
    margin = ns["margin"]
    assert math.isfinite(margin.lower) and margin.lower > 0
    assert margin.lower <= margin.upper < math.inf
    assert margin.critical is not None  # the member that breaks the loop at the upper bound
    # what the README says of it: a nominal design holds only near the nominal
    assert margin.upper < 0.1


def test_the_validation_and_the_specification_report(ran):
    _, ns = ran
    v, check = ns["v"], ns["check"]
    assert 0.0 < v.fraction_stable < 0.5 and v.max_real_pole > 0  # "about a quarter" stable
    assert check.members == 4 and not check.holds
    assert check.binding in {c.name for c in check.constraints if not c.holds}


def test_the_artifact_is_written_and_loads_back(ran):
    tmp, ns = ran
    files = ns["files"]
    assert set(files) == {"json", "mat"}
    for path in files.values():
        assert path.is_file() and path.is_relative_to(tmp)
    art = load_artifact(files["json"])
    K = ns["K"]
    assert art.name == "hinf-nominal"
    assert art.inputs == list(K.input_labels) and art.outputs == list(K.output_labels)
    np.testing.assert_allclose(art.continuous.A, K.A, rtol=1e-12, atol=0)
    assert art.discrete.dt == pytest.approx(ns["limits"].sample_time_s)
    assert art.validation["margin"]["lower"] == pytest.approx(ns["margin"].lower)
