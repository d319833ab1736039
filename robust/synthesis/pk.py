"""Multi-model, multi-objective synthesis by sequential LMIs: the P-K iteration on a family.

One fixed-order controller ``u = K y`` for a set of members. Each member has three
plants that share the controls ``u`` and measurements ``y`` (:class:`SynthesisMember`):
the *region* plant (the loop whose closed-loop poles must lie in a
:class:`~robust.analysis.region.Region`, its damping enforced at every frequency), the
*H-infinity* plant (a performance channel ``w -> z``) and, optionally, the *H2* plant (a
white-noise channel whose output power is bounded, e.g. the handle force under the
realistic intended motion).

Problem::

    minimise gamma  over  K, P_i, Q_i, Z_i
    s.t. for every member i:
         BRL(A_i(K) + alpha I, B_i(K), C_i(K), D_i(K); P_i) < 0      (H-infinity <= gamma, decay)
         [[A_i' Q_i + Q_i A_i, Q_i B_i], [., -I]] < 0, [[Q_i, C_i'], [., Z_i]] > 0,
         trace Z_i <= h2_bound^2                                          (H2 <= h2_bound)
         every closed-loop pole of the region plant in the damping cone.

The bounded-real lemma is written for the closed loop shifted by the decay rate
``alpha``: its certificate proves every pole has real part below ``-alpha`` *and*
``||G(s - alpha)||_inf <= gamma``, which bounds ``||G||_inf`` (maximum modulus on
``Re s >= -alpha``). The H2 conditions are those of Scherer, Gahinet & Chilali (IEEE
TAC 42(7), 1997), the bounded-real lemma that of Boyd, El Ghaoui, Feron &
Balakrishnan (SIAM 1994, Sec. 2.7.3).

Method: the P-K iteration (El Ghaoui & Balakrishnan, "Synthesis of fixed-structure
controllers via numerical optimization", IEEE CDC 1994), the workbench's one (the
generalized plants of :func:`robust.synthesis.multi.hinfsyn_multi` run through it). With the
controller fixed, every inequality is an LMI in the Lyapunov matrices (P-step, one
small SDP per member and objective, at a level ``1 + LEVEL_SLACK`` above the norm
computed directly, maximising the margin); with the Lyapunov matrices fixed, an LMI in
the controller data ``Omega = [[Ak, Bk], [Ck, Dk]]`` (K-step, one SDP over all members),
since ``A(Omega) = A0 + Bb Omega Cb``. The K-step is feasible at the current controller,
so the certified level never increases. Three changes make it work on lightly damped
loops whose data spread over decades: each member's certificates are kept as state
coordinates in which they are the identity (``T' P T = I``; the closed loop is
transformed by ``T``, the controller data are untouched since ``T^-1 Bb Omega Cb T``),
the K-step stays in a trust region, and the P-step's levels come from the exact norms
(Bruinsma-Steinbuch, Gramian) so that a solver's inaccuracy never inflates a bound. The
damping cone of [CG96] doubles the LMI size and would dominate every solve; inside
the K-step it is kept by first-order eigenvalue constraints
(``d lambda = l^H Bb dOmega Cb r / l^H r``) within the trust region, as are the
members' response bounds (:class:`ResponseBound`); every step is re-checked with exact
eigenvalues and responses before it is kept, and the final controller gets a
cone-and-decay certificate per member from the region LMI
(:func:`robust.synthesis.region.certify_region`).

Every answer is verified before it is returned: each certificate's LMI matrices
rebuilt in numpy, each member's closed-loop eigenvalues, its H-infinity norm
(:func:`robust.analysis.norms.hinf_norm`) and its H2 norm
(:func:`robust.analysis.norms.h2_norm`, controllability Gramian).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence

import control
import cvxpy as cp
import numpy as np

from robust.analysis.region import Region
from robust.checks import POSITIVE, Spec, check_int, check_scalar
from robust.errors import InfeasibleError, ModelStructureError, ParameterError, SolverError
from robust.synthesis.pk_certificates import (
    MemberCertificates,
    _final_certificates,
    _region_certificate,
)
from robust.synthesis.pk_members import (
    ResponseBound,
    SynthesisMember,
    _Affine,
    _bmi,
    _brl_parts,
    _controller_data,
    _h2_output,
    _h2_parts,
    from_scaled,
    responses,
    scale_members,
    to_scaled,
)
from robust.synthesis.pk_pstep import _analyse_hinf as _analyse_hinf
from robust.synthesis.pk_pstep import _h2_analysis_data as _h2_analysis_data
from robust.synthesis.pk_pstep import _h2_analysis_sdp as _h2_analysis_sdp
from robust.synthesis.pk_pstep import _hinf_analysis_data as _hinf_analysis_data
from robust.synthesis.pk_pstep import _hinf_analysis_sdp as _hinf_analysis_sdp
from robust.synthesis.pk_pstep import _p_step, _Point
from robust.synthesis.pk_pstep import _sizes as _sizes
from robust.synthesis.pole_derivatives import (
    eigen_derivatives,
    eigen_derivatives_many,
    eigen_region_rows,
)
from robust.synthesis.region import synthesis_region
from robust.synthesis.solve import DEFAULT_SOLVERS, check_solvers, solve_problem

__all__ = [
    "ResponseBound",
    "SynthesisMember",
    "MemberCertificates",
    "MultiObjectiveResult",
    "pksyn_multi",
    "certify_regions",
    "eigen_derivatives",
    "eigen_derivatives_many",
    "eigen_region_rows",
    "responses",
    "scale_members",
    "to_scaled",
    "from_scaled",
]

#: Strictness margin of the LMIs in the recentred coordinates (certificates near I).
LMI_MARGIN = 1e-7
#: Eigenvalues whose region violation is below ``-ACTIVE`` (scaled time) get no
#: linearised constraint in a step.
ACTIVE = 0.5
#: Weight of the relative H2 excess in the merit (relative to the scaled gamma).
SLACK_WEIGHT = 10.0


# --------------------------------------------------------------------- results
@dataclasses.dataclass(frozen=True)
class MultiObjectiveResult:
    """A verified multi-model design by sequential LMIs.

    Parameters
    ----------
    K : control.StateSpace
        The common controller ``u = K y``.
    gamma_bound : float
        Certified common bound of the decay-shifted H-infinity norms (so of the norms).
    h2_bound : float or None
        The H2 bound imposed (``None`` without H2 plants).
    h2_met : bool
        Whether every member's certified H2 bound is within ``h2_bound``.
    certificates : tuple of MemberCertificates
        One per member, in order.
    region : robust.analysis.region.Region
        The region certified for every member, its damping at every frequency.
    history : tuple of dict
        Per accepted step: ``gamma`` (certified), ``h2_excess`` (relative slack),
        ``trust`` radius.
    iterations : int
        Steps tried (accepted and rejected).
    solve_times : tuple of float
        Seconds of every SDP solve (analysis and steps), in order.
    wall_time : float
        Seconds for the whole call.
    method : str
        The method and its guarantee, in words.
    notes : tuple of str
        Rejected steps, why the iteration stopped.
    w0 : float
        Time scale of the SDPs, rad/s.
    omega_scaled : numpy.ndarray or None
        The controller data in the SDPs' coordinates (what :func:`certify_regions`
        certifies when the region certificates were deferred).
    """

    K: control.StateSpace
    gamma_bound: float
    h2_bound: float | None
    h2_met: bool
    certificates: tuple
    region: Region
    history: tuple
    iterations: int
    solve_times: tuple
    wall_time: float
    method: str
    notes: tuple = ()
    w0: float = 20.0
    omega_scaled: np.ndarray | None = None

    @property
    def gammas(self) -> np.ndarray:
        """Each member's independently computed H-infinity norm."""
        return np.array([c.gamma for c in self.certificates])

    @property
    def h2s(self) -> np.ndarray:
        """Each member's independently computed H2 norm."""
        return np.array([c.h2 for c in self.certificates])

    def to_json(self) -> dict:
        """The facts of the result (no matrices)."""
        return {
            "method": self.method,
            "members": len(self.certificates),
            "order": self.K.nstates,
            "gamma_bound": self.gamma_bound,
            "gammas": self.gammas.tolist(),
            "h2_bound": self.h2_bound,
            "h2_met": self.h2_met,
            "h2s": self.h2s.tolist(),
            "region": self.region.describe(),
            "certificates": [c.to_json() for c in self.certificates],
            "history": list(self.history),
            "iterations": self.iterations,
            "lmi_solves": len(self.solve_times),
            "solve_time_s": float(sum(self.solve_times)),
            "solve_time_per_lmi_s": float(np.mean(self.solve_times)) if self.solve_times else 0.0,
            "wall_time_s": self.wall_time,
            "notes": list(self.notes),
        }


# ------------------------------------------------------------------- internals
def _k_step(members, pt: _Point, region_s, h2cap, trust, solvers):
    """K-step: the certificates fixed (identity in their coordinates), the controller free.

    Every inequality is then affine in the controller data; each member's level ``g_i``
    (relative to its current one) and the H2 output level are variables. The damping
    cone and the response bounds enter as first-order constraints, softened by one
    penalised slack. Returns the new controller data and the solve time.
    """
    Om_k = pt.Om
    Om = cp.Variable(Om_k.shape, name="Omega")
    gam = cp.Variable(name="gamma")
    excess = cp.Variable(nonneg=True, name="h2_excess")
    soft = cp.Variable(nonneg=True, name="linearised_slack")
    gref = max(pt.g_member)
    cons = [cp.norm(Om - Om_k, "fro") <= trust * max(1.0, float(np.linalg.norm(Om_k)))]
    step = cp.vec(Om - Om_k, order="F")
    for i, m in enumerate(members):
        cl = m.hinf_shifted.transformed(pt.T_hinf[i]).scaled_output(pt.g_member[i])
        g = cp.Variable()
        M = _bmi(*_brl_parts(cl, np.eye(cl.N), Om, g))
        cons += [M << -LMI_MARGIN * np.eye(M.shape[0]), g * pt.g_member[i] <= gam]
        if m.h2 is not None:
            cl2 = m.h2.transformed(pt.T_h2[i])
            Z = cp.Variable((cl2.C0.shape[0],) * 2, symmetric=True)
            M = _bmi(*_h2_parts(cl2, np.eye(cl2.N), Om))
            cons += [
                M << -LMI_MARGIN * np.eye(M.shape[0]),
                _h2_output(cl2, np.eye(cl2.N), Om, Z) >> LMI_MARGIN * np.eye(cl2.N + Z.shape[0]),
                cp.trace(Z) <= h2cap * (1 + excess),
            ]
        # the first-order rows as one vector inequality each (one row per eigenvalue or
        # frequency, the gradient flattened in the order of cp.vec): compiled at once
        rows = [(v0, g) for v0, g in eigen_region_rows(m.region, Om_k, region_s) if v0 > -ACTIVE]
        if rows:
            v0s = np.array([v0 for v0, _ in rows])
            G = np.array([np.ravel(grad, order="F") for _, grad in rows])
            cons.append(v0s + G @ step <= -0.05 * ACTIVE + soft)
        if m.response is not None:
            T, dT = responses(m.hinf, Om_k, m.w_resp)
            rb = m.response
            r = rb.offset + rb.gain * T
            # |r + gain dT|^2 <= bound^2, first order: |r|^2 + 2 Re(conj(r) gain dT)
            coef = 2 * (np.conj(r)[:, None, None] * rb.gain[:, None, None] * dT).real
            G = coef.reshape(T.size, -1, order="F")
            b2 = rb.bound**2
            cons.append(np.abs(r) ** 2 + G @ step <= b2 + b2 * soft)
    obj = gam / gref + SLACK_WEIGHT * excess + 100.0 * soft
    sol = solve_problem(
        cp.Problem(cp.Minimize(obj), cons), step="pksyn_multi: synthesis (K) step", solvers=solvers
    )
    if Om.value is None:
        raise SolverError("pksyn_multi: K-step returned no controller")
    return np.asarray(Om.value, float), sol.solve_time


def _response_excess(members, Om) -> float:
    worst = 0.0
    for m in members:
        if m.response is not None:
            T, _ = responses(m.hinf, Om, m.w_resp)
            worst = max(worst, float(np.max(m.response.values(T))) - 1.0)
    return max(worst, 0.0)


def _check_options(region, h2_bound, w0, max_iter, trust, rtol) -> Region:
    region = synthesis_region(region, "pksyn_multi")
    if h2_bound is not None:
        check_scalar("h2_bound", h2_bound, POSITIVE, owner="pksyn_multi")
    check_scalar("w0", w0, POSITIVE, owner="pksyn_multi")
    check_int("max_iter", max_iter, low=0, owner="pksyn_multi")
    check_scalar("trust", trust, Spec(low=0.0, low_open=True), owner="pksyn_multi")
    check_scalar("rtol", rtol, Spec(0.0, 1.0, False, True), owner="pksyn_multi")
    return region


def pksyn_multi(
    members: Sequence[SynthesisMember],
    K0,
    region: Region,
    *,
    h2_bound: float | None = None,
    w0: float = 20.0,
    max_iter: int = 10,
    trust: float = 0.2,
    rtol: float = 1e-3,
    solvers=DEFAULT_SOLVERS,
    progress: Callable[[int, dict], None] | None = None,
    region_certificates: bool = True,
) -> MultiObjectiveResult:
    """One controller for every member: poles in ``region``, certified H-infinity and H2 bounds.

    See the module notes for the problem and the method. The iteration is local: it
    starts from ``K0``, which must place every member's region-plant poles in
    ``region`` (:func:`robust.synthesis.tuning.tune_members` can supply it). Each
    K-step minimises the common level of the decay-shifted H-infinity certificates plus
    a penalty on the H2 level's excess over ``h2_bound`` (so a ``K0`` whose H2 norm is
    too large is driven into the bound) within a trust region of relative radius
    ``trust``; the P-step then certifies the new controller member by member. A step is
    kept only if every pole stays in the region, the response bounds are not worsened
    and the merit (certified level relative to the first, plus the weighted H2 excess)
    decreases; otherwise the radius is halved.

    Parameters
    ----------
    members : sequence of SynthesisMember
        The design members (same controls and measurements).
    K0 : control.StateSpace or ControllerMatrices
        Initial controller ``y -> u``.
    region : robust.analysis.region.Region
        The pole region (decay rate and damping cone). Its damping is enforced at every
        frequency, whatever its band (conservative for a band-limited region, which the
        analyses check exactly in its band).
    h2_bound : float, optional
        Bound on every member's H2 norm, original units (required when members have
        H2 plants; ignored otherwise).
    w0 : float
        Time scale of the SDPs, rad/s (a frequency inside the band of interest).
    max_iter : int
        Largest number of K-steps (0: certify ``K0``).
    trust : float
        Initial relative trust-region radius of the K-step.
    rtol : float
        Stop when an accepted step improves the merit by less than this fraction.
    solvers : sequence of str
        cvxpy SDP solvers, in order.
    progress : callable, optional
        Called after each accepted step as ``progress(step, entry)``.
    region_certificates : bool
        Solve each member's region LMI for the final controller (the costliest part of the
        final checks). ``False`` defers them (``certificates[i].region`` is ``None``; the
        closed-loop poles are still checked): for a caller that runs many syntheses and
        keeps one, which it then certifies with :func:`certify_regions`.

    Returns
    -------
    MultiObjectiveResult

    Raises
    ------
    ModelStructureError
        Empty or inconsistent members, a ``K0`` of the wrong size.
    ParameterError
        An option out of range, or H2 plants without ``h2_bound``.
    InfeasibleError
        ``K0`` leaves a member's poles outside the region (members named), or an
        initial certificate cannot be found.
    VerificationError
        A final certificate fails its numpy re-check or an independent check.
    """
    t_start = time.perf_counter()
    region = _check_options(region, h2_bound, w0, max_iter, trust, rtol)
    solvers = check_solvers(solvers, name="pksyn_multi: solvers", sdp=True)
    members = list(members)
    if not members or not all(isinstance(m, SynthesisMember) for m in members):
        raise ModelStructureError(
            "pksyn_multi: members must be a non-empty sequence of SynthesisMember"
        )
    if len({(m.nu, m.ny) for m in members}) != 1:
        raise ModelStructureError("pksyn_multi: members must share controls and measurements")
    with_h2 = [m.h2 is not None for m in members]
    if any(with_h2) and not all(with_h2):
        raise ModelStructureError("pksyn_multi: either every member has an H2 plant or none")
    if all(with_h2) and h2_bound is None:
        raise ParameterError("pksyn_multi: h2_bound is required with H2 plants; got None")
    Om, nk = _controller_data(K0)
    nu, ny = members[0].nu, members[0].ny
    if Om.shape != (nk + nu, nk + ny):
        raise ModelStructureError(
            f"pksyn_multi: K0 must map {ny} measurement(s) to {nu} control(s); got "
            f"{Om.shape[1] - nk} -> {Om.shape[0] - nk}"
        )
    bad = []
    for i, m in enumerate(members):
        v = region.worst_violation(np.linalg.eigvals(_Affine(m.region, nk).matrices(Om)[0]))
        if v >= 0:
            bad.append(f"{m.label or i} (violation {v:.3g} rad/s)")
    if bad:
        raise InfeasibleError(
            f"pksyn_multi: K0 leaves members outside the region ({region.describe()}): "
            + ", ".join(bad)
        )
    channels, scaled = scale_members(members, nk, w0)
    region_s = region.scaled(w0)
    for m in scaled:
        m.hinf_shifted = m.hinf.shifted(region_s.decay_rate)
    h2cap = (h2_bound**2 / w0) if all(with_h2) else 0.0
    solve_times, notes = [], []
    try:
        pt = _p_step(scaled, to_scaled(Om, nk, w0, channels), None, solvers, solve_times)
    except SolverError as exc:
        raise InfeasibleError(f"pksyn_multi: no initial certificates: {exc}") from None
    g_first = max(pt.g_member)

    def merit(p: _Point) -> float:
        return max(p.g_member) / g_first + SLACK_WEIGHT * _excess(p, h2cap)

    history = [_entry(pt, h2cap, trust, _response_excess(scaled, pt.Om))]
    radius = trust
    it = 0
    for it in range(1, max_iter + 1):
        try:
            Om_new, st = _k_step(scaled, pt, region_s, h2cap, radius, solvers)
            solve_times.append(st)
        except (SolverError, InfeasibleError) as exc:
            notes.append(f"step {it}: K-step failed ({str(exc)[:120]}); radius halved")
            radius /= 2
            if radius < 1e-4 * trust:
                break
            continue
        reason = _reject_reason(scaled, pt, Om_new, region_s)
        new = None
        if reason is None:
            try:
                new = _p_step(scaled, Om_new, pt, solvers, solve_times)
            except (SolverError, InfeasibleError) as exc:
                reason = f"P-step failed ({str(exc)[:120]})"
        if new is not None and not merit(new) < merit(pt):
            reason = f"no decrease of the merit ({merit(new):.6g} vs {merit(pt):.6g})"
        if reason is not None:
            notes.append(f"step {it}: {reason}; radius halved")
            radius /= 2
            if radius < 1e-4 * trust:
                break
            continue
        before = merit(pt)
        pt = new
        history.append(_entry(pt, h2cap, radius, _response_excess(scaled, pt.Om)))
        if progress is not None:
            progress(it, history[-1])
        radius = min(2 * radius, 4 * trust)
        if before - merit(pt) < rtol * before:
            notes.append(f"step {it}: relative improvement below rtol = {rtol:g}")
            break
    else:
        if max_iter:
            notes.append(f"stopped after max_iter = {max_iter} steps")

    certificates = _final_certificates(
        members, scaled, pt, nk, w0, channels, region, solvers, solve_times, region_certificates
    )
    Om_o = from_scaled(pt.Om, nk, w0, channels)
    K = control.ss(Om_o[:nk, :nk], Om_o[:nk, nk:], Om_o[nk:, :nk], Om_o[nk:, nk:])
    return MultiObjectiveResult(
        K=K,
        gamma_bound=max(c.gamma_bound for c in certificates),
        h2_bound=h2_bound if all(with_h2) else None,
        h2_met=bool(
            all(with_h2) and max(c.h2_bound for c in certificates) <= h2_bound * (1 + 1e-9)
        ),
        certificates=tuple(certificates),
        region=region,
        history=tuple(history),
        iterations=it,
        solve_times=tuple(solve_times),
        wall_time=time.perf_counter() - t_start,
        method=(
            "P-K iteration (El Ghaoui & Balakrishnan, IEEE CDC 1994) on the decay-shifted "
            "bounded-real and the H2 inequalities of every member (Boyd et al. 1994; Scherer, "
            "Gahinet & Chilali 1997), each member's certificates in recentred coordinates, "
            "trust region; damping cone and feedthrough bounds as first-order constraints, "
            "the cone certified per member by the region LMI (Chilali & Gahinet, IEEE TAC "
            "41(3), 1996)"
        ),
        notes=tuple(notes),
        w0=float(w0),
        omega_scaled=np.array(pt.Om, float),
    )


def certify_regions(members, result: MultiObjectiveResult, *, solvers=DEFAULT_SOLVERS):
    """``result`` with every deferred region certificate solved and checked.

    Parameters
    ----------
    members : sequence of SynthesisMember
        The members ``result`` was synthesised on, in the same order.
    result : MultiObjectiveResult
        From :func:`pksyn_multi` (with ``region_certificates=False``, or not: certificates
        already present are kept).
    solvers : sequence of str
        cvxpy SDP solvers, in order.

    Returns
    -------
    MultiObjectiveResult
        The same result, each member's region certificate filled in (its solve times
        appended), as :func:`pksyn_multi` with ``region_certificates=True`` returns it.

    Raises
    ------
    ModelStructureError
        If ``members`` does not match the result.
    VerificationError
        If a member has no region certificate for the controller.
    """
    members = list(members)
    if len(members) != len(result.certificates) or result.omega_scaled is None:
        raise ModelStructureError(
            f"certify_regions: expected the {len(result.certificates)} members of the result "
            f"(and a result of pksyn_multi); got {len(members)}"
        )
    if all(c.region is not None for c in result.certificates):
        return result
    nk = result.K.nstates
    _, scaled = scale_members(members, nk, result.w0)
    times = list(result.solve_times)
    out = []
    for i, (m, s, c) in enumerate(zip(members, scaled, result.certificates)):
        if c.region is None:
            rc = _region_certificate(
                m,
                s,
                result.omega_scaled,
                nk,
                result.w0,
                result.region,
                solvers,
                times,
                i,
                c.region_violation,
            )
            c = dataclasses.replace(c, region=rc, region_violation=rc.violation)
        out.append(c)
    return dataclasses.replace(result, certificates=tuple(out), solve_times=tuple(times))


def _entry(pt: _Point, h2cap: float, radius: float, response_excess: float) -> dict:
    return {
        "gamma": max(pt.g_member),
        "h2_excess": _excess(pt, h2cap),
        "response_excess": response_excess,
        "trust": radius,
    }


def _reject_reason(scaled, pt: _Point, Om_new, region_s) -> str | None:
    """Why a K-step's controller is not kept (poles leave the region, bounds worsen)."""
    for i, m in enumerate(scaled):
        v = region_s.worst_violation(
            np.linalg.eigvals(m.region.A0 + m.region.Bb @ Om_new @ m.region.Cb)
        )
        if v >= 0:
            return f"member {i} leaves the region (violation {v:.3g}, scaled time)"
    before = _response_excess(scaled, pt.Om)
    after = _response_excess(scaled, Om_new)
    if after > max(before, 0.0) + 1e-9:
        return f"response bounds worsen (excess {after:.3g} vs {before:.3g})"
    return None


def _excess(p: _Point, h2cap: float) -> float:
    return max(max(p.z_member) / h2cap - 1.0, 0.0) if h2cap else 0.0
