"""Fitted component models as JSON files, so an identified model feeds validation and design.

Layout (``kind = "bdft-component-fit"``)::

    {
      "kind": "bdft-component-fit",
      "form": "structure",
      "params_class": "StructureParams",
      "params": {"k_s": 199.97, "zeta1": 0.1258, "zeta2": 0.2234, "f1_hz": 6.302, "f2_hz": 6.495},
      "fit_error_db": 0.039,
      "band": [2.0, 15.0],
      "fs": 1000.0,
      "seed": 7,
      "source": "chirp_structure.csv"
    }

``seed`` is the seed of simulated data (``null`` for measured data). Extra keys
(``fit_error_deg``, ``std_errors``, ``notes``, ...) are kept for people and ignored
by the loader.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

from backhoe.model.components import StructureParams, ValveCylinderParams
from backhoe.model.human import LiteralHumanParams
from robust.checks import POSITIVE, check_int, check_scalar
from robust.errors import ArtifactError, ParameterError
from robust.jsonio import atomic_write_json

__all__ = ["KIND", "ComponentFit", "load_component_fit", "read_component_fit", "save_component_fit"]

#: Value of the ``kind`` field.
KIND = "bdft-component-fit"

_CLASSES = {
    "valve": ValveCylinderParams,
    "structure": StructureParams,
    "human": LiteralHumanParams,
}


@dataclasses.dataclass(frozen=True)
class ComponentFit:
    """A component-fit file's content.

    Attributes
    ----------
    form : str
        ``"valve"``, ``"structure"`` or ``"human"``.
    params : ValveCylinderParams, StructureParams or LiteralHumanParams
    fit_error_db : float
        Weighted RMS magnitude error of the fit over ``band``, dB.
    band : (float, float)
        Fit band in Hz.
    fs : float
        Sampling rate of the data, Hz.
    seed : int or None
        Seed of simulated data, ``None`` for measured data.
    source : str
        The data file.
    extra : dict
        Other fields in the file.
    """

    form: str
    params: object
    fit_error_db: float
    band: tuple[float, float]
    fs: float
    seed: int | None
    source: str
    extra: dict = dataclasses.field(default_factory=dict)


def save_component_fit(
    path: str | os.PathLike, fit, *, fs: float, seed: int | None, source: str
) -> Path:
    """Write a fixed-form :class:`~backhoe.sysid.fit.FitResult` as a component-fit file, atomically.

    Parameters
    ----------
    path : str or path-like
        Target ``.json`` file.
    fit : FitResult
        A ``"valve"``, ``"structure"`` or ``"human"`` fit.
    fs : float
        Sampling rate of the data, Hz.
    seed : int or None
        Seed of simulated data (``None`` for measured data).
    source : str
        The data file.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ParameterError
        If ``fit`` is not a fit result or is a general rational fit (only the paper's
        forms map to plant parameters), ``fs`` is not finite and positive, ``seed`` is
        neither None nor a non-negative integer, or ``source`` is not a string; checked
        before anything is written.
    """
    if not hasattr(fit, "form") or not hasattr(fit, "params_dict"):
        raise ParameterError(
            f"save_component_fit: fit must be a backhoe.sysid.FitResult; got {type(fit).__name__}"
        )
    check_scalar("save_component_fit: fs", fs, POSITIVE)
    if seed is not None:
        check_int("save_component_fit: seed", seed, low=0)
    if not isinstance(source, str):
        raise ParameterError(
            f"save_component_fit: source must be a string; got {type(source).__name__}"
        )
    if fit.form not in _CLASSES:
        raise ParameterError(
            f"only the forms {tuple(_CLASSES)} can be saved as component models; got {fit.form!r}"
        )
    obj = {
        "kind": KIND,
        "form": fit.form,
        "params_class": type(fit.params).__name__,
        "params": fit.params_dict(),
        "fit_error_db": fit.fit_error_db,
        "fit_error_deg": fit.fit_error_deg,
        "band": list(fit.band_hz),
        "fs": float(fs),
        "seed": None if seed is None else int(seed),
        "source": str(source),
        "std_errors": dict(fit.std_errors),
        "notes": list(fit.notes),
    }
    return atomic_write_json(path, obj)


def _number(obj: dict, key: str, path: str) -> float:
    val = obj.get(key)
    if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(float(val)):
        raise ArtifactError(f"{path}: field {key!r} must be a finite number; got {val!r}")
    return float(val)


def read_component_fit(path: str | os.PathLike) -> ComponentFit:
    """Read and validate a component-fit file.

    Parameters
    ----------
    path : str or path-like
        A file written by :func:`save_component_fit` (or by hand in that layout).

    Returns
    -------
    ComponentFit

    Raises
    ------
    ArtifactError
        Missing or unreadable file, invalid JSON, wrong ``kind``, unknown ``form``,
        ``params_class`` not matching ``form``, missing or unexpected parameter
        names, non-numeric or unphysical values, malformed ``band``/``fs``/``seed``.
    """
    p = Path(path)
    label = str(p)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ArtifactError(
            f"cannot read component-fit file {label!r}: {exc.strerror or exc}"
        ) from None
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ArtifactError(f"{label}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(obj, dict):
        raise ArtifactError(f"{label}: expected a JSON object; got {type(obj).__name__}")
    if obj.get("kind") != KIND:
        raise ArtifactError(f"{label}: field 'kind' must be {KIND!r}; got {obj.get('kind')!r}")
    form = obj.get("form")
    if form not in _CLASSES:
        raise ArtifactError(f"{label}: field 'form' must be one of {tuple(_CLASSES)}; got {form!r}")
    cls = _CLASSES[form]
    if obj.get("params_class") != cls.__name__:
        raise ArtifactError(
            f"{label}: form {form!r} needs params_class {cls.__name__!r}; "
            f"got {obj.get('params_class')!r}"
        )
    params = obj.get("params")
    if not isinstance(params, dict):
        raise ArtifactError(f"{label}: field 'params' must be an object of name -> value")
    expected = [f.name for f in dataclasses.fields(cls)]
    missing = [n for n in expected if n not in params]
    unexpected = [n for n in params if n not in expected]
    if missing or unexpected:
        raise ArtifactError(
            f"{label}: {cls.__name__} parameters must be exactly {expected}; "
            f"missing {missing}, unexpected {unexpected}"
        )
    values = {n: _number(params, n, f"{label} params") for n in expected}
    try:
        pobj = cls(**values)
    except ParameterError as exc:
        raise ArtifactError(f"{label}: parameters are not physical: {exc}") from None
    band = obj.get("band")
    if (
        not isinstance(band, list)
        or len(band) != 2
        or not all(
            isinstance(b, (int, float)) and not isinstance(b, bool) and math.isfinite(b)
            for b in band
        )
        or not 0 < band[0] < band[1]
    ):
        raise ArtifactError(
            f"{label}: field 'band' must be [lo, hi] in Hz with 0 < lo < hi; got {band!r}"
        )
    fs = _number(obj, "fs", label)
    if fs <= 0:
        raise ArtifactError(f"{label}: field 'fs' must be positive; got {fs!r}")
    seed = obj.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
        raise ArtifactError(f"{label}: field 'seed' must be an integer or null; got {seed!r}")
    source = obj.get("source")
    if not isinstance(source, str):
        raise ArtifactError(f"{label}: field 'source' must be a string; got {source!r}")
    known = {
        "kind",
        "form",
        "params_class",
        "params",
        "fit_error_db",
        "band",
        "fs",
        "seed",
        "source",
    }
    return ComponentFit(
        form=form,
        params=pobj,
        fit_error_db=_number(obj, "fit_error_db", label),
        band=(float(band[0]), float(band[1])),
        fs=fs,
        seed=seed,
        source=source,
        extra={k: v for k, v in obj.items() if k not in known},
    )


def load_component_fit(path: str | os.PathLike):
    """Load a component-fit file and return its parameter object.

    Parameters
    ----------
    path : str or path-like
        A component-fit file (see the module notes).

    Returns
    -------
    ValveCylinderParams, StructureParams or LiteralHumanParams
        Ready for :class:`backhoe.model.loop.BDFTLoop` (``valve=``, ``struct=``) or
        ``backhoe.model.human.LiteralHuman(params)``.

    Raises
    ------
    ArtifactError
        See :func:`read_component_fit`.
    """
    return read_component_fit(path).params
