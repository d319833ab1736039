"""The pole region a robust margin requires, and the margin's result.

:class:`Region` is the region D every member's poles must lie in: a decay rate and,
optionally, a minimum damping ratio over a frequency band. Its two measures are what every
part of the margin asks of it: :meth:`Region.violation` (how far a member's poles lie
outside, the objective of the worst-case search, :mod:`uncertainty.search`) and
:meth:`Region.distance_inside` (a lower bound of each pole's distance to the edge, which the
eigenvalue enclosures of the certificate scale their splits by, :mod:`uncertainty.boxcert`).
:class:`MarginResult` holds both bounds of the robust margin, the critical member and the
summaries of both routes (:func:`uncertainty.margins.robust_margin`).

They sit in a module of their own, below the search, the enclosures and the certificates,
so that each of those (and the designs' specifications) takes them without the others.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from robust.analysis.stability import STABILITY_TOL, in_band
from robust.errors import ParameterError

__all__ = ["Region", "MarginResult", "EVERY_FREQUENCY_HZ"]

#: The damping band of a user's own system by default: every pole, whatever its frequency
#: (the BDFT family's default is :data:`robust.analysis.stability.DAMPING_BAND_HZ`).
EVERY_FREQUENCY_HZ = (0.0, math.inf)


@dataclasses.dataclass(frozen=True)
class Region:
    """The required pole region D.

    Parameters
    ----------
    decay_rate : float
        Every pole must have real part below ``-decay_rate`` (rad/s; 0: the open left
        half-plane, within :data:`robust.analysis.stability.STABILITY_TOL`).
    min_damping : float
        Poles whose frequency ``|Im p| / (2 pi)`` lies in ``band_hz`` must have damping
        ratio ``-Re p / |p|`` of at least this (0: no requirement).
    band_hz : (float, float) or None
        The band of the damping requirement, Hz (``high`` may be ``inf``). None (default):
        the default band of what is analysed, set by the margin functions
        (:meth:`with_default_band`): the BDFT band
        (:data:`robust.analysis.stability.DAMPING_BAND_HZ`, 0.5-10 Hz) for the BDFT
        family, every frequency (:data:`EVERY_FREQUENCY_HZ`) for a user's own system.
    """

    decay_rate: float = 0.0
    min_damping: float = 0.0
    band_hz: tuple[float, float] | None = None

    def __post_init__(self):
        a, z = float(self.decay_rate), float(self.min_damping)
        if not (math.isfinite(a) and a >= 0):
            raise ParameterError(f"Region.decay_rate must be a finite value >= 0; got {a!r}")
        if not (math.isfinite(z) and 0 <= z < 1):
            raise ParameterError(f"Region.min_damping must be in [0, 1); got {z!r}")
        object.__setattr__(self, "decay_rate", a)
        object.__setattr__(self, "min_damping", z)
        if self.band_hz is None:
            return
        lo, hi = (float(b) for b in self.band_hz)
        if not (math.isfinite(lo) and 0 <= lo < hi):
            raise ParameterError(
                f"Region.band_hz must satisfy 0 <= low < high; got {self.band_hz} (high may be "
                "inf; None: the default band of what is analysed)"
            )
        object.__setattr__(self, "band_hz", (lo, hi))

    def with_default_band(self, band_hz) -> Region:
        """This region, its band ``band_hz`` if it was left to the default (None).

        Parameters
        ----------
        band_hz : (float, float)
            The default band of what is analysed, Hz.
        """
        return self if self.band_hz is not None else dataclasses.replace(self, band_hz=band_hz)

    def _band(self) -> tuple[float, float]:
        if self.band_hz is None:
            raise ParameterError(
                "Region: the damping band was left to the default of what is analysed; "
                "give band_hz or resolve it with Region.with_default_band"
            )
        return self.band_hz

    @classmethod
    def parse(cls, text: str) -> Region:
        """A region from its command-line form.

        ``lhp`` (the open left half-plane), ``decay:A`` (real parts below ``-A``
        rad/s), ``damping:Z`` or ``damping:Z@LO-HI`` (damping ratio at least ``Z`` for
        poles in ``LO-HI`` Hz, ``HI`` may be ``inf``; without a band, the default of what
        is analysed: 0.5-10 Hz for the BDFT family, every frequency for a user's own
        system), joined by ``,`` (e.g. ``decay:0.1,damping:0.1``).

        Parameters
        ----------
        text : str
            The region, e.g. ``"decay:0.3"``.
        """
        kw = {}
        for part in str(text).split(","):
            part = part.strip()
            try:
                if part == "lhp":
                    continue
                key, _, val = part.partition(":")
                if key == "decay":
                    kw["decay_rate"] = float(val)
                elif key == "damping":
                    z, _, band = val.partition("@")
                    kw["min_damping"] = float(z)
                    if band:
                        lo, _, hi = band.partition("-")
                        kw["band_hz"] = (float(lo), float(hi))
                else:
                    raise ValueError(key)
            except ValueError:
                raise ParameterError(
                    f"region: expected 'lhp', 'decay:A', 'damping:Z' or 'damping:Z@LO-HI' "
                    f"(comma-separated); got {part!r}"
                ) from None
        return cls(**kw)

    def describe(self) -> str:
        """The region in words."""
        parts = [
            f"real parts below -{self.decay_rate:g} rad/s"
            if self.decay_rate > 0
            else "open left half-plane"
        ]
        if self.min_damping > 0:
            band = self.band_hz
            where = (
                "in the default band"
                if band is None
                else "at every frequency"
                if band == EVERY_FREQUENCY_HZ
                else f"in {band[0]:g}-{band[1]:g} Hz"
            )
            parts.append(f"damping ratio >= {self.min_damping:g} for poles {where}")
        return "; ".join(parts)

    def distance_inside(self, poles) -> np.ndarray:
        """A lower bound of each pole's distance to the region's edge (<= 0: outside).

        The distance to the line ``Re s = -max(decay_rate, STABILITY_TOL)`` and, with a
        damping requirement, to the cone ``Re s = -min_damping |s|`` (for every pole,
        inside the band or not: a lower bound).

        Parameters
        ----------
        poles : array_like of complex
            Poles, rad/s.
        """
        p = np.asarray(poles, complex).ravel()
        d = -(p.real + max(self.decay_rate, STABILITY_TOL))
        if self.min_damping > 0:
            theta = math.acos(self.min_damping)
            phi = np.arctan2(np.abs(p.imag), -p.real)
            d = np.minimum(d, np.abs(p) * np.sin(np.clip(theta - phi, -np.pi / 2, np.pi / 2)))
        return d

    def violation(self, poles: np.ndarray) -> np.ndarray:
        """Largest violation of the region per member, rad/s (> 0: outside the region).

        ``max(Re p + max(decay_rate, STABILITY_TOL))`` over the poles and, with a damping
        requirement, ``max(Re p + min_damping |p|)`` over the poles in the band.

        Parameters
        ----------
        poles : ndarray, shape (N, n)
            Poles of ``N`` members, rad/s.
        """
        p = np.atleast_2d(np.asarray(poles))
        v = p.real.max(axis=1) + max(self.decay_rate, STABILITY_TOL)
        if self.min_damping > 0:
            d = np.where(in_band(p, self._band()), p.real + self.min_damping * np.abs(p), -np.inf)
            v = np.maximum(v, d.max(axis=1))
        return v


@dataclasses.dataclass(frozen=True)
class MarginResult:
    """Bounds of the robust margin ``k_m`` and the member that breaks the loop.

    Parameters
    ----------
    lower : float
        Certified lower bound (0 if not even the nominal member is certified).
    upper : float
        Upper bound: a member violating the region exists at this scale (``inf`` if
        none was found up to the search limit).
    critical : dict or None
        The violating member at ``upper``: ``parameters`` (name -> value), ``poles``
        (complex, python-control), ``violation`` (rad/s).
    region : Region
        The required region.
    method : dict
        Methods of both bounds, their assumptions and enclosures.
    certificate : dict
        Summary of the lower bound's certificate: sub-boxes certified, by which route
        (Lyapunov/Patel-Toda or LMI), the largest independent-check eigenvalue, and the
        bisection history.
    search : dict
        Summary of the upper bound's search: samples, seed, local starts, bisection.
    timings_s : dict
        Wall-clock seconds of each bound (run information, not part of the result's
        numbers).
    """

    lower: float
    upper: float
    critical: dict | None
    region: Region
    method: dict
    certificate: dict
    search: dict
    timings_s: dict

    def __str__(self) -> str:
        text = (
            f"robust margin in [{self.lower:.4g}, {self.upper:.4g}] for the "
            f"{self.region.describe()} (lower: {self.certificate.get('method', '?')})"
        )
        crit = self.critical
        if crit is None:
            return text + "; no violating member found"
        params = ", ".join(f"{k}={v:.4g}" for k, v in crit["parameters"].items())
        poles = np.asarray(crit["poles"])
        worst = ""
        if poles.size:
            p = poles[int(np.argmax(poles.real))]
            worst = f", rightmost pole {p.real:.4g}{p.imag:+.4g}j"
        return f"{text}; critical member {params}{worst}"

    def to_json(self) -> dict:
        """JSON-ready dict (poles as ``{"re", "im"}`` pairs)."""
        crit = None
        if self.critical is not None:
            crit = dict(self.critical)
            crit["poles"] = [{"re": float(p.real), "im": float(p.imag)} for p in crit["poles"]]
        return {
            "lower": self.lower,
            "upper": self.upper,
            "critical": crit,
            "region": dict(dataclasses.asdict(self.region), text=self.region.describe()),
            "method": self.method,
            "certificate": self.certificate,
            "search": self.search,
            "timings_s": self.timings_s,
        }
