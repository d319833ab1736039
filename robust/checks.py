"""Shared validation helpers: every parameter check in the workbench goes through here.

Frozen parameter dataclasses call :func:`validate_fields` from ``__post_init__``
so that a bad value is rejected once, at construction, with a message that names
the parameter, what was expected and what was got.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from robust.errors import DataError, ParameterError

__all__ = ["check_scalar", "validate_fields", "check_finite_array", "Spec"]


@dataclasses.dataclass(frozen=True)
class Spec:
    """What a scalar field must satisfy.

    Parameters
    ----------
    low, high : float or None
        Bounds; ``None`` means unbounded on that side.
    low_open, high_open : bool
        Whether the bound itself is excluded (``low_open=True`` and ``low=0``
        means strictly positive).
    """

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False

    def describe(self) -> str:
        """The accepted range in words, e.g. ``"a finite value in (0, inf]"``."""
        lo = "(" if self.low_open else "["
        hi = ")" if self.high_open else "]"
        a = "-inf" if self.low is None else f"{self.low:g}"
        b = "inf" if self.high is None else f"{self.high:g}"
        return f"a finite value in {lo}{a}, {b}{hi}"


POSITIVE = Spec(low=0.0, low_open=True)
NONNEGATIVE = Spec(low=0.0)
FINITE = Spec()


def check_scalar(name: str, value: Any, spec: Spec = FINITE, *, owner: str = "") -> float:
    """Return ``value`` as a float after checking it against ``spec``.

    Parameters
    ----------
    name : str
        Name of the parameter, used in the error message.
    value : int or float
        The value to check: a real Python or numpy number (``bool`` is rejected).
    spec : Spec, optional
        Bounds the value must satisfy; by default any finite value.
    owner : str, optional
        Name of the object the parameter belongs to (e.g. a dataclass name); the
        message then names ``owner.name``.

    Returns
    -------
    float
        ``value`` converted to a Python float.

    Raises
    ------
    ParameterError
        If the value is not a real finite number or violates the bounds; the
        message names ``owner.name``, the expected range and the value got.
    """
    label = f"{owner}.{name}" if owner else name
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(
            f"{label} must be a real number; got {value!r} ({type(value).__name__})"
        )
    x = float(value)
    bad = not math.isfinite(x)
    if not bad and spec.low is not None:
        bad = x <= spec.low if spec.low_open else x < spec.low
    if not bad and spec.high is not None:
        bad = x >= spec.high if spec.high_open else x > spec.high
    if bad:
        raise ParameterError(f"{label} must be {spec.describe()}; got {value!r}")
    return x


def validate_fields(obj: Any, specs: Mapping[str, Spec]) -> None:
    """Check every field of a frozen dataclass named in ``specs``.

    Values are normalised to ``float`` in place (through ``object.__setattr__``,
    as frozen dataclasses require).

    Parameters
    ----------
    obj : dataclass instance
        The (usually frozen) dataclass being constructed; error messages name its
        type.
    specs : mapping of str to Spec
        Field name to the bounds its value must satisfy. Fields not named here are
        left alone.

    Raises
    ------
    ParameterError
        On the first field (in ``specs`` order) that fails :func:`check_scalar`.
    """
    owner = type(obj).__name__
    for name, spec in specs.items():
        object.__setattr__(obj, name, check_scalar(name, getattr(obj, name), spec, owner=owner))


def check_finite_array(
    name: str, value: Any, *, ndim: int | None = None, error=DataError
) -> np.ndarray:
    """Return ``value`` as a float array, rejecting NaN/inf and a wrong number of dimensions.

    Parameters
    ----------
    name : str
        Name of the array, used in the error message.
    value : array_like
        Anything :func:`numpy.asarray` converts to a float array.
    ndim : int, optional
        Required number of dimensions; any number when None.
    error : type of Exception, optional
        Exception class raised on failure, :class:`DataError` by default (pass
        :class:`ParameterError` for arrays that are parameters rather than data).

    Returns
    -------
    numpy.ndarray
        ``value`` as a float array (not copied when it already is one).

    Raises
    ------
    DataError
        (or ``error``) If ``value`` is not numeric, has the wrong number of
        dimensions or contains NaN or inf.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise error(f"{name} must be a numeric array; got {type(value).__name__}: {exc}") from None
    if ndim is not None and arr.ndim != ndim:
        raise error(f"{name} must have {ndim} dimension(s); got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        n_bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise error(
            f"{name} contains {n_bad} non-finite value(s) (NaN or inf); clean or drop them first"
        )
    return arr
