"""Robust H-infinity handle-force feedback: the nominal LMI design tuned over family members.

The design, top to bottom:

1. family: the default family; the design sample is the scenario set;
2. weights: :class:`backhoe.synthesis.forcefb.ForceFeedbackWeights`; force budget 0.8 of
   the device limits on the design members; decay-rate margin 0.3 rad/s;
3. synthesis: the nominal LMI design (:mod:`designs.hinf_nominal`), reduced, then
   multi-model spectral-abscissa tuning over sampled members with scenario
   enlargement (:func:`design_hinf_robust`, :mod:`designs.multimodel`), the design
   members seen through a half-sample lag at the controller's output (the 1 kHz
   zero-order hold's delay: without it the tuned controller's nominal sampled-data loop
   can be unstable while its continuous loop decays); the weighted
   closed-loop H-infinity norm of every design member is recomputed independently; the
   synthesis and tuning run on one BLAS and one solver thread
   (:func:`robust.synthesis.solve.deterministic_solvers`), so the controller does not
   depend on the thread count or the machine's load;
4. validation and export: the common pipeline (:func:`designs.registry.run_design`).

The sibling design :mod:`designs.hinf_robust_corr` is this one with a
cylinder-reference correction output; it calls :func:`build_robust` with its options.

Run it alone with ``python -m designs hinf-robust [--samples N] [--seed S] [--out DIR]``.
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np

from backhoe.analysis.loops import reduce_controller
from backhoe.model.device import DeviceLimits
from backhoe.synthesis.forcefb import (
    ForceFeedbackWeights,
    as_loop_controller,
    as_plant_controller,
    force_feedback_plant,
)
from designs.evaluate import TRACKING_BAND_HZ
from designs.hinf_nominal import NominalHinf, design_hinf_nominal, synthesis_json
from designs.multimodel import ForceBudget, TrackingBudget, tune_spectral_abscissa
from designs.result import Design, DesignFacts, DesignResult
from robust.analysis.loops import frequency_response
from robust.analysis.norms import hinf_norm
from robust.synthesis.genplant import as_generalized_plant
from robust.synthesis.solve import deterministic_solvers

__all__ = [
    "RobustHinf",
    "RobustHinfFacts",
    "design_hinf_robust",
    "build_robust",
    "build",
    "DESIGN",
]

DESIGN_NAME = "hinf-robust"
DESCRIPTION = (
    "robust H-infinity handle-force feedback: nominal LMI design tuned over family members"
)


@dataclasses.dataclass(frozen=True)
class RobustHinf:
    """A controller tuned over family members and the facts behind it.

    Parameters
    ----------
    controller : control.StateSpace
        Loop convention ``x, c -> f`` (``, r_corr``).
    gamma : float
        Verified weighted closed-loop H-infinity norm, worst design member.
    member_gammas : tuple of float
        That norm on every design member (the nominal first).
    solver : dict
        Method, rounds, convergence, force phase.
    weights : ForceFeedbackWeights
        The weights used.
    design_members : int
        Number of design members at the end of the enlargement.
    """

    controller: object
    gamma: float
    member_gammas: tuple[float, ...]
    solver: dict
    weights: ForceFeedbackWeights
    design_members: int


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
    """Robust H-infinity force feedback: the nominal LMI design made to hold over the members.

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
       (:func:`backhoe.synthesis.forcefb.force_feedback_plant`) is computed independently on every
       design member and reported (worst member, nominal, and all of them).

    With ``reference_correction`` the controller gets a second output, a correction of
    the cylinder reference (signal level, no force), starting from zero; the tuning
    then also keeps the nominal tracking error ``|Y/Y_ref - 1|`` over 0.05-2 Hz below
    ``tracking_error`` (:class:`designs.multimodel.TrackingBudget`), since a
    reference correction can stabilise simply by cancelling the operator's command.

    The guarantee is per sampled member (closed-loop eigenvalues); nothing is claimed
    between samples, so callers validate on a held-out sample too.

    Parameters
    ----------
    family : backhoe.Family
        The family (physical human).
    samples : uncertainty.SampleSet
        The scenario set of the tuning.
    weights : ForceFeedbackWeights, optional
        Weights of the force-feedback plant (intended-motion amplitude, norms).
    limits : DeviceLimits, optional
        Device limits (force budget).
    K0 : control.StateSpace, optional
        Starting controller (loop convention ``x, c -> f``).
    margin : float
        Required decay rate of every sampled member, rad/s.
    rounds, add_per_round : int
        Scenario-enlargement rounds and members added per round.
    force_margin : float
        Fraction of the device limits the design members' force may use.
    reference_correction : bool
        Add the cylinder-reference correction output ``r_corr``.
    tracking_error : float
        Tracking budget of the nominal member with ``reference_correction``.
    progress : callable, optional
        Progress callback of :func:`designs.multimodel.tune_spectral_abscissa`.

    Returns
    -------
    RobustHinf
    """
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
        amplitude=nominal.intended_amplitude(lim, w.intent_fraction),
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
        actuator_lag_s=0.5 * lim.sample_time_s,
        progress=progress,
    )
    K = as_loop_controller(tuned.controller, name="hinf_robust")
    Kp = as_plant_controller(K)
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
        "method": "nominal LMI H-infinity design (Gahinet & Apkarian 1994), balanced "
        "truncation, then multi-model spectral-abscissa tuning over sampled members with "
        "scenario enlargement (HIFOO stabilisation phase: Burke, Henrion, Lewis & Overton "
        "2006; BFGS, Lewis & Overton 2013)",
        "margin_rad_s": margin,
        "converged": tuned.converged,
        "force_margin": force_margin,
        "reference_correction": reference_correction,
        "tracking_error_budget": tracking_error,
        "rounds": [
            dict(zip(("design_members", "worst_sampled_max_real", "fraction_stable"), h))
            for h in tuned.history
        ],
        "chosen_round": tuned.chosen_round,
        "design_member_alpha_max": float(tuned.alpha_design.max()),
        "force_phase": tuned.force_phase,
        "member_gammas": gammas.tolist(),
        "gamma_nominal": float(gammas[0]),
    }
    return RobustHinf(
        K, float(gammas.max()), tuple(float(g) for g in gammas), solver, w, len(tuned.design_rows)
    )


@dataclasses.dataclass(frozen=True)
class RobustHinfFacts(DesignFacts):
    """What the robust H-infinity design reports of itself.

    Parameters
    ----------
    design : RobustHinf
        The tuned design (its norms, solver statistics, weights and design members).
    nominal : designs.hinf_nominal.NominalHinf
        The nominal LMI design it starts from (before reduction and tuning).
    reduction_error_bound : float
        Balanced-truncation error bound of the nominal design's reduction.
    """

    design: RobustHinf
    nominal: NominalHinf
    reduction_error_bound: float

    def to_json(self) -> dict:
        """The facts under ``bdft design --json``'s keys (no controller)."""
        d = self.design
        order, bound = self.nominal.controller.nstates, self.reduction_error_bound
        return dict(
            gamma_worst_design_member=d.gamma,
            gamma_nominal=d.solver["gamma_nominal"],
            gamma_nominal_design=self.nominal.gamma,
            design_members=d.design_members,
            **synthesis_json(d.solver, d.weights, order, bound),
        )


def build_robust(family, samples, limits, **options) -> DesignResult:
    """The robust design on ``family``: nominal LMI design, reduced, tuned over members.

    Parameters
    ----------
    family : backhoe.Family
        The default family.
    samples : uncertainty.SampleSet
        The scenario set.
    limits : backhoe.model.device.DeviceLimits
        Device limits.
    **options
        Passed to :func:`design_hinf_robust` (``reference_correction``, ``margin``,
        ``tracking_error``...); ``name`` and ``description`` name the result.
    """
    name = options.pop("name", DESIGN_NAME)
    description = options.pop("description", DESCRIPTION)
    nominal = family.member(family.nominal_values())
    # one BLAS and one solver thread: the nonsmooth tuning amplifies rounding differences
    # (thread counts, the machine's load) into different controllers
    with deterministic_solvers():
        nominal_design = design_hinf_nominal(family, limits=limits)
        K0, bound = reduce_controller(nominal_design.controller, [nominal])
        d = design_hinf_robust(family, samples, K0=K0, limits=limits, **options)
    notes = []
    if not d.solver["converged"]:
        notes.append(
            "the multi-model tuning did not reach the required decay rate on every sampled member"
        )
    fp = d.solver.get("force_phase")
    if fp is not None and not fp["accepted"]:
        notes.append(
            "the force-budget phase met the budget on the design members only by losing "
            f"stability (fraction stable {fp['fraction_stable']:.4f}, worst real part "
            f"{fp['worst_sampled_max_real']:.3g} rad/s); it was rejected: the stabilising "
            "handle-position gain acts in the intended-motion band, where it also resists the "
            "operator"
        )
    return DesignResult(
        name=name,
        description=description,
        family=family,
        controller=d.controller,
        order_full=nominal_design.controller.nstates,
        reduction_error_bound=bound,
        facts=RobustHinfFacts(d, nominal_design, bound),
        notes=tuple(notes),
    )


def build(family, samples, limits) -> DesignResult:
    """The force-only robust design: decay-rate margin 0.3 rad/s, no reference correction.

    Parameters
    ----------
    family : backhoe.Family
        The default family.
    samples : uncertainty.SampleSet
        The scenario set.
    limits : backhoe.model.device.DeviceLimits
        Device limits.
    """
    return build_robust(family, samples, limits, reference_correction=False, margin=0.3)


DESIGN = Design(DESIGN_NAME, DESCRIPTION, build)
