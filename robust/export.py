"""Controller artifacts for real-time targets: JSON and MATLAB ``.mat``, written atomically.

An artifact holds the continuous controller, its discrete 1 kHz equivalent
(Tustin, prewarped at the structure mode), signal names and units, the design's
weights and solver information, the family seed its validation used, and the
software versions. :func:`load_artifact` validates a file before anything uses it:
structure, shapes, finiteness, sample time, and that the discrete matrices are
the Tustin transform of the continuous ones.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
import platform
from pathlib import Path

import control as ct
import numpy as np

from robust.errors import ArtifactError, ModelStructureError
from robust.jsonio import atomic_write, atomic_write_json, to_jsonable
from robust.model.loop import CONTROLLER_INPUTS, CONTROLLER_OUTPUTS
from robust.version import __version__

__all__ = [
    "ControllerArtifact",
    "discretize",
    "write_artifact",
    "load_artifact",
    "FORMAT_VERSION",
    "SIGNAL_UNITS",
]

FORMAT_VERSION = 1

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
    ModelStructureError
        If ``K`` is not continuous-time.
    """
    if not K.isctime():
        raise ModelStructureError(f"discretize needs a continuous-time controller; got dt={K.dt}")
    kw = {}
    if prewarp_hz is not None:
        kw["prewarp_frequency"] = 2 * math.pi * prewarp_hz
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
        Continuous-time controller; its input names are among ``x, c, y`` and its
        output names among ``f, r_corr`` (see :data:`SIGNAL_UNITS`).
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


def write_artifact(
    art: ControllerArtifact, path: str | Path, *, mat: bool = True
) -> dict[str, Path]:
    """Write ``path`` (JSON) and, with ``mat=True``, the ``.mat`` beside it; both atomically.

    The ``.mat`` holds ``Ac, Bc, Cc, Dc`` (continuous), ``Ad, Bd, Cd, Dd, Ts``
    (discrete), ``inputs``, ``outputs`` (cell arrays of names) and ``meta_json``.

    Parameters
    ----------
    art : ControllerArtifact
        The controller and its provenance.
    path : str or pathlib.Path
        The JSON file to write (:meth:`ControllerArtifact.to_dict`); parent
        directories are created, an existing file is replaced.
    mat : bool, optional
        Also write the MATLAB file ``path.with_suffix(".mat")`` (default True).

    Returns
    -------
    dict of str to pathlib.Path
        ``"json"`` and, with ``mat=True``, ``"mat"``: the files written.
    """
    import scipy.io

    path = Path(path)
    d = art.to_dict()
    out = {"json": atomic_write_json(path, d)}
    if mat:
        matpath = path.with_suffix(".mat")
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

        def _w(tmp: str) -> None:
            with open(tmp, "wb") as fh:
                scipy.io.savemat(fh, payload)

        out["mat"] = atomic_write(matpath, _w)
    return out


def _matrix(d: dict, key: str, where: str) -> np.ndarray:
    if key not in d:
        raise ArtifactError(f"{where}: missing matrix {key!r}")
    try:
        m = np.array(d[key], dtype=float)
    except (TypeError, ValueError) as exc:
        raise ArtifactError(f"{where}.{key}: not a numeric matrix ({exc})") from None
    if m.size == 0:
        m = m.reshape((0, 0)) if m.ndim < 2 else m
    if m.ndim != 2:
        raise ArtifactError(f"{where}.{key}: expected a 2-D matrix; got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ArtifactError(f"{where}.{key}: contains NaN or inf")
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
    return ct.ss(A, B, C, D, dt, inputs=list(inputs), outputs=list(outputs))


def load_artifact(path: str | Path, *, rtol: float = 1e-8) -> ControllerArtifact:
    """Load and validate a controller artifact written by :func:`write_artifact`.

    Parameters
    ----------
    path : str or pathlib.Path
        The artifact's JSON file (the ``.mat`` file is not read).
    rtol : float, optional
        Not used: the check that the discrete matrices are the Tustin transform
        of the continuous ones compares frequency responses at 0.5, 2, 6 and 20 Hz
        with a fixed relative tolerance of 1e-6 (and an absolute one of 1e-9 times
        the largest gain). Kept for compatibility.

    Returns
    -------
    ControllerArtifact
        The controller, rebuilt from the file; the free-form sections are as
        stored (numbers in JSON form).

    Raises
    ------
    ArtifactError
        On a missing or unreadable file, a wrong kind or version, malformed or
        non-finite matrices, inconsistent shapes, a non-positive sample time, or
        discrete matrices that are not the Tustin transform of the continuous ones.
    """
    path = Path(path)
    try:
        d = json.loads(path.read_text())
    except FileNotFoundError:
        raise ArtifactError(f"controller artifact {path} does not exist") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ArtifactError(f"controller artifact {path} is not valid JSON: {exc}") from None
    if not isinstance(d, dict) or d.get("kind") != "bdft-controller":
        raise ArtifactError(
            f"{path}: 'kind' must be 'bdft-controller'; "
            f"got {d.get('kind') if isinstance(d, dict) else type(d).__name__!r}"
        )
    if d.get("format_version") != FORMAT_VERSION:
        raise ArtifactError(
            f"{path}: format_version must be {FORMAT_VERSION}; got {d.get('format_version')!r}"
        )
    ins, outs = d.get("inputs"), d.get("outputs")
    if not (isinstance(ins, list) and isinstance(outs, list) and ins and outs):
        raise ArtifactError(
            f"{path}: 'inputs' and 'outputs' must be non-empty lists of signal names"
        )
    bad = [s for s in ins if s not in CONTROLLER_INPUTS] + [
        s for s in outs if s not in CONTROLLER_OUTPUTS
    ]
    if bad:
        raise ArtifactError(
            f"{path}: unknown signal name(s) {bad}; inputs must be among "
            f"{CONTROLLER_INPUTS}, outputs among {CONTROLLER_OUTPUTS}"
        )
    for sec in ("continuous", "discrete"):
        if not isinstance(d.get(sec), dict):
            raise ArtifactError(f"{path}: missing section {sec!r}")
    cont = _ss(d["continuous"], f"{path.name}:continuous", ins, outs)
    dt = d["discrete"].get("dt")
    if not isinstance(dt, (int, float)) or not math.isfinite(dt) or dt <= 0:
        raise ArtifactError(f"{path}: discrete.dt must be a positive sample time in s; got {dt!r}")
    disc = _ss(d["discrete"], f"{path.name}:discrete", ins, outs, dt=float(dt))
    prewarp = d["discrete"].get("prewarp_hz")
    again = discretize(cont, float(dt), prewarp_hz=prewarp)
    w = 2 * np.pi * np.array([0.5, 2.0, 6.0, 20.0])
    z = np.exp(1j * w * dt)
    g1 = np.asarray(disc(z, squeeze=False))
    g2 = np.asarray(again(z, squeeze=False))
    if not np.allclose(g1, g2, rtol=1e-6, atol=1e-9 * max(1.0, np.abs(g2).max())):
        raise ArtifactError(
            f"{path}: the discrete controller is not the Tustin transform "
            f"(dt={dt}, prewarp={prewarp} Hz) of the continuous one"
        )
    return ControllerArtifact(
        name=str(d.get("name", path.stem)),
        continuous=cont,
        discrete=disc,
        prewarp_hz=prewarp,
        weights=d.get("weights", {}),
        solver=d.get("solver", {}),
        family=d.get("family", {}),
        validation=d.get("validation", {}),
        extra=d.get("extra", {}),
    )
