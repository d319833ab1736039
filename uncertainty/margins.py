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

    By mu (``method="mu"``, the automatic choice for a loop closed by a compensator and
    wherever the value sets do not apply): the closed-loop state matrix as an LFT over
    the scaled box, and the mixed-mu upper bound below 1 on every edge of the region, no
    frequency grid trusted (:func:`_region_maps`: the decay line, the damping cone's
    edges, and for a damping ratio asked in a band only the cone's edge over the band
    and the band's edges ``|Im s| = w0``); the scales are tried downwards from just
    below the upper bound.

Modules
-------
The margin's parts live in modules of their own, in layers (each imports only those
above it):

* :mod:`uncertainty.region`: the required region :class:`Region` and the result
  :class:`MarginResult`;
* :mod:`uncertainty.enclosure`: interval enclosures of the closed-loop matrix
  (:func:`closed_loop_enclosure`) and the loops the margin analyses (a family's with a
  controller, or an uncertain system);
* :mod:`uncertainty.search`: the scaled box (:func:`scaled_bounds`) and the upper bound
  (:func:`worst_member`, :func:`margin_upper_bound`);
* :mod:`uncertainty.boxcert`: the certificates of one sub-box (:func:`certify_box`,
  :func:`certify_interval_matrix`);
* here: the lower bound (the bisection on the scale, the sub-box subdivision on every
  engine, the value-set and mu routes: :func:`margin_lower_bound`) and the margin itself
  (:func:`robust_margin`). The public names of those modules are imported here too.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable

import control as ct
import numpy as np

from robust.analysis.box_subdivision import subdivide
from robust.analysis.stability import STABILITY_TOL
from robust.checks import check_int
from robust.engine import map_tasks, scheduler_address
from robust.errors import BDFTError, ParameterError
from uncertainty.boxcert import _box_task, _boxes_task, certify_box, certify_interval_matrix
from uncertainty.constants import DEFAULT_BOXES, LOWER_METHODS
from uncertainty.enclosure import MarginFamily, loop_region, margin_loop
from uncertainty.lft import lft_form
from uncertainty.mucover import G_MAX, mu_cover
from uncertainty.region import EVERY_FREQUENCY_HZ, MarginResult, Region
from uncertainty.search import (
    _critical,
    _local_worst,
    _member_scale,
    _ray_critical,
    _scaled_t,
    _to_values,
    _violations,
    margin_upper_bound,
    scaled_bounds,
    worst_member,
)
from uncertainty.uss import USS, uss

__all__ = [
    "Region",
    "MarginResult",
    "scaled_bounds",
    "certify_interval_matrix",
    "certify_box",
    "DEFAULT_BOXES",
    "LOWER_METHODS",
    "margin_upper_bound",
    "margin_lower_bound",
    "worst_member",
    "robust_margin",
]

# LOWER_METHODS (auto, eigenvalues, lyapunov, valueset) and DEFAULT_BOXES (sub-boxes per
# scale) are defined in uncertainty.constants (the command line reads them without NumPy)
#: Cells of the value-set certificate per sub-box of the budget (``max_boxes``).
VALUESET_CELLS_PER_BOX = 500
#: Sub-boxes taken from the search's stack and certified together per step, on every
#: engine (one process, local processes, a Dask cluster), so that every engine gives the
#: same statistics; the certified scales do not depend on it
#: (:func:`robust.analysis.eigen_enclosure.subdivide`).
WAVE = 8


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
    """:func:`backhoe.families.valueset.certify_scale_valueset` at scale ``k``, the nominal's
    stability first and seeded members of a certified box re-checked (numpy eigenvalues)."""
    lo_t, hi_t = _scaled_t(loop, k)
    centre = loop.matrices(_to_values(loop, (lo_t + hi_t) / 2)[None])[0]
    if np.linalg.eigvals(centre).real.max() >= 0:
        return False, {"cells": 0, "centre_violates": True}
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

    ok, st = loop.certify_valueset(lo_t, hi_t, w_max, max_boxes * VALUESET_CELLS_PER_BOX, probe)
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


def _valueset_why_not(loop, region) -> str:
    """Why the value-set route does not apply to ``loop`` and ``region`` ('' where it does):
    the loop says (a family's open loop may qualify, an uncertain system's never)."""
    why_not = getattr(loop, "valueset_why_not", None)
    return "needs a family without a compensator" if why_not is None else why_not(region)


def _resolve_method(loop, region, method: str) -> str:
    """``auto``: mu for an uncertain system's loop and for a family's loop closed by a
    compensator; the value-set route for a family's open loop and the open left half-plane
    (where it applies); mu for any other loop that gives an uncertain system; else the
    eigenvalue enclosures (mu is the tighter on the family's loops: the CHANGELOG has the
    figures)."""
    if method != "auto":
        return method
    prefers = getattr(loop, "prefers_mu", False)
    if prefers:
        return "mu"
    if not _valueset_why_not(loop, region):
        return "valueset"
    return "mu" if _has_system(loop) else "eigenvalues"


def _has_system(loop) -> bool:
    """Whether ``loop`` gives itself as an uncertain system (the mu route's input)."""
    try:
        loop.system  # noqa: B018 (built on first use; a family without one refuses)
    except (AttributeError, ParameterError):
        return False
    return True


#: The first scales the mu route tries, as fractions of the top of its search (then halving).
_MU_FRACTIONS = (15 / 16, 7 / 8, 3 / 4)

#: Bound of the real blocks' G scalings (relative to D) on the rotated map of the damping
#: cone: the rotated loop is complex and its real parameters' mu bound needs larger G than
#: the shifted axis's :data:`uncertainty.mucover.G_MAX` (on ``s^2 + 2 z w s + w^2`` with a
#: damping ratio of 0.3, G within 10 D certified 0.879 of the exact margin, within 100 D
#: 0.974, within 1000 D the same).
CONE_G_MAX = 100.0


def _region_maps(A0, L, region: Region, shift: float) -> list:
    """The maps whose imaginary axis, over a band, no member's pole may reach.

    ``(what, A, L, band)``: a member of ``A(delta) = A0 + L Delta (I - F Delta)^-1 R`` has a
    pole on the boundary piece ``what`` exactly when ``A(delta)`` mapped by ``s -> a s + b``
    (``A -> a A0 + b I``, ``L -> a L``) has an eigenvalue ``j w`` with ``w`` in ``band``
    (rad/s, ``w >= 0``). With the centre member inside the region, the box's members stay
    inside while no pole of any of them meets the boundary (the poles move continuously
    along the segment from the centre): the mu cover of each map shows that none does.

    * the decay rate: the line ``Re s = -shift``, ``s -> s + shift``, every frequency;
    * a damping ratio ``zeta = cos(theta)`` of every pole: the cone's edges,
      ``s -> e^{j(pi/2 - theta)} s`` turns its lower edge onto the negative imaginary axis
      and the conjugate map its upper one onto the positive axis;
    * a damping ratio in a band ``w_lo <= |Im s| <= w_hi`` only: the region is not convex,
      and its boundary inside the left half-plane is the upper edge between the moduli
      ``w_lo / sin(theta)`` and ``w_hi / sin(theta)`` (the conjugate map over that band)
      and the horizontal segments ``Im s = w0`` (``w0`` = ``w_lo``, ``w_hi``) from the cone
      edge, ``Re s = -w0 cot(theta)``, to the decay line: ``s -> -j (s - j w0)`` turns the
      point ``x + j w0`` into ``-j x``, so the segment is the band ``shift <= w <=
      w0 cot(theta)`` (a pole entering the band with less damping crosses it). The lower
      half-plane's pieces are the conjugates of these: a real matrix's poles come in
      conjugate pairs, and ``mu`` of a conjugate matrix is the same.
    """
    n = A0.shape[0]
    eye = np.eye(n)
    maps = [("decay rate", A0 + shift * eye, L, (0.0, math.inf))]
    if region.min_damping <= 0:
        return maps
    sin_t, cos_t = region.cone
    rot = complex(sin_t, cos_t)
    band_hz = tuple(region.band_hz)
    if band_hz == EVERY_FREQUENCY_HZ:
        maps.append(("damping", rot * A0, rot * L, (0.0, math.inf)))
        maps.append(("damping", rot.conjugate() * A0, rot.conjugate() * L, (0.0, math.inf)))
        return maps
    w_lo, w_hi = (2 * math.pi * f for f in band_hz)
    maps.append(
        ("damping", rot.conjugate() * A0, rot.conjugate() * L, (w_lo / sin_t, w_hi / sin_t))
    )
    for w0 in (w_lo, w_hi):
        edge = cos_t * w0 / sin_t  # -Re s of the cone's edge at Im s = w0
        if 0 < w0 < math.inf and edge > shift:
            maps.append(
                (
                    f"damping at {w0 / (2 * math.pi):g} Hz",
                    -1j * A0 - w0 * eye,
                    -1j * L,
                    (shift, edge),
                )
            )
    return maps


def _mu_scale(loop, k, region, max_boxes, deadline):
    """Robust pole placement of the box scaled by ``k`` by mu (:mod:`uncertainty.mucover`).

    The state matrix's LFT over the box, ``A(delta) = A0 + L Delta (I - F Delta)^-1 R``,
    mapped onto the open left half-plane (the main loop theorem, Zhou, Doyle & Glover 1996,
    ch. 10): shifted by the required decay rate, every member's poles lie left of
    ``-max(decay_rate, STABILITY_TOL)`` when the shifted centre is stable and
    ``mu(R (jw I - A0 - a I)^-1 L + F) < 1`` at every frequency. A damping ratio is
    shown the same way on the maps of the region's other edges (:func:`_region_maps`: the
    cone's edges, rotated onto the imaginary axis, and for a band only the edges of the
    band), each over the frequencies of its piece of the boundary, with the centre member
    inside the region. ``max_boxes`` bounds the frequencies the cover may use over all the
    maps."""
    sysA = loop.system
    n = sysA.nstates
    lo, hi = scaled_bounds(sysA, k)
    state = uss(sysA.A, np.zeros((n, 1)), np.zeros((1, n)), [[0.0]])
    bounds = {nm: (a, b) for nm, a, b in zip(loop.names, lo, hi) if nm in state.parameters}
    form = lft_form(state, bounds=bounds) if state.parameters else None
    shift = max(region.decay_rate, STABILITY_TOL)
    if form is None or not form.blocks:
        A = np.asarray(sysA.nominal().A, float)
        p = np.linalg.eigvals(A)
        ok = bool(p.real.max() + shift < 0) and bool(region.violation(p[None])[0] < 0)
        return ok, {"method": "mu", "frequencies": 0, "note": "the state matrix is certain"}
    R = sum(r for _, r in form.blocks)
    M = form.M
    A0 = np.asarray(M.A, float)
    B, C, D = (np.asarray(x, float) for x in (M.B[:, :R], M.C[:R], M.D[:R, :R]))
    stats = {"method": "mu", "blocks": [list(b) for b in form.mu_blocks]}
    p0 = np.linalg.eigvals(A0)
    if float(region.violation(p0[None])[0]) >= 0:
        return False, dict(stats, reason="the box's centre member is outside the region")
    used, peak = 0, 0.0
    for what, Am, Lm, band in _region_maps(A0, B, region, shift):
        complex_map = np.iscomplexobj(Am)
        res = mu_cover(
            Am,
            Lm,
            C,
            D,
            form.mu_blocks,
            max_frequencies=max_boxes - used,
            deadline=deadline,
            g_max=CONE_G_MAX if complex_map else G_MAX,
            band=band,
        )
        used += len(res["frequencies"])
        peak = max([peak] + [f["mu_upper"] for f in res["frequencies"]])
        if not res["certified"]:
            stats.update(frequencies=used, peak_mu_upper=peak)
            stats["reason"] = f"{what}: {res['reason']}"
            return False, stats
    stats.update(frequencies=used, peak_mu_upper=peak)
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
    family: MarginFamily | USS,
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
        stopping at the first that is not certified (by mu: downwards, ``15/16, 7/8, 3/4,
        1/2, ..., 1/2^ladder`` of ``k_hint``, stopping at the first certified); 0: ``k_hint``
        only.
    iterations : int
        Bisection steps after the ladder.
    max_boxes : int
        Sub-boxes tried per scale.
    time_limit_s : float
        Wall-clock safety limit of the whole search, s (shared equally by the scales
        tried; by mu, each scale may use what is left of it). The result is set by the box
        budget and is the same on every machine unless this limit is hit, which the history
        records.
    method : str
        ``"auto"`` (default: ``"mu"`` for an uncertain system or a family's loop with a
        compensator, else ``"valueset"`` where it applies, else ``"mu"`` where the loop
        gives an uncertain system, else ``"eigenvalues"``),
        ``"eigenvalues"`` (verified eigenvalue enclosures over sub-boxes, see
        :func:`certify_box`), ``"lyapunov"`` (a quadratic Lyapunov certificate of the
        interval matrix, :func:`certify_interval_matrix`; decay rate only) or
        ``"valueset"`` (zero exclusion on value sets, :mod:`backhoe.families.valueset`: a family
        of the physical human without a compensator, the open left half-plane; its budget
        is :data:`VALUESET_CELLS_PER_BOX` cells per box of ``max_boxes``) or ``"mu"`` (the
        state matrix as an LFT over the scaled box, an uncertain system's or the family's
        loop built from the same blocks over uncertain reals
        (:func:`backhoe.families.loop.family_uss`), the mixed-mu upper bound below 1 at every
        frequency, :mod:`uncertainty.mucover`; a decay rate, and a damping ratio of every
        pole by the cone's rotation, or in a band by the cone's edge and the band's edges
        (:func:`_region_maps`); ``max_boxes`` caps the frequencies of one scale; the
        scales are tried downwards from 15/16 of ``k_hint``, then bisected). The method
        used is the certificate's ``"method"``.
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
    if method not in LOWER_METHODS:
        raise ParameterError(f"method: expected one of {LOWER_METHODS}; got {method!r}")
    jobs = check_int("margin_lower_bound: jobs", jobs, low=1)
    loop = margin_loop(family, controller)
    region = loop_region(loop, region)
    if method == "lyapunov":
        region = Region(decay_rate=region.decay_rate)
    method = _resolve_method(loop, region, method)
    if method == "valueset":
        why = _valueset_why_not(loop, region)
        if why:
            raise ParameterError(f"margin_lower_bound: method 'valueset' {why}")
    if method == "mu":
        if not hasattr(loop, "system"):
            raise ParameterError(
                f"margin_lower_bound: method 'mu' needs the loop as an uncertain system (a "
                f"'system' attribute), which {type(loop).__name__} does not give"
            )
    step = progress or (lambda msg: None)
    start = time.perf_counter()
    history = []
    ok0, st0 = _certify_scale(loop, 0.0, region, 1, start + 1e9, method)
    history.append({"scale": 0.0, "certified": ok0, **st0})
    if not ok0:
        return 0.0, {"history": history, "certified_scale": None, "method": method}
    top = float(k_hint) if math.isfinite(k_hint) and k_hint > 0 else 1.0
    # each scale's share of the time limit; mu's certificate has its own budget (at most
    # max_boxes frequencies), and the share cut it short on the family's loop closed by a
    # compensator (31 frequencies, about 46 s, at a scale below the margin), so its scales
    # draw on what is left of the whole limit and the result is set by the budget
    per_scale = time_limit_s if method == "mu" else time_limit_s / (ladder + iterations + 1)

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

    if method == "mu":
        # mu's bound is close to exact on these loops and a cover costs about the same at
        # any scale, so the scales are tried downwards from just below the top (the upper
        # bound, held by a member outside the region): 15/16, 7/8, 3/4, then halving, down
        # to top / 2^ladder, stopping at the first certified; the bisection then works
        # between it and the last that failed (the top itself when none did)
        # (ladder 0: the top only, as for the other methods)
        bad = top
        fractions = _MU_FRACTIONS + tuple(2.0**-j for j in range(1, ladder + 1))
        for f in fractions if ladder > 0 else (1.0,):
            k = top * f
            if time.perf_counter() - start > time_limit_s:
                break
            ok, st = attempt(k)
            if ok:
                good, good_stats = k, st
                break
            bad = failed(k, st)
    else:
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
    "Glover 1996, ch. 10), shifted by the decay rate, and for a damping ratio rotated by "
    "the cone's angle (its negative frequencies covered as the conjugate system's), over "
    "the band's moduli only when the damping is asked in a band, whose edges |Im s| = "
    "w0 are covered from the cone to the decay line by the map s -> -j (s - j w0); the "
    "mixed-mu upper bound (D-G "
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


def _lower_region_text(region: Region, method: str, cert: dict) -> str:
    """What the lower bound's certificate holds for, beside the region asked."""
    if method == "lyapunov":
        text = Region(decay_rate=region.decay_rate).describe()
        if region.min_damping > 0:
            text += " (the damping requirement is checked by the upper bound only)"
        return text
    return region.describe()


def robust_margin(
    family: MarginFamily | USS,
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
        Required region (default: open left half-plane). A damping requirement without a
        band (``Region(min_damping=z)``) applies in the BDFT band (0.5-10 Hz) for a family
        and to every pole for an uncertain system.
    samples, seed : int
        Upper-bound search: Latin-hypercube members per scale and seed.
    max_boxes : int
        Lower bound: sub-boxes tried per scale (sets the result).
    ladder, iterations : int
        Lower bound: scales tried upwards from ``upper / 2^ladder``, then bisection steps.
    time_limit_s : float
        Lower bound: wall-clock safety limit, s.
    method : str
        Lower bound: ``"auto"``, ``"eigenvalues"``, ``"lyapunov"``, ``"valueset"`` or
        ``"mu"`` (see :func:`margin_lower_bound`).
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
    >>> round(res.lower, 4), round(res.upper, 4), round(res.critical["parameters"]["c"], 4)
    (0.4985, 0.5005, 0.5996)
    """
    loop = margin_loop(family, controller)
    region = loop_region(loop, region)
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
        "lower_region": _lower_region_text(region, cert.get("method", method), cert),
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
