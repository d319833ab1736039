"""Controller artifacts for real-time targets: JSON and MATLAB ``.mat``, written atomically.

An artifact holds the continuous controller, its discrete 1 kHz equivalent
(Tustin, prewarped at the structure mode), signal names and units, the design's
weights and solver information, the family seed its validation used, and the
software versions. :func:`load_artifact` validates a file before anything uses it:
structure, the type of every field, shapes, finiteness, sample time, and that the
discrete matrices are the Tustin transform of the continuous ones; any malformed file
(random bytes, a directory, a field of the wrong type) raises
:class:`~robust.errors.ArtifactError` naming the file and the field.

:func:`write_artifact` writes the JSON and ``.mat`` files as a pair (both or
neither, :func:`robust.jsonio.atomic_write_group`) and replaces existing files only
when they are artifacts themselves (:func:`check_artifact_target`), never a file of
the user's.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
import platform
import warnings
from pathlib import Path

import control as ct
import numpy as np
import scipy.linalg

from robust.errors import ArtifactError, ModelStructureError, ParameterError
from robust.jsonio import atomic_write_group, to_jsonable
from robust.version import __version__

__all__ = [
    "ARTIFACT_KINDS",
    "ControllerArtifact",
    "discretize",
    "write_artifact",
    "load_artifact",
    "check_artifact_target",
    "is_artifact_file",
    "FORMAT_VERSION",
    "MAX_ARTIFACT_BYTES",
    "SIGNAL_UNITS",
]

#: ``kind`` of the JSON artifacts this project writes: one controller, a scheduled bank.
ARTIFACT_KINDS = ("bdft-controller", "bdft-controller-bank")

FORMAT_VERSION = 1

#: Largest artifact file :func:`load_artifact` reads (a controller of a few hundred
#: states is well under 1 MiB; anything bigger is not an artifact).
MAX_ARTIFACT_BYTES = 64 * 2**20

#: Units of the signals a controller can measure or drive (paper's units where it gives
#: none).
SIGNAL_UNITS = {
    "x": "handle position, handle units (the paper's u/x units)",
    "c": "cab acceleration, the paper's Eqn 4 output units",
    "y": "cylinder position, the paper's Eqn 3 output units",
    "f": "N (force of the handle on the hand)",
    "r_corr": "cylinder reference correction, the paper's Eqn 3 output units",
}


def discretize(K: ct.StateSpace, dt: float, *, prewarp_hz: float | None = None) -> ct.StateSpace:
    """Tustin (bilinear) discretisation, prewarped at ``prewarp_hz`` if given.

    Parameters
    ----------
    K : control.StateSpace
        Continuous-time controller (or any continuous-time system).
    dt : float
        Sample time, s (0.001 for the 1 kHz rig).
    prewarp_hz : float, optional
        Frequency in Hz at which the discrete response matches the continuous one
        exactly (the structure mode, for the designs); plain Tustin when None.

    Returns
    -------
    control.StateSpace
        Discrete system with sample time ``dt``, the same number of states and the
        same input and output names, named ``<K.name>_d``.

    Raises
    ------
    ParameterError
        If ``dt`` is not a positive finite number, or ``prewarp_hz`` is not a
        positive finite frequency below the Nyquist frequency ``1 / (2 dt)``.
    ModelStructureError
        If ``K`` is not a continuous-time state-space system.
    """
    if not isinstance(K, ct.StateSpace):
        raise ModelStructureError(
            f"discretize: K must be a control.StateSpace; got {type(K).__name__}"
        )
    if not K.isctime():
        raise ModelStructureError(f"discretize needs a continuous-time controller; got dt={K.dt}")
    if not _is_real(dt) or not math.isfinite(dt) or dt <= 0:
        raise ParameterError(
            f"discretize: dt must be a positive, finite sample time in s; got {_show(dt)}"
        )
    dt = float(dt)
    kw = {}
    if prewarp_hz is not None:
        nyquist = 0.5 / dt
        if (
            not _is_real(prewarp_hz)
            or not math.isfinite(prewarp_hz)
            or not 0 < prewarp_hz < nyquist
        ):
            raise ParameterError(
                f"discretize: prewarp_hz must be a frequency in (0, {nyquist:g}) Hz (below the "
                f"Nyquist frequency 1/(2 dt) for dt={dt:g} s) or None; got {_show(prewarp_hz)}"
            )
        kw["prewarp_frequency"] = 2 * math.pi * float(prewarp_hz)
    Kd = ct.sample_system(K, dt, method="bilinear", **kw)
    return ct.ss(
        Kd.A,
        Kd.B,
        Kd.C,
        Kd.D,
        dt,
        inputs=K.input_labels,
        outputs=K.output_labels,
        name=f"{K.name}_d",
    )


@dataclasses.dataclass(frozen=True)
class ControllerArtifact:
    """A controller ready for export, and everything needed to trust it.

    Write it with :func:`write_artifact`; :func:`load_artifact` returns one.

    Parameters
    ----------
    name : str
        Name of the design (the file name stem when loaded from a file without one).
    continuous : control.StateSpace
        Continuous-time controller with distinct signal names: a controller of the BDFT
        loop measures among ``x, c, y`` and drives among ``f, r_corr`` (see
        :data:`SIGNAL_UNITS`), a controller of a user's own system has any names
        (python-control's ``u[0]``, ``y[0]`` too). The names are kept as they are; the
        BDFT loop checks its own where it is closed
        (:meth:`backhoe.model.loop.BDFTLoop.system`).
    discrete : control.StateSpace
        Its Tustin discretisation (:func:`discretize`), same signals, sample time
        ``discrete.dt`` in s.
    prewarp_hz : float or None
        Prewarping frequency of the discretisation, Hz; None for plain Tustin.
    weights : dict, optional
        The design's weights and tuning options, JSON-ready (free form).
    solver : dict, optional
        Information about the synthesis solver, JSON-ready (free form).
    family : dict, optional
        The uncertainty family the design was validated on (the designs store its
        name, sampling seed and method, number of samples and ``k_psf``).
    validation : dict, optional
        Results of that validation, JSON-ready (free form).
    extra : dict, optional
        Anything else worth keeping with the controller, JSON-ready.
    """

    name: str
    continuous: ct.StateSpace
    discrete: ct.StateSpace
    prewarp_hz: float | None
    weights: dict = dataclasses.field(default_factory=dict)
    solver: dict = dataclasses.field(default_factory=dict)
    family: dict = dataclasses.field(default_factory=dict)
    validation: dict = dataclasses.field(default_factory=dict)
    extra: dict = dataclasses.field(default_factory=dict)

    @property
    def inputs(self) -> list[str]:
        """Names of the measured signals (the continuous controller's inputs)."""
        return list(self.continuous.input_labels)

    @property
    def outputs(self) -> list[str]:
        """Names of the driven signals (the continuous controller's outputs)."""
        return list(self.continuous.output_labels)

    def to_dict(self) -> dict:
        """The JSON document of the artifact (as written by :func:`write_artifact`).

        Holds kind and format version, name, signal names and units, both sets of
        matrices (the discrete ones with ``dt``, method and ``prewarp_hz``), order,
        the free-form sections, the software versions and the creation time (UTC),
        all converted by :func:`robust.jsonio.to_jsonable`.
        """

        def mats(s):
            return {"A": s.A, "B": s.B, "C": s.C, "D": s.D}

        return to_jsonable(
            {
                "kind": "bdft-controller",
                "format_version": FORMAT_VERSION,
                "name": self.name,
                "inputs": self.inputs,
                "outputs": self.outputs,
                "units": {s: SIGNAL_UNITS.get(s, "") for s in self.inputs + self.outputs},
                "continuous": mats(self.continuous),
                "discrete": {
                    **mats(self.discrete),
                    "dt": self.discrete.dt,
                    "method": "tustin",
                    "prewarp_hz": self.prewarp_hz,
                },
                "order": self.continuous.nstates,
                "weights": self.weights,
                "solver": self.solver,
                "family": self.family,
                "validation": self.validation,
                "extra": self.extra,
                "versions": _versions(),
                "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            }
        )


def _versions() -> dict:
    import cvxpy
    import scipy

    return {
        "bdft-workbench": __version__,
        "python": platform.python_version(),
        "control": ct.__version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "cvxpy": cvxpy.__version__,
    }


def _is_real(x) -> bool:
    """A real number (Python or numpy), not a bool."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(
        x, (bool, np.bool_)
    )


def _json_type(value) -> str:
    """The JSON name of a parsed value's type (object, array, string, number, boolean, null)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    return {dict: "object", list: "array", str: "string", int: "number", float: "number"}.get(
        type(value), type(value).__name__
    )


def _show(value, width: int = 60) -> str:
    """``repr`` of a value, cut to ``width`` characters (file contents can be huge)."""
    text = repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def is_artifact_file(path: str | Path) -> bool:
    """Whether ``path`` is a controller artifact file (JSON or ``.mat``) written by this module.

    Used before replacing a file, so that only artifacts are ever overwritten. The
    check is by content, not name: a JSON file must hold an object whose ``kind`` is one
    of :data:`ARTIFACT_KINDS` (a controller, or a scheduled bank of them); a ``.mat`` file
    must hold the variables ``Ac`` and ``meta_json`` that :func:`write_artifact` writes.

    Parameters
    ----------
    path : str or pathlib.Path
        The file to look at.

    Returns
    -------
    bool
        True for an artifact file; False for anything else (missing, a directory,
        unreadable, too big, other content).
    """
    import scipy.io

    path = Path(path)
    try:
        if not path.is_file() or path.stat().st_size > MAX_ARTIFACT_BYTES:
            return False
        if path.suffix.lower() == ".mat":
            names = {name for name, _, _ in scipy.io.whosmat(str(path))}
            return {"Ac", "meta_json"} <= names
        obj = json.loads(path.read_bytes().decode("utf-8"))
    except Exception:  # noqa: BLE001 - any failure to read it means it is not an artifact
        return False
    return isinstance(obj, dict) and obj.get("kind") in ARTIFACT_KINDS


def check_artifact_target(path: str | Path, *, mat: bool = True) -> tuple[Path, Path | None]:
    """Check that :func:`write_artifact` may write ``path`` (and its ``.mat``), before any work.

    Parameters
    ----------
    path : str or pathlib.Path
        The artifact's JSON file: its name must end in ``.json``; it must not be a
        directory; an existing file there (and at the ``.mat`` path) must be a
        controller artifact (:func:`is_artifact_file`), so a file of the user's is
        never replaced.
    mat : bool, optional
        Whether the ``.mat`` file ``path.with_suffix(".mat")`` is written too.

    Returns
    -------
    (pathlib.Path, pathlib.Path or None)
        The JSON path and the ``.mat`` path (None with ``mat=False``).

    Raises
    ------
    ParameterError
        If ``path`` does not end in ``.json``, or a target exists and is a directory
        or not an artifact; the message names the file.
    """
    path = Path(path)
    if path.suffix.lower() != ".json":
        raise ParameterError(f"artifact path must end in .json; got {str(path)!r}")
    targets = [path, path.with_suffix(".mat")] if mat else [path]
    for target in targets:
        if target.is_dir():
            raise ParameterError(
                f"artifact path {str(target)!r} is a directory; expected a file to write"
            )
        if (target.exists() or target.is_symlink()) and not is_artifact_file(target):
            raise ParameterError(
                f"refusing to replace {str(target)!r}: it exists and is not a bdft controller "
                "artifact; expected no file there or a previous artifact. Move it away or "
                "choose another folder"
            )
    return path, (targets[1] if mat else None)


def write_artifact(
    art: ControllerArtifact, path: str | Path, *, mat: bool = True
) -> dict[str, Path]:
    """Write ``path`` (JSON) and, with ``mat=True``, the ``.mat`` beside it, as one pair.

    Both files are written to temporary names and renamed into place together
    (:func:`robust.jsonio.atomic_write_group`): after a failure neither is left (and
    previous artifacts are as they were). New files get the usual mode (umask).
    The ``.mat`` holds ``Ac, Bc, Cc, Dc`` (continuous), ``Ad, Bd, Cd, Dd, Ts``
    (discrete), ``inputs``, ``outputs`` (cell arrays of names) and ``meta_json``.

    Parameters
    ----------
    art : ControllerArtifact
        The controller and its provenance.
    path : str or pathlib.Path
        The JSON file to write (:meth:`ControllerArtifact.to_dict`), ending in
        ``.json``; parent directories are created. An existing artifact is replaced;
        any other existing file is refused (:func:`check_artifact_target`).
    mat : bool, optional
        Also write the MATLAB file ``path.with_suffix(".mat")`` (default True).

    Returns
    -------
    dict of str to pathlib.Path
        ``"json"`` and, with ``mat=True``, ``"mat"``: the files written.

    Raises
    ------
    ParameterError
        If a target is a directory or an existing file that is not an artifact.
    """
    import scipy.io

    path, matpath = check_artifact_target(path, mat=mat)
    d = art.to_dict()
    text = json.dumps(d, indent=2, allow_nan=False) + "\n"

    def _write_json(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    items = [(path, _write_json)]
    if mat:
        c, k = art.continuous, art.discrete
        payload = {
            "Ac": c.A,
            "Bc": c.B,
            "Cc": c.C,
            "Dc": c.D,
            "Ad": k.A,
            "Bd": k.B,
            "Cd": k.C,
            "Dd": k.D,
            "Ts": float(k.dt),
            "inputs": np.array(art.inputs, dtype=object),
            "outputs": np.array(art.outputs, dtype=object),
            "meta_json": json.dumps(
                {
                    key: d[key]
                    for key in ("name", "weights", "solver", "family", "versions", "created_utc")
                }
            ),
        }

        def _write_mat(tmp: str) -> None:
            with open(tmp, "wb") as fh:
                scipy.io.savemat(fh, payload)

        items.append((matpath, _write_mat))
    written = atomic_write_group(items)
    return dict(zip(("json", "mat"), written))


_NO_ENTRY = object()
#: How :func:`robust.jsonio.to_jsonable` writes non-finite numbers.
_NONFINITE_TEXT = ("nan", "inf", "-inf")


def _non_number(raw):
    """The first entry of nested lists that is not a number, or ``_NO_ENTRY``."""
    stack = [raw]
    while stack:
        v = stack.pop()
        if isinstance(v, list):
            stack.extend(reversed(v))
        elif isinstance(v, bool) or not (
            isinstance(v, (int, float)) or (isinstance(v, str) and v in _NONFINITE_TEXT)
        ):
            return v
    return _NO_ENTRY


def _matrix(d: dict, key: str, where: str) -> np.ndarray:
    if key not in d:
        raise ArtifactError(f"{where}: missing matrix {key!r}")
    raw = d[key]
    if not isinstance(raw, list):
        raise ArtifactError(
            f"{where}.{key}: expected a numeric matrix (a list of rows); "
            f"got a JSON {_json_type(raw)} {_show(raw)}"
        )
    bad = _non_number(raw)
    if bad is not _NO_ENTRY:
        raise ArtifactError(
            f"{where}.{key}: expected a numeric matrix (a list of rows of numbers); "
            f"got an entry {_show(bad)} (a JSON {_json_type(bad)})"
        )
    try:
        m = np.array(raw, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ArtifactError(
            f"{where}.{key}: expected a numeric matrix (a list of rows of numbers); "
            f"got {_show(raw)} ({exc})"
        ) from None
    if m.size == 0:
        m = m.reshape((0, 0)) if m.ndim < 2 else m
    if m.ndim != 2:
        raise ArtifactError(f"{where}.{key}: expected a 2-D matrix; got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ArtifactError(f"{where}.{key}: contains NaN or inf; expected finite numbers")
    return m


def _ss(d: dict, where: str, inputs, outputs, dt=0):
    A, B, C, D = (_matrix(d, k, where) for k in "ABCD")
    n = A.shape[0]
    m, p = len(inputs), len(outputs)
    B = B.reshape(n, m) if B.size == n * m else B
    C = C.reshape(p, n) if C.size == n * p else C
    expected = {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m)}
    for key, mat in zip("ABCD", (A, B, C, D)):
        if mat.shape != expected[key]:
            raise ArtifactError(
                f"{where}.{key}: expected shape {expected[key]} for {n} states, "
                f"{m} inputs, {p} outputs; got {mat.shape}"
            )
    try:
        return ct.ss(A, B, C, D, dt, inputs=list(inputs), outputs=list(outputs))
    except (ValueError, TypeError, np.linalg.LinAlgError) as exc:
        raise ArtifactError(f"{where}: not a valid state-space system ({exc})") from None


def _read_document(path: Path) -> dict:
    """The artifact's JSON object; every way of not being one raises ArtifactError."""
    try:
        info = path.stat()
    except FileNotFoundError:
        raise ArtifactError(f"controller artifact {path} does not exist") from None
    except OSError as exc:
        raise ArtifactError(
            f"controller artifact {path} cannot be read: {exc.strerror or exc}"
        ) from None
    if path.is_dir():
        raise ArtifactError(f"controller artifact {path} is a directory; expected a JSON file")
    if info.st_size > MAX_ARTIFACT_BYTES:
        raise ArtifactError(
            f"controller artifact {path} has {info.st_size} bytes; expected a JSON file of at "
            f"most {MAX_ARTIFACT_BYTES} bytes"
        )
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ArtifactError(
            f"controller artifact {path} cannot be read: {exc.strerror or exc}"
        ) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ArtifactError(
            f"controller artifact {path} is not valid JSON: not UTF-8 text "
            f"(byte {raw[exc.start]:#04x} at offset {exc.start})"
        ) from None
    try:
        d = json.loads(text)
    except RecursionError:
        raise ArtifactError(
            f"controller artifact {path} is not valid JSON for an artifact: nested too deeply"
        ) from None
    except ValueError as exc:  # json.JSONDecodeError, and integers too long to convert
        raise ArtifactError(f"controller artifact {path} is not valid JSON: {exc}") from None
    if not isinstance(d, dict):
        raise ArtifactError(
            f"{path}: expected a JSON object with 'kind': 'bdft-controller'; "
            f"got a JSON {_json_type(d)}"
        )
    return d


def _signals(d: dict, key: str, path: Path) -> list[str]:
    v = d.get(key)
    if not isinstance(v, list) or not v or not all(isinstance(s, str) and s for s in v):
        raise ArtifactError(
            f"{path}: field {key!r} must be a non-empty list of signal names; got {_show(v)}"
        )
    if len(set(v)) != len(v):
        raise ArtifactError(f"{path}: field {key!r} names a signal twice; got {v}")
    return v


def load_artifact(path: str | Path, *, rtol: float = 1e-8) -> ControllerArtifact:
    """Load and validate a controller artifact written by :func:`write_artifact`.

    Parameters
    ----------
    path : str or pathlib.Path
        The artifact's JSON file (the ``.mat`` file is not read); at most
        :data:`MAX_ARTIFACT_BYTES` bytes.
    rtol : float, optional
        Not used: the check that the discrete matrices are the Tustin transform
        of the continuous ones compares frequency responses at 0.5, 2, 6 and 20 Hz
        with a fixed relative tolerance of 1e-6 (and an absolute one of 1e-9 times
        the largest gain). Kept for compatibility.

    Returns
    -------
    ControllerArtifact
        The controller, rebuilt from the file with its signal names (any distinct names:
        the BDFT loop's or a user system's); the free-form sections are as stored
        (numbers in JSON form).

    Raises
    ------
    ArtifactError
        On a missing, unreadable or oversized file, a directory, bytes that are not
        UTF-8 JSON, a wrong kind or version, a field of the wrong type (signal names
        that are not a non-empty list of distinct non-empty strings), malformed or
        non-finite matrices, inconsistent shapes, a non-positive sample time, a
        prewarping frequency outside (0, Nyquist), or discrete matrices that are not
        the Tustin transform of the continuous ones. The message names the file and
        the field.
    """
    path = Path(path)
    d = _read_document(path)
    if d.get("kind") != "bdft-controller":
        raise ArtifactError(f"{path}: 'kind' must be 'bdft-controller'; got {_show(d.get('kind'))}")
    version = d.get("format_version")
    if not (type(version) is int and version == FORMAT_VERSION):
        raise ArtifactError(
            f"{path}: format_version must be {FORMAT_VERSION}; got {_show(version)}"
        )
    ins = _signals(d, "inputs", path)
    outs = _signals(d, "outputs", path)
    for sec in ("continuous", "discrete"):
        if not isinstance(d.get(sec), dict):
            raise ArtifactError(
                f"{path}: field {sec!r} must be an object holding A, B, C, D; "
                f"got {_show(d.get(sec))}"
            )
    name = d.get("name", path.stem)
    if not isinstance(name, str):
        raise ArtifactError(f"{path}: field 'name' must be a string; got {_show(name)}")
    free = {}
    for key in ("weights", "solver", "family", "validation", "extra"):
        free[key] = d.get(key, {})
        if not isinstance(free[key], dict):
            raise ArtifactError(
                f"{path}: field {key!r} must be a JSON object; got {_show(free[key])}"
            )
    cont = _ss(d["continuous"], f"{path.name}:continuous", ins, outs)
    dt = d["discrete"].get("dt")
    if not _is_real(dt) or not math.isfinite(dt) or dt <= 0:
        raise ArtifactError(
            f"{path}: discrete.dt must be a positive sample time in s; got {_show(dt)}"
        )
    dt = float(dt)
    disc = _ss(d["discrete"], f"{path.name}:discrete", ins, outs, dt=dt)
    prewarp = d["discrete"].get("prewarp_hz")
    if prewarp is not None and (
        not _is_real(prewarp) or not math.isfinite(prewarp) or not 0 < prewarp < 0.5 / dt
    ):
        raise ArtifactError(
            f"{path}: discrete.prewarp_hz must be null or a frequency in (0, {0.5 / dt:g}) Hz "
            f"(below the Nyquist frequency); got {_show(prewarp)}"
        )
    prewarp = None if prewarp is None else float(prewarp)
    w = 2 * np.pi * np.array([0.5, 2.0, 6.0, 20.0])
    z = np.exp(1j * w * dt)
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            # a singular I - A dt/2 has no Tustin transform: an error here, not a warning
            warnings.simplefilter("error", scipy.linalg.LinAlgWarning)
            again = discretize(cont, dt, prewarp_hz=prewarp)
            g1 = np.asarray(disc(z, squeeze=False))
            g2 = np.asarray(again(z, squeeze=False))
    except (
        ValueError,
        np.linalg.LinAlgError,
        scipy.linalg.LinAlgWarning,
        ZeroDivisionError,
        OverflowError,
    ) as exc:
        raise ArtifactError(
            f"{path}: discrete: cannot check that it is the Tustin transform of the continuous "
            f"controller ({type(exc).__name__}: {exc})"
        ) from None
    if not (
        np.all(np.isfinite(g1))
        and np.all(np.isfinite(g2))
        and np.allclose(g1, g2, rtol=1e-6, atol=1e-9 * max(1.0, np.abs(g2).max()))
    ):
        raise ArtifactError(
            f"{path}: the discrete controller is not the Tustin transform "
            f"(dt={dt}, prewarp={prewarp} Hz) of the continuous one"
        )
    return ControllerArtifact(
        name=name,
        continuous=cont,
        discrete=disc,
        prewarp_hz=prewarp,
        **free,
    )
