"""Uncertain parameters: a name, a nominal value, bounds, a distribution, units and a source.

An :class:`UncertainParameter` is a small frozen value. It maps unit-interval
numbers to values through its inverse distribution function (:meth:`ppf`), which
is all the samplers of :mod:`uncertainty.sampling` need: Monte Carlo draws uniform
numbers, Latin hypercube stratifies them, a grid spaces them evenly and box
vertices take 0 and 1.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats

from robust.checks import POSITIVE, Spec, check_array, check_scalar
from robust.errors import ParameterError

__all__ = ["BOUNDS_RTOL", "DISTRIBUTIONS", "UncertainParameter"]

#: Relative tolerance of the bounds check of member values: a value within
#: ``BOUNDS_RTOL * max(|low|, |high|)`` of the family's range counts as inside it (values
#: rebuilt from rounded text or as ``scale * nominal`` land a few ulps outside).
BOUNDS_RTOL = 1e-9

#: Supported distributions.
DISTRIBUTIONS = ("uniform", "loguniform", "truncnormal")
_UNIT = Spec(low=0.0, high=1.0)


@dataclasses.dataclass(frozen=True)
class UncertainParameter:
    """One uncertain physical parameter.

    Parameters
    ----------
    name : str
        Dotted name (for a model parameter, :func:`backhoe.model.blocks.parameter_name`);
        used in reports and as the key of
        worst-case parameters.
    nominal : float
        Nominal value, within ``[low, high]``.
    low, high : float
        Bounds, ``low < high``; strictly positive for ``"loguniform"``.
    distribution : str
        ``"uniform"``, ``"loguniform"`` (uniform in log) or ``"truncnormal"``
        (normal around ``nominal`` with standard deviation ``std``, truncated to
        the bounds).
    units : str
        Units of the value (``"N/m"``, ``"Hz"``, ``"-"``).
    source : str
        One line: where the nominal and the range come from.
    std : float, optional
        Standard deviation of ``"truncnormal"`` (default ``(high - low) / 4``);
        must be left unset for the other distributions.

    Raises
    ------
    ParameterError
        (a ``ValueError``) naming the parameter: NaN or infinite values, inverted
        bounds, nominal outside the bounds, non-positive bound of a log-uniform
        parameter, unknown distribution.
    """

    name: str
    nominal: float
    low: float
    high: float
    distribution: str = "uniform"
    units: str = ""
    source: str = ""
    std: float | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(
                f"UncertainParameter.name must be a non-empty string; got {self.name!r}"
            )
        owner = f"UncertainParameter {self.name!r}"
        for field in ("units", "source"):
            if not isinstance(getattr(self, field), str):
                raise ParameterError(
                    f"{owner}: {field} must be a string; got {type(getattr(self, field)).__name__}"
                )
        for field in ("nominal", "low", "high"):
            object.__setattr__(self, field, check_scalar(field, getattr(self, field), owner=owner))
        if self.distribution not in DISTRIBUTIONS:
            raise ParameterError(
                f"{owner}: distribution must be one of {DISTRIBUTIONS}; got {self.distribution!r}"
            )
        if not self.low < self.high:
            raise ParameterError(
                f"{owner}: bounds must satisfy low < high; got low={self.low!r}, high={self.high!r}"
            )
        if not self.low <= self.nominal <= self.high:
            raise ParameterError(
                f"{owner}: nominal must lie in [low, high] = [{self.low!r}, {self.high!r}]; "
                f"got {self.nominal!r}"
            )
        if self.distribution == "loguniform" and self.low <= 0.0:
            raise ParameterError(
                f"{owner}: a log-uniform parameter needs low > 0; got low={self.low!r}"
            )
        if self.std is not None:
            if self.distribution != "truncnormal":
                raise ParameterError(
                    f"{owner}: std applies only to 'truncnormal'; got std={self.std!r} "
                    f"with distribution {self.distribution!r}"
                )
            object.__setattr__(self, "std", check_scalar("std", self.std, POSITIVE, owner=owner))

    @property
    def sigma(self) -> float:
        """Standard deviation used by ``"truncnormal"`` (``std`` or ``(high - low) / 4``)."""
        return self.std if self.std is not None else (self.high - self.low) / 4.0

    def ppf(self, u) -> np.ndarray:
        """Values at unit-interval quantiles ``u`` (the inverse distribution function).

        Parameters
        ----------
        u : array_like
            Quantiles, any shape, entries in [0, 1] (0 maps to ``low``, 1 to
            ``high``).

        Returns
        -------
        numpy.ndarray
            Parameter values in the parameter's units, the shape of ``u``, clipped
            to ``[low, high]``.

        Raises
        ------
        ParameterError
            If an entry of ``u`` is not numeric, non-finite or outside [0, 1].
        """
        u = check_array(f"UncertainParameter {self.name!r}: ppf quantile u", u, _UNIT)
        if self.distribution == "uniform":
            x = self.low + u * (self.high - self.low)
        elif self.distribution == "loguniform":
            lo, hi = math.log(self.low), math.log(self.high)
            x = np.exp(lo + u * (hi - lo))
        else:
            s = self.sigma
            a, b = (self.low - self.nominal) / s, (self.high - self.nominal) / s
            x = stats.truncnorm.ppf(u, a, b, loc=self.nominal, scale=s)
        return np.clip(x, self.low, self.high)

    def describe(self) -> dict:
        """JSON-ready description: every field, with ``std`` resolved for ``"truncnormal"``."""
        d = dataclasses.asdict(self)
        if self.distribution == "truncnormal":
            d["std"] = self.sigma
        return d
