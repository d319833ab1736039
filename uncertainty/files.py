"""Reading the files that feed a family validation: controllers and component fits.

Two formats are read here:

* a controller, :func:`load_controller`: either a bare continuous state-space
  JSON object ``{"A": .., "B": .., "C": .., "D": .., "inputs": [..], "outputs": [..]}``
  or a controller artifact (``"kind": "bdft-controller"``) written by
  :mod:`robust.export`, of which the continuous controller is used;
* a component fit, :func:`load_component_fit` (``"kind": "bdft-component-fit"``,
  written by the system-identification tools)::

      {"kind": "bdft-component-fit", "form": "structure",
       "params_class": "StructureParams", "params": {"k_s": 199.9, ...}, ...}

  whose parameters replace that component's nominal values in a family
  (:func:`family_nominals`).

Malformed files raise :class:`robust.errors.ArtifactError` naming the file and
the field.

A user's own uncertain system comes from a Python file, :func:`load_system`: the file is
run and must define ``system`` (an :func:`uncertainty.uss`) and may define
``controller`` (a python-control system in the loop's feedback path).
"""

from __future__ import annotations

import json
import os
import runpy
from collections.abc import Sequence
from pathlib import Path

import control as ct
import numpy as np

from robust.errors import ArtifactError, BDFTError, ParameterError
from robust.export import load_artifact
from robust.model.components import StructureParams, ValveCylinderParams
from robust.model.human import LiteralHumanParams
from robust.sysid import read_component_fit
from uncertainty.family import HUMAN_VARIANTS
from uncertainty.uss import USS

__all__ = [
    "load_controller",
    "load_component_fit",
    "family_nominals",
    "load_system",
    "COMPONENT_FIT_KIND",
]

COMPONENT_FIT_KIND = "bdft-component-fit"


def _read_json(path, what: str) -> dict:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ArtifactError(f"{what} {str(p)!r} cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ArtifactError(f"{what} {str(p)!r} is not UTF-8 text: {exc.reason}") from None
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ArtifactError(f"{what} {str(p)!r} is not valid JSON: {exc}") from None
    except (RecursionError, ValueError) as exc:  # nesting too deep, integer too long
        raise ArtifactError(f"{what} {str(p)!r} cannot be parsed as JSON: {exc}") from None
    if not isinstance(obj, dict):
        raise ArtifactError(f"{what} {str(p)!r} must hold a JSON object; got {type(obj).__name__}")
    return obj


def _matrix(obj: dict, key: str, where: str, shape: tuple[int | None, int | None]) -> np.ndarray:
    if key not in obj:
        raise ArtifactError(f"{where}: missing matrix {key!r}")
    raw = obj[key]
    try:
        m = np.array(raw, dtype=float)
    except (TypeError, ValueError, OverflowError, RecursionError):
        raise ArtifactError(
            f"{where}: {key} must be a numeric matrix (list of rows); got {raw!r:.80}"
        ) from None
    if m.size == 0:
        target = tuple(0 if s is None else s for s in shape)
        if int(np.prod(target)) != 0:
            raise ArtifactError(
                f"{where}: {key} is empty; expected shape "
                f"{tuple('n' if s is None else s for s in shape)}"
            )
        m = m.reshape(target)
    if m.ndim != 2:
        raise ArtifactError(f"{where}: {key} must be 2-D (a list of rows); got shape {m.shape}")
    for axis, want in enumerate(shape):
        if want is not None and m.shape[axis] != want:
            raise ArtifactError(
                f"{where}: {key} must have shape {tuple('n' if s is None else s for s in shape)} "
                f"consistent with the other matrices and signals; got {m.shape}"
            )
    if not np.all(np.isfinite(m)):
        raise ArtifactError(f"{where}: {key} contains NaN or infinite entries")
    return m


def _labels(obj: dict, key: str, where: str) -> list[str]:
    v = obj.get(key)
    if not isinstance(v, list) or not v or not all(isinstance(s, str) for s in v):
        raise ArtifactError(
            f"{where}: {key!r} must be a non-empty list of signal names; got {v!r:.80}"
        )
    if len(set(v)) != len(v):
        raise ArtifactError(f"{where}: {key!r} must name each signal once; got {v!r:.80}")
    return v


def load_controller(path) -> ct.StateSpace:
    """Read a continuous state-space controller for :func:`uncertainty.validate_family`.

    Parameters
    ----------
    path : str or Path
        JSON file: a bare state-space object or a ``bdft-controller`` artifact
        (see the module docstring).

    Returns
    -------
    control.StateSpace
        Continuous-time, with named inputs (among ``x, c, y``) and outputs (among
        ``f, r_corr``); the loop checks the names when it is connected.

    Raises
    ------
    ArtifactError
        If the file is unreadable, not JSON, or its matrices are missing,
        non-numeric, non-finite or of inconsistent shapes.
    """
    where = f"controller file {str(path)!r}"
    obj = _read_json(path, "controller file")
    if obj.get("kind") == "bdft-controller":
        try:
            return load_artifact(path).continuous
        except BDFTError as exc:
            raise ArtifactError(f"{where}: {exc}") from None
    if "kind" in obj:
        raise ArtifactError(
            f"{where}: unknown kind {obj['kind']!r}; expected 'bdft-controller' or a bare "
            "state-space object with A, B, C, D, inputs, outputs"
        )
    if obj.get("dt") not in (None, 0, 0.0):
        raise ArtifactError(
            f"{where}: the controller must be continuous-time (dt 0 or absent); "
            f"got dt={obj['dt']!r}"
        )
    inputs, outputs = _labels(obj, "inputs", where), _labels(obj, "outputs", where)
    A = _matrix(obj, "A", where, (None, None))
    n = A.shape[0]
    if A.shape != (n, n):
        raise ArtifactError(f"{where}: A must be square; got shape {A.shape}")
    B = _matrix(obj, "B", where, (n, len(inputs)))
    C = _matrix(obj, "C", where, (len(outputs), n))
    D = _matrix(obj, "D", where, (len(outputs), len(inputs)))
    try:
        return ct.ss(
            A, B, C, D, inputs=inputs, outputs=outputs, name=str(obj.get("name", "controller"))
        )
    except ValueError as exc:
        raise ArtifactError(f"{where}: not a valid state-space controller: {exc}") from None


def load_component_fit(path):
    """Read and validate a ``bdft-component-fit`` file (the format :mod:`robust.sysid` writes).

    One reader serves the whole workbench: this calls
    :func:`robust.sysid.read_component_fit`, for the family code.

    Parameters
    ----------
    path : str or pathlib.Path
        The JSON file of the fit.

    Returns
    -------
    robust.sysid.ComponentFit
        ``form``, ``params`` (the plant's own parameter object), ``fit_error_db``,
        ``band``, ``fs``, ``seed``, ``source`` and ``extra``.

    Raises
    ------
    ParameterError
        If ``path`` is not a str or path-like object.
    ArtifactError
        Unreadable file, wrong ``kind``, unknown ``form``, ``params_class`` not
        matching the form, missing or unexpected parameter names, invalid values.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ParameterError(
            f"load_component_fit: path must be a str or os.PathLike; got {type(path).__name__}"
        )
    return read_component_fit(path)


def family_nominals(fits: Sequence, *, human: str) -> dict:
    """Keyword arguments of :func:`uncertainty.default_family` from component fits.

    Parameters
    ----------
    fits : sequence of robust.sysid.ComponentFit
        At most one per form.
    human : {"physical", "literal"}
        The family's human variant. A ``human`` fit is of the paper's Eqn 5
        (:class:`~robust.model.human.LiteralHumanParams`) and so applies to the literal
        variant only.

    Returns
    -------
    dict
        ``valve=...``, ``struct=...``, ``literal=...`` as given by the fits.

    Raises
    ------
    ParameterError
        If ``human`` is not a known variant, ``fits`` is not a sequence of component
        fits (objects with a known ``form`` and its parameter object), naming the entry.
    ArtifactError
        If two fits have the same form, or a ``human`` fit is given for a family
        whose variant is not ``"literal"``.
    """
    if human not in HUMAN_VARIANTS:
        raise ParameterError(
            f"family_nominals: human must be one of {HUMAN_VARIANTS}; got {human!r}"
        )
    if isinstance(fits, (str, bytes)) or not isinstance(fits, Sequence):
        raise ParameterError(
            "family_nominals: fits must be a sequence of robust.sysid.ComponentFit; "
            f"got {type(fits).__name__}"
        )
    out = {}
    keys = {"valve": "valve", "structure": "struct", "human": "literal"}
    classes = {
        "valve": ValveCylinderParams,
        "structure": StructureParams,
        "human": LiteralHumanParams,
    }
    for i, fit in enumerate(fits):
        form = getattr(fit, "form", None)
        if not isinstance(form, str) or form not in keys:
            raise ParameterError(
                f"family_nominals: fits[{i}] must be a component fit whose form is one of "
                f"{tuple(keys)}; got {type(fit).__name__} with form {form!r}"
            )
        if not isinstance(getattr(fit, "params", None), classes[form]):
            raise ParameterError(
                f"family_nominals: fits[{i}].params must be {classes[form].__name__} for "
                f"form {form!r}; got {type(getattr(fit, 'params', None)).__name__}"
            )
        key = keys[fit.form]
        if key in out:
            raise ArtifactError(
                f"two component fits of form {fit.form!r} given ; give one per component"
            )
        if fit.form == "human" and human != "literal":
            raise ArtifactError(
                f"the component fit of {fit.source or 'unknown data'!r} is a fit of the "
                "paper's Eqn 5 (LiteralHumanParams), which "
                f"replaces the literal human; the family uses the {human!r} human. "
                "Use --human literal."
            )
        out[key] = fit.params
    return out


def load_system(path) -> tuple[USS, ct.StateSpace | None]:
    """A user's uncertain system (and controller) from a Python file.

    The file is run as a script (it is code: run only files you trust) and must define
    ``system``, an uncertain system built with :func:`uncertainty.uss` and
    :func:`uncertainty.ureal`; it may define ``controller``, a continuous python-control
    system (state space or transfer function) or a number, closed around ``system`` by
    negative feedback (``system.feedback(controller)``).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.py`` file.

    Returns
    -------
    system : USS
    controller : control.StateSpace or None

    Raises
    ------
    ParameterError
        If the file cannot be run (the message carries the file's own error), defines no
        ``system`` or one that is not a ``uss``, or a ``controller`` of another kind.
    """
    where = f"system file {os.fspath(path)}"
    try:
        ns = runpy.run_path(os.fspath(path), run_name="bdft_system")
    except Exception as exc:  # the user's code: report what it raised
        raise ParameterError(f"{where}: running it failed: {type(exc).__name__}: {exc}") from exc
    if "system" not in ns:
        raise ParameterError(f"{where}: must define `system` (an uncertainty.uss); it does not")
    system = ns["system"]
    if not isinstance(system, USS):
        raise ParameterError(
            f"{where}: `system` must be an uncertain system (uncertainty.uss); "
            f"got {type(system).__name__}"
        )
    if not system.parameters:
        raise ParameterError(
            f"{where}: `system` has no uncertain real (build its matrices with uncertainty.ureal)"
        )
    controller = ns.get("controller")
    if controller is None:
        return system, None
    if isinstance(controller, ct.TransferFunction):
        controller = ct.ss(controller)
    elif isinstance(controller, (int, float, np.integer, np.floating)) and not isinstance(
        controller, bool
    ):
        controller = ct.ss([], [], [], [[float(controller)]])
    if not isinstance(controller, ct.StateSpace):
        raise ParameterError(
            f"{where}: `controller` must be a python-control system or a number; "
            f"got {type(controller).__name__}"
        )
    if not controller.isctime():
        raise ParameterError(
            f"{where}: `controller` must be continuous-time; got dt={controller.dt}"
        )
    if (controller.ninputs, controller.noutputs) != (system.noutputs, system.ninputs):
        raise ParameterError(
            f"{where}: `controller` must map the system's {system.noutputs} outputs to its "
            f"{system.ninputs} inputs; got {controller.ninputs} -> {controller.noutputs}"
        )
    return system, controller
