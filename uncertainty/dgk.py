"""Mu-synthesis of an uncertain generalized plant by D-K and D-G-K iteration.

The plant ``P`` (:func:`uncertainty.uss`) has inputs ``[w; u]`` (performance inputs, then
control inputs) and outputs ``[z; y]`` (performance outputs, then measurements), as
:func:`control.hinfsyn`; its uncertain reals are pulled out by :func:`uncertainty.lft_form`
(each ``p = c + h delta``, ``|delta| <= 1``), which gives a certain plant ``M`` with the
``Delta`` channels in front. A controller ``u = K y`` (the lower LFT, as
:func:`control.hinfsyn`) gives the closed loop ``M_K`` from ``[w_Delta; w]`` to
``[z_Delta; z]``; robust performance is ``mu(M_K(jw)) < 1`` at every frequency for the
structure ``diag(delta_1 I_r1, ..., delta_n I_rn, Delta_p)``, ``Delta_p`` a full complex
performance block (the main loop theorem, Packard & Doyle, Automatica 29(1), 1993; the
block padded square as :func:`uncertainty.certify_performance` does).

**The iteration** (Doyle, "Synthesis of robust controllers and filters", CDC 1983;
Balas, Doyle, Glover, Packard & Smith, *mu-Analysis and Synthesis Toolbox*, 1993):

1. *K-step*: H-infinity synthesis on the scaled plant (below): SLICOT ``sb10ad``, the
   routine behind :func:`control.hinfsyn`, asked for the central controller at
   ``gamma = 1`` (Glover & Doyle, Systems & Control Letters 11, 1988) while ``beta`` is
   bisected; the first iterate on ``M`` itself (no scalings).
2. *mu-step*: the D-G upper bound of ``mu(M_K(jw))`` on the frequency grid
   (:mod:`uncertainty.mu`, Fan, Tits & Doyle, IEEE TAC 36(1), 1991), with its scalings
   ``(D, G)`` at each frequency, in the structure the iteration designs for (below).
3. *D-step*: each uncertainty channel's ``D`` fitted by a stable, minimum-phase real
   rational ``d_i(s)`` (second-order sections, which follow a lightly damped resonance, and
   a first-order one; a weighted least-squares fit of ``log |d_i(jw)|^2``) and, in D-G-K,
   its ``G`` by the para-skew ``Y_i(s)`` below (real poles, variable projection). Each pair
   of orders (0 to 4 by default) is scored by its *excess*: how far the bound the fitted
   scalings give the current closed loop rises above the grid's mu, relative to mu's peak
   (the criterion of dkpy's automatic order, a one-sided version); the two best are refined
   to lower their largest excess directly, and the lowest total order within 1 % is kept.
4. Repeat until the grid peak improves by less than 0.5 % twice in a row (or
   ``max_iter``); the iterate with the lowest grid peak of the designed-for mu is kept.

**Design structure.** Each uncertainty channel gets its own scalar ``d_i`` and (D-G-K) ``g_i``:
a diagonal ``D`` and ``G``. For a parameter that appears once (``r_i = 1``) that is the
full set of scalings; a repeated real scalar (``r_i > 1``) allows full Hermitian ``D_i``,
``G_i``, and the diagonal ones bound the mu of each channel as its own real scalar, a larger
set (still an upper bound; first version). D-K (``method="dk"``) treats every channel as a
complex scalar (``G = 0``). The *reported* figures always use the true structure: repeated
real scalars with full ``D_i``, ``G_i``.

**The D-G-K scaled plant.** At one frequency, with ``N = D^(1/2) M D^(-1/2)`` and the
scaled ``G_1 = D^(-1/2) G D^(-1/2)``, the D-G condition
``M^H D M + j (G M - M^H G) - beta^2 D <= 0`` reads

    N^H N + j (G_1 N - N^H G_1) <= beta^2 I,

equivalently ``sigma_max((N / beta - j G_1 / beta)(I + G_1^2 / beta^2)^(-1/2)) <= 1``
(Young, "Controller design for mixed uncertainties", Automatica 32(8), 1996; Young, Newlin
& Doyle, IJRNC 1995). ``-j G_1(w)`` is the value on the imaginary axis of a para-skew real
rational ``Y(s) = -Y(-s)``, which cannot be stable, so it is not a plant block as it
stands. Factor the multiplier instead (a J-spectral factorisation,
``Pi = Psi~ diag(I, -I) Psi`` with ``Psi = [[A, A Y / beta], [0, E]]``):

* ``A(s) = prod (a_j - s) / (a_j + s)``: all-pass, its poles those of the stable half of
  ``Y``; ``Y(s) = -sum_j h_j 2 a_j s / (a_j^2 - s^2)``, so ``A Y`` is stable;
* ``E(s)``: the stable, minimum-phase spectral factor of ``1 + Y~ Y / beta^2``, from the
  Riccati equation of the return-difference identity (Kalman's equality), so that
  ``(A Y / beta) E^(-1)`` and ``E^(-1)`` share one stable realisation.

Then, for any stable minimum-phase ``d_i(s)`` and any ``Y_i`` of that form,

    X_beta = A (D M_K D^-1 + Y) E_beta^-1 / beta,  ||X_beta||_inf < 1

implies at every frequency ``(A N + A Y)^H (A N + A Y) <= beta^2 E^H E = beta^2 I + Y^H Y``,
which is the D-G condition above with ``D = |d(jw)|^2`` and ``G = |d(jw)|^2 j Y(jw)``: the
mixed-mu upper bound of ``M_K`` is below ``beta`` at *every* frequency, whatever the fit's
quality (the fit only decides how conservative). ``X_beta`` is a lower LFT of the scaled
plant and ``K``, so the K-step bisects ``beta`` for the least one at which
:func:`control.hinfsyn` reaches ``||X_beta||_inf < 1``; each such norm is re-computed by the
Bruinsma-Steinbuch algorithm (:func:`robust.analysis.norms.hinf_norm`) before it is used.
D-K is the case ``Y = 0`` (``A = E = 1``): one synthesis, ``beta = ||D M_K D^-1||_inf``.

**The reported figure is independent of all this.** For the best iterate (lowest grid
peak of the designed-for mu), the closed loop's eigenvalues are checked (stable), the D-G
bound with the true structure is evaluated on the grid (``mu_peak_grid``), and the cover of
:func:`uncertainty.mucover.mu_cover` (no grid trusted between frequencies) certifies
``mu(M_K(jw) / b) < 1`` on ``[0, inf]``; ``b`` is raised from just above the grid peak by
factors ``1 + CERT_RTOL`` (or to the cover's own bound where a frequency fails) until a
cover is found: ``mu_peak_certified = b``. By the main loop theorem, every member with
``|delta_i| <= 1 / b`` is then stable with weighted closed-loop norm ``< b``: with ``b < 1``
the whole box (and more) meets the specification.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence

import control as ct
import numpy as np
import scipy.linalg as sla
import slycot

from robust.analysis.norms import hinf_norm, is_stable
from robust.errors import (
    AssumptionError,
    InfeasibleError,
    ModelStructureError,
    ParameterError,
    VerificationError,
)
from robust.synthesis.assumptions import check_hinf_assumptions
from robust.synthesis.genplant import GeneralizedPlant
from uncertainty.dgk_scalings import (
    G_DESIGN_MAX,
    _abcd,
    _DFit,
    _fit_all,
    _identity,
    _Plant,
    _Scalings,
)
from uncertainty.dgk_scalings import _GFit as _GFit
from uncertainty.lft import lft_form
from uncertainty.mu import _balance, _upper
from uncertainty.mucover import MAX_FREQUENCIES, _response, _start_bound, mu_cover
from uncertainty.synthesis import UncertainPlant
from uncertainty.uss import USS

__all__ = ["MusynResult", "musyn", "certified_mu_peak", "METHODS", "DEFAULT_ORDERS"]

#: The iterations: ``"dgk"`` (D and G scalings on real parameters) and ``"dk"`` (every
#: uncertainty channel treated as a complex scalar, D scalings only).
METHODS = ("dgk", "dk")
#: Orders the scalings' fits may take (each fit's order chosen per iteration among them).
DEFAULT_ORDERS = (0, 1, 2, 3, 4)
#: Relative tolerance of the grid's D-G bisection at each frequency.
MU_RTOL = 1e-3
#: Relative tolerance of the K-step's bisection on ``beta``.
BETA_RTOL = 2e-3
#: The iteration stops when a grid peak improves on the best so far by less than this.
IMPROVE_RTOL = 5e-3
#: Ratio of the ladder on the certified bound (``b`` tried at the grid peak times
#: ``1 + CERT_RTOL``, then raised by that factor).
CERT_RTOL = 5e-3


@dataclasses.dataclass(frozen=True)
class MusynResult:
    """The controller of a mu-synthesis and its certified robust performance.

    Parameters
    ----------
    controller : control.StateSpace
        ``u = K y`` (lower LFT, as :func:`control.hinfsyn`): ``nmeas`` inputs, ``ncon`` outputs.
    mu_peak_grid : float
        Largest mixed-mu upper bound (D-G scalings, the true structure) of the closed loop on
        the frequency grid.
    mu_peak_certified : float
        ``b`` with ``mu(M_K(jw)) < b`` at every frequency in ``[0, inf]``, certified by
        :func:`uncertainty.mucover.mu_cover` (module notes); ``inf`` if no cover was found.
    history : tuple of dict
        Per iteration: ``iteration``, ``step`` (``"D-K"`` or ``"D-G-K"``), ``gamma`` (the
        K-step's least ``beta`` with an exact ``||X_beta|| < 1``: an upper bound of the
        designed-for mu at every frequency), ``mu_peak_design`` (grid peak of the mu the
        iteration minimises), ``mu_peak_grid`` (the true structure's), ``orders`` (``D`` and
        ``G`` fit orders), ``fit_peak`` (the fitted scalings' peak bound on the grid for the
        previous closed loop), ``controller_order``, ``seconds``; the first iterate also
        ``start`` (``"identity"``: the unscaled plant; ``"balanced"``: constant scalings
        from Osborne's balancing of the open loop; the one whose synthesis reached the
        lower bound).
    method : str
        ``"D-K"`` or ``"D-G-K"``.
    best_iteration : int
        The iterate returned (index into ``history``).
    frequencies : numpy.ndarray
        The grid, rad/s.
    blocks : tuple of (int, str)
        The true structure: ``(r_i, "real")`` per uncertain real, then the performance block.
    certificate : dict
        The cover at ``mu_peak_certified`` (its frequencies and intervals) and the ladder of
        bounds tried (``tried``).
    stopped : str
        Why the iteration ended: ``"converged"`` (the grid peak improved by less than
        :data:`IMPROVE_RTOL` twice in a row), ``"max_iter"``, or the message of a scaled
        K-step that found no verified controller (the iterates before it are kept).
    """

    controller: ct.StateSpace
    mu_peak_grid: float
    mu_peak_certified: float
    history: tuple
    method: str
    best_iteration: int
    frequencies: np.ndarray
    blocks: tuple
    certificate: dict
    stopped: str = "max_iter"

    def __str__(self) -> str:
        h = self.history[self.best_iteration]
        return (
            f"musyn ({self.method}): peak mu certified {self.mu_peak_certified:.4g} "
            f"(grid {self.mu_peak_grid:.4g}) at iteration {self.best_iteration} of "
            f"{len(self.history) - 1}; controller order {self.controller.nstates}; "
            f"{sum(x['seconds'] for x in self.history):.3g} s"
            + (
                f"; orders D {h['orders']['D']}, G {h['orders']['G']}"
                if self.best_iteration
                else ""
            )
        )


# -- the LFT plant -----------------------------------------------------------------------------
def _check_inputs(P, nmeas, ncon, method, max_iter, orders, frequencies):
    if not isinstance(P, USS):
        raise ModelStructureError(
            f"musyn: P must be an uncertain system (uncertainty.uss); got {type(P).__name__}"
        )
    if not P.parameters:
        raise ParameterError(
            "musyn: P has no uncertain real; mu-synthesis needs uncertainty (build its "
            "matrices with uncertainty.ureal), or use control.hinfsyn for a certain plant"
        )
    for label, val, top in (("nmeas", nmeas, P.noutputs), ("ncon", ncon, P.ninputs)):
        if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or not 0 < val < top:
            raise ModelStructureError(
                f"musyn: {label} must be an integer in [1, {top - 1}] (P has {P.noutputs} "
                f"outputs and {P.ninputs} inputs: performance channels first); got {val!r}"
            )
    if method not in METHODS:
        raise ParameterError(f"musyn: method must be one of {METHODS}; got {method!r}")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 0:
        raise ParameterError(f"musyn: max_iter must be an integer >= 0; got {max_iter!r}")
    orders = tuple(orders)
    if not orders or any(
        isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= 8
        for k in orders
    ):
        raise ParameterError(f"musyn: orders must be integers in [0, 8]; got {orders!r}")
    if frequencies is not None:
        w = np.asarray(frequencies, dtype=float)
        if w.ndim != 1 or w.size < 3 or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise ParameterError(
                "musyn: frequencies must be at least 3 finite values > 0, rad/s; got "
                f"{np.asarray(frequencies)!r}"
            )
        frequencies = np.unique(w)
    return tuple(sorted(set(int(k) for k in orders))), frequencies


def _lft_plant(P: USS, nmeas: int, ncon: int) -> _Plant:
    form = lft_form(P)
    M = form.M
    R = sum(r for _, r in form.blocks)
    nw, nz = P.ninputs - ncon, P.noutputs - nmeas
    s = max(nw, nz)
    A, B, C, D = (np.asarray(x, float) for x in (M.A, M.B, M.C, M.D))
    n = A.shape[0]
    # pad the performance channels square: zero inputs after w, zero outputs after z
    B = np.hstack([B[:, : R + nw], np.zeros((n, s - nw)), B[:, R + nw :]])
    D = np.hstack([D[:, : R + nw], np.zeros((D.shape[0], s - nw)), D[:, R + nw :]])
    C = np.vstack([C[: R + nz], np.zeros((s - nz, n)), C[R + nz :]])
    D = np.vstack([D[: R + nz], np.zeros((s - nz, D.shape[1])), D[R + nz :]])
    # measurements and controls in units where D21's rows and D12's columns have norm 1:
    # an encoder's noise beside a large feedthrough of the uncertainty channels would
    # otherwise read as a rank-deficient D21 (the synthesis' rank tests are relative)
    y_scale = _unit_scales(D[R + s :, : R + s], axis=1)
    u_scale = _unit_scales(D[: R + s, R + s :], axis=0)
    C[R + s :] *= y_scale[:, None]
    D[R + s :] *= y_scale[:, None]
    B[:, R + s :] *= u_scale[None, :]
    D[:, R + s :] *= u_scale[None, :]
    sys = ct.ss(
        A,
        B,
        C,
        D,
        inputs=[f"dw[{i}]" for i in range(R)]
        + [f"pw[{j}]" for j in range(s)]
        + [f"u[{k}]" for k in range(ncon)],
        outputs=[f"dz[{i}]" for i in range(R)]
        + [f"pz[{j}]" for j in range(s)]
        + [f"y[{k}]" for k in range(nmeas)],
    )
    gp = GeneralizedPlant.from_counts(sys, nmeas=nmeas, ncon=ncon)
    true_blocks = tuple((r, "real") for _, r in form.blocks) + ((s, "complex"),)
    return _Plant(gp, R, s, true_blocks, form, y_scale=y_scale, u_scale=u_scale)


def _unit_scales(block: np.ndarray, axis: int) -> np.ndarray:
    """``1 / norm`` of each row (``axis=1``) or column (``axis=0``), 1 where that is 0."""
    norms = np.linalg.norm(block, axis=axis)
    return np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 1.0)


def _given_units(plant: _Plant, K: ct.StateSpace, *, inverse: bool = False) -> ct.StateSpace:
    """The controller of the plant as given from ``K`` of the scaled ``plant.gp``
    (measurements ``y_scale * y``, controls ``u = u_scale * u'``):
    ``diag(u_scale) K diag(y_scale)``; with ``inverse``, the scaled plant's from the given
    plant's ``K``."""
    A, B, C, D = _abcd(K)
    sy, su = plant.y_scale, plant.u_scale
    if inverse:
        sy, su = 1.0 / sy, 1.0 / su
    return ct.ss(A, B * sy[None, :], su[:, None] * C, su[:, None] * D * sy[None, :])


def _default_frequencies(plant: _Plant) -> np.ndarray:
    """10 points a decade over the plant's natural frequencies, a decade beyond each end."""
    p = np.abs(np.linalg.eigvals(plant.gp.A)) if plant.gp.nx else np.zeros(0)
    p = p[p > 1e-8]
    lo, hi = (p.min(), p.max()) if p.size else (1.0, 1.0)
    lo, hi = math.floor(math.log10(lo)) - 1, math.ceil(math.log10(hi)) + 1
    lo = max(lo, hi - 8)
    return np.logspace(lo, hi, 10 * (hi - lo) + 1)


# -- the mu-step -------------------------------------------------------------------------------
def _mu_grid(cl: ct.StateSpace, freqs, blocks, g_max):
    """Per frequency: the D-G bound and its scalings ``(D, G)``."""
    A, B, C, D = _abcd(cl)
    bounds, Ds, Gs = [], [], []
    for w in freqs:
        Mw = _response(A, B, C, D, float(w))
        b, Dsc, Gsc = _upper(Mw, blocks, _start_bound(Mw, blocks), rtol=MU_RTOL, g_max=g_max)
        bounds.append(b)
        Ds.append(Dsc)
        Gs.append(Gsc)
    return np.array(bounds), Ds, Gs


def _true_peak(cl: ct.StateSpace, freqs, blocks, mu_design) -> float:
    """The grid peak of the D-G bound in the true structure (full ``D_i``, free ``G_i``).

    Its scalings include the design structure's, so its bound is at most the design bound
    at each frequency (up to :data:`MU_RTOL`): frequencies are taken in decreasing order of
    the design bound, and the rest skipped once that falls below the peak found."""
    A, B, C, D = _abcd(cl)
    peak = 0.0
    for i in np.argsort(-np.asarray(mu_design)):
        if mu_design[i] * (1 + 2 * MU_RTOL) < peak:
            break
        Mw = _response(A, B, C, D, float(freqs[i]))
        peak = max(peak, _upper(Mw, blocks, _start_bound(Mw, blocks), rtol=MU_RTOL)[0])
    return float(peak)


# -- the K-step --------------------------------------------------------------------------------
def _allpass(a: np.ndarray) -> ct.StateSpace:
    """``prod (a_j - s) / (a_j + s)``: sections ``-1 + 2 a / (s + a)`` in cascade."""
    k = a.size
    if not k:
        return ct.ss([], [], [], [[1.0]])
    A = np.zeros((k, k))
    B = np.zeros((k, 1))
    C = np.zeros((1, k))
    # v_0 = input; x_j' = -a_j x_j + v_{j-1}; v_j = -v_{j-1} + 2 a_j x_j
    # v_{j-1} = sum_{l<j} c_l x_l + sign * input
    coef = np.zeros(k)  # v_{j-1} in terms of x
    sign = 1.0
    for j in range(k):
        A[j, :] += coef
        A[j, j] += -a[j]
        B[j, 0] = sign
        coef = -coef
        coef[j] += 2 * a[j]
        sign = -sign
    C[0, :] = coef
    return ct.ss(A, B, C, [[sign]])


def _scaled_plant(plant: _Plant, sc: _Scalings, beta: float) -> ct.StateSpace:
    """The plant whose lower LFT with ``K`` is ``X_beta`` (module notes), by signal names."""
    gp = plant.gp
    R, s = plant.R, plant.s
    blocks = [gp.sys]
    et = [f"et[{i}]" for i in range(R)] + [f"ep[{j}]" for j in range(s)]
    zt = [f"zt[{i}]" for i in range(R)] + [f"zq[{j}]" for j in range(s)]
    for i in range(R):
        d, g = sc.d[i], sc.g[i]
        out = _allpass(g.a) * d.system() * (1.0 / beta)
        if g.a.size:
            Ab, Bb, Cb = g.stable_part()
            Cs = Cb / beta
            X = sla.solve_continuous_are(Ab, Bb, Cs.T @ Cs, np.eye(1))
            F = Bb.T @ X
            # E^-1 and (A Y / beta) E^-1 from one realisation: (Ab - Bb F, Bb, [-F; Cs], [1; 0])
            einv = ct.ss(
                Ab - Bb @ F,
                Bb,
                np.vstack([-F, Cs]),
                [[1.0], [0.0]],
                inputs=et[i],
                outputs=[f"v[{i}]", f"f[{i}]"],
            )
            blocks.append(einv)
            blocks.append(ct.ss(d.system(inverse=True), inputs=f"v[{i}]", outputs=f"dw[{i}]"))
            blocks.append(ct.ss(out, inputs=f"dz[{i}]", outputs=f"zn[{i}]"))
            blocks.append(ct.summing_junction(inputs=[f"zn[{i}]", f"f[{i}]"], output=zt[i]))
        else:
            blocks.append(ct.ss(d.system(inverse=True), inputs=et[i], outputs=f"dw[{i}]"))
            blocks.append(ct.ss(out, inputs=f"dz[{i}]", outputs=zt[i]))
    for j in range(s):
        blocks.append(ct.ss([], [], [], [[1.0]], inputs=et[R + j], outputs=f"pw[{j}]"))
        blocks.append(ct.ss([], [], [], [[1.0 / beta]], inputs=f"pz[{j}]", outputs=zt[R + j]))
    return ct.interconnect(
        blocks,
        inplist=et + list(gp.u),
        outlist=zt + list(gp.y),
        inputs=et + list(gp.u),
        outputs=zt + list(gp.y),
    )


def _suboptimal(Pt: ct.StateSpace, nmeas: int, ncon: int):
    """A controller with ``||F_l(Pt, K)||_inf < 1`` (SLICOT ``sb10ad``, ``job=4``: the
    central controller at ``gamma = 1``, Glover & Doyle 1988), or None if there is none."""
    A, B, C, D = _abcd(Pt)
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    if n:  # a diagonal state similarity (SLICOT tb01id): K does not depend on it
        _, A, B, C, _ = slycot.tb01id(n, m, p, 0.0, A.copy(), B.copy(), C.copy(), job="A")
    try:
        out = slycot.sb10ad(A.shape[0], B.shape[1], C.shape[0], ncon, nmeas, 1.0, A, B, C, D, job=4)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):  # slycot's errors
        return None
    Ak, Bk, Ck, Dk = out[1:5]
    return ct.ss(Ak, Bk, Ck, Dk)


def _verified(plant: _Plant, Pt: ct.StateSpace, K: ct.StateSpace) -> float:
    """The exact H-infinity norm of ``F_l(Pt, K)`` (inf when it or ``F_l(M, K)`` is unstable)."""
    gp = plant.gp
    if not is_stable(gp.closed_loop(K)):
        return math.inf
    scaled = GeneralizedPlant.from_counts(Pt, nmeas=gp.ny, ncon=gp.nu).closed_loop(K)
    return float(hinf_norm(scaled))


def _k_step(plant: _Plant, sc: _Scalings, beta0: float, where: str):
    """``(K, beta)``: the least ``beta`` (to :data:`BETA_RTOL`) at which SLICOT finds a
    controller with ``||X_beta||_inf < 1`` (module notes), that controller's exact norm
    confirmed (else ``beta`` is raised, by that tolerance doubling each time)."""
    gp = plant.gp
    found: dict = {}

    def feasible(beta) -> bool:
        K = _suboptimal(_scaled_plant(plant, sc, beta), gp.ny, gp.nu)
        if K is not None:
            found[beta] = K
        return K is not None

    hi = beta0
    for _ in range(40):
        if feasible(hi):
            break
        hi *= 2.0
    else:
        raise InfeasibleError(
            f"musyn: {where}: SLICOT sb10ad finds no controller with a scaled closed-loop "
            f"norm below 1 for any beta up to {hi:.6g}; check that (A, B2) is "
            "stabilisable, (C2, A) detectable, D12 of full column rank and D21 of full row "
            "rank, with no imaginary-axis zeros"
        )
    lo = 0.7 * hi
    for _ in range(60):
        if not feasible(lo):
            break
        hi, lo = lo, 0.7 * lo
    while hi / lo - 1 > BETA_RTOL:
        mid = math.sqrt(lo * hi)
        if feasible(mid):
            hi = mid
        else:
            lo = mid
    # the exact norm decides, not the synthesis' claim
    # near the optimum the central controller is ill-conditioned: step away from it
    for k in range(10):
        if hi in found and _verified(plant, _scaled_plant(plant, sc, hi), found[hi]) < 1.0:
            return found[hi], hi
        hi *= 1 + BETA_RTOL * 2**k
        feasible(hi)
    raise VerificationError(
        f"musyn: {where}: the controllers SLICOT sb10ad returns near beta = {hi:.6g} do "
        "not give the scaled closed loop an exact H-infinity norm below 1 (or do not "
        "stabilise the loop)"
    )


# -- the iteration -----------------------------------------------------------------------------
def _certify(cl, blocks, start: float, deadline: float):
    """The least ``b`` of the ladder (module notes) at which the cover certifies ``M / b``."""
    A, B, C, D = _abcd(cl)
    b = start * (1 + CERT_RTOL)
    tried = []
    for _ in range(60):
        res = mu_cover(
            A, B, C / b, D / b, list(blocks), max_frequencies=MAX_FREQUENCIES, deadline=deadline
        )
        tried.append({"bound": b, "certified": res["certified"], "reason": res.get("reason", "")})
        if res["certified"]:
            return b, dict(res, tried=tried)
        if time.perf_counter() > deadline:
            break
        b *= max(res.get("mu_upper", 1.0), 1.0) * (1 + CERT_RTOL)
    return math.inf, dict(res, tried=tried)


def _balanced_start(plant: _Plant, freqs) -> _Scalings:
    """Constant ``D`` scalings of the first K-step: Osborne's balancing of the open loop.

    The uncertainty channels of a physical model can differ in size by orders of magnitude
    (a stiffness in N/m beside a damping ratio); an H-infinity synthesis on the unscaled
    plant then weighs a few channels only and its central controller is ill-conditioned.
    At each frequency of the grid the open loop's map from ``[w_Delta; w]`` to
    ``[z_Delta; z]`` is balanced by :func:`uncertainty.mu._balance` (every channel its own
    group, the performance block one group); each channel's scale relative to the
    performance block's, its median over the grid in log, is its constant ``d_i`` (the
    scaling the D-K iteration would start from were its first iterate the open loop).
    Any positive constants are valid D scalings, so this only chooses where the iteration
    starts.
    """
    R, s = plant.R, plant.s
    if R < 1:
        return _identity(R)
    sys = plant.gp.sys
    A, B, C, D = _abcd(sys)
    B1, C1, D11 = B[:, : R + s], C[: R + s], D[: R + s, : R + s]
    blocks = tuple((1, "complex") for _ in range(R)) + ((s, "complex"),)
    logs = []
    for w in freqs:
        try:
            Mw = _response(A, B1, C1, D11, float(w))
        except np.linalg.LinAlgError:  # a pole of the open loop on the grid
            continue
        if not np.isfinite(Mw).all():
            continue
        sc = _balance(Mw, blocks)
        logs.append(np.log(sc[:R]) - np.log(sc[R]))
    if not logs:
        return _identity(R)
    d = np.exp(np.median(np.array(logs), axis=0))
    return _Scalings(
        tuple(_DFit.constant(float(x)) for x in d),
        tuple(_GFit(np.zeros(0), np.zeros(0)) for _ in range(R)),
    )


def _first_k_step(plant: _Plant, freqs, where: str):
    """``(K, beta, start)``: the first synthesis, from the unscaled plant and from
    :func:`_balanced_start`'s constant scalings, the one with the lower ``beta`` kept (both
    bound the designed-for mu at every frequency; a channel far out of scale leaves the
    unscaled synthesis weighing it alone, while on a well-scaled plant balancing can only
    move the start); ``start`` says which (``"identity"`` or ``"balanced"``). Raises the
    unscaled synthesis' error where neither finds a verified controller."""
    found = []
    error = None
    for label, sc in (
        ("identity", _identity(plant.R)),
        ("balanced", _balanced_start(plant, freqs)),
    ):
        try:
            K, beta = _k_step(
                plant, sc, 1.0, where if label == "identity" else f"{where}, balanced"
            )
        except (VerificationError, InfeasibleError) as exc:
            error = error or exc
            continue
        found.append((beta, label, K))
    if not found:
        raise error
    beta, label, K = min(found, key=lambda x: x[0])
    return K, beta, label


def _phase(plant: _Plant, freqs, orders, max_iter: int, step: str, history, iterates) -> str:
    """Iterations of one kind (``"D-K"``: complex channels, ``G = 0``; ``"D-G-K"``) appended
    to ``history`` and ``iterates``, from the last iterate (none: an unscaled synthesis),
    until the grid peak improves by less than :data:`IMPROVE_RTOL` twice in a row; returns
    why it stopped (:attr:`MusynResult.stopped`)."""
    real = step == "D-G-K"
    kind = "real" if real else "complex"
    blocks = tuple((1, kind) for _ in range(plant.R)) + ((plant.s, "complex"),)
    g_max = G_DESIGN_MAX if real else None
    sc, beta0, stale, best = _identity(plant.R), 1.0, 0, math.inf
    if iterates:
        cl = iterates[-1][1]
        mu_d, Ds, Gs = _mu_grid(cl, freqs, blocks, g_max)
    for _ in range(max_iter + (0 if iterates else 1)):
        t0 = time.perf_counter()
        it = len(history)
        where = f"K-step of iteration {it} ({step})"
        if iterates:
            sc, beta0 = _fit_all(freqs, Ds, Gs, mu_d, plant, cl, orders, real)
            try:
                K, gamma = _k_step(plant, sc, beta0, where)
            except (VerificationError, InfeasibleError) as exc:
                # a scaled synthesis SLICOT cannot solve to a verified norm (an
                # ill-conditioned scaled plant): the iterates so far stand
                return str(exc)
            start = None
        else:
            K, gamma, start = _first_k_step(plant, freqs, where)
        cl = plant.gp.closed_loop(K)
        if not is_stable(cl):  # pragma: no cover - _k_step checks it
            raise VerificationError(f"musyn: {where}: the closed loop is not stable")
        mu_d, Ds, Gs = _mu_grid(cl, freqs, blocks, g_max)
        history.append(
            {
                "iteration": it,
                "step": step,
                "gamma": float(gamma),
                "mu_peak_design": float(mu_d.max()),
                "mu_peak_grid": _true_peak(cl, freqs, plant.true_blocks, mu_d),
                "orders": sc.orders(),
                "fit_peak": float(beta0) if iterates else math.nan,
                "controller_order": int(K.nstates),
                "seconds": time.perf_counter() - t0,
            }
        )
        if start is not None:
            history[-1]["start"] = start
        iterates.append((K, cl))
        stale = stale + 1 if mu_d.max() > best * (1 - IMPROVE_RTOL) else 0
        best = min(best, float(mu_d.max()))
        if stale >= 2:
            return "converged"
    return "max_iter"


def musyn(
    P: USS | UncertainPlant,
    nmeas: int | None = None,
    ncon: int | None = None,
    *,
    method: str = "dgk",
    max_iter: int = 8,
    orders: Sequence[int] = DEFAULT_ORDERS,
    frequencies=None,
    time_limit_s: float = 300.0,
) -> MusynResult:
    """Mu-synthesis of an uncertain generalized plant by D-K or D-G-K iteration.

    Parameters
    ----------
    P : USS or UncertainPlant
        Generalized plant: inputs ``[w; u]`` (performance inputs, then the ``ncon``
        controls), outputs ``[z; y]`` (performance outputs, then the ``nmeas``
        measurements); its uncertain reals (:func:`uncertainty.ureal`) range over their
        own ``[low, high]``. An :class:`uncertainty.UncertainPlant` (from
        :func:`uncertainty.augw`) brings its own partition.
    nmeas, ncon : int
        Numbers of measurements and controls (the last outputs and inputs); taken from
        the partition of an ``UncertainPlant`` when not given.
    method : {"dgk", "dk"}
        ``"dgk"``: D and G scalings, the real parameters as real; ``"dk"``: every
        uncertainty channel as a complex scalar, D scalings only.
    max_iter : int
        Largest number of scaled syntheses after the first, unscaled one.
    orders : sequence of int
        Orders the scalings' fits may take (0 to 8; each iteration chooses among them).
    frequencies : array_like, optional
        The grid of the mu-step, rad/s (default: 10 points a decade over the LFT plant's
        natural frequencies and a decade beyond each end).
    time_limit_s : float
        Wall-clock limit of the final certificate, s (``mu_peak_certified`` is ``inf``
        when it runs out).

    Returns
    -------
    MusynResult

    Raises
    ------
    robust.errors.ModelStructureError
        If ``P`` is not a :class:`USS` or ``nmeas``/``ncon`` do not partition it.
    robust.errors.ParameterError
        If ``P`` has no uncertain real, or an option is out of range.
    robust.errors.AssumptionError
        If the LFT plant fails an assumption of H-infinity synthesis (stabilisability,
        detectability, the ranks of D12 and D21), naming it.
    robust.errors.InfeasibleError
        If a K-step finds no controller.
    robust.errors.VerificationError
        If the first controller does not stabilise the nominal closed loop, or a
        synthesis' closed-loop norm is not confirmed by the exact norm.

    Examples
    --------
    A lightly damped mode whose stiffness is known to +-30 %, its position measured,
    a sensitivity weight on the error and a small control penalty:

    >>> import numpy as np
    >>> from uncertainty import musyn, ureal, uss
    >>> k = ureal("k", 1.0, 0.7, 1.3, unit="N/m")
    >>> P = uss(  # states: position, velocity, weight state
    ...     [[0, 1, 0], [-k, -0.2, 0], [-1, 0, -0.01]],
    ...     [[0, 0], [0, 1], [1, 0]],
    ...     [[0, 0, 0.5], [0, 0, 0], [-1, 0, 0]],
    ...     [[0.5, 0], [0, 0.1], [1, 0]],
    ... )
    >>> res = musyn(P, 1, 1, method="dk", max_iter=1, orders=(0, 1, 2),
    ...             frequencies=np.logspace(-2, 2, 17))
    >>> res.method, res.mu_peak_grid <= res.mu_peak_certified
    ('D-K', True)
    """
    if isinstance(P, UncertainPlant):
        given = (nmeas, ncon)
        nmeas, ncon = len(P.y), len(P.u)
        if any(g is not None and g != want for g, want in zip(given, (nmeas, ncon))):
            raise ModelStructureError(
                f"musyn: nmeas, ncon {given} differ from the plant's partition ({nmeas} "
                f"measurements {list(P.y)}, {ncon} controls {list(P.u)})"
            )
        P = P.ordered()
    orders, frequencies = _check_inputs(P, nmeas, ncon, method, max_iter, orders, frequencies)
    if not (isinstance(time_limit_s, (int, float)) and time_limit_s > 0):
        raise ParameterError(f"musyn: time_limit_s must be > 0 s; got {time_limit_s!r}")
    plant = _lft_plant(P, int(nmeas), int(ncon))
    try:
        check_hinf_assumptions(plant.gp)
    except AssumptionError as exc:
        raise AssumptionError(
            f"musyn: the LFT plant (P with its uncertainty channels) fails an assumption of "
            f"H-infinity synthesis: {exc}"
        ) from exc
    freqs = _default_frequencies(plant) if frequencies is None else frequencies
    history: list = []
    iterates: list = []
    stopped = _phase(
        plant, freqs, orders, max_iter, "D-G-K" if method == "dgk" else "D-K", history, iterates
    )
    ibest = int(np.argmin([h["mu_peak_design"] for h in history]))
    K, cl = iterates[ibest][:2]
    t0 = time.perf_counter()
    cert, certificate = _certify(
        cl, plant.true_blocks, history[ibest]["mu_peak_grid"], t0 + float(time_limit_s)
    )
    certificate["seconds"] = time.perf_counter() - t0
    return MusynResult(
        controller=_given_units(plant, K),
        mu_peak_grid=history[ibest]["mu_peak_grid"],
        mu_peak_certified=float(cert),
        history=tuple(history),
        method="D-G-K" if method == "dgk" else "D-K",
        best_iteration=ibest,
        frequencies=freqs,
        blocks=plant.true_blocks,
        certificate=certificate,
        stopped=stopped,
    )


def certified_mu_peak(
    P: USS,
    K: ct.StateSpace,
    nmeas: int,
    ncon: int,
    *,
    start: float,
    time_limit_s: float = 300.0,
) -> tuple[float, dict]:
    """The certified peak of the robust-performance mu of ``P`` closed by any ``K``.

    What :func:`musyn` reports of its own controller, for another one (a reduced
    controller, one from another method): the LFT closed loop ``M_K`` of ``P`` with ``u = K
    y`` (the lower LFT, as :func:`control.hinfsyn`) in the true structure (the uncertain
    reals as repeated real scalars, a full complex performance block), and the least ``b``
    of the ladder from ``start`` at which :func:`uncertainty.mucover.mu_cover` certifies
    ``mu(M_K(jw)) < b`` at every frequency (module notes): every member with
    ``|delta_i| <= 1 / b`` is stable with weighted closed-loop norm below ``b``.

    Parameters
    ----------
    P : USS
        Generalized plant, as :func:`musyn` takes it.
    K : control.StateSpace
        Controller, ``nmeas`` inputs and ``ncon`` outputs.
    nmeas, ncon : int
        Numbers of measurements and controls (the last outputs and inputs of ``P``).
    start : float
        The ladder's first bound (> 0), e.g. a grid estimate of the peak.
    time_limit_s : float
        Wall-clock limit of the certificate, s.

    Returns
    -------
    (float, dict)
        The certified bound (``inf`` if none was found in time) and the cover's record
        (``tried``: the ladder; ``seconds``).

    Raises
    ------
    robust.errors.ModelStructureError
        If ``K``'s size does not match ``nmeas`` and ``ncon``.
    robust.errors.ParameterError
        If ``start`` or ``time_limit_s`` is not a positive finite number.
    robust.errors.VerificationError
        If ``K`` does not stabilise the nominal closed loop.
    """
    _check_inputs(P, nmeas, ncon, "dk", 0, DEFAULT_ORDERS, None)
    if not (isinstance(K, ct.StateSpace) and (K.ninputs, K.noutputs) == (nmeas, ncon)):
        raise ModelStructureError(
            f"certified_mu_peak: K must be a control.StateSpace with {nmeas} inputs and "
            f"{ncon} outputs; got {getattr(K, 'ninputs', None)} inputs and "
            f"{getattr(K, 'noutputs', None)} outputs ({type(K).__name__})"
        )
    for name, value in (("start", start), ("time_limit_s", time_limit_s)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"certified_mu_peak: {name} must be > 0; got {value!r}")
    plant = _lft_plant(P, int(nmeas), int(ncon))
    cl = plant.gp.closed_loop(_given_units(plant, K, inverse=True))
    if not is_stable(cl):
        raise VerificationError(
            "certified_mu_peak: K does not stabilise the nominal closed loop of P"
        )
    t0 = time.perf_counter()
    # _certify's first rung is its start times 1 + CERT_RTOL
    b, record = _certify(
        cl, plant.true_blocks, float(start) / (1 + CERT_RTOL), t0 + float(time_limit_s)
    )
    record["seconds"] = time.perf_counter() - t0
    return float(b), record
