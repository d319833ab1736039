"""A content-addressed cache of expensive results (designs, margins, maps).

A result is stored under the hash of everything it depends on: the caller's inputs (the
design's name, sample sizes, seeds, limits...) and :func:`code_version`, a hash of the
workbench's own source files, of the numerical libraries' versions and of the kernels they
run (:func:`numeric_kernels`). Change any input, any line of the model, the families or
the designs, upgrade numpy or run other kernels, and the key changes:
a stale result is never returned, it is simply not found. Nothing is ever invalidated by
hand; old entries can be deleted at any time (``rm -r`` the folder).

Where: ``$BDFT_CACHE_DIR``, else ``$XDG_CACHE_HOME/bdft``, else ``~/.cache/bdft``. Entries
are pickles written to a temporary file and renamed, so a crash leaves no half entry; an
entry that cannot be read (truncated, from another Python) is recomputed and replaced.
Pickles run code when loaded: the cache folder must be the user's own.
"""

from __future__ import annotations

import contextlib
import contextvars
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
from threadpoolctl import threadpool_info

try:  # NumPy's vector-loop dispatch (what this CPU and NPY_DISABLE_CPU_FEATURES left on)
    from numpy._core._multiarray_umath import __cpu_dispatch__ as _NPY_DISPATCH
    from numpy._core._multiarray_umath import __cpu_features__ as _NPY_FEATURES
except ImportError:  # pragma: no cover - another NumPy layout
    _NPY_DISPATCH, _NPY_FEATURES = (), {}

__all__ = [
    "cache_dir",
    "code_version",
    "numeric_kernels",
    "cache_key",
    "cached",
    "caching",
    "caching_enabled",
    "lookup",
    "store",
    "CACHE_ENV",
]

#: Environment variable naming the cache folder.
CACHE_ENV = "BDFT_CACHE_DIR"
#: The packages whose source makes up the code version.
PACKAGES = ("robust", "uncertainty", "backhoe", "designs", "reports")
#: Libraries whose versions make up the code version.
LIBRARIES = ("numpy", "scipy", "control", "cvxpy", "clarabel", "slycot")

_VERSION: str | None = None
_CACHING: contextvars.ContextVar[bool] = contextvars.ContextVar("bdft_caching", default=False)


@contextlib.contextmanager
def caching(enabled: bool = True):
    """Within the block, steps of a computation may keep and reuse their results in the cache.

    A command run with its cache (``bdft design``, ``bdft report``) sets it around its work,
    so that a long computation that repeats another's steps (the robust LMI ladders' rungs,
    :mod:`designs.robust_lmi_ahead`) reads them back; ``--no-cache`` leaves it off. It holds in
    this thread and its context only: a task sent to another process sets it there.

    Parameters
    ----------
    enabled : bool
        Whether steps may be cached.
    """
    token = _CACHING.set(bool(enabled))
    try:
        yield
    finally:
        _CACHING.reset(token)


def caching_enabled() -> bool:
    """Whether :func:`caching` is on here."""
    return _CACHING.get()


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
    """Hash of the workbench's source files, the numerical libraries' versions and kernels."""
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
        h.update(numeric_kernels().encode())
        _VERSION = h.hexdigest()
    return _VERSION


def numeric_kernels() -> str:
    """The kernels this process computes with: OpenBLAS's and NumPy's vector loops.

    Results differ in their last digits between kernels (and the robust designs more),
    so a result computed with other kernels (another CPU sharing the cache folder, or a
    process that did not fix them, see ``bdft.kernels``) has another key.
    """
    arch = sorted(
        {
            str(i.get("architecture"))
            for i in threadpool_info()
            if i.get("internal_api") == "openblas"
        }
    )
    simd = [f for f in _NPY_DISPATCH if _NPY_FEATURES.get(f)] if _NPY_DISPATCH else ["unknown"]
    return f"openblas={','.join(arch)};numpy={','.join(simd)}"


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


def _entry(kind: str, inputs: dict) -> Path:
    return cache_dir() / kind / f"{cache_key(kind, inputs)}.pkl"


def lookup(kind: str, inputs: dict) -> tuple[bool, object]:
    """The stored result for ``inputs`` and this code, if there is one.

    Parameters
    ----------
    kind : str
        What the result is (see :func:`cache_key`).
    inputs : dict
        Everything the result depends on besides the code.

    Returns
    -------
    found : bool
        Whether a readable entry exists (a damaged or foreign one counts as none).
    value
        The result, or None.
    """
    path = _entry(kind, inputs)
    if path.is_file():
        try:
            with path.open("rb") as fh:
                return True, pickle.load(fh)
        except Exception:  # a damaged or foreign entry: recompute and replace it
            pass
    return False, None


def store(kind: str, inputs: dict, value) -> None:
    """Store ``value`` for ``inputs`` and this code (atomically; a failure only costs time).

    Parameters
    ----------
    kind : str
        What the result is (see :func:`cache_key`).
    inputs : dict
        Everything the result depends on besides the code.
    value : object
        The result (picklable; state-space systems by their data).
    """
    path = _entry(kind, inputs)
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
    found, value = lookup(kind, inputs)
    if found:
        return value, True
    value = compute()
    store(kind, inputs, value)
    return value, False
