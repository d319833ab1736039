"""Run scripts in a fresh process twice: with Numba's build for this CPU, and with a build for
a generic x86-64 (no AVX, no fused multiply-add) in a cache of its own.

Test modules register their scripts at import (:func:`register`); the first test that asks
for its outputs (:func:`outputs_here_and_generic`) runs every registered script in one pair of
processes, and the other tests read their lines back, in this process or, under
pytest-xdist, in another worker of the same run (a file in the temporary directory, named
by the run and the scripts, under a lock): one generic build of the kernels per run.
"""

import atexit
import contextlib
import fcntl
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

_SCRIPTS: dict = {}
_OUTPUTS: dict = {}

_RUNNER = """
import contextlib, io
scripts = {scripts!r}
for name, src in scripts.items():
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(compile(src, name, "exec"), {{"__name__": "__main__"}})
    print(name, buf.getvalue().strip().replace(chr(10), " "))
"""


def register(name: str, script: str) -> None:
    """Add a script (one that prints its result) under ``name``."""
    _SCRIPTS[name] = script


def _run(env=None) -> dict:
    code = _RUNNER.format(scripts=dict(sorted(_SCRIPTS.items())))
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    ).stdout
    return dict(line.split(" ", 1) for line in out.strip().splitlines())


def _both(cache_dir) -> dict:
    env = dict(os.environ, NUMBA_CPU_NAME="generic", NUMBA_CACHE_DIR=str(cache_dir))
    return {"here": _run(), "generic": _run(env)}


def _shared(digest: str, cache_dir) -> dict:
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run is None:
        return _both(cache_dir)
    path = Path(tempfile.gettempdir()) / f"bdft-numba-builds-{run}-{digest[:16]}.json"
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        with contextlib.suppress(OSError, ValueError):
            return json.loads(path.read_text())
        out = _both(cache_dir)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(out))
        tmp.replace(path)
        for p in (path, path.with_suffix(".lock")):
            atexit.register(p.unlink, missing_ok=True)
        return out


def outputs_here_and_generic(name: str, cache_dir) -> tuple[str, str]:
    """The registered script's standard output (stripped) for this CPU's build and for a
    generic one."""
    digest = hashlib.sha256(json.dumps(sorted(_SCRIPTS.items())).encode()).hexdigest()
    if _OUTPUTS.get("digest") != digest:
        _OUTPUTS.clear()
        _OUTPUTS.update(_shared(digest, cache_dir), digest=digest)
    return _OUTPUTS["here"][name], _OUTPUTS["generic"][name]
