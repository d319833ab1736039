"""The README's design script runs as written and prints what the README says of it: a
user's own uncertain plant (not the BDFT family), its weights, one controller, the certified
stability margin and robust performance, the validation on fresh members and an artifact
that loads back. Each claim is checked again here by other means: python-control's poles
and norms of the members the certificates cover and of those the searches found."""

from __future__ import annotations

import ast
import contextlib
import importlib
import io
import itertools
import math
import re
import tempfile
import time
from pathlib import Path

import control as ct
import numpy as np
import pytest
import scipy.io

from robust import hinf_norm, load_artifact
from uncertainty import scaled_bounds

README = Path(__file__).resolve().parents[1] / "README.md"
MARK = "<!-- design-script -->"
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?")


def _after_mark() -> str:
    text = README.read_text(encoding="utf-8")
    assert MARK in text, "the README lost its design script (the design-script marker)"
    return text.split(MARK, 1)[1]


def _script() -> str:
    block = re.match(r"\s*```python\n(.*?)```", _after_mark(), re.S)
    assert block, "the design-script marker must stand on the line before a ```python block"
    return block.group(1)


def _printed() -> str:
    block = re.search(r"It prints \([^)]*\):\n\n```text\n(.*?)```", _after_mark(), re.S)
    assert block, "the README must show what the design script prints (It prints (...):)"
    return block.group(1)


def test_the_script_imports_public_names_only():
    imports = [n for n in ast.walk(ast.parse(_script())) if isinstance(n, ast.ImportFrom)]
    project = [n for n in imports if n.module.split(".")[0] in ("robust", "uncertainty", "designs")]
    assert project, "the design script imports nothing from the workbench"
    for node in project:
        module = importlib.import_module(node.module)
        for alias in node.names:
            assert alias.name in module.__all__, f"{node.module}.{alias.name} is not public"
    # the user's own plant, through the uncertain-system API: no built-in family or design
    names = {alias.name for node in project for alias in node.names}
    assert not {"default_family", "get_design", "Family"} & names
    assert {n.module.split(".")[0] for n in project} == {"robust", "uncertainty"}


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """The script's namespace and standard output after running it in a temporary folder
    (its temporary output folder inside it too), and its wall-clock time."""
    tmp = tmp_path_factory.mktemp("readme")
    out = io.StringIO()
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(tmp)
        mp.setattr(tempfile, "tempdir", str(tmp))
        namespace = {"__name__": "__main__"}
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(out):
            exec(compile(_script(), f"{README}:design-script", "exec"), namespace)
        seconds = time.perf_counter() - t0
    return tmp, namespace, out.getvalue(), seconds


def test_it_prints_what_the_readme_says(ran):
    """The same lines; each number within two units of the README's last digit (the
    controller's last digits differ between CPUs: AVX-512 and AVX2 loops give controllers
    whose margins are 1 % apart, so the README prints two decimals)."""
    _, _, out, seconds = ran
    got, want = out.strip().splitlines(), _printed().strip().splitlines()
    assert len(got) == len(want), out
    for g, w in zip(got, want):
        assert NUMBER.split(g) == NUMBER.split(w), f"{g!r} != {w!r}"
        for a, b in zip(NUMBER.findall(g), NUMBER.findall(w)):
            digits = len(b.split(".")[1]) if "." in b else 0
            assert abs(float(a) - float(b)) <= 2.000001 * 10.0**-digits, f"{g!r} != {w!r}"
    assert seconds < 100  # the README: about 15 s; the whole file must stay under two minutes


def _scaled_corners(G, scale):
    lo, hi = scaled_bounds(G, scale)
    names = list(G.parameters)
    return [dict(zip(names, x)) for x in itertools.product(*zip(lo, hi))]


def _rightmost(G, K, values):
    """Largest real part of the poles of the member's loop G.feedback(K) (python-control)."""
    return float(ct.feedback(G.at(values), K).poles().real.max())


def test_the_controller_meets_its_bound_on_the_nine_members(ran):
    _, ns, _, _ = ran
    P, K, syn = ns["P"], ns["K"], ns["syn"]
    assert len(syn.gammas) == 9 and K.nstates == 3
    corners = _scaled_corners(ns["G"], 1.0)
    assert len(corners) == 8
    for values, gamma in zip([{}] + corners, syn.gammas):
        cl = P.at(values).closed_loop(K)
        assert np.linalg.eigvals(cl.A).real.max() < 0
        assert hinf_norm(cl) == pytest.approx(gamma, rel=1e-6)
        assert float(ct.norm(cl, p="inf")) == pytest.approx(gamma, rel=1e-5)
    assert max(syn.gammas) <= syn.gamma_bound * (1 + 1e-6) < 1.0


def test_the_stability_margin_is_certified_beyond_the_box_and_broken_just_past_it(ran):
    _, ns, _, _ = ran
    G, K, margin = ns["G"], ns["K"], ns["margin"]
    assert margin.certificate["method"] == "mu"
    assert 1.0 < margin.lower <= margin.upper <= 1.05 * margin.lower
    # every corner of the certified box is stable (python-control's poles)
    for values in _scaled_corners(G, margin.lower):
        assert _rightmost(G, K, values) < 0
    # the member found at the upper bound lies outside the box and is not stable: the
    # damper, the mass and the spring each beyond their range
    crit = margin.critical["parameters"]
    p = G.parameters
    assert crit["c"] < p["c"].low and crit["m"] > p["m"].high and crit["k"] < p["k"].low
    assert _rightmost(G, K, crit) > -1e-3
    # robust performance includes stability: its margin cannot pass an unstable member
    assert ns["perf"].upper <= margin.upper


def test_robust_performance_is_bracketed_and_its_worst_member_breaks_the_bound(ran):
    _, ns, _, _ = ran
    P, K, perf = ns["P"], ns["K"], ns["perf"]
    cl = P.closed_loop(K)
    assert perf.nominal_norm == pytest.approx(hinf_norm(cl.nominal()), rel=1e-6)
    assert perf.nominal_norm < 1.0
    assert 1.0 < perf.lower <= perf.upper <= 1.01 * perf.lower
    # the certified box's corners: stable, weighted norm below 1 (two norm algorithms)
    for values in _scaled_corners(ns["G"], perf.lower):
        member = cl.at(values)
        assert np.linalg.eigvals(member.A).real.max() < 0
        assert hinf_norm(member) < 1.0 and float(ct.norm(member, p="inf")) < 1.0
    worst = perf.worst
    norm = hinf_norm(cl.at(worst["parameters"]))
    assert norm >= 1.0 - 1e-6 and norm == pytest.approx(worst["norm"], rel=1e-5)


def test_the_fresh_members_are_stable(ran):
    _, ns, _, _ = ran
    G, K, v, fresh = ns["G"], ns["K"], ns["v"], ns["fresh"]
    assert v.samples == len(fresh) == 100_000 and (fresh.method, fresh.seed) == ("mc", 1)
    assert v.fraction_stable == 1.0 and v.n_unstable == 0
    # the member with the slowest pole, by python-control
    worst = fresh.row(v.worst_index)
    assert v.max_real_pole == pytest.approx(_rightmost(G, K, worst), rel=1e-6)
    assert v.max_real_pole < 0
    # inside the box, which the certified margin (> 1) covers
    for name, p in G.parameters.items():
        col = fresh.column(name)
        assert p.low <= col.min() and col.max() <= p.high


def test_the_artifact_is_written_and_loads_back_equal(ran):
    tmp, ns, _, _ = ran
    files, K = ns["files"], ns["K"]
    assert set(files) == {"json", "mat"}
    for path in files.values():
        assert path.is_file() and path.is_relative_to(tmp)
    art = load_artifact(files["json"])
    assert art.name == "msd-hinf" and (art.inputs, art.outputs) == (["v"], ["u"])
    for x in "ABCD":
        np.testing.assert_array_equal(getattr(art.continuous, x), getattr(K, x))
    assert ns["same"] is True
    # 100 Hz Tustin prewarped at the nominal mode, 2 rad/s, by python-control directly
    assert art.discrete.dt == 0.01 and art.prewarp_hz == pytest.approx(1 / math.pi)
    ref = ct.sample_system(K, 0.01, method="bilinear", prewarp_frequency=2.0)
    z = np.exp(1j * np.array([0.1, 2.0, 30.0]) * 0.01)
    np.testing.assert_allclose(
        np.asarray(art.discrete(z, squeeze=False)), np.asarray(ref(z, squeeze=False)), rtol=1e-9
    )
    assert art.validation["margin"]["lower"] == ns["margin"].lower
    assert art.validation["performance"] == [ns["perf"].lower, ns["perf"].upper]
    assert art.validation["fraction_stable"] == 1.0
    assert art.family["parameters"] == ["c", "m", "k"] and art.family["samples"] == 100_000
    mat = scipy.io.loadmat(files["mat"])
    np.testing.assert_array_equal(mat["Ac"], K.A)
    assert float(mat["Ts"].squeeze()) == 0.01
