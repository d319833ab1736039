"""bdft fixes OpenBLAS's and NumPy's kernels before NumPy is imported (bdft.kernels)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from bdft.kernels import NATIVE_ENV, NUMPY_DISABLED, _cpu_flags, pin_numeric_kernels, pinned

CAPABLE = {"avx2", "fma"} <= _cpu_flags() and os.uname().machine == "x86_64"


def test_the_pin_sets_both_kernels_and_keeps_what_was_disabled():
    env = {"NPY_DISABLE_CPU_FEATURES": "AVX512_SPR,FOO", "OPENBLAS_CORETYPE": "Sandybridge"}
    done = pin_numeric_kernels(env, {})
    if not CAPABLE:
        assert not done and env["OPENBLAS_CORETYPE"] == "Sandybridge"
        assert "AVX2" in pinned()[1] or "x86-64" in pinned()[1]
        return
    assert done and pinned() == (True, "OpenBLAS Haswell, NumPy x86-64-v3")
    assert env["OPENBLAS_CORETYPE"] == "Haswell"
    disabled = env["NPY_DISABLE_CPU_FEATURES"].split()
    assert disabled[:2] == ["AVX512_SPR", "FOO"]  # the user's, then the missing ones once
    assert sorted(disabled) == sorted({"FOO", *NUMPY_DISABLED})


@pytest.mark.parametrize(
    "env, modules, why",
    [
        ({NATIVE_ENV: "1"}, {}, "BDFT_NATIVE_KERNELS=1"),
        ({}, {"numpy": object()}, "NumPy was imported before bdft"),
    ],
    ids=["native", "numpy-first"],
)
def test_the_pin_stands_back_when_asked_or_too_late(env, modules, why):
    before = dict(env)
    assert pin_numeric_kernels(env, modules) is False
    assert env == before
    assert pinned()[0] is False and why in pinned()[1]


@pytest.mark.skipif(not CAPABLE, reason="the CPU lacks AVX2 or FMA: nothing is pinned")
def test_a_bdft_process_runs_the_pinned_kernels_whatever_the_environment_asks():
    code = (
        "import json, bdft\n"
        "from threadpoolctl import threadpool_info\n"
        "from numpy._core._multiarray_umath import __cpu_features__ as f\n"
        "import scipy.linalg\n"
        "print(json.dumps([[i.get('architecture') for i in threadpool_info()"
        " if i['internal_api'] == 'openblas'], f['X86_V4'], f['AVX2']]))\n"
    )
    env = dict(os.environ, OPENBLAS_CORETYPE="Sandybridge")
    env.pop(NATIVE_ENV, None)
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    archs, v4, avx2 = json.loads(out.stdout)
    # NumPy's and SciPy's OpenBLAS (and any other copy loaded) run the Haswell kernels
    assert len(archs) >= 2 and set(archs) == {"Haswell"}
    assert v4 is False and avx2 is True
    env[NATIVE_ENV] = "1"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    assert set(json.loads(out.stdout)[0]) == {"Sandybridge"}
