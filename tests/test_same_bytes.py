"""The same run prints the same bytes under any BLAS thread count and x86-64 kernel.

The commands run in a fresh process for each environment (one process runs the four in
turn, as ``python -m bdft`` would one by one): ``OPENBLAS_NUM_THREADS`` at 1, 4 and 2, with
``OPENBLAS_CORETYPE`` asking for an older kernel (Sandybridge: no FMA) or Haswell, and with
NumPy's AVX-512 loops disabled as on a CPU without them; each command's ``--json`` output
must hash alike in the three (the artifact path aside). What makes them so: ``bdft`` runs
OpenBLAS's Haswell kernels and NumPy's x86-64-v3 loops whatever the CPU or the environment
asks (:mod:`bdft.kernels`; without that the LMI designs, whose start is a non-unique SDP
solution, differ between kernels: ``hinf-nominal`` below gave three hashes under these
three environments with ``BDFT_NATIVE_KERNELS=1``), every robust design runs its BLAS and
solvers on one thread (:func:`robust.synthesis.solve.deterministic_solvers`), ties are
decided with a relative margin, the sampled-data deviation is rounded to 0.001 dB and an
exact cancellation's residual suppression and tracking error (rounding, 1e-14 to 1e-12) to
0, and JSON numbers are printed to six significant digits
(:func:`robust.jsonio.round_significant`). (The virtual-damping design, with a nearly
double closed-loop pole whose real part moves by 6e-10 between kernels, was checked the
same way by hand.)
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys

import pytest

ENVS = (
    {"OPENBLAS_CORETYPE": "Haswell", "OPENBLAS_NUM_THREADS": "1"},
    {"OPENBLAS_NUM_THREADS": "4"},
    {
        "OPENBLAS_CORETYPE": "Sandybridge",
        "OPENBLAS_NUM_THREADS": "2",
        "NPY_DISABLE_CPU_FEATURES": "X86_V4",
    },
)


#: The commands, by test id. Their sizes do not matter to the property: the same code runs
#: on fewer members (the scheduled design on 3 coverage members and 1 border member calls
#: the same functions of the workbench as on 20 and 3, measured with cProfile)
COMMANDS = {
    "validate": ["validate", "--samples", "20000", "--jobs", "1", "--json"],
    "design": ["design", "cancellation", "--samples", "40", "--coverage-samples", "50"]
    + ["--margin-boxes", "0", "--no-cache", "--json"],
    # an LMI design: its SDP's solution is not unique, so the kernels' rounding shows
    "lmi-design": ["design", "hinf-nominal", "--samples", "100", "--coverage-samples", "0"]
    + ["--margin-boxes", "0", "--jobs", "1", "--no-cache", "--json"],
    # the per-operator design: simulated records, fits, the joint error regions (an
    # eigendecomposition and a search along each axis) and the border checks
    "scheduled": ["design", "scheduled", "--coverage-samples", "3", "--border-samples", "1"]
    + ["--certify-samples", "0", "--limit-samples", "0", "--cells", "1", "--jobs", "1"]
    + ["--json"],
}

# one fresh process per environment runs every command in turn through bdft.main, as
# ``python -m bdft`` does (bdft imported first, so it fixes the kernels before NumPy
# loads), and prints each command's standard output: the environment takes effect at
# load time, so one process per environment sees what a process per command would, and
# the libraries are imported three times instead of twelve
_RUNNER = """
import contextlib, io, json, sys

import bdft

outs = []
for argv in json.loads(sys.argv[1]):
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = bdft.main(argv)
    if code != 0:
        sys.exit(f"bdft {' '.join(argv)}: exit code {code}")
    outs.append(buf.getvalue())
sys.stdout.write(json.dumps(outs))
"""


def _outputs(argvs, extra_env, folder):
    env = {
        k: v for k, v in os.environ.items() if not k.startswith(("OPENBLAS", "NPY_", "BDFT_NATIVE"))
    }
    env.update(extra_env, BDFT_CACHE_DIR=str(folder / "cache"))
    done = subprocess.run(
        [sys.executable, "-c", _RUNNER, json.dumps(argvs)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    if done.returncode != 0:
        raise AssertionError(f"the commands failed under {extra_env}:\n{done.stderr[-4000:]}")
    return json.loads(done.stdout)


def _hash(out, folder):
    obj = json.loads(out)
    obj.pop("artifact", None)
    text = json.dumps(obj, sort_keys=True, indent=1)
    (folder / f"out-{hashlib.sha256(text.encode()).hexdigest()[:8]}.json").write_text(text)
    return hashlib.sha256(text.encode()).hexdigest()


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """Each command's standard output under each environment, and the artifacts' folder."""
    folder = tmp_path_factory.mktemp("same-bytes")
    runs = []
    for i, extra_env in enumerate(ENVS):
        (folder / f"env{i}").mkdir()
        argvs = []
        for name, args in COMMANDS.items():
            if args[0] == "design":
                args = [*args, "--out", str(folder / f"{name}-art{i}")]
            argvs.append(args)
        runs.append(dict(zip(COMMANDS, _outputs(argvs, extra_env, folder / f"env{i}"))))
    return folder, runs


@pytest.mark.slow
@pytest.mark.parametrize("name", list(COMMANDS))
def test_the_json_hashes_alike_across_threads_and_kernels(name, outputs):
    folder, runs = outputs
    hashes = {_hash(run[name], folder) for run in runs}
    if name == "scheduled":  # its artifact holds no timings: the same bytes too
        arts = {
            (folder / f"{name}-art{i}" / "scheduled.json").read_bytes() for i in range(len(ENVS))
        }
        assert len(hashes) == 1 and len(arts) == 1
        return
    assert len(hashes) == 1


def test_deterministic_solvers_put_every_blas_on_one_thread_and_restore_it(monkeypatch):
    """Inside the block every loaded BLAS runs one thread (Clarabel too), and the counts are
    restored after it; the view of the loaded libraries is kept between blocks and made
    again once a module has been imported."""
    from threadpoolctl import ThreadpoolController

    from robust.synthesis import solve

    def blas_threads():
        return {
            i["filepath"]: i["num_threads"]
            for i in ThreadpoolController().info()
            if i["user_api"] == "blas"
        }

    with ThreadpoolController().limit(limits=2, user_api="blas"):
        before = blas_threads()
        assert 2 in before.values()  # (a single-threaded build stays at 1)
        with solve.deterministic_solvers():
            assert blas_threads() == dict.fromkeys(before, 1)
            assert solve.solver_threads() == 1
            first = solve._blas_controller()
        assert blas_threads() == before
        assert solve.solver_threads() == 0
        with solve.deterministic_solvers():
            assert solve._blas_controller() is first
        monkeypatch.setitem(sys.modules, "bdft_test_new_module", type(sys)("bdft_test_new_module"))
        with solve.deterministic_solvers():
            assert blas_threads() == dict.fromkeys(before, 1)
            assert solve._blas_controller() is not first
        assert blas_threads() == before
