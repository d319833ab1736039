"""A content-addressed cache of expensive results (designs, margins, maps).

A result is stored under the hash of everything it depends on: the caller's inputs (the
design's name, sample sizes, seeds, limits...) and :func:`code_version`, a hash of the
workbench's own source files and of the numerical libraries' versions. Change any input,
any line of the model, the families or the designs, or upgrade numpy, and the key changes:
a stale result is never returned, it is simply not found. Nothing is ever invalidated by
hand; old entries can be deleted at any time (``rm -r`` the folder).

Where: ``$BDFT_CACHE_DIR``, else ``$XDG_CACHE_HOME/bdft``, else ``~/.cache/bdft``. Entries
are pickles written to a temporary file and renamed, so a crash leaves no half entry; an
entry that cannot be read (truncated, from another Python) is recomputed and replaced.
Pickles run code when loaded: the cache folder must be the user's own.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.util
import json
import os
import pickle
import tempfile
from collections.abc import Callable
from pathlib import Path

import control as ct

__all__ = ["cache_dir", "code_version", "cache_key", "cached", "CACHE_ENV"]

#: Environment variable naming the cache folder.
CACHE_ENV = "BDFT_CACHE_DIR"
#: The packages whose source makes up the code version.
PACKAGES = ("robust", "uncertainty", "designs", "reports")
#: Libraries whose versions make up the code version.
LIBRARIES = ("numpy", "scipy", "control", "cvxpy", "clarabel", "slycot")

_VERSION: str | None = None


def _state_space(A, B, C, D, dt, inputs, outputs, states, name):
    return ct.ss(A, B, C, D, dt, inputs=inputs, outputs=outputs, states=states, name=name)


class _Pickler(pickle.Pickler):
    """Pickles python-control state-space systems by their matrices and signal names
    (their instances hold a local function that plain pickle cannot store)."""

    def reducer_override(self, obj):
        """Reduce a :class:`control.StateSpace` to its data; other objects as usual.

        Parameters
        ----------
        obj : object
            The object being pickled.
        """
        if type(obj) is ct.StateSpace:
            return _state_space, (
                obj.A,
                obj.B,
                obj.C,
                obj.D,
                obj.dt,
                list(obj.input_labels),
                list(obj.output_labels),
                list(obj.state_labels),
                obj.name,
            )
        return NotImplemented


def cache_dir() -> Path:
    """The cache folder (not created here)."""
    env = os.environ.get(CACHE_ENV, "").strip()
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME", "").strip()
    return (Path(xdg) if xdg else Path.home() / ".cache") / "bdft"


def code_version() -> str:
    """Hash of the workbench's source files and the numerical libraries' versions."""
    global _VERSION
    if _VERSION is None:
        h = hashlib.sha256()
        for pkg in PACKAGES:
            spec = importlib.util.find_spec(pkg)
            roots = list(spec.submodule_search_locations or []) if spec else []
            for root in roots:
                for path in sorted(Path(root).rglob("*.py")):
                    h.update(str(path.relative_to(Path(root).parent)).encode())
                    h.update(path.read_bytes())
        for lib in LIBRARIES:
            try:
                h.update(f"{lib}={importlib.metadata.version(lib)}".encode())
            except importlib.metadata.PackageNotFoundError:
                h.update(f"{lib}=absent".encode())
        _VERSION = h.hexdigest()
    return _VERSION


def cache_key(kind: str, inputs: dict) -> str:
    """The key of a result: a hash of its kind, its inputs (as JSON) and the code version.

    Parameters
    ----------
    kind : str
        What the result is (``"design"``, ``"limit-map"``...), also its sub-folder.
    inputs : dict
        Everything the result depends on besides the code, JSON-serialisable.
    """
    text = json.dumps(
        {"kind": kind, "inputs": inputs, "code": code_version()}, sort_keys=True, default=repr
    )
    return hashlib.sha256(text.encode()).hexdigest()


def cached(kind: str, inputs: dict, compute: Callable[[], object], *, enabled: bool = True):
    """``compute()``, or its stored result for the same inputs and code.

    Parameters
    ----------
    kind : str
        What the result is (see :func:`cache_key`).
    inputs : dict
        Everything the result depends on besides the code.
    compute : callable
        Computes the result (called on a miss, or always when not ``enabled``).
    enabled : bool
        Use the cache (False: compute, read and write nothing).

    Returns
    -------
    value
        The result.
    hit : bool
        Whether it came from the cache.
    """
    if not enabled:
        return compute(), False
    path = cache_dir() / kind / f"{cache_key(kind, inputs)}.pkl"
    if path.is_file():
        try:
            with path.open("rb") as fh:
                return pickle.load(fh), True
        except Exception:  # a damaged or foreign entry: recompute and replace it
            pass
    value = compute()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".pkl")
        try:
            with os.fdopen(fd, "wb") as fh:
                _Pickler(fh, protocol=pickle.HIGHEST_PROTOCOL).dump(value)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        pass  # a cache that cannot be written only costs time
    return value, False
