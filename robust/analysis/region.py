"""The pole region D: a decay rate and a damping requirement, optionally over a band.

:class:`Region` is the one pole region of the workbench: every pole's real part below
``-decay_rate`` and, for the poles whose frequency ``|Im p| / (2 pi)`` lies in a band, a
damping ratio of at least ``min_damping``. The band is an option: ``None`` leaves it to
what is analysed (:meth:`Region.with_default_band`), :data:`EVERY_FREQUENCY_HZ` asks the
damping of every pole.

Its measures are what the margins and the synthesis ask of it:

* :meth:`Region.violation`, per member (rows of poles), how far the poles lie outside with
  the decay line kept at least :data:`robust.analysis.stability.STABILITY_TOL` left of the
  imaginary axis: the worst-case search's objective (:mod:`uncertainty.search`);
* :meth:`Region.distance_inside`, a lower bound of each pole's distance to the edge, which
  the eigenvalue enclosures of the certificates scale their splits by
  (:mod:`uncertainty.boxcert`);
* :meth:`Region.violations` and :meth:`Region.worst_violation`, per pole and the largest,
  the exact region without a tolerance: the synthesis' objectives and checks
  (:mod:`robust.synthesis.region`, :mod:`robust.synthesis.pk`,
  :mod:`robust.synthesis.tuning`).

The LMI regions of synthesis (Chilali & Gahinet 1996) are convex: a damping cone cannot be
asked of one band only. Synthesis therefore enforces a band-limited region at every
frequency (:meth:`Region.everywhere`), conservatively, and the analyses check it exactly
in its band.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from robust.analysis.stability import STABILITY_TOL, in_band
from robust.errors import ParameterError

__all__ = ["Region", "EVERY_FREQUENCY_HZ"]


#: Every pole, whatever its frequency: the damping band of a user's own system by default
#: and the one synthesis enforces (the BDFT family's default is
#: :data:`backhoe.constants.DAMPING_BAND_HZ`).
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
        (:data:`backhoe.constants.DAMPING_BAND_HZ`, 0.5-10 Hz) for the BDFT
        family, every frequency (:data:`EVERY_FREQUENCY_HZ`) for a user's own system.
        Synthesis enforces the damping at every frequency whatever the band
        (:meth:`everywhere`; module notes).
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

    def everywhere(self) -> Region:
        """This region with its damping required of every pole (:data:`EVERY_FREQUENCY_HZ`).

        What synthesis enforces: the LMI cone holds for every pole, whatever the band (a
        band-limited region is enforced at every frequency, conservatively).
        """
        if self.band_hz == EVERY_FREQUENCY_HZ:
            return self
        return dataclasses.replace(self, band_hz=EVERY_FREQUENCY_HZ)

    def scaled(self, w0: float) -> Region:
        """The same region in time ``tau = w0 t``: the decay rate and the band divided by
        ``w0``.

        Parameters
        ----------
        w0 : float
            Time scale, rad/s.
        """
        band = None if self.band_hz is None else tuple(b / w0 for b in self.band_hz)
        return Region(self.decay_rate / w0, self.min_damping, band)

    @property
    def cone(self) -> tuple[float, float]:
        """``(sin theta, cos theta)`` of the damping cone's half-angle ``theta = arccos(zeta)``."""
        th = math.acos(self.min_damping)
        return math.sin(th), math.cos(th)

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

    def violations(self, poles) -> np.ndarray:
        """Per pole, ``max(Re p + decay_rate, Re p + min_damping |p|)``, the second term only
        for a pole in the band (``<= 0``: inside; no tolerance), rad/s.

        Parameters
        ----------
        poles : array_like of complex
            Poles, rad/s.
        """
        p = np.asarray(poles, complex).ravel()
        v = p.real + self.decay_rate
        if self.min_damping > 0:
            d = p.real + self.min_damping * np.abs(p)
            v = np.maximum(v, np.where(in_band(p, self._band()), d, -np.inf))
        return v

    def worst_violation(self, poles) -> float:
        """Largest of :meth:`violations` (``-inf`` without poles), rad/s.

        Parameters
        ----------
        poles : array_like of complex
            Poles, rad/s.
        """
        v = self.violations(poles)
        return float(v.max()) if v.size else -math.inf

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
