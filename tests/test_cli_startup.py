"""``bdft --help`` and argument errors are answered without the numerical stack.

Building the parser and parsing import no numerical library: each command module imports
the layers below it in the functions that run the command, and the packages' public
names load on first use (:mod:`robust.lazy`). Checked in fresh processes (this one has
NumPy already): the help of ``bdft`` and of every command, argparse's errors (an unknown
option, a bad integer, a bad choice, a missing or unknown command) through
:func:`bdft.main` with exit code 2, and then none of :data:`HEAVY` imported; and ``python
-m bdft --help`` exits 0 listing every command.
"""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import bdft

ROOT = Path(__file__).resolve().parents[1]
#: The numerical stack: none of it may be imported to answer ``--help`` or a usage error.
HEAVY = ("numpy", "scipy", "control", "cvxpy", "matplotlib", "pandas", "dask", "joblib", "numba")
COMMANDS = [m.__name__.rsplit(".", 1)[1] for m in bdft.COMMANDS]
#: Argument errors argparse finds (exit code 2 from bdft.main).
USAGE_ERRORS = [
    ["validate", "--samples", "abc"],
    ["validate", "--no-such-option"],
    ["validate", "--method", "magic"],
    ["margin", "--method", "magic"],
    ["limit", "--sets", "magic"],
    ["design", "--cells", "99"],
    ["reproduce", "--human", "robot"],
    ["sweep"],
    ["identify"],
    ["no-such-command"],
    [],
]


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_help_and_usage_errors_import_no_numerical_library():
    done = _run(
        f"""
        import contextlib, io, json, sys
        import bdft

        parser = bdft.build_parser()
        helps = {{}}
        for argv in [["--help"], *[[c, "--help"] for c in {COMMANDS!r}]]:
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                try:
                    parser.parse_known_args(argv)
                    code = None
                except SystemExit as exc:
                    code = exc.code
            helps[" ".join(argv)] = [code, out.getvalue()]
        codes = {{}}
        for argv in {USAGE_ERRORS!r}:
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                codes[" ".join(argv)] = [bdft.main(argv), err.getvalue()]
        heavy = [m for m in {HEAVY!r} if m in sys.modules]
        print(json.dumps({{"helps": helps, "codes": codes, "heavy": heavy}}))
        """
    )
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout)
    for argv, (code, text) in got["helps"].items():
        assert code == 0 and text.startswith("usage: bdft"), argv
    for argv, (code, err) in got["codes"].items():
        assert code == 2, f"bdft {argv}: exit code {code}"
        assert err.startswith("bdft") and ": error: " in err and err.count("\n") == 1, err
    assert got["heavy"] == [], f"imported for --help and usage errors: {got['heavy']}"


def test_python_m_bdft_help_lists_every_command():
    done = subprocess.run(
        [sys.executable, "-m", "bdft", "--help"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage: bdft") and done.stderr == ""
    for name in COMMANDS:
        assert f"\n    {name}" in done.stdout, f"{name} missing from bdft --help"


def test_the_kernels_are_pinned_before_numpy_loads():
    # bdft.kernels still runs first: importing bdft (and NumPy after it) leaves the reason
    # of a pinned or unpinned process, never "NumPy was imported before bdft"
    done = _run(
        """
        import bdft, bdft.kernels, numpy
        print(bdft.kernels.pinned()[1])
        """
    )
    assert done.returncode == 0, done.stderr
    assert "NumPy was imported before bdft" not in done.stdout
