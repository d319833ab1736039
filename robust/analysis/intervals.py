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

S. M. Rump, "Fast and parallel interval arithmetic", BIT 39(3):534-554, 1999.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robust.errors import ParameterError

__all__ = ["Interval", "ROUNDING", "norm2_bound"]

#: Relative widening of every result radius, covering floating-point rounding.
ROUNDING = 8 * np.finfo(float).eps


def _widen(mid: np.ndarray, rad: np.ndarray, scale: np.ndarray) -> np.ndarray:
    return rad + ROUNDING * (np.abs(mid) + scale) + np.finfo(float).tiny


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
    def point(cls, x) -> Interval:
        """The degenerate interval ``[x, x]``.

        Parameters
        ----------
        x : array_like
            The value.
        """
        x = np.asarray(x, float)
        return cls(x, np.zeros_like(x))

    @classmethod
    def hull(cls, lo, hi) -> Interval:
        """The interval ``[lo, hi]``.

        Parameters
        ----------
        lo, hi : array_like
            Bounds, ``lo <= hi``.
        """
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        if np.any(lo > hi):
            raise ParameterError("Interval.hull: need lo <= hi")
        return cls((lo + hi) / 2, (hi - lo) / 2)

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
        return x if isinstance(x, Interval) else Interval.point(x)

    def __add__(self, other) -> Interval:
        o = self._as(other)
        mid = self.mid + o.mid
        return Interval(mid, _widen(mid, self.rad + o.rad, 0.0))

    __radd__ = __add__

    def __neg__(self) -> Interval:
        return Interval(-self.mid, self.rad)

    def __sub__(self, other) -> Interval:
        return self + (-self._as(other))

    def __rsub__(self, other) -> Interval:
        return self._as(other) + (-self)

    def __mul__(self, other) -> Interval:
        o = self._as(other)
        mid = self.mid * o.mid
        rad = np.abs(self.mid) * o.rad + self.rad * np.abs(o.mid) + self.rad * o.rad
        return Interval(mid, _widen(mid, rad, 0.0))

    __rmul__ = __mul__

    def __matmul__(self, other) -> Interval:
        o = self._as(other)
        mid = self.mid @ o.mid
        rad = np.abs(self.mid) @ o.rad + self.rad @ np.abs(o.mid) + self.rad @ o.rad
        return Interval(mid, _widen(mid, rad, np.abs(self.mid) @ np.abs(o.mid)))

    def __rmatmul__(self, other) -> Interval:
        return self._as(other) @ self

    def reciprocal(self) -> Interval:
        """``1 / [x]`` for an interval that does not contain 0."""
        lo, hi = self.lo, self.hi
        if np.any((lo <= 0) & (hi >= 0)):
            raise ParameterError("Interval.reciprocal: the interval contains 0")
        a, b = 1.0 / hi, 1.0 / lo
        out = Interval.hull(np.minimum(a, b), np.maximum(a, b))
        return Interval(out.mid, _widen(out.mid, out.rad, 0.0))

    def __truediv__(self, other) -> Interval:
        return self * self._as(other).reciprocal()

    def square(self) -> Interval:
        """``[x]^2`` (tight: the square of an interval containing 0 starts at 0)."""
        lo, hi = self.lo, self.hi
        a, b = lo * lo, hi * hi
        low = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(a, b))
        out = Interval.hull(low, np.maximum(a, b))
        return Interval(out.mid, _widen(out.mid, out.rad, 0.0))

    def __getitem__(self, key) -> Interval:
        return Interval(self.mid[key], self.rad[key])


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
    return float(np.linalg.norm(r, 2) * (1 + 1e-12) + np.finfo(float).tiny)
