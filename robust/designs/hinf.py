"""H-infinity force-feedback designs: nominal (one plant) and robust (many members at once).

Both synthesise on :func:`robust.forcefb.force_feedback_plant` with LMIs
(:func:`robust.hinfsyn.hinfsyn_lmi`, :func:`robust.hinfsyn.hinfsyn_multi`); every
answer is verified there (closed-loop poles, independent H-infinity norm) and again
here on the Figure 5 loop of each member.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..analysis import loop_poles
from ..device import DeviceLimits
from ..forcefb import ForceFeedbackWeights, as_loop_controller, force_feedback_plant
from ..reduction import balanced_truncation

__all__ = ["HinfDesign", "design_hinf_nominal", "design_hinf_robust", "reduce_controller", "design_members"]


@dataclasses.dataclass(frozen=True)
class HinfDesign:
    """A synthesised force-feedback controller and the synthesis facts behind it."""

    controller: object  # control.StateSpace, loop convention x, c -> f
    gamma: float  # verified closed-loop H-infinity norm (worst member for the robust design)
    gamma_bound: float
    member_gammas: tuple[float, ...]
    solver: dict
    weights: ForceFeedbackWeights
    design_members: int


def reduce_controller(K, members, *, rtol: float = 0.01):
    """Balanced truncation of ``K`` to the smallest order whose error bound is below
    ``rtol * ||K||_inf`` and that keeps every loop in ``members`` stable.

    Returns ``(K_reduced, error_bound)``; ``K`` itself if no smaller order qualifies.
    """
    from ..norms import hinf_norm

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


def design_hinf_nominal(family, *, weights: ForceFeedbackWeights | None = None, limits: DeviceLimits | None = None):
    """Nominal H-infinity force feedback: LMI synthesis on the family's nominal member."""
    from ..hinfsyn import hinfsyn_lmi

    w = weights or ForceFeedbackWeights()
    nominal = family.member(family.nominal_values())
    res = hinfsyn_lmi(force_feedback_plant(nominal, w, limits))
    K = as_loop_controller(res.K, name="hinf_nominal")
    solver = {"method": "LMI (Gahinet-Apkarian 1994), Clarabel/SCS", "solver": res.solver, "status": res.status,
              "gamma_bound": res.gamma_bound, "gamma_verified": res.gamma}
    return HinfDesign(K, res.gamma, res.gamma_bound, (res.gamma,), solver, w, 1)


def design_members(family, samples, controller, n: int, *, stable_only: bool = False):
    """The nominal member plus ``n - 1`` members where ``controller`` does worst (largest real part).

    With ``stable_only`` the members are taken among those ``controller`` stabilises
    (the ones closest to instability), so that ``controller`` can start a
    multi-model iteration on them.
    """
    from uncertainty.batched import validate_family

    v = validate_family(family, samples, controller=controller)
    idx = np.arange(len(v.max_real))
    if stable_only:
        idx = idx[v.max_real < v.stability_threshold]
    order = idx[np.argsort(v.max_real[idx])[::-1][: max(0, n - 1)]]
    rows = [family.nominal_values()] + [samples.values[i] for i in order]
    return [family.member(r) for r in rows], rows


def design_hinf_robust(family, samples, *, n_members: int = 6, rounds: int = 3, weights=None, limits=None, K0=None,
                       max_iter: int = 8, progress=None):
    """Robust H-infinity force feedback by multi-model synthesis with progressive enlargement.

    Each round takes the nominal member and the ``n_members - 1`` members that the
    current controller stabilises with the least margin (largest closed-loop real
    part), and runs :func:`robust.hinfsyn.hinfsyn_multi` from the current controller
    (a sequential convex P-K iteration with a Lyapunov certificate for every design
    member). Members the current controller does not stabilise cannot start that
    iteration; as the margin grows round by round, the stabilised set grows with it.
    The first controller is ``K0`` (e.g. the nominal design).
    """
    from ..hinfsyn import hinfsyn_multi

    w = weights or ForceFeedbackWeights()
    K = K0
    res = None
    used = 0
    history = []
    for r in range(rounds):
        members, _ = design_members(family, samples, K, n_members, stable_only=K is not None)
        plants = [force_feedback_plant(m, w, limits) for m in members]
        res = hinfsyn_multi(plants, K0=None if K is None else _as_plant_controller(K), max_iter=max_iter)
        K = as_loop_controller(res.K, name="hinf_robust")
        used = len(plants)
        history.append(float(np.max(res.gammas)))
        if progress:
            progress(r, res)
    solver = {"method": "multi-model P-K iteration (El Ghaoui & Balakrishnan 1994) with progressive enlargement, "
              "Clarabel/SCS", "gamma_bound": res.gamma_bound, "iterations": res.iterations,
              "member_gammas": list(res.gammas), "worst_member_gamma_per_round": history}
    return HinfDesign(K, float(np.max(res.gammas)), res.gamma_bound, tuple(float(g) for g in res.gammas), solver, w,
                      used)


def _as_plant_controller(K):
    import control as ct

    rename = {"x": "x_m", "c": "c_m", "y": "y_m"}
    return ct.ss(K.A, K.B, K.C, K.D, inputs=[rename[s] for s in K.input_labels], outputs=["f"], name=K.name)
