"""Interval matrices in midpoint-radius form: enclosures that cover a whole box of parameters.

An :class:`Interval` is a pair of arrays ``(mid, rad)`` with ``rad >= 0``: it stands
for every array ``X`` with ``|X - mid| <= rad`` entrywise. The operations return an
interval that contains every result of the operation on members of the operands
(an *enclosure*), using the midpoint-radius rules of Rump (1999):

* ``[a] + [b] = <a_m + b_m, a_r + b_r>``;
* ``[a] * [b] = <a_m b_m, |a_m| b_r + a_r |b_m| + a_r b_r>`` (entrywise);
* ``[A] @ [B] = <A_m B_m, |A_m| B_r + A_r |B_m| + A_r B_r>``;
* ``1 / [a]`` and ``[a]^2`` for intervals that do not contain 0, from the endpoints.

Floating-point rounding of the midpoints is covered by widening every result's
radius by :data:`ROUNDING` times the magnitudes involved (a few ulps, far more than
the rounding error of these short sums and products).

A :class:`Gradient` carries, next to the interval value of a quantity over a box of
parameters, interval enclosures of its partial derivatives over the same box (forward
differentiation in interval arithmetic). It gives the *mean-value form*
``f(t) in f(t_c) + sum_p (t_p - t_c,p) [df/dt_p]`` of an enclosure, whose width shrinks
quadratically with the box where the plain interval evaluation shrinks linearly
(Moore, Kearfott & Cloud, *Introduction to Interval Analysis*, SIAM 2009, Sec. 6.4).

S. M. Rump, "Fast and parallel interval arithmetic", BIT 39(3):534-554, 1999.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robust.errors import ParameterError

__all__ = ["Interval", "Gradient", "ROUNDING", "norm2_bound", "imatrix", "ivstack", "iblockdiag"]

#: Relative widening of every result radius, covering floating-point rounding.
ROUNDING = 8 * np.finfo(float).eps
#: The smallest normal float, added to every radius (so that no radius is 0 after rounding).
_TINY = np.finfo(float).tiny


def _widen(mid: np.ndarray, rad: np.ndarray, scale: np.ndarray) -> np.ndarray:
    out = rad + ROUNDING * (np.abs(mid) + scale) + _TINY
    if not np.isfinite(out).all():
        raise ParameterError("Interval: an operation overflowed (result not finite)")
    return out


@dataclasses.dataclass(frozen=True)
class Interval:
    """An interval array ``{X : |X - mid| <= rad}`` (entrywise).

    Parameters
    ----------
    mid : array_like
        Midpoint.
    rad : array_like
        Radius (>= 0, the shape of ``mid`` or broadcastable to it).
    """

    mid: np.ndarray
    rad: np.ndarray

    #: numpy defers binary operators to this class (``ndarray @ Interval``)
    __array_ufunc__ = None

    def __post_init__(self):
        mid = np.asarray(self.mid, float)
        rad = np.broadcast_to(np.asarray(self.rad, float), mid.shape).copy()
        if not (np.all(np.isfinite(mid)) and np.all(np.isfinite(rad))):
            raise ParameterError("Interval: midpoint and radius must be finite")
        if np.any(rad < 0):
            raise ParameterError("Interval: radius must be >= 0")
        object.__setattr__(self, "mid", mid)
        object.__setattr__(self, "rad", rad)

    @classmethod
    def _raw(cls, mid: np.ndarray, rad: np.ndarray) -> Interval:
        """An interval from arrays already known to be valid (results of the operations)."""
        out = object.__new__(cls)
        object.__setattr__(out, "mid", mid)
        object.__setattr__(out, "rad", rad)
        return out

    @classmethod
    def point(cls, x) -> Interval:
        """The degenerate interval ``[x, x]``.

        Parameters
        ----------
        x : array_like
            The value.
        """
        x = np.asarray(x, float)
        if not np.isfinite(x).all():
            raise ParameterError("Interval: midpoint and radius must be finite")
        return cls._raw(x, np.zeros_like(x))

    @classmethod
    def hull(cls, lo, hi) -> Interval:
        """The interval ``[lo, hi]``.

        Parameters
        ----------
        lo, hi : array_like
            Bounds, ``lo <= hi``.
        """
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        if (lo > hi).any():
            raise ParameterError("Interval.hull: need lo <= hi")
        mid = (lo + hi) / 2
        rad = np.broadcast_to((hi - lo) / 2, mid.shape).copy()
        # (the checks of the constructor, on arrays of the right type and shape already;
        # a radius is >= 0 once lo <= hi holds and both are finite)
        if not (np.isfinite(mid).all() and np.isfinite(rad).all()):
            raise ParameterError("Interval: midpoint and radius must be finite")
        return cls._raw(mid, rad)

    @property
    def lo(self) -> np.ndarray:
        """Lower bound."""
        return self.mid - self.rad

    @property
    def hi(self) -> np.ndarray:
        """Upper bound."""
        return self.mid + self.rad

    @property
    def shape(self) -> tuple:
        """Shape of the arrays."""
        return self.mid.shape

    def contains(self, x) -> bool:
        """Whether the array ``x`` lies in the interval.

        Parameters
        ----------
        x : array_like
            An array of the interval's shape.
        """
        return bool(np.all(np.abs(np.asarray(x, float) - self.mid) <= self.rad))

    @staticmethod
    def _as(x) -> Interval:
        if isinstance(x, Interval):
            return x
        arr = np.asarray(x, float)
        if not np.isfinite(arr).all():
            raise ParameterError("Interval: midpoint and radius must be finite")
        return Interval._raw(arr, np.zeros_like(arr))

    def __add__(self, other) -> Interval:
        if isinstance(other, Gradient):
            return NotImplemented
        o = self._as(other)
        mid = self.mid + o.mid
        return Interval._raw(mid, _widen(mid, self.rad + o.rad, 0.0))

    __radd__ = __add__

    def __neg__(self) -> Interval:
        return Interval._raw(-self.mid, self.rad)

    def __sub__(self, other) -> Interval:
        if isinstance(other, Gradient):
            return NotImplemented
        return self + (-self._as(other))

    def __rsub__(self, other) -> Interval:
        return self._as(other) + (-self)

    def __mul__(self, other) -> Interval:
        if isinstance(other, Gradient):
            return NotImplemented
        o = self._as(other)
        mid = self.mid * o.mid
        rad = np.abs(self.mid) * o.rad + self.rad * np.abs(o.mid) + self.rad * o.rad
        return Interval._raw(mid, _widen(mid, rad, 0.0))

    __rmul__ = __mul__

    def __matmul__(self, other) -> Interval:
        if isinstance(other, Gradient):
            return NotImplemented
        o = self._as(other)
        mid = self.mid @ o.mid
        rad = np.abs(self.mid) @ o.rad + self.rad @ np.abs(o.mid) + self.rad @ o.rad
        return Interval._raw(mid, _widen(mid, rad, np.abs(self.mid) @ np.abs(o.mid)))

    def __rmatmul__(self, other) -> Interval:
        return self._as(other) @ self

    def reciprocal(self) -> Interval:
        """``1 / [x]`` for an interval that does not contain 0."""
        lo, hi = self.lo, self.hi
        if np.any((lo <= 0) & (hi >= 0)):
            raise ParameterError("Interval.reciprocal: the interval contains 0")
        a, b = 1.0 / hi, 1.0 / lo
        out = Interval.hull(np.minimum(a, b), np.maximum(a, b))
        return Interval._raw(out.mid, _widen(out.mid, out.rad, 0.0))

    def __truediv__(self, other) -> Interval:
        return self * self._as(other).reciprocal()

    def square(self) -> Interval:
        """``[x]^2`` (tight: the square of an interval containing 0 starts at 0)."""
        lo, hi = self.lo, self.hi
        a, b = lo * lo, hi * hi
        low = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(a, b))
        out = Interval.hull(low, np.maximum(a, b))
        return Interval._raw(out.mid, _widen(out.mid, out.rad, 0.0))

    def __getitem__(self, key) -> Interval:
        return Interval._raw(self.mid[key], self.rad[key])


def norm2_bound(rad) -> float:
    """Upper bound of ``||E||_2`` over every ``E`` with ``|E| <= rad`` entrywise.

    ``||E||_2 <= || |E| ||_2 <= ||rad||_2`` (the spectral norm is monotone on
    nonnegative matrices), widened for rounding.

    Parameters
    ----------
    rad : array_like, shape (n, m)
        Entrywise bound, >= 0.
    """
    r = np.asarray(rad, float)
    if r.size == 0:
        return 0.0
    return float(np.linalg.norm(r, 2) * (1 + 1e-12) + _TINY)


def _lift(x: Interval, ndim: int) -> Interval:
    """A derivative array ``(d,) + S`` with singleton axes inserted after the first so that
    it broadcasts against values of ``ndim`` dimensions."""
    extra = ndim - (x.mid.ndim - 1)
    if extra <= 0:
        return x
    shape = x.mid.shape[:1] + (1,) * extra + x.mid.shape[1:]
    return Interval._raw(x.mid.reshape(shape), x.rad.reshape(shape))


@dataclasses.dataclass(frozen=True)
class Gradient:
    """An interval value and interval enclosures of its ``d`` partial derivatives.

    ``val`` encloses the quantity over a box of parameters ``t``; ``der[p]`` encloses
    its derivative with respect to ``t_p`` over the same box. The operations follow
    the rules of differentiation with every factor replaced by its enclosure over the
    box, so the results enclose the derivatives at every point of the box.

    Parameters
    ----------
    val : Interval
        Value, shape ``S``.
    der : Interval
        Derivatives, shape ``(d,) + S``.
    """

    val: Interval
    der: Interval

    __array_ufunc__ = None

    @classmethod
    def variable(cls, lo: float, hi: float, index: int, d: int, dvalue=None) -> Gradient:
        """The parameter ``t_index`` over ``[lo, hi]`` (or a function of it).

        Parameters
        ----------
        lo, hi : float
            Range of the value.
        index : int
            Which of the ``d`` parameters it depends on.
        d : int
            Number of parameters.
        dvalue : Interval, optional
            Enclosure of the derivative over the range (default 1: the parameter itself).
        """
        mid, rad = np.zeros(d), np.zeros(d)
        dv = Interval.point(1.0) if dvalue is None else dvalue
        mid[index], rad[index] = float(dv.mid), float(dv.rad)
        return cls(Interval.hull(lo, hi), Interval._raw(mid, rad))

    @property
    def shape(self) -> tuple:
        """Shape of the value."""
        return self.val.shape

    @staticmethod
    def _parts(x, d):
        if isinstance(x, Gradient):
            return x.val, x.der
        v = Interval._as(x)
        zero = np.zeros((d,) + v.shape)
        return v, Interval._raw(zero, np.zeros_like(zero))

    def _d(self):
        return self.der.mid.shape[0]

    def __add__(self, other) -> Gradient:
        ov, od = self._parts(other, self._d())
        nd = max(self.val.mid.ndim, ov.mid.ndim)
        return Gradient(self.val + ov, _lift(self.der, nd) + _lift(od, nd))

    __radd__ = __add__

    def __neg__(self) -> Gradient:
        return Gradient(-self.val, -self.der)

    def __sub__(self, other) -> Gradient:
        return self + (-other if isinstance(other, Gradient) else -Interval._as(other))

    def __rsub__(self, other) -> Gradient:
        return (-self) + other

    def __mul__(self, other) -> Gradient:
        ov, od = self._parts(other, self._d())
        nd = max(self.val.mid.ndim, ov.mid.ndim)
        der = _lift(self.der, nd) * ov + self.val * _lift(od, nd)
        return Gradient(self.val * ov, der)

    __rmul__ = __mul__

    def __matmul__(self, other) -> Gradient:
        ov, od = self._parts(other, self._d())
        return Gradient(self.val @ ov, self.der @ ov + self.val @ od)

    def __rmatmul__(self, other) -> Gradient:
        ov, od = self._parts(other, self._d())
        return Gradient(ov @ self.val, od @ self.val + ov @ self.der)

    def square(self) -> Gradient:
        """``x^2`` (derivative ``2 x x'``)."""
        return Gradient(self.val.square(), 2.0 * (self.val * self.der))

    def reciprocal(self) -> Gradient:
        """``1 / x`` for a value that does not contain 0 (derivative ``-x' / x^2``)."""
        inv = self.val.reciprocal()
        return Gradient(inv, -(inv.square() * self.der))

    def __truediv__(self, other) -> Gradient:
        o = other if isinstance(other, Gradient) else Interval._as(other)
        return self * o.reciprocal()

    def __getitem__(self, key) -> Gradient:
        k = key if isinstance(key, tuple) else (key,)
        return Gradient(self.val[key], self.der[(slice(None),) + k])


def imatrix(rows) -> Interval | Gradient:
    """A matrix from nested lists of scalars (numbers, Interval or Gradient scalars).

    Parameters
    ----------
    rows : list of list
        The entries, row by row.
    """
    flat = [x for r in rows for x in r]
    grads = [x for x in flat if isinstance(x, Gradient)]
    shape = (len(rows), len(rows[0]) if rows else 0)

    def vals(xs):
        mid, rad = np.empty(len(xs)), np.zeros(len(xs))
        for k, x in enumerate(xs):
            v = x.val if isinstance(x, Gradient) else x
            if isinstance(v, Interval):
                mid[k], rad[k] = v.mid, v.rad
            else:
                mid[k] = v
        if not np.isfinite(mid).all():
            raise ParameterError("imatrix: entries must be finite")
        return Interval._raw(mid.reshape(shape), rad.reshape(shape))

    value = vals(flat)
    if not grads:
        return value
    d = grads[0].der.mid.shape[0]
    dm, dr = np.zeros((d,) + shape), np.zeros((d,) + shape)
    for k, x in enumerate(flat):
        if isinstance(x, Gradient):
            i, j = divmod(k, shape[1])
            dm[:, i, j], dr[:, i, j] = x.der.mid.reshape(d), x.der.rad.reshape(d)
    return Gradient(value, Interval._raw(dm, dr))


def _combine(items, fn_mid):
    grads = [x for x in items if isinstance(x, Gradient)]
    vals = [x.val if isinstance(x, Gradient) else Interval._as(x) for x in items]
    value = Interval._raw(fn_mid([v.mid for v in vals]), fn_mid([v.rad for v in vals]))
    if not grads:
        return value
    d = grads[0].der.mid.shape[0]
    ders = [
        x.der if isinstance(x, Gradient) else Interval._raw(*(np.zeros((d,) + v.shape),) * 2)
        for x, v in zip(items, vals)
    ]
    return Gradient(
        value, Interval._raw(fn_mid([q.mid for q in ders]), fn_mid([q.rad for q in ders]))
    )


def _vstack_last(arrays):
    """Stack along the second-to-last axis (rows), leading axes broadcast alike."""
    return np.concatenate(arrays, axis=-2)


def _blockdiag_last(arrays):
    """Block diagonal over the last two axes, leading axes alike."""
    lead = arrays[0].shape[:-2]
    rows = sum(a.shape[-2] for a in arrays)
    cols = sum(a.shape[-1] for a in arrays)
    out = np.zeros(lead + (rows, cols))
    r = c = 0
    for a in arrays:
        out[..., r : r + a.shape[-2], c : c + a.shape[-1]] = a
        r, c = r + a.shape[-2], c + a.shape[-1]
    return out


def ivstack(items) -> Interval | Gradient:
    """Rows stacked (Interval or Gradient matrices).

    Parameters
    ----------
    items : list
        Matrices with the same number of columns.
    """
    return _combine(list(items), _vstack_last)


def iblockdiag(items) -> Interval | Gradient:
    """Block-diagonal matrix of Interval or Gradient blocks (zero off the blocks).

    Parameters
    ----------
    items : list
        The diagonal blocks.
    """
    return _combine(list(items), _blockdiag_last)
