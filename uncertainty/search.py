"""The upper bound of the robust margin: a worst-case search of the scaled box.

The scaled box first (:func:`scaled_bounds`): each parameter scaled about its nominal by
``k`` in its own coordinates (log for log-uniform, linear otherwise), non-negative linear
ranges floored at :data:`PHYSICAL_FLOOR` of their upper end. Its private helpers
(``_coords``, ``_to_values``, ``_scaled_t``, ``_member_scale``) are the coordinates the
certificates (:mod:`uncertainty.boxcert`), the lower bound (:mod:`uncertainty.margins`) and
robust performance (:mod:`uncertainty.performance`) share.

The search (:func:`worst_member` at one scale, :func:`margin_upper_bound` over the scales):
a seeded Latin-hypercube sample of the scaled box (batched poles), then local optimisation
(L-BFGS-B) from the worst samples, with eigenvalue gradients
``d lambda = w^H dA u / (w^H u)`` (``dA`` by central differences of the batched closed-loop
matrix); bisection on the scale. The violating member found is moved to the first violating
member on its segment from the nominal (bisection to 1e-3 of its scale), and that member's
own scale (the smallest box holding it) is the bound: it proves ``k_m <= k``. The member is
re-checked with python-control's poles of its loop before it is reported.

Split out of :mod:`uncertainty.margins` (whose module notes give the whole method) so that
the upper bound and the scaled box are one concern, apart from the certificates of the
lower bound. The loops it searches come from :mod:`uncertainty.enclosure`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import control as ct
import numpy as np
import scipy.linalg as sla
from scipy.optimize import minimize
from scipy.stats import qmc

from robust.analysis.stability import STABILITY_TOL, in_band
from robust.errors import ParameterError
from uncertainty.enclosure import MarginFamily, loop_region, margin_loop
from uncertainty.region import Region
from uncertainty.uss import USS

__all__ = ["PHYSICAL_FLOOR", "scaled_bounds", "worst_member", "margin_upper_bound"]

#: Floor of a scaled linear range, relative to its upper end (keeps parameters physical).
PHYSICAL_FLOOR = 1e-6


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


def first_violation_on_segment(loop, row, violates, rel: float = 1e-3):
    """The first member on the segment from the nominal to the member ``row`` (values) for
    which ``violates(member)`` holds, to ``rel`` of its scale by bisection (in the scaled
    coordinates, log for log-uniform parameters): ``(scale, member)``.

    ``row`` itself must violate and the nominal must not; the member returned violates, so
    its scale is an upper bound of any margin the predicate defines."""
    logs, tn, _, _, _ = _coords(loop)
    row = np.asarray(row, float)
    t_row = np.where(logs, np.log(np.where(logs, row, 1.0)), row)

    def at(s):
        return _to_values(loop, (tn + s * (t_row - tn))[None])[0]

    lo, hi = 0.0, 1.0
    for _ in range(60):
        if hi - lo <= rel * hi:
            break
        mid = 0.5 * (lo + hi)
        if violates(at(mid)):
            hi = mid
        else:
            lo = mid
    out = at(hi)
    return _member_scale(loop, out), out


def _ray_critical(loop, row, region, rel: float = 1e-3):
    """The first member outside ``region`` on the segment from the nominal to ``row``
    (:func:`first_violation_on_segment`): ``(scale, row)``."""
    return first_violation_on_segment(
        loop, row, lambda m: _violations(loop, m[None], region)[0][0] > 0, rel
    )


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
    loop = margin_loop(family, None)
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
    family: MarginFamily | USS,
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
    loop = margin_loop(family, controller)
    return _worst_in_box(
        loop,
        float(k),
        loop_region(loop, region),
        samples=samples,
        seed=seed,
        starts=starts,
    )


def margin_upper_bound(
    family: MarginFamily | USS,
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
    loop = margin_loop(family, controller)
    region = loop_region(loop, region)
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
