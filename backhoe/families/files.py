"""Reading the files that feed a family validation: controllers and component fits.

Two formats are read here:

* a controller, :func:`load_controller`: either a bare continuous state-space
  JSON object ``{"A": .., "B": .., "C": .., "D": .., "inputs": [..], "outputs": [..]}``
  or a controller artifact (``"kind": "bdft-controller"``) written by
  :mod:`robust.export`, of which the continuous controller is used. Its signal names are
  its own: the BDFT loop's (``x, c, y`` to ``f, r_corr``) where it closes the BDFT loop
  (``bdft_loop=True``), or any names for a user's own system, whose signals
  :func:`match_controller` pairs them with (by name, or by position);
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

from backhoe.families.family import HUMAN_VARIANTS
from backhoe.model.components import StructureParams, ValveCylinderParams
from backhoe.model.human import LiteralHumanParams
from backhoe.model.loop import CONTROLLER_INPUTS, CONTROLLER_OUTPUTS
from backhoe.sysid import read_component_fit
from robust.errors import ArtifactError, BDFTError, ModelStructureError, ParameterError
from robust.export import load_artifact
from uncertainty.uss import USS
from uncertainty.utf import UTF

__all__ = [
    "load_controller",
    "match_controller",
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


def load_controller(path, *, bdft_loop: bool = False) -> ct.StateSpace:
    """Read a continuous state-space controller for :func:`uncertainty.validate_family`.

    Parameters
    ----------
    path : str or Path
        JSON file: a bare state-space object or a ``bdft-controller`` artifact
        (see the module docstring).
    bdft_loop : bool
        The controller closes the BDFT loop: its inputs must be among ``x, c, y`` and its
        outputs among ``f, r_corr``, checked here so that the message names the file
        (default False: any distinct names, those of a user's own system or
        python-control's ``u[0]``, ``y[0]``; :func:`match_controller` pairs them with a
        system's signals).

    Returns
    -------
    control.StateSpace
        Continuous-time, with the file's signal names.

    Raises
    ------
    ArtifactError
        If the file is unreadable, not JSON, or its matrices are missing,
        non-numeric, non-finite or of inconsistent shapes; with ``bdft_loop``, if a
        signal name is not one of the loop's.

    Examples
    --------
    A controller saved under python-control's default names loads with them:

    >>> import tempfile, control as ct
    >>> from robust.export import ControllerArtifact, discretize, write_artifact
    >>> from backhoe import load_controller
    >>> K = ct.ss([[-10.0]], [[1.0]], [[-20.0]], [[3.0]])
    >>> art = ControllerArtifact("pd", K, discretize(K, 0.001), None)
    >>> path = write_artifact(art, tempfile.mkdtemp() + "/pd.json", mat=False)["json"]
    >>> load_controller(path).input_labels, load_controller(path).output_labels
    (['u[0]'], ['y[0]'])
    """
    where = f"controller file {str(path)!r}"
    obj = _read_json(path, "controller file")
    if obj.get("kind") == "bdft-controller":
        try:
            K = load_artifact(path).continuous
        except BDFTError as exc:
            raise ArtifactError(f"{where}: {exc}") from None
    elif "kind" in obj:
        raise ArtifactError(
            f"{where}: unknown kind {obj['kind']!r}; expected 'bdft-controller' or a bare "
            "state-space object with A, B, C, D, inputs, outputs"
        )
    else:
        K = _bare_controller(obj, where)
    if bdft_loop:
        ins, outs = list(K.input_labels), list(K.output_labels)
        if any(n not in CONTROLLER_INPUTS for n in ins) or any(
            n not in CONTROLLER_OUTPUTS for n in outs
        ):
            raise ArtifactError(
                f"{where}: controller inputs must be among {CONTROLLER_INPUTS} and outputs "
                f"among {CONTROLLER_OUTPUTS} to close the BDFT loop; got inputs {ins}, "
                f"outputs {outs} (a controller of your own system goes with its system: "
                "--system FILE.py)"
            )
    return K


def _bare_controller(obj: dict, where: str) -> ct.StateSpace:
    """The controller of a bare state-space JSON object."""
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


def match_controller(system: USS, controller, *, where: str = "controller") -> ct.StateSpace:
    """A controller of a user's system with its signals paired to the system's.

    The controller sits in the feedback path (``system.feedback(controller)``): it
    measures the system's outputs and drives its inputs. When its input names are the
    system's output names and its output names the system's input names (in any order),
    the signals are paired by name; when they share none of them (python-control's
    defaults ``u[0]``, ``y[0]``, or other names), by position. The controller returned
    carries the system's names, in the system's order.

    Parameters
    ----------
    system : USS
        The user's uncertain system.
    controller : control.StateSpace, control.TransferFunction or number
        Continuous-time, ``system.noutputs`` inputs and ``system.ninputs`` outputs.
    where : str
        Where the controller comes from, for the messages (a file, an option).

    Returns
    -------
    control.StateSpace

    Raises
    ------
    ParameterError
        If the controller is not a continuous-time system or a number, its numbers of
        inputs and outputs are not the system's numbers of outputs and inputs, or its names
        match some of the system's signals but not all (ambiguous: name them all as the
        system's, or none).

    Examples
    --------
    >>> import control as ct
    >>> from backhoe import match_controller
    >>> from uncertainty import ureal, uss
    >>> k = ureal("k", 1.0, 0.5, 2.0)
    >>> P = uss([[-k, 0], [0, -1]], [[1, 0], [0, 1]], [[1, 0], [0, 1]], [[0, 0], [0, 0]],
    ...         inputs=["f1", "f2"], outputs=["x1", "x2"])
    >>> K = ct.ss([], [], [], [[0.0, 2.0], [5.0, 0.0]], inputs=["x2", "x1"], outputs=["f1", "f2"])
    >>> match_controller(P, K).D  # reordered to read x1, x2
    array([[2., 0.],
           [0., 5.]])
    """
    K = controller
    if isinstance(K, ct.TransferFunction):
        K = ct.ss(K)
    elif isinstance(K, (int, float, np.integer, np.floating)) and not isinstance(K, bool):
        K = ct.ss([], [], [], [[float(K)]])
    if not isinstance(K, ct.StateSpace):
        raise ParameterError(
            f"{where}: the controller must be a python-control system or a number; "
            f"got {type(K).__name__}"
        )
    if not K.isctime():
        raise ParameterError(f"{where}: the controller must be continuous-time; got dt={K.dt}")
    if (K.ninputs, K.noutputs) != (system.noutputs, system.ninputs):
        raise ParameterError(
            f"{where}: the controller must map the system's {system.noutputs} outputs "
            f"{system.outputs} to its {system.ninputs} inputs {system.inputs}; got "
            f"{K.ninputs} inputs {list(K.input_labels)} and {K.noutputs} outputs "
            f"{list(K.output_labels)}"
        )
    ins, outs = list(K.input_labels), list(K.output_labels)
    by_name = sorted(ins) == sorted(system.outputs) and sorted(outs) == sorted(system.inputs)
    shared = set(ins) & set(system.outputs) or set(outs) & set(system.inputs)
    if not by_name and shared:
        raise ParameterError(
            f"{where}: the controller's signals {ins} -> {outs} name some of the system's "
            f"outputs {system.outputs} and inputs {system.inputs} but not all; name the "
            "controller's inputs as the system's outputs and its outputs as its inputs, or "
            "use other names (then they are paired by position)"
        )
    ii = [ins.index(n) for n in system.outputs] if by_name else list(range(len(ins)))
    oi = [outs.index(n) for n in system.inputs] if by_name else list(range(len(outs)))
    return ct.ss(
        K.A,
        np.asarray(K.B)[:, ii].reshape(K.nstates, len(ii)),
        np.asarray(K.C)[oi, :].reshape(len(oi), K.nstates),
        np.asarray(K.D)[np.ix_(oi, ii)],
        inputs=list(system.outputs),
        outputs=list(system.inputs),
        name=K.name,
    )


def load_component_fit(path):
    """Read and validate a ``bdft-component-fit`` file (the format :mod:`robust.sysid` writes).

    One reader serves the whole workbench: this calls
    :func:`backhoe.sysid.read_component_fit`, for the family code.

    Parameters
    ----------
    path : str or pathlib.Path
        The JSON file of the fit.

    Returns
    -------
    backhoe.sysid.ComponentFit
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
    """Keyword arguments of :func:`backhoe.default_family` from component fits.

    Parameters
    ----------
    fits : sequence of backhoe.sysid.ComponentFit
        At most one per form.
    human : {"physical", "literal"}
        The family's human variant. A ``human`` fit is of the paper's Eqn 5
        (:class:`~backhoe.model.human.LiteralHumanParams`) and so applies to the literal
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
            "family_nominals: fits must be a sequence of backhoe.sysid.ComponentFit; "
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
    :func:`uncertainty.ureal` (or an uncertain transfer function, :func:`uncertainty.tf`);
    it may define ``controller``, a continuous python-control system (state space or
    transfer function) or a number, closed around ``system`` by negative feedback
    (``system.feedback(controller)``), its signals paired with the system's by
    :func:`match_controller`.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.py`` file.

    Returns
    -------
    system : USS
    controller : control.StateSpace or None
        With the system's signal names (:func:`match_controller`).

    Raises
    ------
    ParameterError
        If the file cannot be run (the message carries the file's own error), defines no
        ``system`` or one that is not a ``uss`` (or an uncertain transfer function), or a
        ``controller`` of another kind or of other sizes.
    """
    where = f"system file {os.fspath(path)}"
    try:
        ns = runpy.run_path(os.fspath(path), run_name="bdft_system")
    except Exception as exc:  # the user's code: report what it raised
        raise ParameterError(f"{where}: running it failed: {type(exc).__name__}: {exc}") from exc
    if "system" not in ns:
        raise ParameterError(f"{where}: must define `system` (an uncertainty.uss); it does not")
    system = ns["system"]
    if isinstance(system, UTF):
        try:
            system = system.to_uss()
        except ModelStructureError as exc:
            raise ParameterError(f"{where}: `system`: {exc}") from None
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
    return system, match_controller(system, controller, where=f"{where}: `controller`")
