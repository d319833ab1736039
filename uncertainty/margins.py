"""Robust stability margins of a family: a certified lower bound, an upper bound and the
member that breaks the loop.

Definitions
-----------
The family's box is scaled about its nominal by a factor ``k``, each parameter in
its own coordinates (log for log-uniform, linear otherwise): the scaled range of a
parameter is ``t_nom + k (t_low - t_nom) .. t_nom + k (t_high - t_nom)``. ``k = 1`` is
the family itself, ``k = 0`` the nominal member. The *robust margin* ``k_m`` of a
closed loop (with or without a controller) is the largest ``k`` for which every
member's poles lie in the required region :class:`Region` (a decay rate, optionally a
minimum damping ratio over a frequency band). ``k_m >= 1`` means the whole family
meets the region. Scaled linear ranges are kept physical: a lower end that would
fall below 1e-6 of the upper end is clipped there (for parameters whose own range is
non-negative; one that may be negative is scaled as it is).

Upper bound (:func:`margin_upper_bound`)
    A worst-case search for the member with the largest region violation at a given
    scale: a seeded Latin-hypercube sample of the scaled box (batched poles), then
    local optimisation (L-BFGS-B) from the worst samples, with eigenvalue gradients
    ``d lambda = w^H dA u / (w^H u)`` (``dA`` by central differences of the batched
    closed-loop matrix); bisection on the scale. The violating member found is moved
    to the first violating member on its segment from the nominal (bisection to 1e-3 of
    its scale), and that member's own scale ``k`` (the smallest box holding it) is the
    bound: it proves ``k_m <= k``, not a step of the bisection. The member is
    re-checked with python-control's poles of its Figure 5 loop before it is reported.
    Where the lower bound runs on value sets, an unstable member its probe finds with a
    smaller scale takes the critical member's place the same way.

Lower bound (:func:`margin_lower_bound`)
    A certificate that covers the continuum of the scaled box, not samples. The box is
    cut into sub-boxes; on each, the closed-loop state matrix is enclosed by an
    interval matrix ``[A_c - R, A_c + R]`` computed by interval arithmetic through
    the blocks and the interconnection (:mod:`robust.analysis.intervals`), so every
    member's matrix is ``A_c + E`` with ``||E||_2 <= rho = ||R||_2``. The sub-box is
    certified by a common quadratic Lyapunov function for that norm-bounded set
    (Boyd, El Ghaoui, Feron & Balakrishnan, *Linear Matrix Inequalities in System and
    Control Theory*, SIAM 1994, Sec. 5.1; the S-procedure is exact for one
    norm-bounded block): ``P > 0``, ``eps > 0`` with::

        [[(A_c + a I)' P + P (A_c + a I) + eps rho^2 I,  P    ],
         [P,                                            -eps I]] < 0

    which proves every eigenvalue of every member left of ``-a`` (``a`` the decay
    rate). ``P`` comes from the Lyapunov equation of the centre when the
    Patel-Toda bound ``2 rho ||P|| < 1`` already holds (Patel & Toda, JACC 1980),
    otherwise from the LMI solved with cvxpy (Clarabel first). Every certificate is
    checked independently: the LMI matrix is rebuilt in numpy from ``P`` and ``eps``
    and its eigenvalues, and those of ``P``, are checked before the sub-box counts.
    A sub-box that fails is split in two along the parameter that widens the
    enclosure most; a sub-box whose centre member violates the region ends the
    attempt (that scale is not certifiable). Bisection on the scale gives the
    largest certified ``k``. Enclosures: interval arithmetic with outward widening
    for rounding; the region certified by the lower bound is the decay-rate
    half-plane (a damping-ratio requirement is checked by the upper bound only, and
    the output says so).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable

import control as ct
import cvxpy as cp
import numpy as np
import scipy.linalg as sla
from scipy.optimize import minimize
from scipy.stats import qmc

from robust.analysis.eigen_enclosure import enclose_eigenvalues, split_coordinate, subdivide
from robust.analysis.intervals import Gradient, Interval, imatrix, norm2_bound
from robust.analysis.loops import loop_poles
from robust.analysis.stability import DAMPING_BAND_HZ, STABILITY_TOL, in_band
from robust.checks import check_int
from robust.engine import map_tasks, scheduler_address
from robust.errors import BDFTError, ModelStructureError, ParameterError
from robust.synthesis.solve import solve_problem
from uncertainty.batched import closed_loop_matrices
from uncertainty.constants import DEFAULT_BOXES, LOWER_METHODS
from uncertainty.family import Family
from uncertainty.lft import lft_form
from uncertainty.loop import INTERVALS, LoopAssembly, fixed_parameters
from uncertainty.mucover import mu_cover
from uncertainty.uss import USS, uss
from uncertainty.valueset import ValueSetLoop, certify_scale_valueset

__all__ = [
    "Region",
    "MarginResult",
    "scaled_bounds",
    "closed_loop_enclosure",
    "certify_interval_matrix",
    "certify_box",
    "DEFAULT_BOXES",
    "LOWER_METHODS",
    "margin_upper_bound",
    "margin_lower_bound",
    "worst_member",
    "robust_margin",
]

#: Floor of a scaled linear range, relative to its upper end (keeps parameters physical).
PHYSICAL_FLOOR = 1e-6
# LOWER_METHODS (auto, eigenvalues, lyapunov, valueset) and DEFAULT_BOXES (sub-boxes per
# scale) are defined in uncertainty.constants (the command line reads them without NumPy)
#: Cells of the value-set certificate per sub-box of the budget (``max_boxes``).
VALUESET_CELLS_PER_BOX = 500
#: Sub-boxes taken from the search's stack and certified together per step, on every
#: engine (one process, local processes, a Dask cluster), so that every engine gives the
#: same statistics; the certified scales do not depend on it
#: (:func:`robust.analysis.eigen_enclosure.subdivide`).
WAVE = 8
_EPS = float(np.finfo(float).eps)


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
    band_hz : (float, float)
        The band of the damping requirement, Hz.
    """

    decay_rate: float = 0.0
    min_damping: float = 0.0
    band_hz: tuple[float, float] = DAMPING_BAND_HZ

    def __post_init__(self):
        a, z = float(self.decay_rate), float(self.min_damping)
        if not (math.isfinite(a) and a >= 0):
            raise ParameterError(f"Region.decay_rate must be a finite value >= 0; got {a!r}")
        if not (math.isfinite(z) and 0 <= z < 1):
            raise ParameterError(f"Region.min_damping must be in [0, 1); got {z!r}")
        lo, hi = (float(b) for b in self.band_hz)
        if not (0 <= lo < hi and math.isfinite(hi)):
            raise ParameterError(f"Region.band_hz must satisfy 0 <= low < high; got {self.band_hz}")
        object.__setattr__(self, "decay_rate", a)
        object.__setattr__(self, "min_damping", z)
        object.__setattr__(self, "band_hz", (lo, hi))

    @classmethod
    def parse(cls, text: str) -> Region:
        """A region from its command-line form.

        ``lhp`` (the open left half-plane), ``decay:A`` (real parts below ``-A``
        rad/s), ``damping:Z`` or ``damping:Z@LO-HI`` (damping ratio at least ``Z`` for
        poles in ``LO-HI`` Hz, default 0.5-10 Hz), joined by ``,`` (e.g.
        ``decay:0.1,damping:0.1``).

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
            parts.append(
                f"damping ratio >= {self.min_damping:g} for poles in "
                f"{self.band_hz[0]:g}-{self.band_hz[1]:g} Hz"
            )
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
            d = np.where(in_band(p, self.band_hz), p.real + self.min_damping * np.abs(p), -np.inf)
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


# -- the scaled box ---------------------------------------------------------------------------
def _coords(family):
    logs = np.array([p.distribution == "loguniform" for p in family.parameters])
    nom = np.array([p.nominal for p in family.parameters], float)
    lo = np.array([p.low for p in family.parameters], float)
    hi = np.array([p.high for p in family.parameters], float)
    t = np.where(logs, np.log(np.where(logs, [nom, lo, hi], 1.0)), [nom, lo, hi])
    return logs, t[0], t[1], t[2], hi


def _to_values(family, t: np.ndarray) -> np.ndarray:
    logs = np.array([p.distribution == "loguniform" for p in family.parameters])
    return np.where(logs, np.exp(np.where(logs, t, 0.0)), t)


def _scaled_t(family, k: float):
    logs, tn, tl, th, hi = _coords(family)
    lo_t = tn + k * (tl - tn)
    hi_t = tn + k * (th - tn)
    hi_v = np.where(logs, np.exp(np.where(logs, hi_t, 0.0)), hi_t)
    floor = PHYSICAL_FLOOR * np.abs(hi_v)
    # only a parameter whose own range is non-negative is kept positive
    lo_t = np.where(logs | (tl < 0), lo_t, np.maximum(lo_t, floor))
    return lo_t, hi_t


def _member_scale(loop, row) -> float:
    """The smallest scale whose box (:func:`_scaled_t`) holds the member ``row`` (values)."""
    logs, tn, tl, th, _ = _coords(loop)
    row = np.asarray(row, float)
    t = np.where(logs, np.log(np.where(logs, row, 1.0)), row)
    up = np.where(th > tn, (t - tn) / np.where(th > tn, th - tn, 1.0), 0.0)
    down = np.where(tl < tn, (t - tn) / np.where(tl < tn, tl - tn, 1.0), 0.0)
    k = float(np.max(np.maximum(up, down)))
    return k if k > 0 else 0.0  # (the nominal itself: 0, not -0.0)


def _ray_critical(loop, row, region, rel: float = 1e-3):
    """The first violating member on the segment from the nominal to the violating member
    ``row``, to ``rel`` of its scale by bisection: ``(scale, row)``.

    The nominal must meet the region (as every margin requires); the member returned
    violates it, so its scale is an upper bound of the margin."""
    logs, tn, _, _, _ = _coords(loop)
    row = np.asarray(row, float)
    t_row = np.where(logs, np.log(np.where(logs, row, 1.0)), row)

    def at(s):
        return _to_values(loop, (tn + s * (t_row - tn))[None])

    lo, hi = 0.0, 1.0
    for _ in range(60):
        if hi - lo <= rel * hi:
            break
        mid = 0.5 * (lo + hi)
        if _violations(loop, at(mid), region)[0][0] > 0:
            hi = mid
        else:
            lo = mid
    out = at(hi)[0]
    return _member_scale(loop, out), out


def scaled_bounds(family, k: float) -> tuple[np.ndarray, np.ndarray]:
    """Low and high value of every parameter in the box scaled by ``k`` about the nominal.

    Parameters
    ----------
    family : Family or USS
        The family or uncertain system (its parameters' distributions give the
        coordinates; a system's in the order of ``system.parameters``).
    k : float
        Scale, >= 0.
    """
    if not (math.isfinite(k) and k >= 0):
        raise ParameterError(f"scale k must be a finite value >= 0; got {k!r}")
    loop = _loop(family, None)
    lo_t, hi_t = _scaled_t(loop, k)
    return _to_values(loop, lo_t), _to_values(loop, hi_t)


# -- closed-loop poles of arbitrary members --------------------------------------------------
def _violations(loop, rows, region):
    A = loop.matrices(rows)
    # a member whose matrix is not finite (a divisor at 0) is outside every region
    ok = np.isfinite(A).all(axis=(1, 2))
    v = np.full(A.shape[0], math.inf)
    if ok.any():
        v[ok] = region.violation(np.linalg.eigvals(A[ok]))
    return v, A


def _gradient(loop, t, region, h=1e-6):
    """Violation at ``t`` (scaled coordinates) and its gradient."""
    d = len(t)
    T = np.repeat(t[None], 2 * d + 1, axis=0)
    for j in range(d):
        T[1 + 2 * j, j] += h
        T[2 + 2 * j, j] -= h
    A = loop.matrices(_to_values(loop, T))
    if not np.isfinite(A).all():  # at or next to a pole of the matrix: no gradient
        if not np.isfinite(A[0]).all():
            return math.inf, np.zeros(d)
        return float(region.violation(np.linalg.eigvals(A[0])[None])[0]), np.zeros(d)
    lam, W, V = sla.eig(A[0], left=True, right=True)
    v0 = region.violation(lam[None])[0]
    # the pole that attains the violation
    score = lam.real + max(region.decay_rate, STABILITY_TOL)
    if region.min_damping > 0:
        score = np.maximum(
            score,
            np.where(
                in_band(lam, region.band_hz), lam.real + region.min_damping * np.abs(lam), -np.inf
            ),
        )
    i = int(np.argmax(score))
    w, u = W[:, i], V[:, i]
    denom = np.conj(w) @ u
    g = np.zeros(d)
    for j in range(d):
        dA = (A[1 + 2 * j] - A[2 + 2 * j]) / (2 * h)
        dlam = (np.conj(w) @ dA @ u) / denom
        if region.min_damping > 0 and score[i] > lam[i].real + max(
            region.decay_rate, STABILITY_TOL
        ):
            g[j] = dlam.real + region.min_damping * np.real(np.conj(lam[i]) * dlam) / abs(lam[i])
        else:
            g[j] = dlam.real
    return v0, g


def _worst_in_box(loop, k, region, *, samples, seed, starts):
    lo_t, hi_t = _scaled_t(loop, k)
    d = len(lo_t)
    U = qmc.LatinHypercube(d=d, seed=seed).random(samples)
    T = lo_t + U * (hi_t - lo_t)
    v, _ = _violations(loop, _to_values(loop, T), region)
    order = np.argsort(v)[::-1][:starts]
    best_v, best_t = float(v[order[0]]), T[order[0]]
    for i in order:
        val, t = _local_worst(loop, lo_t, hi_t, T[i], region)
        if val > best_v:
            best_v, best_t = val, t
    return best_v, _to_values(loop, best_t[None])[0]


def _local_worst(loop, lo_t, hi_t, t0, region) -> tuple[float, np.ndarray]:
    """The largest violation L-BFGS-B reaches from ``t0`` within ``lo_t .. hi_t`` (scaled
    coordinates, eigenvalue gradients): ``(violation, t)``."""
    span = np.where(hi_t > lo_t, hi_t - lo_t, 1.0)

    def fun(x):
        t = lo_t + x * span
        val, g = _gradient(loop, t, region)
        return -val, -g * span

    x0 = (np.asarray(t0, float) - lo_t) / span
    # a parameter of zero width (a degenerate range, or the scale 0) stays where it is
    bounds = [(0.0, 1.0) if w > 0 else (0.0, 0.0) for w in hi_t - lo_t]
    res = minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=bounds, options={"maxiter": 60})
    return float(-res.fun), lo_t + res.x * span


def worst_member(
    family: Family | USS,
    k: float,
    *,
    controller: ct.StateSpace | None = None,
    region: Region | None = None,
    samples: int = 300,
    seed: int = 0,
    starts: int = 3,
) -> tuple[float, np.ndarray]:
    """The member of the box scaled to ``k`` with the largest region violation found.

    The search of :func:`margin_upper_bound` at one scale: a seeded Latin hypercube of
    the scaled box (batched poles), then L-BFGS-B with eigenvalue gradients from the
    ``starts`` worst samples.

    Parameters
    ----------
    family : Family or USS
        The family, or an uncertain system (:func:`uncertainty.uss`; closed with
        ``controller`` by negative feedback when one is given).
    k : float
        Scale of the box about the nominal (>= 0).
    controller : control.StateSpace, optional
        Compensator in the loop's convention (a family) or in the feedback path of the
        system (``system.feedback(controller)``).
    region : Region, optional
        Required region (default: open left half-plane).
    samples, seed, starts : int
        Latin-hypercube members, seed, local searches.

    Returns
    -------
    violation : float
        Largest region violation found (> 0: the member breaks the region), rad/s.
    row : numpy.ndarray
        That member's parameter values (``family.names`` order).
    """
    if not (math.isfinite(k) and k >= 0):
        raise ParameterError(f"worst_member: k must be a finite scale >= 0; got {k!r}")
    return _worst_in_box(
        _loop(family, controller),
        float(k),
        region or Region(),
        samples=samples,
        seed=seed,
        starts=starts,
    )


def margin_upper_bound(
    family: Family | USS,
    *,
    controller: ct.StateSpace | None = None,
    region: Region | None = None,
    samples: int = 1000,
    seed: int = 0,
    starts: int = 3,
    k_max: float = 8.0,
    iterations: int = 8,
    progress: Callable[[str], None] | None = None,
) -> tuple[float, dict | None, dict]:
    """Upper bound of the robust margin and the critical member (see the module notes).

    Parameters
    ----------
    family : Family or USS
        The family, or an uncertain system (:func:`uncertainty.uss`; closed with
        ``controller`` by negative feedback when one is given).
    controller : control.StateSpace, optional
        Compensator in the loop's convention (a family) or in the feedback path of the
        system (``system.feedback(controller)``).
    region : Region, optional
        Required region (default: open left half-plane).
    samples : int
        Latin-hypercube members drawn per scale.
    seed : int
        Sampling seed.
    starts : int
        Local optimisations per scale, from the worst samples.
    k_max : float
        Largest scale searched; ``inf`` is returned if no member violates up to it.
    iterations : int
        Bisection steps on the scale.
    progress : callable, optional
        Called with a short message at each scale.

    Returns
    -------
    upper : float
    critical : dict or None
        ``parameters``, ``poles`` (python-control poles of the member's loop),
        ``violation``, ``scale``.
    search : dict
        Settings and the bisection history.
    """
    region = region or Region()
    loop = _loop(family, controller)
    step = progress or (lambda msg: None)
    history = []

    def probe(k):
        step(f"upper bound: searching the box at scale {k:.4g}")
        v, row = _worst_in_box(loop, k, region, samples=samples, seed=seed, starts=starts)
        history.append({"scale": float(k), "worst_violation": v})
        return v, row

    bad = None
    v, row = probe(1.0)
    if v > 0:
        good_k, bad_k, bad = 0.0, 1.0, row
    else:
        good_k, bad_k = 1.0, None
        k = 2.0
        while k <= k_max:
            v, row = probe(k)
            if v > 0:
                bad_k, bad = k, row
                break
            good_k, k = k, 2 * k
    if bad_k is None:
        return (
            math.inf,
            None,
            {
                "samples": samples,
                "seed": seed,
                "starts": starts,
                "k_max": k_max,
                "history": history,
            },
        )
    for _ in range(iterations):
        mid = 0.5 * (good_k + bad_k)
        v, row = probe(mid)
        if v > 0:
            bad_k, bad = mid, row
        else:
            good_k = mid
    # the bound is the violating member's own scale, not a step of the bisection: the first
    # violating member on its segment from the nominal
    k_ray, row_ray = _ray_critical(loop, bad, region)
    if k_ray <= bad_k:
        bad_k, bad = k_ray, row_ray
    critical = _critical(loop, bad, region, bad_k)
    return (
        bad_k,
        critical,
        {"samples": samples, "seed": seed, "starts": starts, "k_max": k_max, "history": history},
    )


def _critical(loop, row, region, k):
    """The violating member, re-checked by python-control where it can be built."""
    A = loop.matrices(np.asarray(row)[None])[0]
    if not np.isfinite(A).all():
        return {
            "scale": float(k),
            "parameters": dict(zip(loop.names, (float(x) for x in row))),
            "poles": np.zeros(0, complex),
            "violation": math.inf,
            "checked_with": "the member's matrix is not finite (a divisor at 0)",
        }
    poles = np.sort_complex(np.linalg.eigvals(A))
    out = {
        "scale": float(k),
        "parameters": dict(zip(loop.names, (float(x) for x in row))),
        "poles": poles,
        "violation": float(region.violation(poles[None])[0]),
        "checked_with": "batched closed-loop matrix",
    }
    checked = loop.recheck(row)
    if checked is not None:
        ref, how = checked
        out["poles"] = np.sort_complex(ref)
        out["violation"] = float(region.violation(ref[None])[0])
        out["checked_with"] = how
    return out


# -- interval enclosure of the closed-loop matrix ---------------------------------------------
def _box_variables(parameters, lo, hi, derivatives: bool) -> dict:
    """The varied parameters over the box ``lo .. hi``: intervals, or :class:`Gradient`
    variables in the parameters' coordinates (log for log-uniform: d value / d t is the
    value itself, 1 for linear)."""
    d = len(parameters)
    out = {}
    for j, (p, a, b) in enumerate(zip(parameters, lo, hi)):
        if not derivatives:
            out[p.name] = Interval.hull(a, b)
        else:
            dv = Interval.hull(a, b) if p.distribution == "loguniform" else None
            out[p.name] = Gradient.variable(a, b, j, d, dvalue=dv)
    return out


def _param_intervals(
    family: Family, lo: np.ndarray, hi: np.ndarray, derivatives: bool, fixed: dict | None = None
) -> dict:
    """Every model parameter over the box: the varied ones as :func:`_box_variables`, the
    others fixed (``fixed``: their point intervals, when the caller keeps them)."""
    if fixed is None:
        fixed = {n: Interval.point(v) for n, v in fixed_parameters(family).items()}
    out = dict(fixed)
    out.update(_box_variables(family.parameters, lo, hi, derivatives))
    return out


def closed_loop_enclosure(
    family: Family,
    lo,
    hi,
    *,
    controller: ct.StateSpace | None = None,
    derivatives: bool = False,
) -> Interval | Gradient:
    """An interval matrix containing the closed-loop state matrix of every member in a box.

    Interval arithmetic through the blocks of :func:`uncertainty.batched.loop_blocks`
    (same block and state order) and the interconnection of the Figure 5 junction
    table, ``A_cl = A + B M (C + D M C + (D M)^2 C + ...)`` (the series is finite: the
    direct feedthroughs form no algebraic cycle).

    Parameters
    ----------
    family : Family
        The family.
    lo, hi : array_like, shape (d,)
        The box: bounds of every uncertain parameter (values, family order).
    controller : control.StateSpace, optional
        Compensator in the loop's convention (fixed).
    derivatives : bool
        Also enclose the partial derivatives of the matrix over the box with respect to
        each parameter in the family's coordinates (log of the value for log-uniform
        parameters): a :class:`~robust.analysis.intervals.Gradient` is returned.

    Raises
    ------
    ParameterError
        If the controller's feedthrough closes an algebraic loop (no finite series).
    """
    return _Assembly(family, controller).matrix(lo, hi, derivatives)


class _Assembly(LoopAssembly):
    """The family's loop evaluated on intervals (or interval gradients) over a box."""

    def __init__(self, family: Family, controller):
        super().__init__(family, controller, INTERVALS)
        # the fixed parameters' point intervals, the same for every box (read-only)
        self._fixed = {n: Interval.point(v) for n, v in fixed_parameters(family).items()}
        for iv in self._fixed.values():
            iv.mid.setflags(write=False)
            iv.rad.setflags(write=False)

    def matrix(self, lo, hi, derivatives: bool):
        """The enclosure of the closed-loop state matrix over the box ``lo .. hi``."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        return self.state_matrix(_param_intervals(self.family, lo, hi, derivatives, self._fixed))


class _FamilyLoop:
    """The BDFT loop of a family with a fixed controller: what the margin needs of it."""

    def __init__(self, family: Family, controller):
        self.family, self.controller = family, controller
        self.parameters = tuple(family.parameters)
        self.names = tuple(family.names)
        self._asm = None

    def matrices(self, rows) -> np.ndarray:
        """Closed-loop state matrices of members (rows of values), batched."""
        return closed_loop_matrices(
            self.family, rows, controller=self.controller, check_bounds=False
        )

    def enclosure(self, lo, hi, derivatives: bool):
        """Interval (or :class:`Gradient`) enclosure of the matrix over a box of values."""
        if self._asm is None:
            self._asm = _Assembly(self.family, self.controller)
        return self._asm.matrix(lo, hi, derivatives)

    def recheck(self, row):
        """Poles of the member's Figure 5 loop by python-control, or None outside the model."""
        try:
            member = self.family.member(row, check_bounds=False)
        except BDFTError:  # e.g. a scaled structure damping ratio >= 1, outside the loop model
            return None
        return (
            loop_poles(member, controller=self.controller).poles,
            "python-control poles of the member's Figure 5 loop",
        )


class _Unbounded(ParameterError):
    """A box holds members whose matrix is unbounded (a divisor's range contains 0)."""


class _SystemLoop:
    """An uncertain system (closed with a controller if one is given) seen by the margin.

    Every evaluation comes from the system's one uncertain state matrix: numbers (batched
    members), intervals and interval gradients (the certificate's enclosures) run through
    the same expressions, shared sub-expressions evaluated once.
    """

    def __init__(self, system: USS, controller):
        closed = system if controller is None else system.feedback(controller, sign=-1)
        if not closed.parameters:
            raise ParameterError(
                "robust margin: the system has no uncertain real (build it with uncertainty.ureal)"
            )
        if closed.nstates == 0:
            raise ModelStructureError("robust margin: the system has no state (a static gain)")
        self.system = closed
        self.parameters = tuple(closed.parameters.values())
        self.names = tuple(closed.parameters)

    def matrices(self, rows) -> np.ndarray:
        """State matrices of members (rows of values, columns in :attr:`names` order)."""
        return self.system.state_matrices(rows)

    def enclosure(self, lo, hi, derivatives: bool):
        """Interval (or :class:`Gradient`) enclosure of the state matrix over a box."""
        vals = _box_variables(self.parameters, lo, hi, derivatives)
        try:
            return imatrix(self.system.state_matrix(vals))
        except ParameterError as exc:
            box = ", ".join(f"{n} in [{a:.6g}, {b:.6g}]" for n, a, b in zip(self.names, lo, hi))
            raise _Unbounded(
                "robust margin: an entry of the system's matrix divides by an expression "
                f"whose range contains 0 on the box {box} "
                f"(the system is unbounded there): {exc}"
            ) from None

    def recheck(self, row):
        """Poles of the member's python-control system."""
        member = self.system.at(dict(zip(self.names, (float(x) for x in row))))
        return ct.poles(member), "python-control poles of the member system"


def _loop(system, controller):
    """The loop a margin function analyses: a family's or an uncertain system's."""
    if isinstance(system, (_FamilyLoop, _SystemLoop)):
        return system
    if isinstance(system, Family):
        return _FamilyLoop(system, controller)
    if isinstance(system, USS):
        return _SystemLoop(system, controller)
    raise ParameterError(
        f"robust margin: expected a Family or an uncertain system (uncertainty.uss); "
        f"got {type(system).__name__}"
    )


# -- certificates ------------------------------------------------------------------------------
def _structured(R: np.ndarray, floor: float, rel: float = 1e-9):
    """Split an entrywise bound into its significant entries and a small remainder.

    Returns ``L`` (n x m), ``Rm`` (m x n) with ``E_big = L diag(delta) Rm``,
    ``|delta_k| <= 1``, for the ``m`` entries above ``rel * max(R)``, and the norm bound
    of the remaining entries (rounding-level widening of structurally fixed entries).
    """
    n = R.shape[0]
    big = R > max(rel * (R.max() if R.size else 0.0), floor)
    idx = np.argwhere(big)
    L = np.zeros((n, len(idx)))
    Rm = np.zeros((len(idx), n))
    for k, (i, j) in enumerate(idx):
        L[i, k] = math.sqrt(R[i, j])
        Rm[k, j] = math.sqrt(R[i, j])
    return L, Rm, norm2_bound(np.where(big, 0.0, R))


def _real_modal_basis(A: np.ndarray) -> np.ndarray:
    """Real basis of eigenvectors of ``A`` (``[Re v, Im v]`` per complex pair), columns of
    unit norm; the identity if ``A`` is too close to defective (condition > 1e8)."""
    lam, V = np.linalg.eig(A)
    cols, done = [], set()
    for i in np.argsort(-lam.real):
        if i in done:
            continue
        v = V[:, i]
        if abs(lam[i].imag) > 1e-12 * max(1.0, abs(lam[i])):
            j = int(np.argmin(np.abs(lam - np.conj(lam[i])) + (np.arange(len(lam)) == i)))
            done.update((i, j))
            cols += [v.real, v.imag]
        else:
            done.add(i)
            cols.append(v.real)
    T = np.column_stack(cols)
    T = T / np.linalg.norm(T, axis=0)
    if not np.isfinite(np.linalg.cond(T)) or np.linalg.cond(T) > 1e8:
        return np.eye(A.shape[0])
    return T


def _lmi_matrix(As, P, lam, eps, L, Rm, rho_s):
    """The robust-stability LMI for ``As + L diag(delta) Rm + E_s``, ``|delta| <= 1``,
    ``||E_s|| <= rho_s`` (Boyd et al. 1994, Sec. 5.1; S-procedure with diagonal scalings).
    """
    n, m = As.shape[0], L.shape[1]
    top = As.T @ P + P @ As + Rm.T @ (lam[:, None] * Rm)
    if rho_s == 0:
        return np.block([[top, P @ L], [L.T @ P, -np.diag(lam)]])
    top = top + eps * rho_s**2 * np.eye(n)
    return np.block(
        [
            [top, P @ L, P],
            [L.T @ P, -np.diag(lam), np.zeros((m, n))],
            [P, np.zeros((n, m)), -eps * np.eye(n)],
        ]
    )


def _check(As, P, lam, eps, L, Rm, rho_s) -> float:
    """Largest normalised eigenvalue of the rebuilt LMI (< 0 certifies); ``inf`` if
    ``P``, ``lam`` or ``eps`` is not positive."""
    P = (P + P.T) / 2
    finite = np.all(np.isfinite(P)) and np.all(np.isfinite(lam)) and math.isfinite(eps)
    if not (finite and eps > 0 and np.all(lam > 0) and np.linalg.eigvalsh(P).min() > 0):
        return math.inf
    M = _lmi_matrix(As, P, lam, eps, L, Rm, rho_s)
    # congruence with blkdiag(I, diag(lam)^-1/2, eps^-1/2 I) (definiteness unchanged)
    # brings the multiplier blocks to -I, so the eigenvalues are resolved at every scale
    n = As.shape[0]
    d = np.concatenate(
        [np.ones(n), 1.0 / np.sqrt(lam), np.full(n if rho_s else 0, 1.0 / math.sqrt(eps))]
    )
    M = M * d[:, None] * d[None, :]
    scale = max(1.0, np.abs(M[:n, :n]).max())
    return float(np.linalg.eigvalsh((M + M.T) / 2).max() / scale)


def certify_interval_matrix(
    enclosure: Interval, decay_rate: float = 0.0, *, lmi: bool = True
) -> dict:
    """Certify that every matrix of an interval matrix has its eigenvalues left of ``-a``.

    The perturbation ``E = A - A_c`` (``|E| <= R``) is written entry by entry,
    ``E = sum_k delta_k R_ij e_i e_j'`` with ``|delta_k| <= 1``, plus a remainder of
    rounding-level entries bounded in norm; the certificate is a common quadratic
    Lyapunov function for that set with one S-procedure multiplier per entry.

    Parameters
    ----------
    enclosure : Interval
        Square interval matrix ``[A_c - R, A_c + R]``.
    decay_rate : float
        ``a`` >= 0, rad/s (``STABILITY_TOL`` is used when smaller).
    lmi : bool
        Solve the LMI when the centre's own Lyapunov matrix does not certify (False: the
        cheap route only).

    Returns
    -------
    dict
        ``certified`` (bool), ``route`` (``"lyapunov"``, ``"lmi"`` or ``None``),
        ``rho`` (the unstructured norm bound, for information), ``entries`` (uncertain
        entries), ``check`` (largest normalised eigenvalue of the LMI rebuilt in numpy;
        < 0 certifies), ``centre_violates`` (the centre matrix itself is outside the
        region).
    """
    # a diagonal similarity (balancing of the centre, scipy.linalg.matrix_balance) scales
    # mid and radius alike, E -> S^-1 E S, and leaves every eigenvalue where it is
    _, (s, _) = sla.matrix_balance(enclosure.mid, permute=False, separate=True)
    Ac = enclosure.mid / s[:, None] * s[None, :]
    R = enclosure.rad / s[:, None] * s[None, :]
    rho = norm2_bound(R)
    a = max(float(decay_rate), STABILITY_TOL)
    n = Ac.shape[0]
    L, Rm, rho_s = _structured(R, 1e-13 * max(1.0, np.abs(Ac).max()))
    # real modal coordinates of the centre, x = T z: each rank-one term e_i e_j' becomes
    # (T^-1 e_i)(e_j' T), the remainder's bound grows by cond(T)
    T = _real_modal_basis(Ac)
    Ti = np.linalg.inv(T)
    As = Ti @ Ac @ T + a * np.eye(n)
    L, Rm = Ti @ L, Rm @ T
    rho_s = rho_s * np.linalg.norm(T, 2) * np.linalg.norm(Ti, 2) * (1 + 1e-9)
    if rho_s < 1e-250:  # the remainder holds only exact zeros (norm2_bound adds a tiny floor)
        rho_s = 0.0
    m = L.shape[1]
    out = {
        "certified": False,
        "route": None,
        "rho": rho,
        "entries": m,
        "check": math.inf,
        "centre_violates": bool(np.linalg.eigvals(As).real.max() >= 0),
    }
    if out["centre_violates"]:
        return out
    # cheap route: the centre's Lyapunov matrix and the best scalar multipliers
    try:
        P = sla.solve_continuous_lyapunov(As.T, -np.eye(n))
    except (np.linalg.LinAlgError, ValueError):
        P = None
    if P is not None and np.all(np.isfinite(P)):
        PL = P @ L
        lam = np.maximum(
            np.linalg.norm(PL, axis=0) / np.maximum(np.linalg.norm(Rm, axis=1), 1e-300), 1e-300
        )
        eps = np.linalg.norm(P, 2) / rho_s if rho_s > 0 else 1.0
        chk = _check(As, P, lam, eps, L, Rm, rho_s)
        if chk < 0:
            out.update(certified=True, route="lyapunov", check=chk)
            return out
    if not lmi:
        return out
    Pv = cp.Variable((n, n), symmetric=True)
    lv = cp.Variable(m, pos=True) if m else None
    ev = cp.Variable(pos=True)
    Im = np.eye(n)
    top = As.T @ Pv + Pv @ As + ev * rho_s**2 * Im
    if m:
        top = top + Rm.T @ cp.diag(lv) @ Rm
    if m and rho_s:
        rows = [
            [top, Pv @ L, Pv],
            [L.T @ Pv, -cp.diag(lv), np.zeros((m, n))],
            [Pv, np.zeros((n, m)), -ev * Im],
        ]
    elif m:
        rows = [[top, Pv @ L], [L.T @ Pv, -cp.diag(lv)]]
    else:
        rows = [[top, Pv], [Pv, -ev * Im]] if rho_s else [[top]]
    Mx = cp.bmat(rows)
    size = Mx.shape[0]
    prob = cp.Problem(cp.Minimize(0), [Pv >> Im, (Mx + Mx.T) / 2 << -1e-7 * np.eye(size)])
    try:
        solve_problem(
            prob, step="robust margin: Lyapunov certificate of a sub-box", solvers=("CLARABEL",)
        )
    except BDFTError:
        return out
    if Pv.value is None or (rho_s and ev.value is None) or (m and lv.value is None):
        return out
    lam = np.asarray(lv.value, float) if m else np.zeros(0)
    eps = float(ev.value) if rho_s else 1.0
    chk = _check(As, Pv.value, lam, eps, L, Rm, rho_s)
    out.update(certified=chk < 0, route="lmi" if chk < 0 else None, check=chk)
    return out


def _split_dimension(loop, lo_t, hi_t):
    """The parameter whose range alone widens the enclosure most."""
    centre = (lo_t + hi_t) / 2
    best, best_j = -1.0, 0
    for j in range(len(lo_t)):
        if hi_t[j] <= lo_t[j]:
            continue
        a, b = centre.copy(), centre.copy()
        a[j], b[j] = lo_t[j], hi_t[j]
        enc = loop.enclosure(_to_values(loop, a), _to_values(loop, b), False)
        r = norm2_bound(enc.rad)
        if r > best:
            best, best_j = r, j
    return best_j


def _rectangles_in_region(res: dict, region: Region) -> np.ndarray:
    """Per eigenvalue rectangle: its largest region violation (< 0: inside), rad/s.

    The decay-rate part is ``Re_max + a``; with a damping requirement, a rectangle whose
    frequency range meets the band must have its four corners in the convex sector
    ``Re s + zeta |s| <= 0``, so its violation is the largest ``Re s + zeta |s|`` at a
    corner.
    """
    c, rr, ri = res["centre"], res["rad_re"], res["rad_im"]
    v = c.real + rr + max(region.decay_rate, STABILITY_TOL)
    if region.min_damping > 0:
        f_lo = np.maximum(np.abs(c.imag) - ri, 0.0) / (2 * math.pi)
        f_hi = (np.abs(c.imag) + ri) / (2 * math.pi)
        meets = (f_hi >= region.band_hz[0]) & (f_lo <= region.band_hz[1])
        corners = [(c.real + sr * rr) + 1j * (c.imag + si * ri) for sr in (-1, 1) for si in (-1, 1)]
        sector = np.max([z.real + region.min_damping * np.abs(z) for z in corners], axis=0)
        v = np.maximum(v, np.where(meets, sector, -np.inf))
    return v


def certify_box(
    family: Family | USS,
    lo,
    hi,
    *,
    controller: ct.StateSpace | None = None,
    region: Region | None = None,
    spot_checks: int = 8,
    seed: int = 0,
) -> dict:
    """Certify that every member of a box has its poles in the region (eigenvalue route).

    The closed-loop matrix over the box is written in mean-value form about the box's
    centre (derivative enclosures by interval forward differentiation,
    :class:`~robust.analysis.intervals.Gradient`) and every eigenvalue of every member is
    enclosed in a rectangle by :func:`robust.analysis.eigen_enclosure.enclose_eigenvalues`.
    The box is certified when the rectangles are disjoint (so they hold every eigenvalue)
    and each lies in the region. Independent check: ``spot_checks`` seeded members of the
    box are assembled by :func:`uncertainty.batched.closed_loop_matrices` and their
    eigenvalues (numpy) must lie in the rectangles; a miss raises :class:`BDFTError`.

    Parameters
    ----------
    family : Family or USS
        The family, or an uncertain system (closed with ``controller`` by negative
        feedback when one is given).
    lo, hi : array_like, shape (d,)
        The box: bounds of every uncertain parameter (values, family order or the order
        of ``system.parameters``; the box is split in the parameters' coordinates, log for
        log-uniform parameters).
    controller : control.StateSpace, optional
        Compensator in the loop's convention (a family) or in the feedback path.
    region : Region, optional
        Required region (default: open left half-plane).
    spot_checks : int
        Members of the box checked against the enclosures.
    seed : int
        Seed of the spot-checked members.

    Returns
    -------
    dict
        ``certified``, ``centre_violates`` (the box's centre member is outside the region),
        ``check`` (largest violation of a rectangle, rad/s; < 0 certifies), ``split``
        (the parameter whose range moves the eigenvalues most, relative to their distance
        to the region's boundary), ``reason``.
    """
    loop = _loop(family, controller)
    logs = np.array([p.distribution == "loguniform" for p in loop.parameters])
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    lo_t = np.where(logs, np.log(np.where(logs, lo, 1.0)), lo)
    hi_t = np.where(logs, np.log(np.where(logs, hi, 1.0)), hi)
    return _certify_box(loop, lo_t, hi_t, region or Region(), spot_checks, seed)


def _certify_box(loop, lo_t, hi_t, region, spot_checks, seed) -> dict:
    lo_t, hi_t = np.asarray(lo_t, float), np.asarray(hi_t, float)
    ct_ = (lo_t + hi_t) / 2
    # the values of the box's ends and centre as floats; the box is widened by a few ulps
    # so that it covers the exact ends, and the half-widths cover the rounded centre
    # (values of either sign: widened away from zero)
    lo_v = _to_values(loop, lo_t)
    hi_v = _to_values(loop, hi_t)
    lo_v = lo_v - 8 * _EPS * np.abs(lo_v)
    hi_v = hi_v + 8 * _EPS * np.abs(hi_v)
    c_v = _to_values(loop, ct_)
    h = (hi_t - lo_t) / 2 * (1 + 1e-12) + 16 * _EPS * (np.abs(ct_) + 1.0)
    try:
        Ac = loop.enclosure(c_v, c_v, False)
        G = loop.enclosure(lo_v, hi_v, True)
    except _Unbounded as exc:
        # a member with an unbounded matrix is outside every region: no sub-box helps
        return {
            "certified": False,
            "centre_violates": True,
            "check": math.inf,
            "split": 0,
            "reason": str(exc),
        }
    E_rad = Ac.rad + np.einsum("p,pab->ab", h, G.der.rad)
    res = enclose_eigenvalues(Ac.mid, G.der.mid, h, E_rad, margin=region.distance_inside)
    if not np.all(np.isfinite(res["eigs"])):
        res = dict(res, eigs=np.linalg.eigvals(Ac.mid))
    centre_v = region.violation(res["eigs"][None])[0]
    out = {
        "certified": False,
        "centre_violates": bool(centre_v > 0),
        "check": math.inf,
        "split": split_coordinate(
            res,
            max(region.decay_rate, STABILITY_TOL),
            hi_t > lo_t,
            margins=region.distance_inside(res["eigs"]),
            remainder=h * np.linalg.norm(G.der.rad, 2, axis=(1, 2)),
        ),
    }
    if out["centre_violates"]:
        return dict(out, reason="the centre member violates the region")
    if not res["ok"]:
        # a cluster of eigenvalues (e.g. the exact copy of the human's poles in a cancelling
        # controller) defeats simple-eigenvalue enclosures; the quadratic Lyapunov route
        # (its cheap form, the centre's own Lyapunov matrix) may still certify the box
        why = "overlapping enclosures" if res["verified"].all() else "enclosure not verified"
        if region.min_damping == 0:
            enc = loop.enclosure(lo_v, hi_v, False)
            alt = certify_interval_matrix(enc, region.decay_rate, lmi=False)
            if alt["certified"]:
                return dict(
                    out,
                    certified=True,
                    check=alt["check"],
                    route="lyapunov",
                    reason="certified (Lyapunov route: eigenvalue cluster)",
                )
        return dict(out, reason=why)
    v = _rectangles_in_region(res, region)
    out["check"] = float(v.max())
    if out["check"] >= 0:
        return dict(out, reason="an enclosure reaches outside the region")
    # independent check of the enclosures on seeded members of the box
    if spot_checks:
        rng = np.random.default_rng(seed)
        T = lo_t + rng.random((spot_checks, len(lo_t))) * (hi_t - lo_t)
        A = loop.matrices(_to_values(loop, T))
        c, rr, ri = res["centre"], res["rad_re"], res["rad_im"]
        for Ak, poles in zip(A, np.linalg.eigvals(A)):
            # numpy's eigenvalues carry their own rounding error (about eps ||A|| cond)
            tol = 1e-9 * np.linalg.norm(Ak)
            inside = (np.abs(poles.real[:, None] - c.real[None]) <= rr[None] + tol) & (
                np.abs(poles.imag[:, None] - c.imag[None]) <= ri[None] + tol
            )
            if not inside.any(axis=1).all():
                raise BDFTError(
                    "robust margin: a member's eigenvalue lies outside the certified "
                    "enclosures of its box; the certificate is wrong"
                )
    return dict(out, certified=True, route="eigenvalues", reason="certified")


def _box_task(loop, region, method, box) -> dict:
    """One sub-box of the search: ``box = (lo_t, hi_t, index)``; the index seeds its spot checks."""
    a, b, index = box
    if method == "eigenvalues":
        return _certify_box(loop, a, b, region, 8, index)
    try:
        enc = loop.enclosure(_to_values(loop, a), _to_values(loop, b), False)
    except _Unbounded:
        return {"certified": False, "centre_violates": True, "check": math.inf}
    res = certify_interval_matrix(enc, region.decay_rate)
    if not res["certified"] and not res["centre_violates"]:
        res["split"] = _split_dimension(loop, a, b)
    return res


def _boxes_task(task, boxes) -> list:
    """Several sub-boxes of one step in one task: ``[task(box) for box in boxes]``."""
    return [task(box) for box in boxes]


def _perron_bound(enc) -> float:
    """Upper bound of every eigenvalue modulus of the interval matrix ``enc``: the Perron
    root of its entrywise magnitude bound, by the Collatz-Wielandt ratio of a positive
    vector (the Perron vector, lifted off zero)."""
    N = np.abs(enc.mid) + enc.rad
    vals, vecs = np.linalg.eig(N)
    v = np.abs(vecs[:, int(np.argmax(vals.real))])
    v = v + 1e-9 * v.max() + np.finfo(float).tiny
    return float(np.max((N @ v) / v)) * (1 + 1e-9)


def _valueset_scale(loop, k, max_boxes, seed=0):
    """:func:`uncertainty.valueset.certify_scale_valueset` at scale ``k``, the nominal's
    stability first and seeded members of a certified box re-checked (numpy eigenvalues)."""
    lo_t, hi_t = _scaled_t(loop, k)
    centre = loop.matrices(_to_values(loop, (lo_t + hi_t) / 2)[None])[0]
    if np.linalg.eigvals(centre).real.max() >= 0:
        return False, {"cells": 0, "centre_violates": True}
    if getattr(loop, "_valueset", None) is None:
        loop._valueset = ValueSetLoop(loop.family)
    enc = loop.enclosure(_to_values(loop, lo_t), _to_values(loop, hi_t), False)
    # rounded up to two significant digits: the cells do not hinge on the eigen-solver's
    # last digits
    bound = _perron_bound(enc)
    step = 10.0 ** (math.floor(math.log10(bound)) - 1)
    w_max = math.ceil(bound / step) * step

    def probe(t):
        # the candidates, then a local search for the largest real part from the best
        v, _ = _violations(loop, _to_values(loop, np.asarray(t, float)), Region())
        j = int(np.argmax(v))
        if v[j] <= 0:
            v[j], t[j] = _local_worst(loop, lo_t, hi_t, t[j], Region())
        return (t[j], float(v[j])) if v[j] > 0 else None

    ok, st = certify_scale_valueset(
        loop._valueset, lo_t, hi_t, w_max, max_boxes * VALUESET_CELLS_PER_BOX, probe
    )
    if "unstable" in st:
        row = _to_values(loop, st.pop("unstable")[None])[0]
        st["unstable_member"] = [float(x) for x in row]
        st["unstable_scale"] = _member_scale(loop, row)
    if ok:
        rng = np.random.default_rng(seed)
        T = lo_t + rng.random((16, len(lo_t))) * (hi_t - lo_t)
        T[0], T[1] = lo_t, hi_t
        worst = np.linalg.eigvals(loop.matrices(_to_values(loop, T))).real.max()
        if worst >= 0:
            raise BDFTError(
                "robust margin: a member of a box certified by zero exclusion is unstable "
                f"(largest real part {worst:g}); the certificate is wrong"
            )
    return ok, dict(st, w_max=w_max)


def _resolve_method(loop, region, method: str) -> str:
    """``auto``: the value-set route for a family's open loop and the open left half-plane
    (where it applies), else the eigenvalue enclosures."""
    if method != "auto":
        return method
    if (
        isinstance(loop, _FamilyLoop)
        and loop.controller is None
        and region.decay_rate == 0
        and region.min_damping == 0
        and ValueSetLoop.applies(loop.family)
    ):
        return "valueset"
    return "eigenvalues"


def _mu_scale(loop, k, region, max_boxes, deadline):
    """Robust stability of the box scaled by ``k`` by mu (:mod:`uncertainty.mucover`).

    The state matrix's LFT over the box, ``A(delta) = A0 + L Delta (I - F Delta)^-1 R``,
    shifted by the required decay rate: every member's poles lie left of
    ``-max(decay_rate, STABILITY_TOL)`` when the shifted centre is stable and
    ``mu(R (jw I - A0 - a I)^-1 L + F) < 1`` at every frequency (the main loop theorem).
    ``max_boxes`` bounds the frequencies the cover may use."""
    sysA = loop.system
    n = sysA.nstates
    lo, hi = scaled_bounds(sysA, k)
    state = uss(sysA.A, np.zeros((n, 1)), np.zeros((1, n)), [[0.0]])
    bounds = {nm: (a, b) for nm, a, b in zip(loop.names, lo, hi) if nm in state.parameters}
    form = lft_form(state, bounds=bounds) if state.parameters else None
    shift = max(region.decay_rate, STABILITY_TOL)
    if form is None or not form.blocks:
        A = np.asarray(sysA.nominal().A, float) + shift * np.eye(n)
        ok = bool(np.linalg.eigvals(A).real.max() < 0)
        return ok, {"method": "mu", "frequencies": 0, "note": "the state matrix is certain"}
    R = sum(r for _, r in form.blocks)
    M = form.M
    A = np.asarray(M.A, float) + shift * np.eye(n)
    B, C, D = (np.asarray(x, float) for x in (M.B[:, :R], M.C[:R], M.D[:R, :R]))
    stats = {"method": "mu", "blocks": [list(b) for b in form.mu_blocks]}
    rightmost = float(np.linalg.eigvals(A).real.max())
    if rightmost >= 0:
        return False, dict(stats, reason="the box's centre member is outside the region")
    res = mu_cover(A, B, C, D, form.mu_blocks, max_frequencies=max_boxes, deadline=deadline)
    stats.update(
        frequencies=len(res["frequencies"]),
        peak_mu_upper=max((f["mu_upper"] for f in res["frequencies"]), default=0.0),
    )
    if not res["certified"]:
        stats["reason"] = res["reason"]
        return False, stats
    # seeded members of the certified box, its corners first: any outside the region
    # means the certificate is wrong
    lo_t, hi_t = _scaled_t(loop, k)
    T = lo_t + np.random.default_rng(0).random((16, len(lo_t))) * (hi_t - lo_t)
    T[0], T[1] = lo_t, hi_t
    worst = float(region.violation(np.linalg.eigvals(loop.matrices(_to_values(loop, T)))).max())
    if worst >= 0:
        raise BDFTError(
            "robust margin: a member of a box certified by mu is outside the region "
            f"(violation {worst:g}); the certificate is wrong"
        )
    return True, stats


def _certify_scale(loop, k, region, max_boxes, deadline, method, jobs=1, scheduler=None):
    if method == "valueset":
        return _valueset_scale(loop, k, max_boxes)
    if method == "mu":
        return _mu_scale(loop, k, region, max_boxes, deadline)
    lo_t, hi_t = _scaled_t(loop, k)
    task = functools.partial(_box_task, loop, region, method)
    count = [0]
    local = jobs == 1 and scheduler_address(scheduler) is None

    def certify_many(batch):
        boxes = [(a, b, count[0] + i + 1) for i, (a, b) in enumerate(batch)]
        count[0] += len(batch)
        if local or len(boxes) == 1:
            return [task(x) for x in boxes]
        if scheduler_address(scheduler) is not None:
            return map_tasks(task, boxes, jobs=jobs, scheduler=scheduler)
        # local processes: one task per process, the boxes dealt in turn and put back in
        # order (a box takes 10-20 ms; a step of one task per box spent about 16 ms more in
        # dispatch than in its work)
        n = min(jobs, len(boxes))
        done = map_tasks(
            functools.partial(_boxes_task, task), [boxes[i::n] for i in range(n)], jobs=jobs
        )
        out = [None] * len(boxes)
        for i, part in enumerate(done):
            out[i::n] = part
        return out

    ok, stats = subdivide(
        lambda a, b: certify_many([(a, b)])[0],
        lo_t,
        hi_t,
        max_boxes=max_boxes,
        deadline=deadline,
        wave=WAVE,
        certify_many=certify_many,
    )
    return ok, dict(stats, method=method)


def margin_lower_bound(
    family: Family | USS,
    *,
    controller: ct.StateSpace | None = None,
    region: Region | None = None,
    k_hint: float = 1.0,
    ladder: int = 8,
    iterations: int = 4,
    max_boxes: int = DEFAULT_BOXES,
    time_limit_s: float = 600.0,
    method: str = "auto",
    progress: Callable[[str], None] | None = None,
    jobs: int = 1,
    scheduler: str | None = None,
) -> tuple[float, dict]:
    """Certified lower bound of the robust margin (see the module notes).

    Parameters
    ----------
    family : Family or USS
        The family, or an uncertain system (:func:`uncertainty.uss`; closed with
        ``controller`` by negative feedback when one is given).
    controller : control.StateSpace, optional
        Compensator in the loop's convention (a family) or in the feedback path of the
        system (``system.feedback(controller)``).
    region : Region, optional
        Required region (default: open left half-plane). The eigenvalue method certifies
        all of it; the Lyapunov method its decay rate only.
    k_hint : float
        Top of the search (e.g. the upper bound), > 0.
    ladder : int
        Scales tried upwards first: ``k_hint / 2^ladder, ..., k_hint / 2, k_hint``,
        stopping at the first that is not certified.
    iterations : int
        Bisection steps after the ladder.
    max_boxes : int
        Sub-boxes tried per scale.
    time_limit_s : float
        Wall-clock safety limit of the whole search, s (shared equally by the scales
        tried). The result is set by the box budget and is the same on every machine
        unless this limit is hit, which the history records.
    method : str
        ``"auto"`` (default: ``"valueset"`` where it applies, else ``"eigenvalues"``),
        ``"eigenvalues"`` (verified eigenvalue enclosures over sub-boxes, see
        :func:`certify_box`), ``"lyapunov"`` (a quadratic Lyapunov certificate of the
        interval matrix, :func:`certify_interval_matrix`; decay rate only) or
        ``"valueset"`` (zero exclusion on value sets, :mod:`uncertainty.valueset`: a family
        of the physical human without a compensator, the open left half-plane; its budget
        is :data:`VALUESET_CELLS_PER_BOX` cells per box of ``max_boxes``) or ``"mu"`` (an
        uncertain system's state matrix as an LFT over the scaled box, the mixed-mu upper
        bound below 1 at every frequency, :mod:`uncertainty.mucover`; decay rate only;
        ``max_boxes`` caps the frequencies of one scale). The method used is the
        certificate's ``"method"``.
    progress : callable, optional
        Called with a short message at each scale.
    jobs : int
        Local worker processes that certify the sub-boxes of each step (:data:`WAVE` at a
        time); 1 certifies them in this process.
    scheduler : str, optional
        A Dask scheduler's address (or ``$DASK_SCHEDULER_ADDRESS``): the sub-boxes are
        certified on its workers (:func:`robust.engine.map_tasks`). Every engine gives the
        same result and statistics.

    Returns
    -------
    lower : float
        Largest certified scale (0 if not even the nominal member is certified).
    certificate : dict
        Per-scale statistics and the summary of the certified scale.
    """
    region = region or Region()
    if method not in LOWER_METHODS:
        raise ParameterError(f"method: expected one of {LOWER_METHODS}; got {method!r}")
    if method == "lyapunov":
        region = Region(decay_rate=region.decay_rate)
    jobs = check_int("margin_lower_bound: jobs", jobs, low=1)
    loop = _loop(family, controller)
    method = _resolve_method(loop, region, method)
    if method == "valueset":
        why = (
            "needs a family without a compensator"
            if not isinstance(loop, _FamilyLoop) or loop.controller is not None
            else ValueSetLoop.why_not(loop.family)
            or ("certifies the open left half-plane only" if region != Region() else "")
        )
        if why:
            raise ParameterError(f"margin_lower_bound: method 'valueset' {why}")
    if method == "mu":
        why = (
            "needs an uncertain system (uncertainty.uss), not a family's loop"
            if not isinstance(loop, _SystemLoop)
            else "certifies a decay rate only (the damping cone is not mapped)"
            if region.min_damping > 0
            else ""
        )
        if why:
            raise ParameterError(f"margin_lower_bound: method 'mu' {why}")
    step = progress or (lambda msg: None)
    start = time.perf_counter()
    history = []
    ok0, st0 = _certify_scale(loop, 0.0, region, 1, start + 1e9, method)
    history.append({"scale": 0.0, "certified": ok0, **st0})
    if not ok0:
        return 0.0, {"history": history, "certified_scale": None, "method": method}
    top = float(k_hint) if math.isfinite(k_hint) and k_hint > 0 else 1.0
    per_scale = time_limit_s / (ladder + iterations + 1)

    def attempt(k):
        step(f"lower bound: certifying the box at scale {k:.4g}")
        deadline = min(time.perf_counter() + per_scale, start + time_limit_s)
        ok, st = _certify_scale(loop, k, region, max_boxes, deadline, method, jobs, scheduler)
        history.append({"scale": float(k), "certified": ok, **st})
        return ok, st

    # a ladder up from top / 2^ladder (certification gets harder quickly with the scale),
    # then bisection between the last certified and the first failed scale
    # an attempt that found an unstable member (the value-set probe) caps the search at
    # that member's own scale, and the smallest such member is kept as a witness
    good, good_stats, bad, witness = 0.0, st0, None, None

    def failed(k, st):
        nonlocal witness
        if "unstable_scale" in st and (witness is None or st["unstable_scale"] < witness[0]):
            witness = (st["unstable_scale"], st["unstable_member"])
        return min(k, witness[0]) if witness is not None else k

    for j in range(ladder, -1, -1):
        k = top / 2.0**j
        if time.perf_counter() - start > time_limit_s:
            break
        ok, st = attempt(k)
        if not ok:
            bad = failed(k, st)
            break
        good, good_stats = k, st
    for _ in range(iterations if bad is not None else 0):
        if time.perf_counter() - start > time_limit_s:
            break
        if bad <= good:
            break
        k = 0.5 * (good + bad)
        ok, st = attempt(k)
        if ok:
            good, good_stats = k, st
        else:
            bad = failed(k, st)
    out = {
        "history": history,
        "certified_scale": good,
        "certified_stats": good_stats,
        "method": method,
    }
    if witness is not None:
        out["unstable_member"] = {"scale": witness[0], "parameters": witness[1]}
    return good, out


_LOWER_TEXT = {
    "mu": "main loop theorem: the state matrix's LFT over the scaled box (Zhou, Doyle & "
    "Glover 1996, ch. 10), shifted by the decay rate; the mixed-mu upper bound (D-G "
    "scalings, Fan, Tits & Doyle 1991) below 1 at every frequency, each frequency's "
    "scalings holding on the interval between the nearest imaginary-axis zeros of the "
    "scaled Popov function (Ferreres & Biannic 1998), backed by direct checks; intervals "
    "added until [0, inf] is covered; 16 seeded members of each certified box (its "
    "corners first) checked with numpy eigenvalues; bisection on the scale",
    "eigenvalues": "verified eigenvalue enclosures over sub-boxes: the closed-loop matrix in "
    "mean-value form about each sub-box's centre (interval forward differentiation, Moore, "
    "Kearfott & Cloud 2009), every eigenvalue of every member enclosed by a Krawczyk-type "
    "operator in the centre's eigenvector basis (Rump 2001; Krawczyk 1969), the enclosures "
    "disjoint and inside the region; each certified sub-box spot-checked against numpy "
    "eigenvalues of seeded members; box subdivision; bisection on the scale",
    "valueset": "zero exclusion on value sets (Barmish 1994, ch. 7): the characteristic "
    "polynomial factored as the blocks' times 1 + L(s), L the product of the tracking loop, "
    "the structure's and the human's transfer functions (disjoint parameters); over cells of "
    "frequency x parameter sub-box, each factor's numerator and denominator in log-polar "
    "mean-value form (interval forward differentiation), their sum a zonotope that must miss "
    "-1; frequencies up to a Perron bound of every eigenvalue modulus; cell subdivision; "
    "the nominal member's stability and seeded members of each certified box checked with "
    "numpy eigenvalues; bisection on the scale",
    "lyapunov": "interval enclosure of the closed-loop matrix over sub-boxes (midpoint-radius "
    "interval arithmetic, Rump 1999) and a quadratic Lyapunov certificate for the "
    "norm-bounded set (Boyd et al. 1994, Sec. 5.1; Patel & Toda 1980), LMIs by cvxpy with "
    "Clarabel, each certificate re-checked in numpy; box subdivision; bisection",
}


def robust_margin(
    family: Family | USS,
    *,
    controller: ct.StateSpace | None = None,
    region: Region | None = None,
    samples: int = 1000,
    seed: int = 0,
    max_boxes: int = DEFAULT_BOXES,
    ladder: int = 8,
    iterations: int = 4,
    time_limit_s: float = 600.0,
    method: str = "auto",
    progress: Callable[[str], None] | None = None,
    jobs: int = 1,
    scheduler: str | None = None,
) -> MarginResult:
    """Both bounds of the robust margin of ``family`` (with ``controller``) for ``region``.

    Parameters
    ----------
    family : Family or USS
        The family, or an uncertain system (:func:`uncertainty.uss`; closed with
        ``controller`` by negative feedback when one is given).
    controller : control.StateSpace, optional
        Compensator in the loop's convention (a family) or in the feedback path of the
        system (``system.feedback(controller)``).
    region : Region, optional
        Required region (default: open left half-plane).
    samples, seed : int
        Upper-bound search: Latin-hypercube members per scale and seed.
    max_boxes : int
        Lower bound: sub-boxes tried per scale (sets the result).
    ladder, iterations : int
        Lower bound: scales tried upwards from ``upper / 2^ladder``, then bisection steps.
    time_limit_s : float
        Lower bound: wall-clock safety limit, s.
    method : str
        Lower bound: ``"auto"``, ``"eigenvalues"``, ``"lyapunov"`` or ``"valueset"`` (see
        :func:`margin_lower_bound`).
    progress : callable, optional
        Called with a short message at each step.
    jobs, scheduler
        Lower bound: where the sub-boxes are certified (see :func:`margin_lower_bound`;
        the same result on every engine).

    Returns
    -------
    MarginResult

    Examples
    --------
    A mass on a spring with an uncertain damper: ``s^2 + c s + 4`` decays faster than
    0.3 1/s while ``c > 0.6``; the damper's low end reaches 0.6 at the scale 0.5 (the upper
    bound is the critical member's own scale, within 1e-3 of it):

    >>> from uncertainty import Region, robust_margin, ureal, uss
    >>> c = ureal("c", 1.0, 0.2, 3.0)
    >>> G = uss([[0, 1], [-4, -c]], [[0], [1]], [[1, 0]], [[0]])
    >>> res = robust_margin(G, region=Region(decay_rate=0.3))
    >>> round(res.lower, 3), round(res.upper, 4), round(res.critical["parameters"]["c"], 4)
    (0.485, 0.5005, 0.5996)
    """
    region = region or Region()
    loop = _loop(family, controller)
    t0 = time.perf_counter()
    upper, critical, search = margin_upper_bound(
        loop,
        region=region,
        samples=samples,
        seed=seed,
        progress=progress,
    )
    t1 = time.perf_counter()
    lower, cert = margin_lower_bound(
        loop,
        region=region,
        k_hint=min(upper, 8.0),
        max_boxes=max_boxes,
        ladder=ladder,
        iterations=iterations,
        time_limit_s=time_limit_s,
        method=method,
        progress=progress,
        jobs=jobs,
        scheduler=scheduler,
    )
    witness = cert.get("unstable_member")
    if witness is not None and witness["scale"] < upper:
        # the certificate's probe found a member the search missed: the first violating
        # member on its segment from the nominal is the critical member
        k, row = _ray_critical(loop, witness["parameters"], region)
        if k < upper:
            upper, critical = k, _critical(loop, row, region, k)
            critical["found_by"] = "the lower bound's probe of its surviving cells"
    t2 = time.perf_counter()
    if lower > upper:
        raise BDFTError(
            f"robust_margin: certified lower bound {lower:g} exceeds the upper bound {upper:g}; "
            "the certificate or the search is wrong"
        )
    method = {
        "upper": "worst-case search: seeded Latin hypercube of the scaled box, L-BFGS-B with "
        "eigenvalue gradients from the worst samples, bisection on the scale; the violating "
        "member found (or an unstable member found by the lower bound's probe of its value "
        "sets, when its scale is smaller) moved to the first violating member on its "
        "segment from the nominal (bisection to 1e-3 of the scale), whose scale is the "
        "bound; the critical member is re-checked with python-control",
        "lower": _LOWER_TEXT[cert.get("method", method)],
        "lower_region": (
            Region(decay_rate=region.decay_rate) if method == "lyapunov" else region
        ).describe()
        + (
            " (the damping requirement is checked by the upper bound only)"
            if method == "lyapunov" and region.min_damping > 0
            else ""
        ),
        "scaling": "each parameter scaled about its nominal in its own coordinates (log for "
        "log-uniform); non-negative linear ranges floored at 1e-6 of their upper end",
    }
    return MarginResult(
        lower=lower,
        upper=upper,
        critical=critical,
        region=region,
        method=method,
        certificate=cert,
        search=search,
        timings_s={"upper": t1 - t0, "lower": t2 - t1},
    )
