"""The pole region a robust margin requires, and the margin's result.

:class:`Region` is the region D every member's poles must lie in: a decay rate and,
optionally, a minimum damping ratio over a frequency band. It is the workbench's one pole
region, defined in :mod:`robust.analysis.region` (synthesis uses it too) and re-exported
here with :data:`EVERY_FREQUENCY_HZ`. Its two measures are what every part of the margin
asks of it: :meth:`Region.violation` (how far a member's poles lie outside, the objective
of the worst-case search, :mod:`uncertainty.search`) and :meth:`Region.distance_inside` (a
lower bound of each pole's distance to the edge, which the eigenvalue enclosures of the
certificate scale their splits by, :mod:`uncertainty.boxcert`). :class:`MarginResult`
holds both bounds of the robust margin, the critical member and the summaries of both
routes (:func:`uncertainty.margins.robust_margin`).

They sit in a module of their own, below the search, the enclosures and the certificates,
so that each of those (and the designs' specifications) takes them without the others.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robust.analysis.region import EVERY_FREQUENCY_HZ, Region

__all__ = ["Region", "MarginResult", "EVERY_FREQUENCY_HZ"]


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
