"""Run a script in a fresh process twice: with Numba's build for this CPU, and with a build for
a generic x86-64 (no AVX, no fused multiply-add) in a cache of its own."""

import os
import subprocess
import sys


def outputs_here_and_generic(script: str, cache_dir) -> tuple[str, str]:
    """The script's standard output (stripped) for this CPU's build and for a generic one."""
    here = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout.strip()
    env = dict(os.environ, NUMBA_CPU_NAME="generic", NUMBA_CACHE_DIR=str(cache_dir))
    generic = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, env=env
    ).stdout.strip()
    return here, generic
