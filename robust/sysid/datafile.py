"""Measured records from CSV and MATLAB ``.mat`` files, by channel name.

CSV layout (one header row of channel names; comment lines start with ``#``)::

    # bdft-chirp-data fs=1000 seed=7
    record,t,e,y
    0,0.000,0.0,0.0
    0,0.001,0.0063,1.2e-05
    ...

* ``record`` (optional): integer record index; rows of one record are contiguous.
  Without it the file holds one record.
* ``t`` or ``time`` (optional): sample times in s, checked for uniform spacing and
  against the sampling rate.
* every other column is a channel.
* ``fs=`` and ``seed=`` in a leading comment line are read if present.

``.mat`` layout (:func:`scipy.io.loadmat`): one variable per channel, a vector
(one record) or a matrix with one record per row when it has more columns than
rows, else one per column (MATLAB's column-per-signal layout); optional scalar
variables ``fs`` and ``seed`` and a ``t``/``time`` variable shaped like the channels.
"""

from __future__ import annotations

import dataclasses
import io
import os
import re
from pathlib import Path

import numpy as np
import scipy.io

from robust.checks import POSITIVE, check_scalar
from robust.errors import DataError, ParameterError
from robust.jsonio import atomic_write

__all__ = ["ChannelData", "load_channels", "save_experiment", "select_channels"]

_TIME_NAMES = ("t", "time")
_REL_DT_TOL = 1e-3  # relative spread of sample intervals accepted as uniform
_REL_FS_TOL = 1e-3  # relative mismatch accepted between stated and measured rates


@dataclasses.dataclass(frozen=True)
class ChannelData:
    """Named channels of one or more records.

    Attributes
    ----------
    channels : dict of str -> tuple of numpy.ndarray
        Each channel's records (1-D arrays, one per record).
    time : tuple of numpy.ndarray or None
        Sample times in s of each record, if the file has a time column.
    fs : float or None
        Sampling rate stated in the file (``fs=`` comment or ``fs`` variable), Hz.
    seed : int or None
        Seed stated in the file (simulated data), else ``None``.
    source : str
        The file the data came from.
    """

    channels: dict
    time: tuple | None
    fs: float | None
    seed: int | None
    source: str

    @property
    def names(self) -> list[str]:
        """Channel names, in file order."""
        return list(self.channels)


def load_channels(path: str | os.PathLike) -> ChannelData:
    """Read a CSV (``.csv``, ``.txt``) or MATLAB (``.mat``) file of named channels.

    Parameters
    ----------
    path : str or path-like
        The file; the layouts are described in the module notes.

    Returns
    -------
    ChannelData

    Raises
    ------
    DataError
        Missing file, unknown extension, unreadable content, non-numeric cells,
        channels of different lengths, or a malformed ``record`` column.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"data file {str(path)!r} does not exist or is not a file")
    suffix = path.suffix.lower()
    if suffix in (".csv", ".txt"):
        return _load_csv(path)
    if suffix == ".mat":
        return _load_mat(path)
    raise DataError(
        f"data file {path.name!r}: expected a .csv, .txt or .mat file; got suffix {suffix!r}"
    )


def _parse_meta(lines: list[str]) -> dict:
    meta = {}
    for line in lines:
        for key, val in re.findall(r"(\w+)=([^\s,]+)", line):
            meta[key] = val
    return meta


def _meta_number(meta, key, cast, source):
    if key not in meta or meta[key].lower() in ("none", "null"):
        return None
    try:
        return cast(meta[key])
    except ValueError:
        raise DataError(
            f"{source}: comment field {key}={meta[key]!r} is not a valid {cast.__name__}"
        ) from None


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _load_csv(path: Path) -> ChannelData:
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.splitlines()
    comments = []
    i = 0
    while i < len(lines) and (lines[i].startswith("#") or not lines[i].strip()):
        comments.append(lines[i])
        i += 1
    if i >= len(lines):
        raise DataError(f"{path.name}: no header row of channel names found")
    header = [h.strip() for h in lines[i].split(",")]
    if any(not h for h in header) or len(set(header)) != len(header):
        raise DataError(f"{path.name}: header must name every column once; got {header}")
    if _is_number(header[0]):
        raise DataError(
            f"{path.name}: first row {header} looks numeric; the first row must name the channels"
        )
    body = "\n".join(lines[i + 1 :])
    if not body.strip():
        raise DataError(f"{path.name}: header found but no data rows")
    try:
        arr = np.loadtxt(io.StringIO(body), delimiter=",", dtype=float, ndmin=2, comments="#")
    except ValueError as exc:
        raise DataError(
            f"{path.name}: non-numeric or missing value in the data rows ({exc})"
        ) from None
    if arr.shape[1] != len(header):
        raise DataError(
            f"{path.name}: header has {len(header)} columns but rows have {arr.shape[1]}"
        )
    cols = {h: arr[:, j] for j, h in enumerate(header)}
    meta = _parse_meta(comments)
    fs = _meta_number(meta, "fs", float, path.name)
    seed = _meta_number(meta, "seed", int, path.name)
    bounds = _record_bounds(cols.pop("record", None), path.name)
    tcol = None
    for tn in _TIME_NAMES:
        if tn in cols:
            tcol = cols.pop(tn)
            break
    if not cols:
        raise DataError(f"{path.name}: no channel columns besides record/time; got header {header}")
    channels = {name: tuple(col[a:b] for a, b in bounds) for name, col in cols.items()}
    time = None if tcol is None else tuple(tcol[a:b] for a, b in bounds)
    return ChannelData(channels=channels, time=time, fs=fs, seed=seed, source=str(path))


def _record_bounds(rec: np.ndarray | None, source: str) -> list[tuple[int, int]]:
    if rec is None:
        return [(0, None)]
    if not np.all(np.isfinite(rec)) or np.any(rec != np.round(rec)):
        raise DataError(f"{source}: the 'record' column must hold integer record indices")
    change = np.flatnonzero(np.diff(rec) != 0) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [rec.size]])
    ids = rec[starts]
    if len(set(ids.tolist())) != ids.size:
        raise DataError(
            f"{source}: rows of each record must be contiguous; record ids repeat: {ids.tolist()}"
        )
    return [(int(a), int(b)) for a, b in zip(starts, ends)]


def _load_mat(path: Path) -> ChannelData:
    try:
        raw = scipy.io.loadmat(str(path), squeeze_me=False)
    except Exception as exc:  # noqa: BLE001 - scipy raises several unrelated types for malformed files
        hint = (
            " (MATLAB v7.3 files are HDF5: save with save(..., '-v7'))" if "7.3" in str(exc) else ""
        )
        raise DataError(
            f"{path.name}: cannot read as a MATLAB .mat file ({type(exc).__name__}: {exc}){hint}"
        ) from None
    fs = seed = None
    channels = {}
    time = None
    for key, val in raw.items():
        if key.startswith("__"):
            continue
        arr = np.asarray(val)
        if key in ("fs", "seed"):
            if arr.size != 1 or not np.issubdtype(arr.dtype, np.number):
                raise DataError(
                    f"{path.name}: variable {key!r} must be a numeric scalar; got shape {arr.shape}"
                )
            if key == "fs":
                fs = float(arr.ravel()[0])
            else:
                seed = int(arr.ravel()[0])
            continue
        if not np.issubdtype(arr.dtype, np.number) or arr.ndim > 2 or arr.size == 0:
            raise DataError(
                f"{path.name}: variable {key!r} must be a numeric vector or 2-D matrix; "
                f"got dtype {arr.dtype}, shape {arr.shape}"
            )
        arr = arr.astype(float)
        if arr.ndim == 2 and arr.shape[0] > arr.shape[1]:
            arr = arr.T
        recs = tuple(np.atleast_2d(arr))
        if key in _TIME_NAMES:
            time = recs
        else:
            channels[key] = recs
    if not channels:
        raise DataError(f"{path.name}: no channel variables found")
    return ChannelData(channels=channels, time=time, fs=fs, seed=seed, source=str(path))


def select_channels(
    data: ChannelData,
    input_name: str,
    output_name: str,
    fs: float,
    *,
    min_duration_s: float | None = None,
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Return the input and output records, after checking them.

    Parameters
    ----------
    data : ChannelData
    input_name, output_name : str
        Channel names.
    fs : float
        Sampling rate in Hz the caller asserts.
    min_duration_s : float, optional
        Shortest acceptable record, in s.

    Returns
    -------
    u, y : list of numpy.ndarray
        One 1-D array per record.

    Raises
    ------
    DataError
        Unknown channel; NaN or inf (names the channel, record and first sample);
        input and output records of different lengths (mismatched sampling);
        a time column that is not uniform or disagrees with ``fs``; a stated
        ``fs`` that disagrees; a record shorter than ``min_duration_s``.
    """
    fs = check_scalar("fs", fs, POSITIVE)
    for name in (input_name, output_name):
        if name not in data.channels:
            raise DataError(
                f"channel {name!r} not found in {Path(data.source).name}; available: {data.names}"
            )
    if input_name == output_name:
        raise ParameterError(
            f"input and output must be different channels; got {input_name!r} for both"
        )
    if data.fs is not None and abs(data.fs - fs) > _REL_FS_TOL * fs:
        raise DataError(
            f"mismatched sampling: the file states fs={data.fs:g} Hz but fs={fs:g} Hz was given"
        )
    u = list(data.channels[input_name])
    y = list(data.channels[output_name])
    if len(u) != len(y):
        raise DataError(
            f"channel {input_name!r} has {len(u)} record(s) but {output_name!r} has {len(y)}"
        )
    for k, (a, b) in enumerate(zip(u, y)):
        for name, rec in ((input_name, a), (output_name, b)):
            bad = np.flatnonzero(~np.isfinite(rec))
            if bad.size:
                raise DataError(
                    f"channel {name!r} record {k} has {bad.size} NaN/inf value(s), first at "
                    f"sample {bad[0]} (t = {bad[0] / fs:g} s); expected finite samples. "
                    "Clean, interpolate or drop them first"
                )
        if a.size != b.size:
            raise DataError(
                f"mismatched sampling: record {k} has {a.size} samples of {input_name!r} but "
                f"{b.size} of {output_name!r}; the channels must be sampled together at one rate"
            )
        if data.time is not None:
            if len(data.time) not in (1, len(u)):
                raise DataError(
                    f"the time variable holds {len(data.time)} record(s); "
                    f"expected 1 (shared) or {len(u)}"
                )
            _check_time(data.time[k] if len(data.time) > 1 else data.time[0], fs, k, a.size)
        if min_duration_s is not None and a.size / fs < min_duration_s:
            raise DataError(
                f"record {k} of {input_name!r}/{output_name!r} lasts {a.size / fs:g} s "
                f"({a.size} samples at {fs:g} Hz); expected at least {min_duration_s:g} s"
            )
    return u, y


def _check_time(t: np.ndarray, fs: float, k: int, n: int) -> None:
    if t.size != n:
        raise DataError(f"record {k}: time column has {t.size} samples but the channels have {n}")
    if t.size < 2:
        return
    if not np.all(np.isfinite(t)):
        raise DataError(f"record {k}: time column contains NaN/inf")
    dt = np.diff(t)
    med = float(np.median(dt))
    if med <= 0 or np.max(np.abs(dt - med)) > _REL_DT_TOL * med:
        j = int(np.argmax(np.abs(dt - med)))
        raise DataError(
            f"non-uniform sampling in record {k}: sample interval should be constant "
            f"({med:g} s) but is {dt[j]:g} s between samples {j} and {j + 1} "
            f"(t = {t[j]:g} s); resample the record first"
        )
    if abs(1.0 / med - fs) > _REL_FS_TOL * fs:
        raise DataError(
            f"mismatched sampling: record {k}'s time column gives {1.0 / med:g} Hz "
            f"but fs={fs:g} Hz was given"
        )


def save_experiment(experiment, path: str | os.PathLike, *, source: str = "") -> Path:
    """Write an :class:`~backhoe.sysid.experiment.Experiment` as CSV or ``.mat``, atomically.

    The format follows the suffix of ``path``.

    The seed and sampling rate are written too (a CSV comment line, or ``.mat``
    variables), so the file can be traced to the noise that made it.

    Parameters
    ----------
    experiment : Experiment
        Records to write (input and output channels by their names).
    path : str or path-like
        Target file, ``.csv`` or ``.mat``.
    source : str
        Free-text provenance for the CSV comment line.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    u, y = np.asarray(experiment.u), np.asarray(experiment.y)
    n_rec, n = u.shape
    t = np.arange(n) / experiment.fs
    seed = experiment.seed
    if suffix == ".csv":
        head = f"# bdft-chirp-data fs={experiment.fs:.17g} seed={'none' if seed is None else seed}"
        if source:
            head += f" source={source.replace(' ', '_')}"

        def writer(tmp):
            rec = np.repeat(np.arange(n_rec), n)
            tt = np.tile(t, n_rec)
            table = np.column_stack([rec, tt, u.ravel(), y.ravel()])
            with open(tmp, "w", encoding="utf-8") as fh:
                fh.write(head + "\n")
                fh.write(f"record,t,{experiment.input_name},{experiment.output_name}\n")
                np.savetxt(fh, table, delimiter=",", fmt=["%d", "%.6f", "%.10g", "%.10g"])

        return atomic_write(path, writer)
    if suffix == ".mat":
        mdict = {
            "fs": float(experiment.fs),
            "t": t,
            experiment.input_name: u,
            experiment.output_name: y,
        }
        if seed is not None:
            mdict["seed"] = int(seed)
        return atomic_write(path, lambda tmp: scipy.io.savemat(tmp, mdict, appendmat=False))
    raise ParameterError(f"save_experiment: path must end in .csv or .mat; got {path.name!r}")
