"""Benchmark: ``bdft report`` cold and cached, and ``bdft design hinf-robust-lmi`` cold.

Each run is the whole command in a fresh process, as a user starts it (``python -m bdft
... --json``), with the default options. A cold run gets an empty result cache of its own
(``BDFT_CACHE_DIR`` in a new temporary folder); the cached report runs again on the cache
its cold run filled. Printed for each kind: min/median/max wall time over ``--runs``, the
median CPU time of the process and its workers (user + system) and the CPU use it implies
(on two cores at most 2.0), the largest peak resident memory of one process, and whether
every run printed the same JSON once the timings and paths are set aside (the numbers
must not depend on the cache or on the run).

The machine's speed varies from hour to hour on shared hosts (the same report has taken
240 s on one hour and 358 s on another); before each run a fixed single-threaded probe
(LAPACK eigenvalues of 13 x 13 matrices and a Python loop, about a second) is timed, and
its median is printed beside the figures, so that timings from different hours can be
told apart from changes of the code.

Run: ``python benchmarks/bench_report.py [--runs 2] [--kinds report,cached,design]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: Keys of the JSON output whose values are timings or paths (set aside when comparing).
VOLATILE = ("seconds", "time", "elapsed", "report", "artifact", "path")
COMMANDS = {
    "report": ["report", "--json"],
    "design": ["design", "hinf-robust-lmi", "--json"],
}


def probe() -> float:
    """Seconds of a fixed single-threaded workload (the machine's speed at this moment)."""
    rng = np.random.default_rng(0)
    stack = rng.standard_normal((4000, 13, 13))
    t = time.perf_counter()
    for _ in range(6):
        np.linalg.eigvals(stack)
    total = 0
    for i in range(6_000_000):
        total += i * i % 7
    return time.perf_counter() - t


def stable_part(obj):
    """``obj`` without the keys that hold timings or paths, recursively."""
    if isinstance(obj, dict):
        return {
            k: stable_part(v) for k, v in obj.items() if not any(s in k.lower() for s in VOLATILE)
        }
    if isinstance(obj, list):
        return [stable_part(v) for v in obj]
    return obj


def run(argv, cache_dir: Path, out_dir: Path | None) -> dict:
    """One command in a fresh process: wall and CPU seconds (the process and the workers it
    waited for), its peak resident memory (the largest of one process), its JSON."""
    env = dict(os.environ, BDFT_CACHE_DIR=str(cache_dir))
    cmd = [sys.executable, "-m", "bdft", *argv]
    if out_dir is not None:
        cmd += ["--out", str(out_dir)]
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, text=True, env=env)
        # os.wait4 rather than Popen.wait: it returns this child's resource usage alone
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    if proc.returncode != 0:
        tail = stderr.strip().splitlines()[-5:]
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): " + " | ".join(tail))
    return {
        "wall": wall,
        "cpu": usage.ru_utime + usage.ru_stime,
        "rss_mib": usage.ru_maxrss / 1024,
        "json": json.dumps(stable_part(json.loads(stdout)), sort_keys=True),
    }


def summary(name: str, rows: list, probes: list) -> str:
    walls = [r["wall"] for r in rows]
    cpu = statistics.median(r["cpu"] for r in rows)
    med = statistics.median(walls)
    same = len({r["json"] for r in rows}) == 1
    return (
        f"{name}: min {min(walls):.1f} s, median {med:.1f} s, max {max(walls):.1f} s "
        f"({len(rows)} runs); CPU {cpu:.0f} s (use {cpu / med:.2f} cores); "
        f"peak RSS {max(r['rss_mib'] for r in rows):.0f} MiB; "
        f"probe median {statistics.median(probes):.2f} s; "
        f"same JSON every run: {'yes' if same else 'NO'}"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2, help="runs of each kind (default 2)")
    ap.add_argument(
        "--kinds",
        default="report,cached,design",
        help="comma-separated: report (cold), cached (the report again, cache filled), design",
    )
    a = ap.parse_args(argv)
    kinds = [k.strip() for k in a.kinds.split(",") if k.strip()]
    unknown = sorted(set(kinds) - {"report", "cached", "design"})
    if unknown or a.runs < 1:
        ap.error(f"--kinds takes report, cached, design; --runs >= 1 (got {a.kinds}, {a.runs})")
    results: dict = {k: [] for k in kinds}
    probes: dict = {k: [] for k in kinds}
    for _ in range(a.runs):
        tmp = Path(tempfile.mkdtemp(prefix="bench-report-"))
        try:
            if "report" in kinds or "cached" in kinds:
                p = probe()
                cold = run(COMMANDS["report"], tmp / "cache", tmp / "cold")
                if "report" in kinds:
                    results["report"].append(cold)
                    probes["report"].append(p)
                if "cached" in kinds:
                    probes["cached"].append(probe())
                    warm = run(COMMANDS["report"], tmp / "cache", tmp / "warm")
                    warm["json_cold"] = cold["json"]
                    results["cached"].append(warm)
            if "design" in kinds:
                probes["design"].append(probe())
                results["design"].append(run(COMMANDS["design"], tmp / "dcache", None))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores")
    labels = {
        "report": "bdft report, cold",
        "cached": "bdft report, cached",
        "design": "bdft design hinf-robust-lmi, cold",
    }
    for k in kinds:
        print(summary(labels[k], results[k], probes[k]))
    if "cached" in kinds:
        same = all(r["json"] == r["json_cold"] for r in results["cached"])
        print(f"cached report prints the cold report's JSON: {'yes' if same else 'NO'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
