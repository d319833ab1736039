"""Uncertain transfer functions: rational functions of ``s`` with uncertain coefficients.

``s = tf("s")`` is the Laplace variable. Arithmetic (``+ - * /``, integer ``**``, unary
minus) with numbers, uncertain expressions (:func:`uncertainty.ureal`), python-control
systems and uncertain systems builds an uncertain system, as python-control's ``tf("s")``
builds a certain one:

* with numbers, uncertain expressions, another :class:`UTF` and python-control systems of
  one input and one output: a :class:`UTF` (polynomial arithmetic on the coefficients;
  sums over one denominator keep it, nothing else is cancelled: ``G * (1 / G)`` keeps
  the factors of both, whose modes stay in the realisation);
* with a :class:`~uncertainty.USS` or a python-control system of several inputs or
  outputs: a ``uss``, the transfer function realised first (:meth:`UTF.to_uss`).

:meth:`UTF.to_uss` (and ``uss(G)``) realise ``G`` in controllable canonical form with
``UExpr`` entries, numerator and denominator normalised by the denominator's leading
coefficient, which may itself be uncertain if it keeps its sign over the parameters' box;
an improper ``G`` (numerator of higher degree than the denominator) is refused. Every
evaluation comes from that one realisation (:mod:`uncertainty.uss`); :meth:`UTF.at` gives
a member as a python-control transfer function.

python-control's own ``tf("s")`` cannot take an uncertain coefficient (its systems convert
their operands to numbers); lift a python-control system with ``tf(sys)`` (one input and
one output) or ``uss(sys)``. ``sys / G`` with a python-control ``sys`` on the left is
refused by python-control; write ``tf(sys) / G``.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping

import control as ct
import numpy as np

from robust.errors import ModelStructureError, ParameterError
from uncertainty.ureal import Arithmetic, UExpr, member_values, merge_parameters
from uncertainty.uss import USS, uss

__all__ = ["UTF", "tf"]

_ZERO = UExpr("const", (0.0,), {})
_ONE = UExpr("const", (1.0,), {})


def _coef(x, where: str) -> UExpr:
    if isinstance(x, (bool, np.bool_)):
        raise ParameterError(f"{where}: a coefficient must be a real number; got {x!r}")
    return UExpr._wrap(x, where)


def _is_zero(e: UExpr) -> bool:
    return e._const() == 0.0


def _trim(p) -> tuple:
    """The polynomial without leading coefficients that are the constant 0."""
    p = tuple(p)
    i = 0
    while i < len(p) - 1 and _is_zero(p[i]):
        i += 1
    return p[i:]


def _padd(p, q) -> tuple:
    n = max(len(p), len(q))
    p = (_ZERO,) * (n - len(p)) + tuple(p)
    q = (_ZERO,) * (n - len(q)) + tuple(q)
    return _trim(a + b for a, b in zip(p, q))


def _pneg(p) -> tuple:
    return tuple(-a for a in p)


def _pmul(p, q) -> tuple:
    out = [_ZERO] * (len(p) + len(q) - 1)
    for i, a in enumerate(p):
        for j, b in enumerate(q):
            out[i + j] = out[i + j] + a * b
    return _trim(out)


def _same(p, q) -> bool:
    """The same polynomial, coefficient by coefficient (one expression or equal constants)."""
    return len(p) == len(q) and all(
        a is b or (a._const() is not None and a._const() == b._const()) for a, b in zip(p, q)
    )


def _is_real(x) -> bool:
    return isinstance(x, (numbers.Real, np.integer, np.floating)) and not isinstance(
        x, (bool, np.bool_)
    )


def _text(p) -> str:
    n = len(p) - 1
    terms = []
    for i, c in enumerate(p):
        if _is_zero(c) and len(p) > 1:
            continue
        power = n - i
        s = "" if power == 0 else "s" if power == 1 else f"s**{power}"
        coef = c._text()
        terms.append(coef if not s else s if c._const() == 1.0 else f"{coef}*{s}")
    return " + ".join(terms) or "0"


def _check_leading(a0: UExpr) -> None:
    """Refuse a leading coefficient shown to vanish or change sign on the parameters' box.

    Its interval enclosure excluding 0 settles it; otherwise the nominal and the box's
    vertices (up to 2**12 of them) are evaluated, and a zero or two signs among them is
    refused. A coefficient that vanishes only inside the box gets through, as a divisor
    does in :func:`uncertainty.uss`: the margins report such boxes as unbounded.
    """
    params = a0.parameters
    if not params:
        return
    try:
        lo, hi = a0.interval()
    except ParameterError:  # a divisor inside it whose range contains 0
        lo, hi = -np.inf, np.inf
    if lo > 0.0 or hi < 0.0:
        return
    names = list(params)
    corners = np.array(list(np.ndindex(*(2,) * len(names)))) if len(names) <= 12 else []
    rows = [[params[n].nominal for n in names]] + [
        [(params[n].low, params[n].high)[i] for n, i in zip(names, c)] for c in corners
    ]
    rows = np.array(rows, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        vals = np.broadcast_to(a0.evaluate(dict(zip(names, rows.T))), rows.shape[:1])
    bad = np.flatnonzero(~(vals > 0)) if vals[0] > 0 else np.flatnonzero(~(vals < 0))
    if bad.size:
        found = f"{vals[0]:g} at the nominal"
        if bad[0] > 0:
            at = ", ".join(f"{n}={v:g}" for n, v in zip(names, rows[bad[0]]))
            found += f" and {vals[bad[0]]:g} at {at}"
        raise ModelStructureError(
            f"uncertain transfer function: the denominator's leading coefficient "
            f"{a0._text()} is {found}: it vanishes or changes sign on the parameters' box "
            "(the order drops there); expected a leading coefficient of one sign"
        )


class UTF(Arithmetic):
    """An uncertain transfer function of one input and one output (build with :func:`tf`).

    Parameters
    ----------
    num, den : sequence of UExpr
        Coefficients of the numerator and the denominator, highest power of ``s`` first.
    inputs, outputs : str
        Signal names.
    gain : bool
        A static gain (a number or an expression lifted to a transfer function): in a
        product or sum, the other operand's signal names are kept.

    Attributes
    ----------
    num, den : tuple of UExpr
        The coefficients, highest power first, leading constant zeros removed.
    parameters : dict
        Name -> :class:`~uncertainty.parameters.UncertainParameter` of every uncertain
        real in the coefficients.
    inputs, outputs : list of str
        Signal names (one each), kept by :meth:`to_uss`.
    """

    #: numpy and uncertain expressions defer their operators to this class
    __array_ufunc__ = None
    ninputs = 1
    noutputs = 1

    def __init__(self, num, den, inputs: str = "u[0]", outputs: str = "y[0]", *, gain=False):
        self.num, self.den = _trim(num), _trim(den)
        if all(_is_zero(c) for c in self.den):
            raise ParameterError("uncertain transfer function: the denominator is zero")
        self.parameters = merge_parameters(*(c.parameters for c in self.num + self.den))
        self.inputs, self.outputs = [str(inputs)], [str(outputs)]
        self._gain = gain  # a number or an expression lifted: the other operand's names win

    def __repr__(self) -> str:
        return f"UTF(({_text(self.num)}) / ({_text(self.den)}); parameters {list(self.parameters)})"

    @property
    def order(self) -> int:
        """Degree of the denominator (the number of states of :meth:`to_uss`)."""
        return len(self.den) - 1

    def is_proper(self) -> bool:
        """Whether the numerator's degree is at most the denominator's."""
        return len(self.num) <= len(self.den)

    # -- evaluation ---------------------------------------------------------------
    def at(self, values: Mapping) -> ct.TransferFunction:
        """The member at ``values`` (name -> number; others nominal), a python-control system.

        Parameters
        ----------
        values : mapping
            Name -> number for some of :attr:`parameters`.
        """
        full = member_values(self.parameters, values, "UTF.at")
        num = [float(c.evaluate(full)) for c in self.num]
        den = [float(c.evaluate(full)) for c in self.den]
        return ct.tf(num, den, inputs=self.inputs, outputs=self.outputs)

    def nominal(self) -> ct.TransferFunction:
        """The nominal member, a python-control transfer function."""
        return self.at({})

    def to_uss(self) -> USS:
        """The uncertain state-space realisation (controllable canonical form).

        With ``den = a0 s^n + a1 s^(n-1) + ... + an`` and ``num`` padded to ``n + 1``
        coefficients ``b0 .. bn``, each divided by ``a0``: ``D = b0/a0``, the first row of
        ``A`` is ``-a1/a0 .. -an/a0`` (a shifted identity below), ``B = e1`` and
        ``C[i] = bi/a0 - D ai/a0``.

        Returns
        -------
        USS
            ``order`` states, the signal names kept.

        Raises
        ------
        robust.errors.ModelStructureError
            If the transfer function is improper, or the denominator's leading coefficient
            is uncertain and found to vanish or change sign on the parameters' box (at
            the nominal or a vertex, where the enclosure does not exclude 0): the order
            would drop there.
        """
        n, m = len(self.den) - 1, len(self.num) - 1
        if m > n:
            raise ModelStructureError(
                f"uncertain transfer function: improper (numerator of degree {m} over a "
                f"denominator of degree {n}); a realisation needs degree {m} <= {n}: add poles "
                "(e.g. a roll-off 1/(tau s + 1)) or drop numerator terms"
            )
        a0 = self.den[0]
        _check_leading(a0)
        a = [c / a0 for c in self.den[1:]]
        b = [c / a0 for c in (_ZERO,) * (n - m) + self.num]
        d = b[0]
        if n == 0:
            return uss([], [], [], [[d]], inputs=self.inputs, outputs=self.outputs)
        A = np.empty((n, n), dtype=object)
        A[:] = _ZERO
        A[0, :] = [-ai for ai in a]
        for i in range(1, n):
            A[i, i - 1] = _ONE
        B = np.array([[_ONE]] + [[_ZERO]] * (n - 1), dtype=object)
        C = np.array([[bi - d * ai for bi, ai in zip(b[1:], a)]], dtype=object)
        return uss(A, B, C, [[d]], inputs=self.inputs, outputs=self.outputs)

    # -- combination --------------------------------------------------------------
    @staticmethod
    def _lift(other, where: str) -> UTF | None:
        """``other`` as a UTF, or None for a system of other sizes (a uss, a MIMO system)."""
        if isinstance(other, UTF):
            return other
        if isinstance(other, UExpr) or _is_real(other):
            return UTF((_coef(other, where),), (_ONE,), gain=True)
        if isinstance(other, ct.StateSpace | ct.TransferFunction):
            if not other.isctime():
                raise ModelStructureError(
                    f"{where}: only continuous-time systems combine with an uncertain "
                    f"transfer function; got dt={other.dt}"
                )
            if (other.ninputs, other.noutputs) != (1, 1):
                return None
            g = other if isinstance(other, ct.TransferFunction) else ct.tf(other)
            num, den = (np.atleast_1d(np.asarray(x[0][0], float)) for x in (g.num, g.den))
            return UTF(
                [_coef(v, where) for v in num],
                [_coef(v, where) for v in den],
                other.input_labels[0],
                other.output_labels[0],
            )
        if isinstance(other, USS):
            return None
        raise ParameterError(
            f"{where}: expected a number, an uncertain expression, an uncertain system or a "
            f"python-control system; got {type(other).__name__}"
        )

    def _names(self, a: UTF, b: UTF, series: bool) -> dict:
        """Signal names of ``a op b``: a lifted gain takes the system's; a series ``a b``
        reads ``b``'s input and drives ``a``'s output."""
        if a._gain and not b._gain:
            a = b
        elif b._gain and not a._gain:
            b = a
        first = b if series else a
        return {"inputs": first.inputs[0], "outputs": a.outputs[0], "gain": a._gain and b._gain}

    def _binary(self, op: str, other, reflected: bool = False):
        o = self._lift(other, f"uncertain transfer function {op}")
        if o is None:  # a uss or a system of several signals: in state space
            if op == "/":
                raise ModelStructureError(
                    f"uncertain transfer function /: cannot divide by a "
                    f"{type(other).__name__} of {other.ninputs} inputs and "
                    f"{other.noutputs} outputs (or a uss); only by a transfer function of one "
                    "input and one output"
                )
            a, b = self.to_uss(), USS._as_uss(other, f"uncertain transfer function {op}")
            a, b = (b, a) if reflected else (a, b)
            return a + b if op == "+" else a - b if op == "-" else a * b
        a, b = (o, self) if reflected else (self, o)
        if op == "-":
            op, b = "+", -b
        if op == "+":
            if _same(a.den, b.den):
                num, den = _padd(a.num, b.num), a.den
            else:
                num, den = _padd(_pmul(a.num, b.den), _pmul(b.num, a.den)), _pmul(a.den, b.den)
        elif op == "*":
            num, den = _pmul(a.num, b.num), _pmul(a.den, b.den)
        else:
            if all(_is_zero(c) for c in b.num):
                raise ParameterError("uncertain transfer function /: division by zero")
            num, den = _pmul(a.num, b.den), _pmul(a.den, b.num)
        return UTF(num, den, **self._names(a, b, series=op in "*/"))

    def __neg__(self) -> UTF:
        return UTF(_pneg(self.num), self.den, self.inputs[0], self.outputs[0], gain=self._gain)

    def __pos__(self) -> UTF:
        return self

    def __pow__(self, k) -> UTF:
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (numbers.Integral, np.integer)):
            raise ParameterError(
                f"uncertain transfer function **: the exponent must be an integer; got {k!r}"
            )
        if k < 0:
            return 1 / (self ** (-int(k)))
        out = UTF((_ONE,), (_ONE,), self.inputs[0], self.outputs[0], gain=self._gain)
        for _ in range(int(k)):
            out = out * self
        return out

    def feedback(self, other=1, sign: int = -1):
        """The loop ``u = r + sign * other(y)`` closed around ``self`` (python-control's).

        Parameters
        ----------
        other : UTF, USS, python-control system, number or UExpr
            In the feedback path (default 1: unit feedback).
        sign : int
            -1 (negative feedback) or +1.

        Returns
        -------
        UTF or USS
            ``G / (1 - sign G H)`` as a transfer function when ``other`` is one (of one
            input and one output), else the ``uss`` of :meth:`USS.feedback`.
        """
        if isinstance(sign, bool) or sign not in (-1, 1):
            raise ParameterError(f"UTF.feedback: sign must be -1 or +1; got {sign!r}")
        h = self._lift(other, "UTF.feedback")
        if h is None:
            return self.to_uss().feedback(other, sign=sign)
        loop = _pmul(self.num, h.num)  # G H's numerator: den = d1 d2 - sign n1 n2
        den = _padd(_pmul(self.den, h.den), _pneg(loop) if sign > 0 else loop)
        return UTF(_pmul(self.num, h.den), den, self.inputs[0], self.outputs[0])


def tf(*args, inputs: str | None = None, outputs: str | None = None) -> UTF:
    """An uncertain transfer function: the Laplace variable, coefficients or a system.

    Parameters
    ----------
    *args
        ``"s"``: the Laplace variable; ``num, den``: sequences (or single values) of
        numbers and uncertain expressions (:func:`uncertainty.ureal`), highest power of
        ``s`` first, as python-control's ``tf``; a python-control system of one input
        and one output (continuous time), lifted with its signal names; a :class:`UTF`.
    inputs, outputs : str, optional
        Signal names (default ``u[0]``, ``y[0]`` or the system's own).

    Returns
    -------
    UTF

    Raises
    ------
    robust.errors.ParameterError
        If the arguments are none of the forms above, a coefficient is not a finite real
        number or an uncertain expression, or the denominator is zero.
    robust.errors.ModelStructureError
        If a python-control system is discrete-time or has several inputs or outputs
        (lift those with :func:`uncertainty.uss`).

    Examples
    --------
    A mass on a spring and a damper, force to position, each uncertain:

    >>> from uncertainty import tf, ureal, uss
    >>> m = ureal("m", 1.0, 0.8, 1.2, unit="kg")
    >>> c = ureal("c", 0.4, 0.2, 0.6, unit="N s/m")
    >>> k = ureal("k", 4.0, 3.0, 5.0, unit="N/m")
    >>> s = tf("s")
    >>> G = 1 / (m * s**2 + c * s + k)
    >>> G.order, list(G.parameters)
    (2, ['m', 'c', 'k'])
    >>> P = uss(G)  # controllable canonical form, divided by m
    >>> abs(complex(P.at({"k": 5.0})(0.0)))  # the static gain 1/k
    0.2
    """
    if len(args) == 1 and isinstance(args[0], str):
        if args[0] != "s":
            raise ParameterError(
                f"tf: the Laplace variable is 's' (continuous time only); got {args[0]!r}"
            )
        G = UTF((_ONE, _ZERO), (_ONE,))
    elif len(args) == 1 and isinstance(args[0], UTF | ct.StateSpace | ct.TransferFunction):
        G = UTF._lift(args[0], "tf")
        if G is None:
            raise ModelStructureError(
                f"tf: a system of {args[0].ninputs} inputs and {args[0].noutputs} outputs is "
                "not a transfer function of one input and one output; lift it with "
                "uncertainty.uss(sys)"
            )
    elif len(args) == 2:
        num, den = _poly("num", args[0]), _poly("den", args[1])
        G = UTF(num, den)
    else:
        raise ParameterError(
            "tf: expected 's', (num, den) or one python-control system; got "
            f"{len(args)} argument(s) of type(s) {[type(a).__name__ for a in args]}"
        )
    if inputs is None and outputs is None:
        return G
    return UTF(
        G.num,
        G.den,
        G.inputs[0] if inputs is None else inputs,
        G.outputs[0] if outputs is None else outputs,
    )


def _poly(what: str, x) -> list:
    """Coefficients of ``num`` or ``den`` of :func:`tf` (one value: a constant)."""
    arr = np.asarray(x, dtype=object) if not isinstance(x, UExpr) else np.array([x], dtype=object)
    if arr.ndim > 1 or arr.size == 0:
        raise ParameterError(
            f"tf: {what} must be a non-empty sequence of coefficients, highest power first "
            f"(one polynomial); got an array of shape {arr.shape}"
        )
    return [_coef(c, f"tf {what}[{i}]") for i, c in enumerate(np.atleast_1d(arr))]
