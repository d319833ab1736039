"""Conversion of results to JSON-ready values and atomic file writing."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

__all__ = [
    "to_jsonable",
    "atomic_write_text",
    "atomic_write_bytes",
    "atomic_write",
    "atomic_write_json",
]


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


def atomic_write(path: str | os.PathLike, writer: Callable[[str], None]) -> Path:
    """Write a file through ``writer(tmp_path)`` into a temporary name, then rename.

    If ``writer`` raises, the temporary file is removed and ``path`` is untouched,
    so no half-written output is ever left behind.

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
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        writer(tmp)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


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
