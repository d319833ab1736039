"""Benchmark: the start of the command line, ``python -m bdft --help``, in fresh processes.

Runs ``python -m bdft --help`` ``--runs`` times, each in a new process started from the
repository's root (so the sources beside this script are the ones imported), and prints
the min/median/max wall time. Beside it, as the floor no command can go below, the same
for ``python -c pass`` (the bare interpreter's start on this machine at this moment: on a
shared host it moves from hour to hour). Then, from one more process that runs the same
``--help`` and lists what it imported: the count of modules loaded (and the bare
interpreter's count), and which of the numerical stack (NumPy, SciPy, python-control,
CVXPY, Matplotlib, pandas, Dask, joblib, Numba) were imported; ``--help`` needs none of
them. Prints figures only; nothing is asserted (``tests/test_cli_startup.py`` asserts).

Run: ``python benchmarks/bench_cli.py [--runs 10] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

#: The repository's root: the processes start there and import its sources.
ROOT = Path(__file__).resolve().parents[1]
#: Top-level modules of the numerical stack, which ``bdft --help`` should not import.
HEAVY = (
    "numpy",
    "scipy",
    "control",
    "cvxpy",
    "matplotlib",
    "pandas",
    "dask",
    "joblib",
    "numba",
)
#: Run in a process: ``python -m bdft --help`` through runpy, then the modules it loaded
#: (on standard error, as JSON, after the help on standard output).
_MODULES = """
import json, runpy, sys
sys.argv = ["bdft", "--help"]
try:
    runpy.run_module("bdft", run_name="__main__", alter_sys=True)
except SystemExit:
    pass
sys.stderr.write(json.dumps(sorted(sys.modules)))
"""
_BARE = "import json, sys; sys.stderr.write(json.dumps(sorted(sys.modules)))"


def wall(argv: list[str]) -> float:
    """Wall seconds of one process running ``python ARGV`` (its output discarded)."""
    t = time.perf_counter()
    done = subprocess.run(
        [sys.executable, *argv], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    dt = time.perf_counter() - t
    if done.returncode != 0:
        raise SystemExit(f"python {' '.join(argv)} failed ({done.returncode}): {done.stderr!r}")
    return dt


def modules(code: str) -> list[str]:
    """The modules loaded by a process running ``python -c CODE`` (which prints them)."""
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    return json.loads(done.stderr)


def figures(times: list[float]) -> dict:
    """Min, median and max of wall times, seconds."""
    return {"min": min(times), "median": statistics.median(times), "max": max(times)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10, help="processes of each kind (default 10)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    a = ap.parse_args(argv)
    if a.runs < 1:
        ap.error(f"--runs: expected at least 1; got {a.runs}")
    helps, bare = [], []
    for _ in range(a.runs):
        bare.append(wall(["-c", "pass"]))
        helps.append(wall(["-m", "bdft", "--help"]))
    loaded, floor = modules(_MODULES), modules(_BARE)
    heavy = [m for m in HEAVY if m in loaded]
    obj = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "python": platform.python_version(),
        "runs": a.runs,
        "help_s": figures(helps),
        "bare_interpreter_s": figures(bare),
        "modules": len(loaded),
        "bare_interpreter_modules": len(floor),
        "heavy_modules": heavy,
    }
    if a.json:
        print(json.dumps(obj, indent=2))
        return 0
    print(f"{obj['machine']}, Python {obj['python']}, {a.runs} runs each")
    for label, key in (
        ("python -m bdft --help", "help_s"),
        ("python -c pass", "bare_interpreter_s"),
    ):
        f = obj[key]
        print(f"{label:22s} min {f['min']:.3f} s, median {f['median']:.3f} s, max {f['max']:.3f} s")
    print(f"modules imported       {len(loaded)} (the bare interpreter: {len(floor)})")
    print(f"numerical stack        {', '.join(heavy) if heavy else 'none imported'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
