"""Conversion of results to JSON-ready values and atomic file writing.

Files are written into a temporary name beside the destination and renamed into
place, so a failure never leaves a half-written file; :func:`atomic_write_group`
does the same for several files that belong together (all or none). A new file gets
the usual mode (``0o666`` less the process umask, as :func:`open` would create it),
a replaced file keeps its mode.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import stat
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "to_jsonable",
    "round_significant",
    "JSON_DIGITS",
    "atomic_write_text",
    "atomic_write_bytes",
    "atomic_write",
    "atomic_write_group",
    "atomic_write_json",
    "current_umask",
    "new_file_mode",
]


#: Significant digits of the numbers the commands print as JSON (``--json``).
JSON_DIGITS = 6


def round_significant(obj, digits: int = JSON_DIGITS):
    """Every float of a JSON-able structure rounded to ``digits`` significant digits.

    The last bits of a computed number depend on the BLAS kernel a CPU selects: about
    1e-12 relative for well-conditioned eigenvalues and norms, up to about 1e-8 for a
    nearly double eigenvalue (its error grows as the square root of the rounding). Rounded
    to 6 digits, the printed numbers are the same on every x86-64 CPU and thread count
    unless a value lies within that error of a rounding boundary (measured: none of the
    validation's and a design's outputs under the Haswell and Sandybridge kernels and 1,
    2 or 4 threads). Where a computation amplifies the last bits (the LMI designs), the
    rounding cannot help: the ``bdft`` command fixes the kernels instead
    (:mod:`bdft.kernels`).

    Parameters
    ----------
    obj : object
        What :func:`to_jsonable` returns.
    digits : int
        Significant digits, >= 1.
    """
    if isinstance(obj, float):
        return float(f"{obj:.{digits}g}") if math.isfinite(obj) and obj != 0.0 else obj
    if isinstance(obj, dict):
        return {k: round_significant(v, digits) for k, v in obj.items()}
    if isinstance(obj, list):
        return [round_significant(v, digits) for v in obj]
    return obj


def to_jsonable(obj):
    """Recursively convert numpy types, dataclasses, paths and complex numbers.

    Non-finite floats become the strings ``"inf"``, ``"-inf"`` or ``"nan"`` so the
    output is strict JSON.

    Parameters
    ----------
    obj : object
        A value to convert: dataclass instances (through
        :func:`dataclasses.asdict`), mappings (keys become ``str``), lists and
        tuples, numpy arrays and scalars, Python numbers, complex numbers and paths,
        nested in any way. Anything else is returned unchanged.

    Returns
    -------
    object
        Built from ``dict``, ``list``, ``str``, ``int``, ``float``, ``bool`` and
        ``None`` only (for inputs of the kinds above). Complex numbers become
        ``{"re": ..., "im": ...}``; paths become strings.
    """
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_jsonable(dataclasses.asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        if math.isfinite(x):
            return x
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if isinstance(obj, (complex, np.complexfloating)):
        return {"re": to_jsonable(obj.real), "im": to_jsonable(obj.imag)}
    if isinstance(obj, Path):
        return str(obj)
    return obj


def current_umask() -> int:
    """The process's file-mode creation mask, read without changing it where possible.

    Returns
    -------
    int
        The umask (e.g. ``0o022``): from ``/proc/self/status`` on Linux, otherwise by
        setting and restoring it with :func:`os.umask`.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def new_file_mode(path: str | os.PathLike | None = None) -> int:
    """The permission bits a file written at ``path`` should get.

    Parameters
    ----------
    path : str or os.PathLike, optional
        The destination. If it exists, its permission bits are kept; otherwise (or
        when None) a new file gets ``0o666`` less the umask, as :func:`open` gives it.

    Returns
    -------
    int
        Permission bits for :func:`os.chmod`.
    """
    if path is not None:
        try:
            return stat.S_IMODE(os.stat(path).st_mode)
        except OSError:
            pass
    return 0o666 & ~current_umask()


def _make_parents(path: Path, created: list[Path]) -> None:
    """Create ``path``'s missing parent folders, recording them (outermost first) in ``created``."""
    missing = []
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        missing.append(parent)
        parent = parent.parent
    for folder in reversed(missing):
        folder.mkdir(exist_ok=True)
        created.append(folder)


def _temp_beside(path: Path) -> str:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    return tmp


def _unlink_quietly(name) -> None:
    try:
        os.unlink(name)
    except FileNotFoundError:
        pass


def atomic_write(path: str | os.PathLike, writer: Callable[[str], None]) -> Path:
    """Write a file through ``writer(tmp_path)`` into a temporary name, then rename.

    If ``writer`` raises, the temporary file is removed and ``path`` is untouched,
    so no half-written output is ever left behind. The file gets the mode of
    :func:`new_file_mode` (the umask's, or the replaced file's).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file; missing parent directories are created. An existing file
        is replaced (atomically, by :func:`os.replace`).
    writer : callable
        ``writer(tmp_path)`` writes the whole content to the file named
        ``tmp_path`` (a ``str`` in the same directory as ``path``).

    Returns
    -------
    pathlib.Path
        ``path``, as a :class:`~pathlib.Path`.
    """
    return atomic_write_group([(path, writer)])[0]


def atomic_write_group(
    items: Sequence[tuple[str | os.PathLike, Callable[[str], None]]],
) -> list[Path]:
    """Write several files that belong together: all of them, or none.

    Every file is first written to a temporary name beside its destination (by its
    ``writer``); only when all are written are they renamed into place. If a writer
    or a rename fails, the temporary files are removed and the destinations already
    renamed are put back as they were (the previous file restored, or the new one
    removed), the folders made for them are removed again, and the error is raised
    again.

    Parameters
    ----------
    items : sequence of (path, writer)
        Destination (``str`` or path-like; missing parent directories are created,
        an existing file is replaced) and ``writer(tmp_path)``, which writes the
        whole content to the file named ``tmp_path``. Destinations must differ.

    Returns
    -------
    list of pathlib.Path
        The destinations, in the order given.
    """
    paths = [Path(p) for p, _ in items]
    if len({os.path.abspath(p) for p in paths}) != len(paths):
        raise ValueError(f"atomic_write_group: destinations must differ; got {paths}")
    temps: list[str] = []  # written content, one per destination
    scratch: list[str] = []  # every temporary name, removed at the end
    backups: dict[Path, str] = {}
    renamed: list[Path] = []
    created: list[Path] = []  # folders made for the files, removed again on failure
    try:
        for path in paths:
            _make_parents(path, created)
        for path, (_, writer) in zip(paths, items):
            tmp = _temp_beside(path)
            temps.append(tmp)
            scratch.append(tmp)
            writer(tmp)
            os.chmod(tmp, new_file_mode(path))
        for path in paths:
            if path.exists():
                # a hard link keeps the previous file until every rename is done
                backup = _temp_beside(path)
                scratch.append(backup)
                try:
                    os.unlink(backup)
                    os.link(path, backup)
                    backups[path] = backup
                except OSError:
                    pass
        for path, tmp in zip(paths, temps):
            os.replace(tmp, path)
            renamed.append(path)
    except BaseException:
        for path in renamed:
            try:
                if path in backups:
                    os.replace(backups[path], path)
                else:
                    os.unlink(path)
            except OSError:
                pass
        for name in scratch:
            _unlink_quietly(name)
        for folder in reversed(created):
            try:
                folder.rmdir()
            except OSError:
                pass
        raise
    finally:
        for name in scratch:
            _unlink_quietly(name)
    return paths


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write bytes to a file atomically (see :func:`atomic_write`).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file; parent directories are created, an existing file is
        replaced.
    data : bytes
        The whole file content.

    Returns
    -------
    pathlib.Path
        ``path``, as a :class:`~pathlib.Path`.
    """

    def _w(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)

    return atomic_write(path, _w)


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write text to a file atomically, UTF-8 encoded (see :func:`atomic_write`).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file; parent directories are created, an existing file is
        replaced.
    text : str
        The whole file content, written as is (no newline translation).

    Returns
    -------
    pathlib.Path
        ``path``, as a :class:`~pathlib.Path`.
    """
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | os.PathLike, obj) -> Path:
    """Write a value as strict JSON (2-space indent, final newline), atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file; parent directories are created, an existing file is
        replaced.
    obj : object
        The value to write, converted by :func:`to_jsonable` first (so numpy
        values, dataclasses, paths and non-finite floats are accepted).

    Returns
    -------
    pathlib.Path
        ``path``, as a :class:`~pathlib.Path`.

    Raises
    ------
    TypeError
        If ``obj`` holds a value :func:`to_jsonable` leaves unconverted and
        :mod:`json` cannot serialise; the file is then not written.
    """
    return atomic_write_text(path, json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")
