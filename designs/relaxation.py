"""Lower bounds on the effort any compensator needs: the frequency-wise relaxation.

Every linear compensator of a member, whatever it measures, makes its actuators' signals
``a(jw) = q(jw) u(jw)`` for some transfer vector ``q`` from the operator's command ``u``
(the command, its remnant and the sensor noise enter the loop together; counting only the
command's part of each signal can only lower an RMS). Dropping the conditions that ``q``
comes from a causal, stabilising compensator of the set's sensors leaves, at each
frequency, a free complex vector ``q`` and closed-loop maps affine in it:

* the tracked deviation ``R = a0 + sum_i b_i q_i`` (:mod:`designs.response`), which the
  specification bounds at every frequency, ``|R(jw)| <= beta(w)``;
* each actuator's effort, ``|h_i q_i|``: the handle force (N per unit ``u``), the cylinder
  speed and the valve command a reference correction asks for
  (:func:`designs.effort.cylinder_filters`).

The least effort meeting the bound at one frequency has a closed form. A point ``q`` meets
it iff ``c = b . q`` lies in the disc ``|a0 + c| <= beta``, whose point nearest the origin
has ``|c| = max(0, |a0| - beta)``; for a weighted effort ``sum_i w_i |q_i|^2`` the least
``q`` with ``b . q = c`` gives ``|c|^2 / sum_i |b_i|^2 / w_i`` (Cauchy-Schwarz). So

    min  sum_i w_i |q_i|^2  =  max(0, |a0| - beta)^2 / sum_i (|b_i|^2 / w_i).

Integrating it against the operator's spectrum (:func:`designs.effort.operator_spectrum`)
bounds the RMS effort from below, for every compensator of every sensor set with these
actuators. With both actuators, the handle force is bounded under the reference effort's
limits by Lagrangian duality: for any multipliers ``lambda >= 0`` the weights
``w_f = |h_f|^2``, ``w_r = lambda_1 |h_speed|^2 + lambda_2 |h_command|^2`` give
``min force^2 >= integral(...) - lambda . limits^2`` (weak duality; the bound reported is
the best of a search over ``lambda``, valid whatever the search finds).

The integrals are trapezoidal sums in ``log w`` on :data:`N_FREQ` frequencies from
:data:`BAND_HZ`; halving the grid changes the default family's bounds by less than 1e-3
relative (tested), which is the bound's numerical uncertainty. The bound ignores the noise,
the pole region, causality and the peak force: it is loose, never optimistic. That is
the bracket ``[lower, upper]`` of :mod:`designs.limit`: the upper bound is a verified
controller, the lower bound no controller can beat.

Reference: S. Boyd and C. Barratt, *Linear Controller Design: Limits of Performance*,
Prentice Hall 1991, ch. 14 (frequency-wise bounds on achievable closed-loop maps).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.optimize as sopt

from designs.effort import correction_limits, cylinder_filters, operator_spectrum
from designs.response import deviation_maps
from robust.analysis.bounds import siso_response
from robust.errors import ParameterError

__all__ = ["EffortBound", "effort_lower_bound", "least_effort", "BAND_HZ", "N_FREQ"]

#: Frequencies of the quadrature, Hz (the intent's spectrum is 1e-9 of its peak at the top).
BAND_HZ = (1e-3, 1e3)
#: Points of the quadrature (log-spaced).
N_FREQ = 800


@dataclasses.dataclass(frozen=True)
class EffortBound:
    """Lower bounds on the effort of every compensator of one member and actuator set.

    Parameters
    ----------
    force : float
        Lower bound of the required force multiple: the least RMS handle force meeting the
        deviation's bounds (and, with a reference correction, the reference effort's
        limits) over the Omni's continuous force (0 without a force actuator).
    rms_force_n : float
        That RMS force, N.
    reference : float
        Lower bound of the reference-effort utilisation of a reference correction acting
        alone (``nan`` for sets with a force actuator, whose force can take its place).
    """

    force: float
    rms_force_n: float
    reference: float

    @property
    def infeasible(self) -> bool:
        """Whether no controller of the set meets the specification at any force (a
        reference correction alone needs more than its limits)."""
        return bool(self.reference > 1.0)


def _responses(plant, omega) -> tuple[np.ndarray, np.ndarray]:
    """``a0 = R/u`` with the actuators at zero and ``b_i = R/a_i`` (plant units) at ``omega``."""
    A, C = plant.A, plant.Cy
    a0 = siso_response((A, plant.Bw, C, np.array([[plant.Dyw]])), omega)
    b = [
        siso_response((A, plant.Bu[:, [j]], C, plant.Dyu[:, [j]]), omega)
        for j in range(plant.Bu.shape[1])
    ]
    return a0, np.stack(b, axis=1)


def least_effort(a0, beta, b, weights) -> np.ndarray:
    """Per frequency, ``min sum_i w_i |q_i|^2`` subject to ``|a0 + sum_i b_i q_i| <= beta``.

    The closed form of the module notes, ``max(0, |a0| - beta)^2 / sum_i |b_i|^2 / w_i``
    (a zero weight: that actuator is free, the minimum 0 where it reaches ``R``).

    Parameters
    ----------
    a0 : ndarray (N,) complex
        The map with the actuators at zero.
    beta : ndarray (N,)
        The bound, > 0.
    b : ndarray (N, m) complex
        The maps from the actuators.
    weights : ndarray (N, m)
        The effort's weights, >= 0.

    Returns
    -------
    ndarray (N,)
    """
    excess2 = np.maximum(np.abs(a0) - beta, 0.0) ** 2
    w = np.asarray(weights, float)
    b2 = np.abs(b) ** 2
    free = (w <= 0) & (b2 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        den = np.sum(np.where(b2 > 0, b2 / np.where(w > 0, w, 1.0), 0.0), axis=1)
        val = np.where(den > 0, excess2 / den, np.inf)
    val = np.where(np.any(free, axis=1) | (excess2 == 0), 0.0, val)
    return val


def _integral(values, omega) -> float:
    """``(1/pi) int values dw`` by the trapezoidal rule in ``log w``."""
    return float(np.trapezoid(values * omega, np.log(omega)) / math.pi)


def effort_lower_bound(loop, plant, scales, actuators, spec, *, n_freq: int = N_FREQ):
    """The frequency-wise relaxation's lower bounds for one member (module notes).

    Parameters
    ----------
    loop : backhoe.model.loop.BDFTLoop
        The member.
    plant : robust.synthesis.youla.YoulaPlant
        Its open loop with the tracked deviation ``R`` and the actuators
        (:func:`designs.limit._member_plant` without sensors).
    scales : ndarray
        The actuators' unit changes (an actuator in loop units is ``plant's / scales``).
    actuators : sequence of str
        The actuators' names (``"f"``, ``"r_corr"``), in the plant's order.
    spec : designs.spec.Specification
    n_freq : int
        Quadrature points (>= 64).

    Returns
    -------
    EffortBound
    """
    acts = tuple(actuators)
    if n_freq < 64:
        raise ParameterError(f"effort_lower_bound: n_freq must be >= 64; got {n_freq}")
    if not acts or any(a not in ("f", "r_corr") for a in acts):
        raise ParameterError(
            f"effort_lower_bound: actuators must be among 'f', 'r_corr'; got {acts!r}"
        )
    omega = 2 * math.pi * np.geomspace(*BAND_HZ, n_freq)
    a0, b = _responses(plant, omega)
    _, r0 = deviation_maps(loop, reference_k_psf=spec.reference_k_psf)
    beta = spec.deviation_bound(omega, siso_response(r0, omega))
    amp = loop.intended_amplitude(spec.limits(), spec.intent_fraction)
    S = operator_spectrum(omega, amp, spec.intent_bandwidth_hz, spec.noise)
    gains = {}
    if "f" in acts:
        gains["f"] = np.full(omega.size, plant.force_gain**2)
    if "r_corr" in acts:
        i = acts.index("r_corr")
        Ac, Bc, Cc, Dc = cylinder_filters(loop)
        h = np.stack([siso_response((Ac, Bc, Cc[[k]], Dc[[k]]), omega) for k in range(2)], axis=1)
        # per unit of the plant's actuator: the loop's r_corr is the plant's over its scale
        gains["r_corr"] = np.abs(h) ** 2 / float(scales[i]) ** 2

    def least(weights):
        """``(1/pi) int S min sum w_i |q_i|^2`` for per-frequency weights ``weights[a]``."""
        w = np.stack([weights[a] for a in acts], axis=1)
        return _integral(least_effort(a0, beta, b, w) * S, omega)

    limits = np.asarray(correction_limits(loop, spec), float)
    if "f" not in acts:
        # a reference correction alone: each of its efforts (speed, valve command) bounded
        util = [math.sqrt(least({"r_corr": gains["r_corr"][:, k]})) / limits[k] for k in range(2)]
        return EffortBound(force=0.0, rms_force_n=0.0, reference=float(max(util)))
    if "r_corr" not in acts:
        rms = math.sqrt(least({"f": gains["f"]}))
        return EffortBound(force=rms / spec.continuous_force_n, rms_force_n=rms, reference=math.nan)

    def dual(log_lam):
        lam = np.exp(np.asarray(log_lam, float))
        wr = lam[0] * gains["r_corr"][:, 0] + lam[1] * gains["r_corr"][:, 1]
        return least({"f": gains["f"], "r_corr": wr}) - float(lam @ limits**2)

    # a coarse search over the multipliers, then a local one from the best: any point is a
    # valid bound (weak duality), the search only makes it tighter
    grid = np.linspace(-30.0, 30.0, 7)
    best = max(((x, y) for x in grid for y in grid), key=dual)
    res = sopt.minimize(lambda z: -dual(z), np.asarray(best), method="Nelder-Mead")
    value = max(dual(best), -float(res.fun), 0.0)
    rms = math.sqrt(value)
    return EffortBound(force=rms / spec.continuous_force_n, rms_force_n=rms, reference=math.nan)
