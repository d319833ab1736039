"""The limit problem of one member and set on its design grid, its cutting planes and the
independent re-check of the controller found.

``_solve_on_grid`` fills the cone programs of :class:`robust.synthesis.limit_problem.LimitProblem`
(kept per size) from the member's Gram matrices and grids; ``_verify`` realises the
controller, closes it around the member and checks it at every frequency, exactly;
where a bound is exceeded between the grid's frequencies, the cuts add them to the grid
(:data:`CUT_ROUNDS` rounds of :data:`N_CUTS`). :class:`SetLimit` is a set's result, with
:data:`UNDECIDED` and :data:`SOLVER_FAILED` naming the members that get no verdict.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import control as ct
import numpy as np

from designs.effort import (
    correction_limits,
    cylinder_filters,
    effort_utilisations,
    operator_filter,
    operator_spectrum,
)
from designs.limit_plant import _grids, _open_loop, _simulate_peak
from designs.response import deviation_maps
from robust.analysis.bounds import siso_response
from robust.analysis.loops import resolvent_times
from robust.synthesis.limit_problem import LimitProblem, gram_factor
from robust.synthesis.youla import affine_maps, force_responses, of_affine_maps
from robust.synthesis.youla_basis import quadrature_gram, quadrature_grid

__all__ = [
    "TIGHTENING",
    "FLOOR",
    "UNDECIDED",
    "SOLVER_FAILED",
    "FORCE_FLOOR_N",
    "SetLimit",
    "CUT_ROUNDS",
    "N_CUTS",
    "N_EFFORT",
]


#: The optimisation's limits are this fraction of the specification's, so that a controller
#: at the optimum passes the exact re-check, whose bounds hold at every frequency and not
#: only on the design grid (between grid points the optimum overshoots by up to about 1 %)
TIGHTENING = 0.98

#: Relative floor of the singular values in the change of variable of the problem.
FLOOR = 1e-8

#: Binding labels of members the map could not decide: the re-check of the controller found
#: failed (the optimisation's grid or quadrature missed it), or a solver failed.
UNDECIDED = "undecided"


SOLVER_FAILED = "solver failed"

#: Force below which a set's controller counts as using none, N (a micronewton: a set that
#: needs no force gets one at the solver's rounding, 1e-11 to 1e-8 N; no limit binds it).
FORCE_FLOOR_N = 1e-6


@dataclasses.dataclass(frozen=True)
class SetLimit:
    """One member's limit for one actuator set.

    Parameters
    ----------
    actuators : str
        Name from :data:`ACTUATOR_SETS`.
    sensors : str
        Name from :data:`SENSOR_SETS`.
    required_force : float
        Smallest multiple of the device's force limits within which the verified
        controller meets the whole specification (0 without a force actuator; ``inf``
        when no verified controller meets tracking and feedthrough).
    rms_force_n, peak_force_n : float
        RMS and simulated peak force of that controller at force multiple 1, N.
    relaxation : float
        Smallest uniform relaxation of tracking and feedthrough the basis can meet (<= 1
        when they can be met; computed only when they cannot, else ``nan``).
    binding : str
        A name of :data:`designs.spec.CONSTRAINTS` or :data:`UNDECIDED` or
        :data:`SOLVER_FAILED`. When ``required_force`` is infinite: the constraint that
        cannot be met (the largest of the uniform relaxation's constraints: ``"tracking"``,
        ``"feedthrough"``, ``"noise"``, ``"reference effort"``; ``"decay rate"`` or
        ``"damping"`` for a mode no controller of the set can move), or why the member is not
        decided; else which force limit sets ``required_force`` (``"continuous force"``,
        ``"peak force"``), or ``""`` without force (none, or RMS and peak below
        :data:`FORCE_FLOOR_N`).
    verified : bool
        Whether the controller passed the numpy re-check (poles, the deviation's bounds at
        every frequency, force, noise and reference effort).
    note : str
        Why a member is undecided or unverified, if it is.
    gap : float
        ``(re-checked - predicted) / predicted`` RMS force: how far the solver's optimum of
        the basis problem is from the force of the controller it returned (the re-checked
        force is the one reported; ``nan`` without force).
    force_lower : float
        Lower bound of the force multiple *any* compensator with these actuators needs
        (:mod:`designs.relaxation`; 0 without a force actuator): ``required_force`` is
        never below it.
    reference_lower : float
        Lower bound of the reference-effort utilisation of a reference correction alone
        (``nan`` with a force actuator); above 1, no compensator of the set meets the
        specification at any force.
    """

    actuators: str
    sensors: str
    required_force: float
    rms_force_n: float
    peak_force_n: float
    relaxation: float
    binding: str
    verified: bool
    note: str = ""
    gap: float = math.nan
    force_lower: float = math.nan
    reference_lower: float = math.nan

    def covered(self, force_scale: float) -> bool:
        """Whether this member is covered at ``force_scale`` times the device's force limits."""
        return self.verified and self.required_force <= force_scale


def _problem(cache: dict, n_theta: int, n_track: int, n_feed: int, n_effort: int) -> LimitProblem:
    # the force's Gram matrix has rank at most 1 + n_theta: its factor has that many rows
    key = (n_theta, n_track, n_feed, n_effort)
    if key not in cache:
        cache[key] = LimitProblem(n_theta, n_track, n_feed, 1 + n_theta, n_effort)
    return cache[key]


#: Effort and noise constraints of the limit problem: the reference correction's cylinder
#: speed and valve command, the handle force and the cylinder position caused by the noise.
N_EFFORT = 4


_PROBLEMS: dict = {}


def _set_limit(actuators, sensors, required, rms, peak, relaxation, binding, ok, notes, gap=None):
    nan = math.nan
    return SetLimit(
        actuators=actuators,
        sensors=sensors,
        required_force=required,
        rms_force_n=rms,
        peak_force_n=peak,
        relaxation=relaxation,
        binding=binding,
        verified=ok,
        note="; ".join(notes) if isinstance(notes, list) else notes,
        gap=nan if gap is None else gap,
    )


#: Rounds of cutting planes: frequencies where the exact re-check finds a bound exceeded
#: are added to the design grid, the grid's limits are lowered by the excess found, and the
#: problem is solved again.
CUT_ROUNDS = 3

#: Rows reserved for those frequencies per grid (unused rows are zero: no constraint).
N_CUTS = 16


@functools.lru_cache(maxsize=4)
def _r0(loop, reference_k_psf):
    return deviation_maps(loop, reference_k_psf=reference_k_psf)[1]


def _cut_bounds(loop, spec, w) -> np.ndarray:
    if not w.size:
        return np.zeros(0)
    return spec.deviation_bound(w, siso_response(_r0(loop, spec.reference_k_psf), w))


def _cuts(r_cl, loop, spec, checks) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (rad/s) to add to the tracking and feedthrough grids: the exact checks'
    worst frequencies and the local maxima above the tightened level on a dense grid."""
    split = 2 * math.pi * spec.split_hz
    w = 2 * math.pi * np.geomspace(1e-3, 1e4, 4000)
    ratio = np.abs(siso_response(r_cl, w)) / _cut_bounds(loop, spec, w)
    peak = np.flatnonzero(
        (ratio[1:-1] >= ratio[:-2]) & (ratio[1:-1] >= ratio[2:]) & (ratio[1:-1] > TIGHTENING)
    )
    cand = [w[1:-1][peak]]
    for c in checks:
        if not c.holds and math.isfinite(c.frequency_hz):
            cand.append([2 * math.pi * c.frequency_hz])
    cand = np.unique(np.concatenate(cand))
    return cand[cand <= split], cand[cand > split]


def _grams(plant, meas, K0, L, basis, extra, loop, spec, nz, amp, acts, s_u):
    """Gram factors of the force and of the effort and noise constraints, affine in theta.

    Returns ``(R, r0, effort)``: the RMS force over the continuous limit is
    ``|| R theta + r0 ||`` (``None`` without a force actuator); ``effort`` lists
    ``(name, W)`` with ``[1, theta]' W [1, theta] <= 1`` the requirement (names of
    :data:`designs.spec.CONSTRAINTS`). Variances by quadrature of the exact frequency
    responses against the operator's spectrum (intent and remnant) and the noise.
    """
    A_c, B_c, C_c, D_c = cylinder_filters(loop)
    Of = operator_filter(spec.intent_bandwidth_hz, amp, nz)
    poles = np.concatenate(
        [np.linalg.eigvals(basis[0]), np.linalg.eigvals(Of[0]), np.linalg.eigvals(A_c)] + extra
    )
    wq, wts = quadrature_grid(poles)
    S = operator_spectrum(wq, amp, spec.intent_bandwidth_hz, nz)
    noise = None if meas is None else meas.noise
    R = r0 = None
    effort = []

    def factor(resp, scale, *, operator=True):
        W = quadrature_gram(resp, wts, intent=S if operator else 0.0 * S, noise=noise)
        return W / scale**2

    def force_factor(resp):
        F = gram_factor(W := factor(resp, spec.continuous_force_n), W.shape[0])
        return F[:, 1:], F[:, 0]

    def actuator(a):
        pa = dataclasses.replace(plant, force=a, force_gain=1.0 / float(s_u[a]))
        return force_responses(pa, K0, basis, wq, meas=meas, L=L)

    resp = {a: actuator(a) for a in range(len(acts))}
    if plant.force is not None:
        rf = resp[plant.force]
        R, r0 = force_factor(rf)
        if meas is not None:
            effort.append(("noise", factor(rf, spec.noise_force_n, operator=False)))
    if "r_corr" in acts:
        rc = resp[acts.index("r_corr")]
        lim_v, lim_e = correction_limits(loop, spec)
        h = (
            siso_response((A_c, B_c, C_c[[0]], D_c[[0]]), wq),
            siso_response((A_c, B_c, C_c[[1]], D_c[[1]]), wq),
        )
        for hk, lim in zip(h, (lim_v, lim_e), strict=True):
            shaped = {"w": rc["w"] * hk[:, None]}
            if "n" in rc:
                shaped["n"] = rc["n"] * hk[:, None, None]
            effort.append(("reference effort", factor(shaped, lim)))
    if meas is not None:
        # the cylinder position the noise causes, through the actuators
        Ao, Bo, Co, Do = _open_loop(loop)
        cols = [1 + ("f", "r_corr").index(a) for a in acts]
        Gya = np.einsum("j,fjm->fm", Co[0], resolvent_times(Ao, wq, Bo[:, cols])) + Do[0, cols]
        yn = sum(Gya[:, a][:, None, None] * resp[a]["n"] for a in range(len(acts)))
        lim_y = spec.noise_cylinder_mm * 1e-3 * loop.cylinder_units_per_m()
        yresp = {"w": np.zeros_like(yn[:, 0, :]), "n": yn}
        effort.append(("noise", factor(yresp, lim_y, operator=False)))
    return R, r0, effort


def _in_coordinates(W, T) -> np.ndarray:
    """A Gram of ``[1, theta]`` as a Gram of ``[1, z]``, ``theta = T z``."""
    Tb = np.zeros((T.shape[0] + 1, T.shape[1] + 1))
    Tb[0, 0] = 1.0
    Tb[1:, 1:] = T
    return Tb.T @ W @ Tb


def _loop_system(loop, plant, A, B, Cx, acts, s_u, s_m) -> ct.StateSpace:
    """The closed loop in loop units: inputs ``u`` then the measurement noises, outputs ``y``
    then the actuators (``Cx`` from ``closed_loop(..., actuators=True)``)."""
    Ao, Bo, Co, Do = _open_loop(loop)
    n, m = plant.n, len(acts)
    cols = [1 + ("f", "r_corr").index(a) for a in acts]
    Cu = Cx[2 : 2 + m] / np.asarray(s_u, float)[:, None]  # actuators, loop units
    Xs = Cx[2 + m : 2 + m + n]  # the plant's states
    Cy = Co[[0]] @ Xs + Do[[0]][:, cols] @ Cu
    C = np.vstack([Cy, Cu])
    Bn = B[:, 1:] / np.asarray(s_m, float)[None, :] if B.shape[1] > 1 else B[:, :0]
    Bl = np.hstack([B[:, [0]], Bn])
    D = np.zeros((1 + m, Bl.shape[1]))
    D[0, 0] = Do[0, 0]
    return ct.ss(A, Bl, C, D)


def _solve_on_grid(plant, meas, K0, L, basis, spec, gt, gb, grams, problems, step, tight=None):
    """The limit problem on the grids ``gt``, ``gb`` (``(omega, bound)`` each): ``(Theta,
    relaxation, predicted RMS force)``, or a :class:`SetLimit` (actuators and sensors left
    blank) where tracking and feedthrough cannot be met or a solver fails."""
    nan = math.nan
    (wt, bt), (wb, bb) = gt, gb
    R, r0, effort = grams
    tight = TIGHTENING if tight is None else tight
    if meas is None:
        mt, mb = affine_maps(plant, K0, basis, wt), affine_maps(plant, K0, basis, wb)
    else:
        mt = of_affine_maps(plant, meas, K0, L, basis, wt)
        mb = of_affine_maps(plant, meas, K0, L, basis, wb)
    track0, track = mt["y0"] / bt, mt["y"] / bt[:, None]
    feed0, feed = mb["y0"] / bb, mb["y"] / bb[:, None]
    n_theta = track.shape[1]
    nt, nb = _grids(spec)[0].size + N_CUTS, _grids(spec)[1].size + N_CUTS
    # pad to the reserved rows (zero rows: |0| <= 1 always holds)
    track0 = np.concatenate([track0, np.zeros(nt - track0.size)])
    feed0 = np.concatenate([feed0, np.zeros(nb - feed0.size)])
    track = np.vstack([track, np.zeros((nt - track.shape[0], n_theta))])
    feed = np.vstack([feed, np.zeros((nb - feed.shape[0], n_theta))])
    # change of variable theta = V diag(1/s) z from the SVD of every map theta enters, so
    # the problem's columns are orthonormal (directions of no effect get a floored s)
    M = np.vstack(
        [track.real, track.imag, feed.real, feed.imag]
        + ([R] if R is not None else [])
        + [gram_factor(W, W.shape[0])[:, 1:] for _, W in effort]
    )
    _, sv, Vt = np.linalg.svd(M, full_matrices=False)
    T = np.where(sv > FLOOR * sv[0], 1.0 / np.maximum(sv, FLOOR * sv[0]), 0.0) * Vt.T
    # directions that move no map (their singular value at the floor) are left out
    T = T[:, sv > FLOOR * sv[0]]
    data = dict(
        track0=track0,
        track=track @ T,
        feed0=feed0,
        feed=feed @ T,
        lim_t=tight,
        lim_f=tight,
        R=None if R is None else R @ T,
        r0=r0,
    )
    effort_z = [(name, _in_coordinates(W, T)) for name, W in effort]

    def effort_values(z):
        # per constraint name, the largest of its Grams (the noise has two: force, cylinder)
        v = np.concatenate([[1.0], z])
        out = {}
        for name, W in effort_z:
            out[name] = max(out.get(name, 0.0), math.sqrt(max(float(v @ W @ v), 0.0)))
        return out

    # the effort and noise constraints rarely bind with a handle force: solved without them
    # first (a problem a quarter of the size), with them where that answer breaks one
    out = None
    for with_effort in (False, True) if effort else (False,):
        prob = _problem(problems, T.shape[1], nt, nb, N_EFFORT if with_effort else 0)
        prob.set(**data, effort=[W for _, W in effort_z] if with_effort else [])
        sol = prob.solve("force", step=step) if plant.force is not None else None
        if sol is None:
            rel = prob.solve("relax", step=step)
            if rel is None:
                why = "undecided: the relaxation problem failed"
                return _set_limit("", "", math.inf, nan, nan, nan, SOLVER_FAILED, False, why)
            z, rho = rel
            worst = {
                "tracking": float(np.max(np.abs(track0 + track @ (T @ z)))),
                "feedthrough": float(np.max(np.abs(feed0 + feed @ (T @ z)))),
            }
            if with_effort:
                worst.update(effort_values(z))
            if rho > 1.0:
                binding = max(worst, key=worst.get)
                return _set_limit("", "", math.inf, nan, nan, rho / tight, binding, False, "")
            out = (z, rho / tight, None)
        else:
            out = (sol[0], nan, sol[1] * spec.continuous_force_n)
        if with_effort or max(effort_values(out[0]).values(), default=0.0) <= tight:
            break
    z, relaxation, predicted = out
    return T @ z, relaxation, predicted


def _verify(
    sysl,
    A,
    B,
    C,
    var,
    spec,
    region,
    checks,
    member,
    names,
    relaxation,
    seed,
    duration_s,
    predicted,
) -> SetLimit:
    """Re-check the closed loop ``(A, B, C)`` (input ``w`` first, then the noise) in numpy;
    ``checks``: the deviation's bounds at every frequency
    (:func:`designs.spec.deviation_bound_checks` of the loop); ``sysl``: the loop in loop
    units (:func:`_loop_system`), whose force, noise and reference effort are computed as
    the specification defines them (:func:`designs.spec.effort_utilisations`)."""
    loop, amp, acts = member
    actuators, sensors = names
    poles = np.linalg.eigvals(A)
    notes = []
    ok = True
    gap = None
    binding = ""
    viol = region.violation(poles[None, :])[0]
    if viol > 0:
        ok = False
        binding = "decay rate" if poles.real.max() > -spec.decay_rate else "damping"
        notes.append(f"closed-loop poles outside the region ({viol:.3g} rad/s)")
    for name, chk in zip(("tracking", "feedthrough"), checks, strict=True):
        if not chk.holds:
            ok = False
            binding = binding or name
            notes.append(
                f"{name} bound exceeded x{chk.value:.4g} at {chk.frequency_hz:.4g} Hz on re-check"
            )
    if not ok:
        # the optimisation meets these by construction (pole region) or on its grid: a
        # re-check that fails leaves the member undecided, not infeasible
        return _set_limit(
            actuators, sensors, math.inf, math.inf, math.inf, relaxation, UNDECIDED, False, notes
        )
    var = np.zeros(0) if var is None else var
    rms, u_noise, u_ref = effort_utilisations(sysl, acts, loop, spec, amp, var)
    for name, u in (("noise", u_noise), ("reference effort", u_ref)):
        if not u <= 1.0:
            ok = False
            binding = binding or name
            notes.append(f"{name} x{u:.4g} of its limit on re-check")
    if not ok:
        return _set_limit(
            actuators, sensors, math.inf, math.inf, math.inf, relaxation, UNDECIDED, False, notes
        )
    if "f" not in acts:
        return _set_limit(actuators, sensors, 0.0, 0.0, 0.0, relaxation, "", True, notes)
    if predicted is not None and predicted > 1e-3:
        # (a relative gap means nothing at forces of a micronewton)
        gap = (rms - predicted) / predicted
    peak = _simulate_peak(A, B, C, amp, spec, seed, duration_s)
    rc, rp = rms / spec.continuous_force_n, peak / spec.peak_force_n
    binding = "continuous force" if rc >= rp else "peak force"
    if max(rms, peak) < FORCE_FLOOR_N:
        # a force the solver leaves at its rounding (a set that needs none): which limit
        # "binds" would be a draw between two zeros
        binding = ""
    return _set_limit(
        actuators, sensors, max(rc, rp), rms, peak, relaxation, binding, True, notes, gap
    )
