"""Shared validation helpers: every parameter check in the workbench goes through here.

Frozen parameter dataclasses call :func:`validate_fields` from ``__post_init__``
so that a bad value is rejected once, at construction, with a message that names
the parameter, what was expected and what was got.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from robust.errors import DataError, ModelStructureError, ParameterError

__all__ = [
    "check_scalar",
    "validate_fields",
    "check_finite_array",
    "check_int",
    "check_sign",
    "check_vector",
    "check_array",
    "check_columns",
    "check_state_space",
    "check_abcd",
    "check_callable",
    "Spec",
    "POSITIVE",
    "NONNEGATIVE",
    "FINITE",
    "NONZERO",
    "DAMPING_RATIO",
]


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
    nonzero : bool
        Whether 0 is excluded (for a signed quantity such as a unit gain).
    """

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    nonzero: bool = False

    def describe(self) -> str:
        """The accepted range in words, e.g. ``"a finite value in (0, inf]"``."""
        lo = "(" if self.low_open else "["
        hi = ")" if self.high_open else "]"
        a = "-inf" if self.low is None else f"{self.low:g}"
        b = "inf" if self.high is None else f"{self.high:g}"
        kind = "a finite nonzero value" if self.nonzero else "a finite value"
        if self.low is None and self.high is None:
            return kind
        return f"{kind} in {lo}{a}, {b}{hi}"

    def contains(self, x: float) -> bool:
        """Whether the real number ``x`` satisfies the spec (finite, bounds, nonzero).

        Parameters
        ----------
        x : float
            The value to test.
        """
        x = float(x)
        if not math.isfinite(x) or (self.nonzero and x == 0.0):
            return False
        if self.low is not None and (x <= self.low if self.low_open else x < self.low):
            return False
        if self.high is not None and (x >= self.high if self.high_open else x > self.high):
            return False
        return True

    def violations(self, x: np.ndarray) -> np.ndarray:
        """Boolean mask of the entries of ``x`` that fail the spec (vectorised :meth:`contains`).

        Parameters
        ----------
        x : numpy.ndarray
            Float array, any shape.
        """
        bad = ~np.isfinite(x)
        if self.low is not None:
            bad |= (x <= self.low) if self.low_open else (x < self.low)
        if self.high is not None:
            bad |= (x >= self.high) if self.high_open else (x > self.high)
        if self.nonzero:
            bad |= x == 0.0
        return bad


#: Strictly positive (masses, stiffnesses, frequencies, gains of known sign).
POSITIVE = Spec(low=0.0, low_open=True)
#: Zero or positive.
NONNEGATIVE = Spec(low=0.0)
#: Any finite value.
FINITE = Spec()
#: Any finite value except 0 (signed unit gains).
NONZERO = Spec(nonzero=True)
#: An underdamped damping ratio, in (0, 1).
DAMPING_RATIO = Spec(low=0.0, high=1.0, low_open=True, high_open=True)


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
    if not spec.contains(x):
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


def _label(name: str, owner: str) -> str:
    return f"{owner}.{name}" if owner else name


def check_int(
    name: str, value: Any, *, low: int | None = None, high: int | None = None, owner: str = ""
) -> int:
    """Return ``value`` as an int after checking that it is an integer in ``[low, high]``.

    Parameters
    ----------
    name : str
        Name of the parameter, used in the error message.
    value : int
        A Python or numpy integer (``bool`` and floats are rejected, even ``3.0``).
    low, high : int, optional
        Inclusive bounds; unbounded on a side given as None.
    owner : str, optional
        Name of the object or function the parameter belongs to; the message then
        names ``owner.name``.

    Returns
    -------
    int

    Raises
    ------
    ParameterError
        If ``value`` is not an integer or lies outside the bounds.
    """
    label = _label(name, owner)
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ParameterError(f"{label} must be an integer; got {value!r} ({type(value).__name__})")
    v = int(value)
    if (low is not None and v < low) or (high is not None and v > high):
        a = "-inf" if low is None else str(low)
        b = "inf" if high is None else str(high)
        raise ParameterError(f"{label} must be an integer in [{a}, {b}]; got {v}")
    return v


def check_sign(name: str, value: Any, *, owner: str = "") -> int:
    """Return ``value`` as the int +1 or -1, rejecting anything else (0, 2, 1.5, True, "+").

    Parameters
    ----------
    name : str
        Name of the parameter, used in the error message.
    value : int
        The sign: an integer (or an integral float) equal to +1 or -1.
    owner : str, optional
        Name of the object or function the parameter belongs to.

    Returns
    -------
    int
        +1 or -1.

    Raises
    ------
    ParameterError
        If ``value`` is not +1 or -1.
    """
    label = _label(name, owner)
    ok = (
        not isinstance(value, bool)
        and isinstance(value, (int, float, np.integer, np.floating))
        and float(value) in (1.0, -1.0)
    )
    if not ok:
        raise ParameterError(f"{label} must be +1 or -1; got {value!r}")
    return int(value)


def _as_float(name: str, value: Any, error) -> np.ndarray:
    if isinstance(value, (str, bytes)):
        raise error(f"{name} must be numeric; got a string {value!r}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise error(f"{name} must be numeric; got {type(value).__name__}: {exc}") from None
    return arr


def check_array(
    name: str, value: Any, spec: Spec = FINITE, *, ndim: int | None = None, error=ParameterError
) -> np.ndarray:
    """Return ``value`` as a float array (any shape) whose every entry satisfies ``spec``.

    Parameters
    ----------
    name : str
        Name of the array, used in the error message.
    value : array_like
        A real number or an array of them.
    spec : Spec, optional
        What every entry must satisfy (default: finite).
    ndim : int, optional
        Required number of dimensions; any when None.
    error : type of Exception, optional
        Exception class raised, :class:`ParameterError` by default.

    Returns
    -------
    numpy.ndarray
        ``value`` as a float array (not copied when it already is one).

    Raises
    ------
    ParameterError
        (or ``error``) Naming the array, the index and value of the first bad entry
        and how many entries fail.
    """
    arr = _as_float(name, value, error)
    if ndim is not None and arr.ndim != ndim:
        raise error(f"{name} must have {ndim} dimension(s); got shape {arr.shape}")
    bad = spec.violations(arr)
    if bad.any():
        flat = int(np.flatnonzero(bad.ravel())[0])
        idx = np.unravel_index(flat, arr.shape)
        where = "" if arr.ndim == 0 else "[" + ", ".join(str(int(i)) for i in idx) + "]"
        n_bad = int(np.count_nonzero(bad))
        count = f" ({n_bad} of {arr.size} entries fail)" if arr.ndim else ""
        raise error(f"{name}{where} must be {spec.describe()}; got {float(arr[idx])!r}{count}")
    return arr


def check_vector(
    name: str,
    value: Any,
    spec: Spec = FINITE,
    *,
    min_size: int = 1,
    increasing: bool = False,
    error=ParameterError,
) -> np.ndarray:
    """Return ``value`` as a 1-D float array whose every entry satisfies ``spec``.

    Parameters
    ----------
    name : str
        Name of the array, used in the error message.
    value : array_like
        A sequence of real numbers (a scalar is read as one entry).
    spec : Spec, optional
        What every entry must satisfy (default: finite).
    min_size : int, optional
        Fewest entries accepted (default 1: not empty).
    increasing : bool, optional
        Require strictly increasing entries.
    error : type of Exception, optional
        Exception class raised, :class:`ParameterError` by default (pass
        :class:`DataError` for measured signals).

    Returns
    -------
    numpy.ndarray
        Shape (n,), float.

    Raises
    ------
    ParameterError
        (or ``error``) Naming the array and the first bad entry's index and value.
    """
    arr = _as_float(name, value, error)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise error(f"{name} must be 1-D; got shape {arr.shape}")
    if arr.size < min_size:
        raise error(f"{name} must have at least {min_size} entries; got {arr.size}")
    check_array(name, arr, spec, error=error)
    if increasing and arr.size > 1:
        d = np.diff(arr)
        if np.any(d <= 0):
            i = int(np.flatnonzero(d <= 0)[0])
            raise error(
                f"{name} must be strictly increasing; got {name}[{i}] = {float(arr[i])!r}, "
                f"{name}[{i + 1}] = {float(arr[i + 1])!r}"
            )
    return arr


def check_columns(
    name: str,
    values: Any,
    specs: Sequence[Spec],
    labels: Sequence[str],
    *,
    row_offset: int = 0,
    note: str = "",
    error=ParameterError,
) -> np.ndarray:
    """Return ``values`` as an (N, d) float array whose column ``j`` satisfies ``specs[j]``.

    Vectorised (a few comparisons per entry), so it is cheap on millions of rows.

    Parameters
    ----------
    name : str
        Name of the table, used in the error message (e.g. ``"validate_family: values"``).
    values : array_like, shape (N, d)
        One row per member, one column per parameter.
    specs : sequence of Spec
        What each column must satisfy, length d.
    labels : sequence of str
        Name of each column, length d.
    row_offset : int, optional
        Added to the row index in the message (when ``values`` is a slice of a larger table).
    note : str, optional
        Appended to the message (what to do about it).
    error : type of Exception, optional
        Exception class raised, :class:`ParameterError` by default.

    Returns
    -------
    numpy.ndarray
        ``values`` as a float array (not copied when it already is one).

    Raises
    ------
    ParameterError
        (or ``error``) If ``values`` is not numeric or not of shape (N, d), or an entry
        fails its column's spec; the message names the first failing row, the column,
        the accepted range, the value got and how many rows fail.
    """
    if len(specs) != len(labels):
        raise ParameterError(f"check_columns: {len(specs)} specs for {len(labels)} labels")
    v = _as_float(name, values, error)
    d = len(specs)
    if v.ndim != 2 or v.shape[1] != d:
        raise error(f"{name} must have shape (N, {d}) (columns {list(labels)}); got {v.shape}")
    if v.size == 0:
        return v
    # whole-table comparisons against per-column bounds (broadcast along the rows): column
    # by column would walk strided memory, several times slower on millions of rows
    lo = np.array([-np.inf if sp.low is None else sp.low for sp in specs])
    hi = np.array([np.inf if sp.high is None else sp.high for sp in specs])
    lo_open = np.array([sp.low is not None and sp.low_open for sp in specs])
    hi_open = np.array([sp.high is not None and sp.high_open for sp in specs])
    nonzero = np.array([sp.nonzero for sp in specs])
    bad = ~np.isfinite(v)
    bad |= v < lo
    bad |= v > hi
    if lo_open.any():
        bad |= (v == lo) & lo_open
    if hi_open.any():
        bad |= (v == hi) & hi_open
    if nonzero.any():
        bad |= (v == 0.0) & nonzero
    if bad.any():
        bad_rows = np.flatnonzero(bad.any(axis=1))
        i = int(bad_rows[0])
        j = int(np.flatnonzero(bad[i])[0])
        extra = f" ({bad_rows.size} of {v.shape[0]} rows fail)" if bad_rows.size > 1 else ""
        raise error(
            f"{name} row {i + row_offset}: {labels[j]} must be {specs[j].describe()}; "
            f"got {float(v[i, j])!r}{extra}{note}"
        )
    return v


def check_abcd(
    name: str, A: Any, B: Any, C: Any, D: Any = None, *, error=ModelStructureError
) -> tuple[np.ndarray, ...]:
    """State-space matrices checked numeric, finite and conformal.

    Parameters
    ----------
    name : str
        Name of the system, used in the error message (``"sys"`` gives ``sys.A``).
    A, B, C : array_like
        Matrices of shapes (n, n), (n, m), (p, n); ``n = 0`` (no states) is allowed.
    D : array_like, optional
        Feedthrough, shape (p, m); zeros when None (for functions without ``D``).
    error : type of Exception, optional
        Exception class raised, :class:`ModelStructureError` by default.

    Returns
    -------
    A, B, C, D : numpy.ndarray
        2-D float arrays (a system without states has ``A`` of shape (0, 0)).

    Raises
    ------
    ModelStructureError
        (or ``error``) If a matrix is not numeric, contains NaN or inf, or the shapes
        do not fit together; the message names the matrix.
    """
    mats = []
    for label, m in zip("ABCD", (A, B, C, D)):
        if m is None:
            mats.append(None)
            continue
        arr = _as_float(f"{name}.{label}", m, error)
        if arr.ndim < 2:
            arr = np.atleast_2d(arr) if arr.size else arr.reshape(0, 0)
        if arr.ndim != 2:
            raise error(f"{name}.{label} must be a 2-D matrix; got shape {arr.shape}")
        if not np.isfinite(arr).all():
            n_bad = int(arr.size - np.count_nonzero(np.isfinite(arr)))
            raise error(f"{name}.{label} contains {n_bad} non-finite entries (NaN or inf)")
        mats.append(arr)
    A, B, C, D = mats
    if D is None:
        D = np.zeros((C.shape[0], B.shape[1]))
    p, m = D.shape
    if A.size == 0:
        return np.zeros((0, 0)), np.zeros((0, m)), np.zeros((p, 0)), D
    n = A.shape[0]
    if A.shape != (n, n):
        raise error(f"{name}.A must be square; got shape {A.shape}")
    if B.shape != (n, m) or C.shape != (p, n):
        raise error(
            f"{name}: with A {n}x{n} and D {p}x{m}, B must be {n}x{m} and C {p}x{n}; "
            f"got B {B.shape[0]}x{B.shape[1]}, C {C.shape[0]}x{C.shape[1]}"
        )
    return A, B, C, D


def check_state_space(name: str, sys: Any, *, error=ModelStructureError) -> tuple[np.ndarray, ...]:
    """The matrices ``A, B, C, D`` of a state-space system, checked finite and conformal.

    Parameters
    ----------
    name : str
        Name of the system, used in the error message (``"sys"`` gives ``sys.A``).
    sys : control.StateSpace or object with A, B, C, D
        The system.
    error : type of Exception, optional
        Exception class raised, :class:`ModelStructureError` by default.

    Returns
    -------
    A, B, C, D : numpy.ndarray
        2-D float arrays (a system without states has ``A`` of shape (0, 0)).

    Raises
    ------
    ModelStructureError
        (or ``error``) If ``sys`` has no ``A, B, C, D``, a matrix is not numeric or
        contains NaN or inf, or the shapes do not fit together.
    """
    try:
        raw = (sys.A, sys.B, sys.C, sys.D)
    except AttributeError:
        raise error(
            f"{name} must be a control.StateSpace (or have A, B, C, D); got {type(sys).__name__}"
        ) from None
    return check_abcd(name, *raw, error=error)


def check_callable(name: str, value: Any, *, owner: str = "") -> None:
    """Check that ``value`` is callable or None (progress callbacks and the like).

    Parameters
    ----------
    name : str
        Name of the parameter, used in the error message.
    value : callable or None
        The value to check.
    owner : str, optional
        Name of the function the parameter belongs to.

    Raises
    ------
    ParameterError
        If ``value`` is neither None nor callable.
    """
    if value is not None and not callable(value):
        raise ParameterError(
            f"{_label(name, owner)} must be callable or None; got {type(value).__name__}"
        )
