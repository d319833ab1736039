"""Named uncertain reals and the expressions built from them.

``ureal("k", 10.0, 8.0, 12.0)`` is an uncertain real with the metadata every parameter of
the workbench carries (:class:`uncertainty.parameters.UncertainParameter`: nominal, range,
distribution, units, source). Ordinary arithmetic (``+ - * /``, integer ``**``, unary
minus) with numbers, numpy scalars and other uncertain expressions builds an expression
(:class:`UExpr`, a small graph of operations); nested lists or object arrays of them are
uncertain matrices (:func:`umatrix`).

Every evaluation comes from that one definition:

* :meth:`UExpr.nominal` and :meth:`UExpr.at` (numbers);
* :meth:`UExpr.evaluate` with arrays of values (many members at once, broadcast);
* :meth:`UExpr.interval`: an enclosure of the expression's range over a box (interval
  arithmetic, :class:`robust.analysis.intervals.Interval`; the square of an interval
  containing 0 starts at 0);
* any other value type with the arithmetic operators (for example
  :class:`robust.analysis.intervals.Gradient`, the mean-value form the margin certifier
  uses) through :meth:`UExpr.evaluate`.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping

import numpy as np

from robust.analysis.intervals import Interval
from robust.errors import ParameterError
from uncertainty.parameters import UncertainParameter

__all__ = ["UExpr", "ureal", "umatrix", "evaluate_matrix", "Arithmetic"]


def _reciprocal(x):
    if hasattr(x, "reciprocal"):
        return x.reciprocal()
    return 1.0 / x


class Arithmetic:
    """``+ - * /`` and their reflected forms, each ``self._binary(op, other, reflected)``.

    The one place the operators are spelled out for the uncertain types built by arithmetic
    (:class:`UExpr`, :class:`uncertainty.UTF`); each defines ``_binary``.
    """

    __slots__ = ()

    def __add__(self, other):
        return self._binary("+", other)

    def __radd__(self, other):
        return self._binary("+", other, reflected=True)

    def __sub__(self, other):
        return self._binary("-", other)

    def __rsub__(self, other):
        return self._binary("-", other, reflected=True)

    def __mul__(self, other):
        return self._binary("*", other)

    def __rmul__(self, other):
        return self._binary("*", other, reflected=True)

    def __truediv__(self, other):
        return self._binary("/", other)

    def __rtruediv__(self, other):
        return self._binary("/", other, reflected=True)


class UExpr(Arithmetic):
    """An expression of named uncertain reals (build with :func:`ureal` and arithmetic).

    Parameters
    ----------
    op : str
        The operation: ``"param"``, ``"const"``, ``"+"``, ``"-"``, ``"*"``, ``"/"``,
        ``"neg"`` or ``"pow"``.
    args : tuple
        Its operands (expressions; the parameter, the constant or the exponent).
    parameters : dict
        Name -> parameter of every uncertain real below it.

    Attributes
    ----------
    parameters : dict
        Name -> :class:`~uncertainty.parameters.UncertainParameter` of every uncertain
        real the expression depends on, in order of appearance.
    """

    __slots__ = ("_op", "_args", "parameters")
    #: numpy defers its operators to this class (``np.float64(2) * k`` is an expression)
    __array_ufunc__ = None

    def __init__(self, op: str, args: tuple, parameters: dict):
        self._op = op
        self._args = args
        self.parameters = parameters

    # -- construction -------------------------------------------------------------
    @staticmethod
    def _wrap(x, where: str) -> UExpr:
        if isinstance(x, UExpr):
            return x
        if isinstance(x, (numbers.Real, np.integer, np.floating)) and not isinstance(x, bool):
            v = float(x)
            if not np.isfinite(v):
                raise ParameterError(f"{where}: a constant must be finite; got {x!r}")
            return UExpr("const", (v,), {})
        hint = (
            "; lift a python-control system first: uncertainty.tf(sys) (one input, one "
            "output) or uncertainty.uss(sys)"
            if hasattr(x, "ninputs") and hasattr(x, "noutputs")
            else ""
        )
        raise ParameterError(
            f"{where}: an operand must be a real number, an uncertain expression or an "
            f"uncertain system; got {type(x).__name__}{hint}"
        )

    @staticmethod
    def _merge(a: UExpr, b: UExpr) -> dict:
        return merge_parameters(a.parameters, b.parameters)

    def _const(self):
        return self._args[0] if self._op == "const" else None

    def _binary(self, op: str, other, reflected: bool = False) -> UExpr:
        if _is_system(other):  # an uncertain system does the arithmetic (its reflected op)
            return NotImplemented
        if isinstance(other, np.ndarray):  # with a matrix: entry by entry, a matrix of them
            out = np.empty(other.shape, dtype=object)
            for idx, v in np.ndenumerate(other):
                out[idx] = self._binary(op, v, reflected)
            return out
        o = self._wrap(other, f"uncertain expression {op}")
        a, b = (o, self) if reflected else (self, o)
        ca, cb = a._const(), b._const()
        if op == "/" and cb == 0.0:
            raise ParameterError("uncertain expression /: division by the constant 0")
        # constants folded and the identities of 0 and 1 applied, so that matrix products
        # of sparse uncertain matrices stay small expressions
        if ca is not None and cb is not None:
            fold = {"+": float.__add__, "-": float.__sub__, "*": float.__mul__}
            return UExpr._wrap(fold[op](ca, cb) if op in fold else ca / cb, op)
        if op == "*" and (ca == 0.0 or cb == 0.0):
            return UExpr("const", (0.0,), {})
        if (op == "*" and ca == 1.0) or (op == "+" and ca == 0.0):
            return b
        if (op in ("*", "/") and cb == 1.0) or (op in ("+", "-") and cb == 0.0):
            return a
        if op == "/" and ca == 0.0:
            return UExpr("const", (0.0,), {})
        return UExpr(op, (a, b), self._merge(a, b))

    def __neg__(self):
        c = self._const()
        return (
            UExpr("const", (-c,), {}) if c is not None else UExpr("neg", (self,), self.parameters)
        )

    def __pos__(self):
        return self

    def __pow__(self, k):
        if isinstance(k, bool) or not isinstance(k, (numbers.Integral, np.integer)):
            raise ParameterError(
                f"uncertain expression **: the exponent must be an integer; got {k!r}"
            )
        return UExpr("pow", (self, int(k)), self.parameters)

    def __bool__(self):
        raise ParameterError(
            "uncertain expression: has no truth value (compare its nominal() or its bounds)"
        )

    def __repr__(self) -> str:
        return f"UExpr({self._text()}; {', '.join(self.parameters) or 'no parameters'})"

    def _text(self) -> str:
        op, args = self._op, self._args
        if op == "param":
            return args[0].name
        if op == "const":
            return f"{args[0]:g}"
        if op == "neg":
            return f"-({args[0]._text()})"
        if op == "pow":
            return f"({args[0]._text()})**{args[1]}"
        return f"({args[0]._text()} {op} {args[1]._text()})"

    # -- evaluation ---------------------------------------------------------------
    def evaluate(self, values: Mapping):
        """The expression with each uncertain real replaced by ``values[name]``.

        Parameters
        ----------
        values : mapping
            Name -> value: a number, an array (many members at once; arrays broadcast
            together) or any object with the arithmetic operators (an
            :class:`~robust.analysis.intervals.Interval`, a
            :class:`~robust.analysis.intervals.Gradient`). Every parameter of the
            expression must be given.

        Returns
        -------
        The value, of the type the operations on ``values`` give.
        """
        missing = [n for n in self.parameters if n not in values]
        if missing:
            raise ParameterError(
                f"UExpr.evaluate: values must give every parameter; missing {missing}"
            )
        return self._eval(values, {})

    def _eval(self, values, memo: dict):
        key = id(self)
        if key in memo:
            return memo[key]
        op, args = self._op, self._args
        if op == "param":
            out = values[args[0].name]
        elif op == "const":
            out = args[0]
        elif op == "neg":
            out = -args[0]._eval(values, memo)
        elif op == "pow":
            out = _power(args[0]._eval(values, memo), args[1])
        else:
            a, b = args[0]._eval(values, memo), args[1]._eval(values, memo)
            if op == "+":
                out = a + b
            elif op == "-":
                out = a - b
            elif op == "*":
                out = a * b
            else:
                out = a * _reciprocal(b) if hasattr(b, "reciprocal") else a / b
        memo[key] = out
        return out

    def nominal(self) -> float:
        """The value at every parameter's nominal."""
        return float(self.evaluate({n: p.nominal for n, p in self.parameters.items()}))

    def at(self, values: Mapping) -> float:
        """The value with ``values`` (name -> number) and the other parameters nominal."""
        return float(self.evaluate(member_values(self.parameters, values, "UExpr.at")))

    def interval(self, box: Mapping | None = None) -> tuple[float, float]:
        """An enclosure ``(low, high)`` of the expression's values over a box.

        Parameters
        ----------
        box : mapping, optional
            Name -> ``(low, high)``; parameters not given range over their own bounds.

        Raises
        ------
        robust.errors.ParameterError
            If a divisor's enclosure contains 0 (the expression is unbounded on the box).
        """
        box = dict(box or {})
        vals = {}
        for n, p in self.parameters.items():
            lo, hi = box.get(n, (p.low, p.high))
            if not lo <= hi:
                raise ParameterError(f"UExpr.interval: box[{n!r}] must have low <= high")
            vals[n] = Interval.hull(np.array(lo, float), np.array(hi, float))
        out = self.evaluate(vals)
        if not isinstance(out, Interval):  # an expression without parameters
            return float(out), float(out)
        return float(out.lo), float(out.hi)


def _is_system(x) -> bool:
    """An uncertain system (:class:`uncertainty.USS`, :class:`uncertainty.UTF`): an operand
    that does its own arithmetic with numbers and uncertain expressions (it defers numpy's
    operators to itself, ``__array_ufunc__ = None``, and is not an expression)."""
    return not isinstance(x, UExpr) and getattr(type(x), "__array_ufunc__", 0) is None


def member_values(parameters: Mapping, values: Mapping, where: str) -> dict:
    """Every parameter's value: ``values`` (name -> number) and the others' nominals.

    Parameters
    ----------
    parameters : mapping
        Name -> :class:`~uncertainty.parameters.UncertainParameter` of an expression or a
        system.
    values : mapping
        Name -> number for some of them.
    where : str
        The caller, for the messages.

    Raises
    ------
    robust.errors.ParameterError
        If a name is not one of ``parameters`` or a value is not a real number.
    """
    unknown = [n for n in values if n not in parameters]
    if unknown:
        raise ParameterError(
            f"{where}: {unknown} are not parameters of this expression or system "
            f"({list(parameters)})"
        )
    full = {n: p.nominal for n, p in parameters.items()}
    for n, v in values.items():
        try:
            if isinstance(v, (bool, np.bool_)) or np.ndim(v) != 0 or np.iscomplexobj(v):
                raise TypeError
            full[n] = float(v)
        except (TypeError, ValueError):
            raise ParameterError(
                f"{where}: values[{n!r}] must be a real number; got {v!r:.60}"
            ) from None
    return full


def merge_parameters(*dicts) -> dict:
    """The union of name -> parameter dicts; the same name must mean the same parameter."""
    out: dict = {}
    for d in dicts:
        for name, p in d.items():
            if name in out and out[name] != p:
                raise ParameterError(
                    f"uncertain reals: two different parameters are named {name!r} "
                    f"({out[name]} and {p})"
                )
            out[name] = p
    return out


def _power(x, k: int):
    if k == 0:
        return x * 0.0 + 1.0
    if k < 0:
        return _reciprocal(_power(x, -k))
    if k % 2 == 0 and hasattr(x, "square"):
        return _power(x.square(), k // 2)
    out = x
    for _ in range(k - 1):
        out = out * x
    return out


def ureal(
    name: str,
    nominal: float,
    low: float,
    high: float,
    *,
    distribution: str = "uniform",
    unit: str = "",
    source: str = "",
    std: float | None = None,
) -> UExpr:
    """A named uncertain real.

    Parameters
    ----------
    name : str
        Its name (unique in an expression: two different parameters may not share it).
    nominal, low, high : float
        Nominal value and range, ``low <= nominal <= high``, ``low < high``.
    distribution : str
        ``"uniform"``, ``"loguniform"`` or ``"truncnormal"`` (what sampling draws).
    unit : str
        Units of the value.
    source : str
        Where the nominal and the range come from.
    std : float, optional
        Standard deviation of ``"truncnormal"``.

    Returns
    -------
    UExpr
        The uncertain real as an expression (its ``parameters`` hold the metadata).

    Examples
    --------
    >>> from uncertainty import ureal
    >>> k = ureal("k", 10.0, 8.0, 12.0, unit="N/m")
    >>> m = ureal("m", 2.0, 1.5, 2.5, unit="kg")
    >>> w2 = k / m
    >>> w2.nominal(), w2.at({"k": 12.0})
    (5.0, 6.0)
    >>> [round(v, 3) for v in w2.interval()]  # encloses the exact range [3.2, 8]
    [2.667, 8.0]
    """
    p = UncertainParameter(
        name, nominal, low, high, distribution=distribution, units=unit, source=source, std=std
    )
    return UExpr("param", (p,), {p.name: p})


def umatrix(rows) -> np.ndarray:
    """An uncertain matrix: a 2-D object array of :class:`UExpr` and numbers.

    Parameters
    ----------
    rows : nested list or array_like
        Rows of numbers and uncertain expressions.
    """
    arr = np.empty(np.shape(np.asarray(rows, dtype=object)), dtype=object)
    src = np.asarray(rows, dtype=object)
    if src.ndim != 2:
        raise ParameterError(f"umatrix: rows must be 2-D; got {src.ndim} dimensions")
    for idx, v in np.ndenumerate(src):
        arr[idx] = UExpr._wrap(v, f"umatrix entry {idx}")
    return arr


def evaluate_matrix(matrix, values: Mapping) -> np.ndarray:
    """An uncertain matrix at ``values`` (numbers or arrays of ``n`` members).

    Parameters
    ----------
    matrix : array_like
        What :func:`umatrix` returns (or rows it accepts).
    values : mapping
        Name -> number or array of shape ``(n,)`` (every parameter of every entry).

    Returns
    -------
    numpy.ndarray
        Shape ``matrix.shape`` for numbers, ``(n,) + matrix.shape`` for arrays.
    """
    M = umatrix(matrix)
    vals = {k: np.asarray(v, float) for k, v in values.items()}
    shape = np.broadcast_shapes(*(v.shape for v in vals.values())) if vals else ()
    out = np.empty(shape + M.shape)
    for idx, e in np.ndenumerate(M):
        out[(Ellipsis, *idx)] = e.evaluate(vals)
    return out
