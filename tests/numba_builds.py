"""Run scripts with Numba's build for this CPU (in this process) and with a build for a
generic x86-64 (no AVX, no fused multiply-add) in a fresh process with a cache of its own.

Test modules register their scripts at import (:func:`register`). A script's output for
this CPU comes from running it here, with the kernels this test process compiled or loaded
(a fresh process would only compile them once more, about 30 s of CPU in a clean checkout).
For the generic build, the first test that asks (:func:`outputs_here_and_generic`) runs
every registered script in one fresh process, and the other tests read their lines back, in
this process or, under pytest-xdist, in another worker of the same run (a file in the
temporary directory, named by the run and the scripts, under a lock).

The generic build's cache is a directory in the temporary directory named by a hash of the
package sources (every ``.py`` file of ``robust``, ``uncertainty``, ``designs`` and ``bdft``)
and of the Python, Numba, llvmlite and NumPy versions: the kernels are built for the generic
CPU once per version of the code, and later runs load that build (Numba's own cache, which
also checks each source file's time stamp and the CPU the build is for) instead of
compiling it again (about 20 s of CPU for the saturation kernels alone). Any change to a
source file gives a new directory, so a stale build is never loaded.
"""

import atexit
import contextlib
import fcntl
import hashlib
import importlib.metadata
import io
import json
import os
import subprocess
import sys
import tempfile
import time
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


_ROOT = Path(__file__).resolve().parent.parent
_PACKAGES = ("robust", "uncertainty", "backhoe", "designs", "bdft")


def _generic_cache_dir() -> Path:
    """The generic build's cache: one directory per version of the sources and libraries."""
    h = hashlib.sha256()
    h.update(sys.version.encode())
    for dist in ("numba", "llvmlite", "numpy"):
        h.update(f"{dist}=={importlib.metadata.version(dist)}".encode())
    for pkg in _PACKAGES:
        for path in sorted((_ROOT / pkg).rglob("*.py")):
            h.update(str(path.relative_to(_ROOT)).encode())
            h.update(hashlib.sha256(path.read_bytes()).digest())
    name = f"bdft-numba-generic-{os.getuid()}-{h.hexdigest()[:20]}"
    return Path(tempfile.gettempdir()) / name


def _generic() -> dict:
    cache_dir = _generic_cache_dir()
    cache_dir.mkdir(mode=0o700, exist_ok=True)
    env = dict(os.environ, NUMBA_CPU_NAME="generic", NUMBA_CACHE_DIR=str(cache_dir))
    return _run(env)


def _here(name: str) -> str:
    """The script's output (stripped, one line) run in this process."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(compile(_SCRIPTS[name], name, "exec"), {"__name__": "__main__"})
    return buf.getvalue().strip().replace(chr(10), " ")


def _shared(digest: str) -> dict:
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run is None:
        return _generic()
    path = Path(tempfile.gettempdir()) / f"bdft-numba-builds-{run}-{digest[:16]}.json"
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        with contextlib.suppress(OSError, ValueError):
            return json.loads(path.read_text())
        out = _generic()
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(out))
        tmp.replace(path)
        for p in (path, path.with_suffix(".lock")):
            atexit.register(p.unlink, missing_ok=True)
        return out


def build_share(index: int, count: int, timeout: float = 300.0) -> None:
    """Compile this worker's share of the registered scripts' kernels, then wait for the
    other workers' shares (at most ``timeout`` seconds).

    Under pytest-xdist every worker needs most kernels early, and Numba compiles a kernel in
    every process that needs it before another has stored it in its cache: in a clean
    checkout both workers compiled every kernel. Split and waited for, each is compiled once
    and loaded from Numba's cache by the other workers at first use.
    """
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID", "")
    for name in sorted(_SCRIPTS)[index::count]:
        _here(name)
    folder = Path(tempfile.gettempdir())
    done = folder / f"bdft-numba-share-{run}-{index}"
    done.touch()
    atexit.register(done.unlink, missing_ok=True)
    others = [folder / f"bdft-numba-share-{run}-{i}" for i in range(count) if i != index]
    deadline = time.monotonic() + timeout
    while not all(p.exists() for p in others) and time.monotonic() < deadline:
        time.sleep(0.1)


def outputs_here_and_generic(name: str, cache_dir=None) -> tuple[str, str]:
    """The registered script's standard output (stripped) for this CPU's build, run here,
    and for a generic one (``cache_dir`` is not used: the generic build has its own cache,
    module notes)."""
    digest = hashlib.sha256(json.dumps(sorted(_SCRIPTS.items())).encode()).hexdigest()
    if _OUTPUTS.get("digest") != digest:
        _OUTPUTS.clear()
        _OUTPUTS.update(generic=_shared(digest), digest=digest)
    return _here(name), _OUTPUTS["generic"][name]
