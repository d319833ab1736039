"""H-infinity force-feedback designs: nominal (one plant) and robust (many members at once).

Both start from LMI synthesis on :func:`robust.synthesis.forcefb.force_feedback_plant`
(:func:`robust.synthesis.hinfsyn.hinfsyn_lmi`, verified there by closed-loop poles and an
independent H-infinity norm); the robust design then tunes that controller over
the family's members (:mod:`designs.multimodel`) and every member's norm is
recomputed here.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robust.analysis.loops import loop_poles
from robust.analysis.reduction import balanced_truncation
from robust.model.device import DeviceLimits
from robust.synthesis.forcefb import ForceFeedbackWeights, as_loop_controller, force_feedback_plant

__all__ = ["HinfDesign", "design_hinf_nominal", "design_hinf_robust", "reduce_controller"]


@dataclasses.dataclass(frozen=True)
class HinfDesign:
    """A synthesised force-feedback controller and the synthesis facts behind it."""

    controller: object  # control.StateSpace, loop convention x, c -> f
    gamma: float  # verified closed-loop H-infinity norm (worst design member for the robust design)
    gamma_bound: float  # LMI bound (nan where the design is not an LMI optimum)
    member_gammas: tuple[float, ...]
    solver: dict
    weights: ForceFeedbackWeights
    design_members: int


def reduce_controller(K, members, *, rtol: float = 0.01):
    """Balanced truncation of ``K`` to the smallest order whose error bound is below
    ``rtol * ||K||_inf`` and that keeps every loop in ``members`` stable.

    Returns ``(K_reduced, error_bound)``; ``K`` itself if no smaller order qualifies.
    """
    from robust.analysis.norms import hinf_norm

    if K.nstates <= 1:
        return K, 0.0
    size = hinf_norm(K) if np.all(np.real(K.poles()) < 0) else np.inf
    best = (K, 0.0)
    for order in range(K.nstates - 1, 0, -1):
        try:
            red = balanced_truncation(K, order=order)
        except ValueError:
            break
        if not np.isfinite(size) or red.error_bound > rtol * size:
            break
        if not all(loop_poles(m, controller=red.sys).stable for m in members):
            break
        best = (red.sys, red.error_bound)
    return best


def design_hinf_nominal(
    family, *, weights: ForceFeedbackWeights | None = None, limits: DeviceLimits | None = None
):
    """Nominal H-infinity force feedback: LMI synthesis on the family's nominal member."""
    from robust.synthesis.hinfsyn import hinfsyn_lmi

    w = weights or ForceFeedbackWeights()
    nominal = family.member(family.nominal_values())
    res = hinfsyn_lmi(force_feedback_plant(nominal, w, limits))
    K = as_loop_controller(res.K, name="hinf_nominal")
    solver = {
        "method": "LMI (Gahinet-Apkarian 1994), Clarabel/SCS",
        "solver": res.solver,
        "status": res.status,
        "gamma_bound": res.gamma_bound,
        "gamma_verified": res.gamma,
    }
    return HinfDesign(K, res.gamma, res.gamma_bound, (res.gamma,), solver, w, 1)


def design_hinf_robust(
    family,
    samples,
    *,
    weights=None,
    limits=None,
    K0=None,
    margin: float = 0.15,
    rounds: int = 10,
    add_per_round: int = 12,
    force_margin: float = 0.8,
    reference_correction: bool = True,
    tracking_error: float = 0.5,
    progress=None,
):
    """Robust H-infinity force feedback: the nominal LMI design made to hold over the family's members.

    1. ``K0`` (default: :func:`design_hinf_nominal`, reduced by balanced truncation
       with the nominal loop kept stable) is the starting point;
    2. :func:`designs.multimodel.tune_spectral_abscissa` tunes its entries
       over a growing set of members (scenario enlargement on ``samples``) until every
       sampled member's closed loop decays faster than ``margin`` rad/s, staying as
       close to ``K0`` as stability allows (HIFOO's stabilisation phase, Burke et al. 2006)
       and keeping every design member's intended-motion-to-force response within
       ``force_margin`` times the device's peak and continuous limits (chirp 0.1-8 Hz at the
       weights' intended-motion amplitude, :class:`designs.multimodel.ForceBudget`);
    3. the H-infinity norm of the weighted force-feedback closed loop
       (:func:`robust.synthesis.forcefb.force_feedback_plant`) is computed independently on every
       design member and reported (worst member, nominal, and all of them).

    With ``reference_correction`` the controller gets a second output, a correction of
    the cylinder reference (signal level, no force), starting from zero; the tuning
    then also keeps the nominal tracking error ``|Y/Y_ref - 1|`` over 0.05-2 Hz below
    ``tracking_error`` (:class:`designs.multimodel.TrackingBudget`), since a
    reference correction can stabilise simply by cancelling the operator's command.

    The guarantee is per sampled member (closed-loop eigenvalues); nothing is claimed
    between samples, so callers validate on a held-out sample too.
    """
    import control as ct

    from designs.evaluate import TRACKING_BAND_HZ
    from designs.multimodel import ForceBudget, TrackingBudget, tune_spectral_abscissa
    from robust.analysis.loops import frequency_response
    from robust.analysis.norms import hinf_norm
    from robust.synthesis.forcefb import handle_units_per_m
    from robust.synthesis.genplant import as_generalized_plant

    w = weights or ForceFeedbackWeights()
    nominal = family.member(family.nominal_values())
    if K0 is None:
        K0, _ = reduce_controller(
            design_hinf_nominal(family, weights=w, limits=limits).controller, [nominal]
        )
    lim = limits or DeviceLimits()
    tracking = None
    scales = None
    if reference_correction:
        K0 = ct.ss(
            K0.A,
            K0.B,
            np.vstack([K0.C, np.zeros((1, K0.nstates))]),
            np.vstack([K0.D, np.zeros((1, K0.ninputs))]),
            inputs=K0.input_labels,
            outputs=[*K0.output_labels, "r_corr"],
            name=K0.name,
        )
        scales = {"r_corr": family.k_psf}
        ft = np.geomspace(*TRACKING_BAND_HZ, 30)
        tracking = TrackingBudget(
            y_ref=frequency_response(nominal.system(bdft=False), ft),
            max_error=tracking_error,
            f_hz=ft,
        )
    budget = ForceBudget(
        amplitude=w.intent_fraction * (lim.workspace_mm / 2) * 1e-3 * handle_units_per_m(nominal),
        peak_n=force_margin * lim.peak_force_n,
        rms_n=force_margin * lim.continuous_force_n,
        f_hz=np.geomspace(0.1, 8.0, 30),
        output=list(K0.output_labels).index("f"),
    )
    tuned = tune_spectral_abscissa(
        family,
        samples,
        K0,
        margin=margin,
        rounds=rounds,
        add_per_round=add_per_round,
        force=budget,
        tracking=tracking,
        output_scales=scales,
        force_while_stabilising=reference_correction,
        progress=progress,
    )
    K = as_loop_controller(tuned.controller, name="hinf_robust")
    Kp = _as_plant_controller(K)
    gammas = []
    for row in tuned.design_rows:
        gp = as_generalized_plant(
            force_feedback_plant(
                family.member(row), w, limits, reference_correction=reference_correction
            )
        )
        gammas.append(hinf_norm(gp.closed_loop(Kp)))
    gammas = np.array(gammas)
    solver = {
        "method": "nominal LMI H-infinity design (Gahinet & Apkarian 1994), balanced truncation, then "
        "multi-model spectral-abscissa tuning over sampled members with scenario enlargement "
        "(HIFOO stabilisation phase: Burke, Henrion, Lewis & Overton 2006; BFGS, Lewis & Overton 2013)",
        "margin_rad_s": margin,
        "converged": tuned.converged,
        "force_margin": force_margin,
        "reference_correction": reference_correction,
        "tracking_error_budget": tracking_error,
        "rounds": [
            dict(zip(("design_members", "worst_sampled_max_real", "fraction_stable"), h))
            for h in tuned.history
        ],
        "design_member_alpha_max": float(tuned.alpha_design.max()),
        "force_phase": tuned.force_phase,
        "member_gammas": gammas.tolist(),
        "gamma_nominal": float(gammas[0]),
    }
    return HinfDesign(
        K,
        float(gammas.max()),
        float("nan"),
        tuple(float(g) for g in gammas),
        solver,
        w,
        len(tuned.design_rows),
    )


def _as_plant_controller(K):
    import control as ct

    rename = {"x": "x_m", "c": "c_m", "y": "y_m"}
    return ct.ss(
        K.A,
        K.B,
        K.C,
        K.D,
        inputs=[rename[s] for s in K.input_labels],
        outputs=list(K.output_labels),
        name=K.name,
    )
