"""Robust performance of an uncertain system: the largest box where a weighted bound holds.

The question (MATLAB's ``robgain``/``wcgain``): how far can the uncertain reals move from
their nominal values, every one of them within the box scaled by ``k`` about the nominal
(the scaling of :func:`uncertainty.margins.robust_margin`: 1 is the parameters' own
ranges), while every member is stable and its weighted closed-loop map ``P`` (a selection
of the closed loop's channels between an output and an input weight, divided by ``gamma``)
keeps ``||P||_inf < 1``? The answer is bracketed by two numbers, each checked by its own
computation:

* **lower bound, certified** at every frequency. By the main loop theorem (Packard &
  Doyle, Automatica 29(1), 1993), if ``P``'s linear fractional form ``M`` over the scaled
  box (:func:`uncertainty.lft.lft_form`) is stable and ``mu(M(jw)) < 1`` at every ``w``
  for the structure ``diag(delta_1 I, ..., delta_n I, Delta_p)`` (the parameters' real
  repeated scalars and a full complex performance block), then every member of the box is
  stable with ``||P||_inf < 1``. ``mu < 1`` at one frequency is shown by D-G scalings
  (Fan, Tits & Doyle, IEEE TAC 36(1), 1991; :func:`uncertainty.mussv`). Between
  frequencies no grid is trusted: with the scalings of one frequency fixed, the matrix
  ``F(w) = M^H D M + j (G M - M^H G) - D`` is negative definite on the whole interval
  around it bounded by the nearest real frequencies where ``det F(w) = 0``, and those are
  the imaginary-axis zeros of the para-Hermitian ``[M~ I] Pi [M; I]``, the finite
  eigenvalues of a Hamiltonian-like pencil (the test of Ferreres & Biannic, "A mu analysis
  technique without frequency gridding", ACC 1998). Frequencies are added where the
  intervals leave a gap, until ``[0, inf]`` is covered (the certificate) or a frequency
  shows ``mu >= 1`` (the scale is not certified). The scale is bisected.
* **upper bound**: a member of the box scaled by ``upper`` is unstable or has
  ``||P||_inf >= 1``, computed exactly for that member (Bruinsma-Steinbuch,
  :func:`robust.analysis.norms.hinf_norm`) and re-checked on a dense frequency grid. The
  member is found by a worst-case search (a seeded Latin hypercube of the scaled box, a
  local ascent of the norm from the worst samples, bisection on the scale) and moved to the
  first violating member on its segment from the nominal (bisection to 1e-3 of its scale).

The pole region of :func:`uncertainty.margins.robust_margin` is not asked here: robust
performance means stability and the norm bound; ask both functions for both statements.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

import control as ct
import numpy as np
from scipy.optimize import minimize
from scipy.stats import qmc

from robust.analysis.bounds import bound_ratio
from robust.analysis.norms import hinf_norm, is_stable, sigma_max
from robust.errors import BDFTError, ModelStructureError, ParameterError
from uncertainty.lft import lft_form
from uncertainty.mucover import MAX_FREQUENCIES, mu_cover
from uncertainty.search import _scaled_t, _to_values, first_violation_on_segment, scaled_bounds
from uncertainty.uss import USS, uss

__all__ = [
    "PerformanceResult",
    "performance_system",
    "certify_performance",
    "worst_performance",
    "robust_performance",
]

#: Relative tolerance of the norms the worst-case search compares (the member kept is
#: re-checked at full accuracy).
SEARCH_RTOL = 1e-5
#: Largest scale the searches try (beyond it the bound is reported as reaching it).
K_MAX = 8.0
#: Fractions of the upper bound the lower bound tries, in order, before its bisection: near
#: the upper bound first, for a certificate as tight as the mu bound allows.
FRACTIONS = (0.999, 0.99, 0.95, 0.9, 0.8, 0.6, 0.4, 0.2, 0.1, 0.05, 0.01)


@dataclasses.dataclass(frozen=True)
class PerformanceResult:
    """Bounds of the robust performance margin and the member that breaks the bound.

    Parameters
    ----------
    lower : float
        Certified: every member of the box scaled by ``lower`` is stable with
        ``||P||_inf < 1`` (0 if not even the nominal is certified).
    upper : float
        A member of the box scaled by ``upper`` is unstable or has ``||P||_inf >= 1``
        (``inf`` if none was found up to the search's largest scale).
    worst : dict or None
        That member: ``parameters`` (name -> value), ``scale``, ``norm`` (its exact
        weighted norm, ``inf`` if unstable), ``frequency_hz`` (where the norm peaks),
        ``checked_with``.
    nominal_norm : float
        The nominal member's weighted norm.
    certificate : dict
        The lower bound's certificate at ``lower``: frequencies used, the covered
        intervals (rad/s) with the mu bound at each frequency, and the bisection history.
    method : dict
        The method of each bound.
    timings_s : dict
        Wall-clock seconds of each bound (run information, not part of the numbers).
    """

    lower: float
    upper: float
    worst: dict | None
    nominal_norm: float
    certificate: dict
    method: dict
    timings_s: dict

    def __str__(self) -> str:
        head = f"robust performance margin in [{self.lower:.4g}, {self.upper:.4g}]"
        if self.worst is None:
            return head + f"; nominal weighted norm {self.nominal_norm:.4g}"
        w = self.worst
        return (
            f"{head}; nominal weighted norm {self.nominal_norm:.4g}; worst member at scale "
            f"{w['scale']:.4g} has norm {w['norm']:.4g} at {w['frequency_hz']:.4g} Hz"
        )

    def to_json(self) -> dict:
        """JSON-ready dict."""
        return dataclasses.asdict(self)


# -- the weighted map ------------------------------------------------------------------------
def _selector(labels: Sequence[str], chosen, what: str) -> np.ndarray:
    labels = list(labels)
    if chosen is None:
        return np.eye(len(labels))
    chosen = [chosen] if isinstance(chosen, str) else list(chosen)
    missing = [c for c in chosen if c not in labels]
    if missing or not chosen:
        raise ParameterError(
            f"performance_system: {what} must name signals of the closed loop among "
            f"{tuple(labels)}; got {chosen!r}"
        )
    S = np.zeros((len(labels), len(chosen)))
    for j, c in enumerate(chosen):
        S[labels.index(c), j] = 1.0
    return S


def _weight(W, size: int, what: str) -> USS:
    if W is None:
        return uss([], [], [], np.eye(size))
    if np.ndim(W) == 0 and not isinstance(W, (ct.StateSpace, ct.TransferFunction, USS)):
        w = float(W)
        if not (math.isfinite(w) and w > 0):
            raise ParameterError(f"performance_system: {what} must be > 0; got {W!r}")
        return uss([], [], [], w * np.eye(size))
    Wu = USS._as_uss(W, f"performance_system: {what}")
    if (Wu.ninputs, Wu.noutputs) != (size, size):
        raise ModelStructureError(
            f"performance_system: {what} must be {size} x {size} (the channels chosen); "
            f"got {Wu.noutputs} x {Wu.ninputs}"
        )
    if Wu.parameters:
        raise ModelStructureError(f"performance_system: {what} must not be uncertain")
    return Wu


def performance_system(
    system: USS,
    *,
    controller: ct.StateSpace | None = None,
    inputs=None,
    outputs=None,
    input_weight=None,
    output_weight=None,
    gamma: float = 1.0,
) -> USS:
    """The weighted closed-loop map ``P = W_out T W_in / gamma`` whose norm is asked.

    Parameters
    ----------
    system : USS
        The uncertain system (:func:`uncertainty.uss`), closed with ``controller`` by
        negative feedback (``system.feedback(controller)``) when one is given.
    controller : control.StateSpace, optional
        Compensator in the feedback path.
    inputs, outputs : str or sequence of str, optional
        Names of the closed loop's input and output channels of ``T`` (default: all).
    input_weight, output_weight : number, control system, optional
        Stable, certain weights (numbers or python-control systems of the channels' sizes).
    gamma : float
        The bound: ``||W_out T W_in||_inf < gamma``.

    Returns
    -------
    USS
    """
    if not isinstance(system, USS):
        raise ModelStructureError(
            f"performance_system: expected an uncertain system (uncertainty.uss); "
            f"got {type(system).__name__}"
        )
    if not (isinstance(gamma, (int, float)) and math.isfinite(gamma) and gamma > 0):
        raise ParameterError(f"performance_system: gamma must be a finite value > 0; got {gamma!r}")
    closed = system if controller is None else system.feedback(controller, sign=-1)
    Si = _selector(closed.inputs, inputs, "inputs")
    So = _selector(closed.outputs, outputs, "outputs").T
    T = uss([], [], [], So) * closed * uss([], [], [], Si)
    Wo = _weight(output_weight, So.shape[0], "output_weight")
    Wi = _weight(input_weight, Si.shape[1], "input_weight")
    return uss([], [], [], np.eye(So.shape[0]) / float(gamma)) * Wo * T * Wi


def _check_system(P) -> USS:
    if not isinstance(P, USS):
        raise ModelStructureError(
            f"robust performance: expected the weighted map as an uncertain system "
            f"(performance_system); got {type(P).__name__}"
        )
    if not P.parameters:
        raise ParameterError(
            "robust performance: the system has no uncertain real (build it with uncertainty.ureal)"
        )
    if P.nstates == 0:
        raise ModelStructureError("robust performance: the system has no state (a static gain)")
    return P


# -- exact norms of members ------------------------------------------------------------------
def _peak(sys: ct.StateSpace, rtol: float, band) -> tuple[float, float]:
    """``(peak gain, its frequency rad/s)`` of a member: its H-infinity norm, or with a band
    (rad/s) the largest gain over the band, exact at every frequency of it
    (:func:`robust.analysis.bounds.bound_ratio` against 1); ``(inf, nan)`` if unstable."""
    if band is None:
        val, w = hinf_norm(sys, rtol=rtol, return_frequency=True)
        return float(val), float(w)
    if not is_stable(sys):
        return math.inf, math.nan
    unit = (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1)))
    hz = (band[0] / (2 * math.pi), band[1] / (2 * math.pi))
    r = bound_ratio(sys, [unit], band_hz=hz, rtol=min(max(rtol, 1e-12), 0.1))
    return float(r.value), 2 * math.pi * float(r.frequency_hz)


def _member_norm(P: USS, names, row, rtol: float = 1e-9, band=None) -> tuple[float, float]:
    """``(||P_member||_inf, peak frequency rad/s)``, over ``band`` (rad/s) if given;
    ``(inf, nan)`` if unstable or unbounded.

    ``rtol`` is the norm's relative tolerance (the searches use a coarse one)."""
    try:
        sys = P.at(dict(zip(names, (float(x) for x in row))))
    except (ParameterError, ZeroDivisionError, FloatingPointError):
        return math.inf, math.nan
    if not np.all(np.isfinite(sys.A)):
        return math.inf, math.nan
    return _peak(sys, rtol, band)


class _Loop:
    """The weighted map seen by the scaled-box helpers of :mod:`uncertainty.search`."""

    def __init__(self, P: USS, band=None):
        self.system = P
        self.parameters = tuple(P.parameters.values())
        self.names = tuple(P.parameters)
        self.band = band

    def norm(self, row, rtol: float = 1e-9) -> tuple[float, float]:
        """A member's weighted norm (over the band, if any) and where it peaks."""
        return _member_norm(self.system, self.names, row, rtol, self.band)


def _worst_at(loop: _Loop, k: float, samples: int, seed: int, starts: int):
    lo_t, hi_t = _scaled_t(loop, k)
    d = len(lo_t)
    T = lo_t + qmc.LatinHypercube(d=d, seed=seed).random(samples) * (hi_t - lo_t)
    rows = _to_values(loop, T)
    vals = np.array([loop.norm(r, SEARCH_RTOL)[0] for r in rows])
    order = np.argsort(-vals)
    best, best_t = float(vals[order[0]]), T[order[0]]
    if not math.isfinite(best):
        return best, rows[order[0]]
    span = np.where(hi_t > lo_t, hi_t - lo_t, 1.0)
    bounds = [(0.0, 1.0) if w > 0 else (0.0, 0.0) for w in hi_t - lo_t]

    def fun(x):
        row = _to_values(loop, (lo_t + x * span)[None])[0]
        v = loop.norm(row, SEARCH_RTOL)[0]
        return -min(v, 1e12)

    for i in order[:starts]:
        res = minimize(
            fun,
            (T[i] - lo_t) / span,
            method="L-BFGS-B",
            bounds=bounds,
            options={"maxiter": 25, "eps": 1e-7},
        )
        if -res.fun > best:
            best, best_t = float(-res.fun), lo_t + res.x * span
        if not math.isfinite(best) or best >= 1e12:
            break
    return best, _to_values(loop, best_t[None])[0]


def worst_performance(
    system: USS, k: float, *, samples: int = 200, seed: int = 0, starts: int = 3
) -> tuple[float, np.ndarray]:
    """The member of the box scaled by ``k`` with the largest weighted norm found.

    Parameters
    ----------
    system : USS
        The weighted map (:func:`performance_system`).
    k : float
        Scale of the box about the nominal (>= 0).
    samples, seed, starts : int
        Latin-hypercube members, their seed, local ascents from the worst of them.

    Returns
    -------
    norm : float
        The largest weighted norm found (``inf``: an unstable member).
    row : numpy.ndarray
        That member's values, in ``system.parameters`` order.
    """
    if not (isinstance(k, (int, float)) and math.isfinite(k) and k >= 0):
        raise ParameterError(f"worst_performance: k must be a finite scale >= 0; got {k!r}")
    return _worst_at(_Loop(_check_system(system)), float(k), samples, seed, starts)


def _ray_violation(loop: _Loop, row, rel: float = 1e-3):
    """The first member with norm >= 1 on the segment from the nominal to ``row``."""
    return first_violation_on_segment(loop, row, lambda m: loop.norm(m)[0] >= 1.0, rel)


def _worst_record(loop: _Loop, row, k: float) -> dict:
    val, w = loop.norm(row)
    out = {
        "scale": float(k),
        "parameters": dict(zip(loop.names, (float(x) for x in row))),
        "norm": val,
        "frequency_hz": w / (2 * math.pi) if math.isfinite(w) else w,
        "checked_with": "Bruinsma-Steinbuch H-infinity norm of the member"
        if loop.band is None
        else "the largest gain over the band, exact at every frequency (bound_ratio)",
    }
    if math.isfinite(val):
        # a second algorithm: the largest singular value on a dense grid about the peak
        sys = loop.system.at(out["parameters"])
        grid = np.concatenate([np.logspace(-4, 6, 4001), [w] if math.isfinite(w) and w > 0 else []])
        if loop.band is not None:
            grid = grid[(grid >= loop.band[0]) & (grid <= loop.band[1])]
            grid = np.concatenate([grid, [x for x in loop.band if math.isfinite(x)]])
        out["grid_norm"] = float(np.max(sigma_max(sys, grid)))
        out["checked_with"] += " and the largest singular value on 4,000 frequencies"
    else:
        sys = loop.system.at(out["parameters"])
        out["rightmost_pole"] = complex(max(np.linalg.eigvals(sys.A), key=lambda p: p.real))
        out["checked_with"] = "the member is unstable (eigenvalues of its state matrix)"
    return out


def _upper_bound(loop: _Loop, samples: int, seed: int, starts: int, iterations: int, step):
    history = []

    def probe(k):
        step(f"upper bound: searching the box at scale {k:.4g}")
        v, row = _worst_at(loop, k, samples, seed, starts)
        history.append({"scale": float(k), "worst_norm": v})
        return v, row

    good, bad, bad_row = 0.0, None, None
    k = 1.0
    while k <= K_MAX:
        v, row = probe(k)
        if v >= 1.0:
            bad, bad_row = k, row
            break
        good, k = k, 2 * k
    if bad is None:
        return math.inf, None, history
    for _ in range(iterations):
        mid = 0.5 * (good + bad)
        v, row = probe(mid)
        if v >= 1.0:
            bad, bad_row = mid, row
        else:
            good = mid
    k_ray, row_ray = _ray_violation(loop, bad_row)
    if k_ray <= bad:
        bad, bad_row = k_ray, row_ray
    return bad, bad_row, history


# -- the certificate ---------------------------------------------------------------------------
def _square(M: ct.StateSpace, R: int):
    """The LFT's matrices with the performance channels padded to a square block."""
    A, B, C, D = (np.asarray(x, float) for x in (M.A, M.B, M.C, M.D))
    n_in, n_out = B.shape[1] - R, C.shape[0] - R
    s = max(n_in, n_out)
    if n_in < s:
        B = np.hstack([B, np.zeros((A.shape[0], s - n_in))])
        D = np.hstack([D, np.zeros((D.shape[0], s - n_in))])
    if n_out < s:
        C = np.vstack([C, np.zeros((s - n_out, A.shape[0]))])
        D = np.vstack([D, np.zeros((s - n_out, D.shape[1]))])
    return A, B, C, D, s


def _lft_at(P: USS, k: float):
    lo, hi = scaled_bounds(P, k)
    return lft_form(P, bounds={n: (a, b) for n, a, b in zip(P.parameters, lo, hi)})


def _band(P: USS, band_hz, owner: str):
    """``band_hz`` checked, in rad/s (``None``: every frequency)."""
    if band_hz is None:
        return None
    try:
        lo, hi = (float(x) for x in band_hz)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{owner}: band_hz must be a pair (low, high) of frequencies in Hz; got {band_hz!r}"
        ) from None
    if not (0.0 <= lo < hi) or math.isnan(hi):
        raise ParameterError(f"{owner}: band_hz must satisfy 0 <= low < high; got {band_hz!r}")
    if P.ninputs != 1 or P.noutputs != 1:
        raise ModelStructureError(
            f"{owner}: a band (band_hz) needs a single-input single-output weighted map; got "
            f"{P.noutputs} outputs and {P.ninputs} inputs"
        )
    return 2 * math.pi * lo, 2 * math.pi * hi


def certify_performance(
    system: USS,
    k: float,
    *,
    max_frequencies: int = MAX_FREQUENCIES,
    time_limit_s: float = 300.0,
    band_hz: tuple[float, float] | None = None,
) -> dict:
    """Certify that every member of the box scaled by ``k`` is stable with ``||P||_inf < 1``.

    With ``band_hz``, that every member is stable and ``|P(jw)| < 1`` at every frequency of
    the band: the mu bound with the performance block is covered over the band only, and
    the stability of the box is certified apart, by the mu bound of the parameters' channels
    alone (``M_11``) over every frequency (the main loop theorem holds frequency by
    frequency once the box is known to be stable).

    Parameters
    ----------
    system : USS
        The weighted map ``P`` (:func:`performance_system`).
    k : float
        Scale of the box about the nominal (>= 0).
    max_frequencies : int
        Frequencies the cover may use before it gives up.
    time_limit_s : float
        Wall-clock limit, s.
    band_hz : (float, float), optional
        The band of the bound, Hz, ``0 <= low < high <= inf`` (a SISO ``P``; default: every
        frequency).

    Returns
    -------
    dict
        ``certified`` (bool), ``scale``, ``frequencies`` (each with its mu upper bound and
        the interval its scalings cover, Hz), ``blocks``; when not certified, ``reason``
        and, where no scalings prove the mu upper bound below 1, ``frequency_hz``; with a
        band, ``stability`` (the same for the box's stability certificate).
    """
    P = _check_system(system)
    band = _band(P, band_hz, "certify_performance")
    if not (isinstance(k, (int, float)) and math.isfinite(k) and k >= 0):
        raise ParameterError(f"certify_performance: k must be a finite scale >= 0; got {k!r}")
    if not (isinstance(max_frequencies, int) and max_frequencies >= 1):
        raise ParameterError(
            f"certify_performance: max_frequencies must be an integer >= 1; got {max_frequencies!r}"
        )
    form = _lft_at(P, float(k))
    R = sum(r for _, r in form.blocks)
    A, B, C, D, s = _square(form.M, R)
    blocks = form.mu_blocks + [(s, "complex")]
    out = {"scale": float(k), "blocks": [list(b) for b in form.mu_blocks] + [[s, "complex"]]}
    rightmost = float(np.max(np.linalg.eigvals(A).real)) if A.shape[0] else -math.inf
    if rightmost >= 0:
        out.update(
            certified=False,
            reason=f"the box's centre member is not stable (rightmost pole real part "
            f"{rightmost:.6g})",
            frequencies=[],
        )
        return out
    deadline = time.perf_counter() + float(time_limit_s)
    if band is not None:
        # the box's stability: mu of the parameters' channels below 1 at every frequency
        stab = mu_cover(
            A,
            B[:, :R],
            C[:R],
            D[:R, :R],
            form.mu_blocks,
            max_frequencies=max_frequencies,
            deadline=deadline,
            least_bound=False,
        )
        out["stability"] = stab
        if not stab["certified"]:
            out.update(
                certified=False,
                reason=f"stability of the box: {stab['reason']}",
                frequencies=[],
            )
            return out
    res = mu_cover(
        A,
        B,
        C,
        D,
        blocks,
        max_frequencies=max_frequencies,
        deadline=deadline,
        band=(0.0, math.inf) if band is None else band,
        least_bound=False,
    )
    out.update(res)
    if out["certified"]:
        # seeded members of the certified box, its corners first: any at or above the bound
        # means the certificate is wrong
        loop = _Loop(P, band)
        lo_t, hi_t = _scaled_t(loop, float(k))
        T = lo_t + np.random.default_rng(0).random((8, len(lo_t))) * (hi_t - lo_t)
        T[0], T[1] = lo_t, hi_t
        worst = max(loop.norm(r, 1e-6)[0] for r in _to_values(loop, T))
        if worst >= 1.0:
            raise BDFTError(
                "robust performance: a member of a box certified by mu has weighted norm "
                f"{worst:g} >= 1; the certificate is wrong"
            )
        out["spot_checked_norm"] = worst
    return out


def robust_performance(
    system: USS,
    *,
    controller: ct.StateSpace | None = None,
    inputs=None,
    outputs=None,
    input_weight=None,
    output_weight=None,
    gamma: float = 1.0,
    samples: int = 64,
    seed: int = 0,
    starts: int = 2,
    iterations: int = 4,
    bisections: int = 5,
    fractions: Sequence[float] = FRACTIONS,
    max_frequencies: int = MAX_FREQUENCIES,
    time_limit_s: float = 600.0,
    band_hz: tuple[float, float] | None = None,
    progress: Callable[[str], None] | None = None,
) -> PerformanceResult:
    """Both bounds of the robust performance margin (module notes).

    The margin is the largest scale ``k`` of the parameters' box about the nominal
    (:func:`uncertainty.search.scaled_bounds`) at which every member is stable with
    ``||W_out T W_in||_inf < gamma``, ``T`` the closed loop's map from ``inputs`` to
    ``outputs``; with ``band_hz``, ``|W_out T W_in (jw)| < gamma`` at every frequency of the
    band (a requirement that holds over a band only, such as tracking in the operator's
    band; :func:`certify_performance`).

    Parameters
    ----------
    system : USS
        The uncertain system (:func:`uncertainty.uss`).
    controller : control.StateSpace, optional
        Closed around ``system`` by negative feedback (``system.feedback(controller)``).
    inputs, outputs : str or sequence of str, optional
        The channels of ``T`` (default: all of the closed loop's).
    input_weight, output_weight : number or control system, optional
        Stable certain weights.
    gamma : float
        The bound.
    samples, seed, starts, iterations : int
        Upper bound: Latin-hypercube members per scale, their seed, local ascents per
        scale, bisection steps on the scale.
    bisections : int
        Lower bound: bisection steps after the first certified scale of the ladder.
    fractions : sequence of float
        Lower bound: the ladder, fractions of the upper bound tried in this order until one
        is certified (:data:`FRACTIONS`; a shorter one starting lower is cheaper where the
        mu bound is far from exact: each scale it fails to certify near the bound costs
        up to ``max_frequencies`` frequencies).
    max_frequencies : int
        Lower bound: frequencies one scale's certificate may use.
    time_limit_s : float
        Lower bound: wall-clock limit, s.
    band_hz : (float, float), optional
        The band of the bound, Hz (a single-input single-output map; default: every
        frequency).
    progress : callable, optional
        Called with a short message at each step.

    Returns
    -------
    PerformanceResult

    Examples
    --------
    A first-order lag ``1 / (s + a)`` with ``a`` in ``[0.5, 3.5]`` about 2 keeps its gain
    below 1 while ``a > 1``: the box's low end reaches 1 at the scale 2/3.

    >>> from uncertainty import robust_performance, ureal, uss
    >>> a = ureal("a", 2.0, 0.5, 3.5)
    >>> G = uss([[-a]], [[1.0]], [[1.0]], [[0.0]])
    >>> res = robust_performance(G)
    >>> round(res.lower, 3), round(res.upper, 3), round(res.worst["parameters"]["a"], 2)
    (0.667, 0.667, 1.0)
    >>> res.lower <= 2 / 3 <= res.upper
    True

    Asked above 0.6 rad/s only, the gain ``1 / sqrt(w^2 + a^2)`` stays below 1 while
    ``a > 0.8``: the scale 0.8.

    >>> import math
    >>> res = robust_performance(G, band_hz=(0.6 / (2 * math.pi), math.inf))
    >>> round(res.lower, 3), res.lower <= 0.8 <= res.upper < 0.802
    (0.8, True)
    """
    step = progress or (lambda msg: None)
    P = _check_system(
        performance_system(
            system,
            controller=controller,
            inputs=inputs,
            outputs=outputs,
            input_weight=input_weight,
            output_weight=output_weight,
            gamma=gamma,
        )
    )
    band = _band(P, band_hz, "robust_performance")
    fracs = [float(f) for f in fractions]
    if not fracs or not all(0.0 < f <= 1.0 for f in fracs):
        raise ParameterError(
            f"robust_performance: fractions must be numbers in (0, 1]; got {fractions!r}"
        )
    loop = _Loop(P, band)
    nominal = _peak(P.nominal(), 1e-9, band)[0]
    t0 = time.perf_counter()
    if nominal >= 1.0:
        upper, row, history = 0.0, np.array([p.nominal for p in loop.parameters]), []
    else:
        upper, row, history = _upper_bound(loop, samples, seed, starts, iterations, step)
    t1 = time.perf_counter()
    deadline = t1 + float(time_limit_s)
    tried = []

    def attempt(k):
        step(f"lower bound: certifying the scale {k:.4g}")
        left = max(deadline - time.perf_counter(), 0.0)
        c = certify_performance(
            P, k, max_frequencies=max_frequencies, time_limit_s=left, band_hz=band_hz
        )
        tried.append(
            {k_: v for k_, v in c.items() if k_ != "frequencies"}
            | {"frequencies_used": len(c["frequencies"])}
        )
        return c

    good, good_cert, bad = 0.0, None, None
    if nominal < 1.0:
        top = upper if math.isfinite(upper) else K_MAX
        for frac in fracs:
            if time.perf_counter() > deadline:
                break
            c = attempt(frac * top)
            if c["certified"]:
                good, good_cert = frac * top, c
                break
            bad = frac * top
        if bad is None and good_cert is not None:
            bad = top if math.isfinite(upper) else None
        for _ in range(bisections if bad is not None and good_cert is not None else 0):
            if time.perf_counter() > deadline:
                break
            mid = 0.5 * (good + bad)
            c = attempt(mid)
            if c["certified"]:
                good, good_cert = mid, c
            else:
                bad = mid
    t2 = time.perf_counter()
    if good > upper:
        raise BDFTError(
            f"robust_performance: certified lower bound {good:g} exceeds the upper bound "
            f"{upper:g}; the certificate or the search is wrong"
        )
    worst = None
    if row is not None and math.isfinite(upper):
        worst = _worst_record(loop, row, upper)
        worst["found_by"] = "worst-case search" if nominal < 1.0 else "the nominal member"
    certificate = dict(good_cert or {"certified": False, "scale": 0.0, "frequencies": []})
    certificate["history"] = tried
    method = {
        "lower": "main loop theorem: mixed mu upper bound (D-G scalings, Fan-Tits-Doyle) of "
        "the weighted map's LFT over the scaled box with a full complex performance block, "
        "below 1 at every frequency: each frequency's scalings hold on the interval bounded "
        "by the nearest imaginary-axis zeros of the scaled Popov function (Ferreres-Biannic), "
        "backed by direct checks inside it; intervals added until [0, inf] is covered"
        + (
            ""
            if band is None
            else " (the band, with the box's stability certified by the parameters' channels' "
            "mu over [0, inf])"
        )
        + "; 8 seeded members of the certified box (its corners first) checked by their exact "
        "norms; bisection on the scale",
        "upper": "worst-case search: seeded Latin hypercube of the scaled box, L-BFGS-B ascent "
        "of the exact H-infinity norm from the worst samples, bisection on the scale; the "
        "violating member moved to the first violating member on its segment from the "
        "nominal (bisection to 1e-3 of the scale); its norm re-checked on a dense grid",
        "scaling": "each parameter scaled about its nominal in its own coordinates, as "
        "robust_margin",
    }
    return PerformanceResult(
        lower=float(good),
        upper=float(upper),
        worst=worst,
        nominal_norm=float(nominal),
        certificate=certificate,
        method=method,
        timings_s={"upper": t1 - t0, "lower": t2 - t1},
    )
