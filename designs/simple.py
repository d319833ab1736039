"""The three simple remedies: workspace scaling, virtual damping/stiffness, model-based cancellation."""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from robust.analysis.loops import loop_poles
from robust.errors import ModelStructureError
from robust.model.loop import BDFTLoop

__all__ = [
    "WorkspaceResult",
    "design_workspace",
    "virtual_damping_controller",
    "design_virtual_damping",
    "cancellation_controller",
    "signed_handle_units_per_m",
]


@dataclasses.dataclass(frozen=True)
class WorkspaceResult:
    """Outcome of the workspace-scaling search."""

    factor: float  # smallest factor that stabilises every sampled member (or the best found)
    stabilises_family: bool
    factors: tuple[float, ...]
    fraction_stable: tuple[float, ...]
    max_real_pole: tuple[float, ...]


def design_workspace(
    family, samples, *, factors=None, refine: int = 12, margin: float = 0.01
) -> WorkspaceResult:
    """Smallest workspace factor (``K_PSF = 0.1097 / factor``) that stabilises every sampled member.

    "Stabilises" means every closed-loop pole has real part below ``-margin`` rad/s
    (default 0.01: the human's passive arm modes decay at a few hundredths of a rad/s
    in the lightest-damped members, so the loop cannot be asked for more), so the
    chosen factor is not on the stability boundary itself.

    Scans ``factors`` (default 1, 1.5, ..., 10, then 12 ... 200), then bisects between the last
    failing and the first passing factor ``refine`` times. If no factor passes, the
    one with the largest fraction stable is returned with ``stabilises_family=False``.
    """
    from uncertainty.batched import validate_family

    default = list(np.arange(1.0, 10.01, 0.5)) + [
        12.0,
        15.0,
        20.0,
        30.0,
        50.0,
        70.0,
        100.0,
        150.0,
        200.0,
    ]
    grid = list(factors) if factors is not None else default
    fr, mr = [], []

    def run(f):
        v = validate_family(family.with_workspace_factor(f), samples)
        return v.fraction_stable, v.max_real_pole

    def passes(res):
        return res[1] < -margin

    for f in grid:
        a, b = run(f)
        fr.append(a)
        mr.append(b)
    passing = [i for i in range(len(grid)) if passes((fr[i], mr[i]))]
    if not passing:
        best = int(np.argmax(fr))
        return WorkspaceResult(grid[best], False, tuple(grid), tuple(fr), tuple(mr))
    i = passing[0]
    if i == 0:
        return WorkspaceResult(grid[0], True, tuple(grid), tuple(fr), tuple(mr))
    lo, hi = grid[i - 1], grid[i]
    for _ in range(refine):
        mid = 0.5 * (lo + hi)
        if passes(run(mid)):
            hi = mid
        else:
            lo = mid
    return WorkspaceResult(hi, True, tuple(grid), tuple(fr), tuple(mr))


def signed_handle_units_per_m(loop: BDFTLoop) -> float:
    """Handle units per metre of hand motion, with the sign of the handle axis: ``sigma*kappa*h_gain``."""
    h_gain = getattr(getattr(loop.human, "params", None), "h_gain", None)
    if h_gain is None:
        raise ModelStructureError(
            f"the {loop.human.variant!r} human has no metric unit gain (h_gain)"
        )
    return loop.calibration.handle_sign * loop.calibration.loop_scale * h_gain


def virtual_damping_controller(
    loop: BDFTLoop, damping: float, stiffness: float, *, rolloff_hz: float = 50.0
) -> ct.StateSpace:
    """Force rendered by the handle: ``f = -(b s + k) / (tau s + 1) * x_m`` (x_m: handle position in m).

    Parameters
    ----------
    damping : float
        Virtual damping ``b``, N s/m (>= 0).
    stiffness : float
        Virtual stiffness ``k``, N/m (>= 0).
    rolloff_hz : float
        First-order roll-off that makes the rendered damping proper (the velocity
        estimate's filter), Hz.
    """
    from robust.checks import POSITIVE, Spec, check_scalar

    b = check_scalar("damping", damping, Spec(low=0.0))
    k = check_scalar("stiffness", stiffness, Spec(low=0.0))
    tau = 1.0 / (2 * math.pi * check_scalar("rolloff_hz", rolloff_hz, POSITIVE))
    per_m = signed_handle_units_per_m(loop)
    g = ct.tf([-b / per_m, -k / per_m], [tau, 1.0])
    return ct.ss(g, inputs="x", outputs="f", name="virtual_damping")


def design_virtual_damping(
    family,
    samples,
    *,
    dampings=(0, 1, 2, 5, 10, 20, 40, 80),
    stiffnesses=(0, 25, 50, 100, 200, 400),
    limits=None,
    intent_fraction: float = 0.25,
    seed: int = 0,
):
    """Grid search of virtual damping and stiffness over the family, within the device's force limits.

    Every pair is validated on ``samples``; candidates are ranked by fraction of
    stable members (ties: smaller worst real part, then smaller gains). The first
    candidate whose handle force on the nominal member (chirp and seeded intended
    motion, :func:`designs.evaluate.force_histories`) stays within ``limits``
    is chosen; if none does, the most stabilising one is returned and flagged.

    Returns
    -------
    damping, stiffness : float
    controller : control.StateSpace
    table : list of tuple
        ``(damping, stiffness, fraction_stable, max_real_pole)`` for every pair.
    within_limits : bool
    """
    from designs.evaluate import force_histories
    from robust.model.device import DeviceLimits, check_force
    from uncertainty.batched import validate_family

    lim = limits or DeviceLimits()
    nominal = family.member(family.nominal_values())
    amp = intent_fraction * (lim.workspace_mm / 2) * 1e-3 * abs(signed_handle_units_per_m(nominal))
    table = []
    for b in dampings:
        for k in stiffnesses:
            K = virtual_damping_controller(nominal, b, k)
            v = validate_family(family, samples, controller=K)
            table.append((float(b), float(k), v.fraction_stable, v.max_real_pole))
    ranked = sorted(table, key=lambda r: (-r[2], r[3], r[0], r[1]))
    for b, k, _, _ in ranked:
        K = virtual_damping_controller(nominal, b, k)
        if not loop_poles(nominal, controller=K).stable:
            continue
        hist = force_histories(nominal, K, amplitude=amp, seed=seed)
        if (
            hist
            and check_force(np.concatenate(hist), lim).within_limits
            and all(np.sqrt(np.mean(np.asarray(h) ** 2)) <= lim.continuous_force_n for h in hist)
        ):
            return b, k, K, table, True
    b, k = ranked[0][:2]
    return b, k, virtual_damping_controller(nominal, b, k), table, False


def cancellation_controller(loop: BDFTLoop) -> ct.StateSpace:
    """Model-based cancellation at signal level: ``r_corr = -K_PSF*sigma*kappa * H_nom(s) c``.

    ``H_nom`` is the nominal human's seat-acceleration-to-hand path; the estimate
    of the hand's motion built from the measured cab acceleration is subtracted
    from the cylinder reference. No force is applied.
    """
    H = loop.human.system()
    ic = H.input_labels.index("c")
    cal = loop.calibration
    g = -loop.k_psf * cal.handle_sign * cal.loop_scale
    return ct.ss(
        H.A,
        H.B[:, [ic]],
        g * H.C,
        g * H.D[:, [ic]],
        inputs="c",
        outputs="r_corr",
        name="cancellation",
    )
