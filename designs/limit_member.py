"""The achievable limit of one member for one set of actuators and sensors.

:func:`member_limit` (the least force multiple, or the relaxation, of the best controller
of the Youla basis on :data:`BASIS_POLES`, each answer re-checked) and
:func:`member_controller` (that controller), both on one BLAS and solver thread so that a
member gives the same digits in any process; the lower bounds of the frequency-wise
relaxation (:func:`designs.relaxation.effort_lower_bound`) are attached to each result.
The map of :mod:`designs.limit` runs them over members and sets.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import control as ct
import numpy as np

from designs.constants import ACTUATOR_SETS, SENSOR_SETS
from designs.effort import sensor_intensities
from designs.limit_plant import (
    ACCEL_NOISE_RMS,
    ENCODER_MM,
    _bounds,
    _gain,
    _grids,
    _member_plant,
    _observer,
)
from designs.limit_solve import (
    _PROBLEMS,
    CUT_ROUNDS,
    N_CUTS,
    TIGHTENING,
    UNDECIDED,
    SetLimit,
    _cut_bounds,
    _cuts,
    _grams,
    _loop_system,
    _set_limit,
    _solve_on_grid,
    _verify,
)
from designs.relaxation import effort_lower_bound
from designs.response import deviation_bound_checks
from designs.specification import Specification
from robust.errors import BDFTError, ParameterError
from robust.synthesis.solve import deterministic_solvers
from robust.synthesis.stabilising import uncontrollable_modes
from robust.synthesis.youla import closed_loop, of_closed_loop, of_controller
from robust.synthesis.youla_basis import pole_basis

__all__ = ["BASIS_POLES", "member_limit", "member_controller"]


#: Poles of the orthonormal lag basis, rad/s: 32 from 0.3 to 1000 rad/s (about 9 per
#: decade), inside the region (above its decay rate, real). Doubling the basis lowers a
#: member's handle-force limit by a few per cent (measured; the page reports the check).
BASIS_POLES = tuple(float(x) for x in np.geomspace(0.3, 1000.0, 32))


def member_limit(
    loop,
    actuators: str,
    spec: Specification | None = None,
    *,
    sensors: str = "full",
    seed: int = 0,
    basis_poles=BASIS_POLES,
    duration_s: float = 20.0,
    encoder_mm: float = ENCODER_MM,
    accel_rms: float = ACCEL_NOISE_RMS,
    problems: dict | None = None,
) -> SetLimit:
    """The best compensator of one member for one actuator and sensor set (module notes).

    :func:`member_controller` returns the compensator itself.

    Parameters
    ----------
    loop : backhoe.model.loop.BDFTLoop
        The member (physical human).
    actuators : str
        A key of :data:`ACTUATOR_SETS`.
    spec : Specification, optional
    sensors : str
        A key of :data:`SENSOR_SETS`: ``"full"`` (every state, noiseless) or measured
        signals with their noise (``encoder_mm``, ``accel_rms``).
    seed : int
        Seed of the peak-force simulation's intended motion.
    basis_poles : sequence of float
        Poles of the lag basis, rad/s (above the decay rate).
    duration_s : float
        Length of the peak-force simulation, s.
    encoder_mm, accel_rms : float
        Encoder resolution, mm, and accelerometer noise RMS (the paper's units of ``c``).
    problems : dict, optional
        Cache of compiled problems (default: this process's).

    Returns
    -------
    SetLimit
    """
    return _member_limit(
        loop,
        actuators,
        spec,
        sensors,
        seed,
        basis_poles,
        duration_s,
        encoder_mm,
        accel_rms,
        problems,
        realise=False,
    )


def member_controller(
    loop,
    actuators: str,
    sensors: str,
    spec: Specification | None = None,
    *,
    seed: int = 0,
    basis_poles=BASIS_POLES,
    duration_s: float = 20.0,
    encoder_mm: float = ENCODER_MM,
    accel_rms: float = ACCEL_NOISE_RMS,
):
    """The compensator :func:`member_limit` finds for a member, as a loop controller.

    Output feedback only (measured ``sensors``, not ``"full"``): the observer-based
    controller with its Youla parameter (:func:`robust.synthesis.youla.of_controller`),
    in the loop's units and signal names (inputs the measurements, outputs the actuators),
    ready for :meth:`backhoe.model.loop.BDFTLoop.system` and the specification check.

    Parameters
    ----------
    loop, actuators, spec, seed, basis_poles, duration_s, encoder_mm, accel_rms
        As for :func:`member_limit`.
    sensors : str
        ``"handle"`` or ``"handle+cab"``.

    Returns
    -------
    (SetLimit, control.StateSpace or None)
        The member's limit and its controller (``None`` where no controller met tracking
        and feedthrough).

    Raises
    ------
    robust.errors.ParameterError
        If ``sensors`` is ``"full"`` (a state feedback is no loop controller) or unknown.
    """
    if sensors == "full":
        raise ParameterError(
            "member_controller: sensors must be measured signals ('handle' or 'handle+cab'); "
            "got 'full' (every state, no loop controller)"
        )
    out = _member_limit(
        loop,
        actuators,
        spec,
        sensors,
        seed,
        basis_poles,
        duration_s,
        encoder_mm,
        accel_rms,
        None,
        realise=True,
    )
    return out if isinstance(out, tuple) else (out, None)


def _member_limit(loop, actuators, spec, *args, **kwargs):
    # one BLAS and one solver thread wherever it is called from: the cached gains, observers
    # and responses a process keeps are then the same digits in this process or a worker
    with deterministic_solvers():
        out = _member_limit_body(loop, actuators, spec, *args, **kwargs)
        spec = Specification() if spec is None else spec
        lb = _lower_bound(loop, actuators, spec)
    res = out[0] if isinstance(out, tuple) else out
    res = dataclasses.replace(res, force_lower=lb.force, reference_lower=lb.reference)
    return (res, out[1]) if isinstance(out, tuple) else res


@functools.lru_cache(maxsize=8)
def _lower_bound(loop, actuators, spec):
    """The frequency-wise relaxation's bounds of a member and actuator set (shared by its
    sensor sets: the relaxation knows ``u`` whatever the set measures)."""
    acts = ACTUATOR_SETS[actuators]
    plant, _, (s_u, _) = _member_plant(loop, acts, scales=True)
    return effort_lower_bound(loop, plant, s_u, acts, spec)


def _member_limit_body(
    loop,
    actuators,
    spec,
    sensors,
    seed,
    basis_poles,
    duration_s,
    encoder_mm,
    accel_rms,
    problems,
    *,
    realise,
):
    spec = Specification() if spec is None else spec
    if actuators not in ACTUATOR_SETS:
        raise ParameterError(
            f"member_limit: actuators must be one of {list(ACTUATOR_SETS)}; got {actuators!r}"
        )
    if sensors not in SENSOR_SETS:
        raise ParameterError(
            f"member_limit: sensors must be one of {list(SENSOR_SETS)}; got {sensors!r}"
        )
    lags = np.asarray(basis_poles, float)
    if lags.size == 0 or np.any(~np.isfinite(lags)) or np.any(lags <= spec.decay_rate):
        raise ParameterError(
            f"member_limit: basis_poles must be finite and above the decay rate "
            f"{spec.decay_rate:g} rad/s; got {basis_poles!r}"
        )
    acts, sens = ACTUATOR_SETS[actuators], SENSOR_SETS[sensors]
    problems = _PROBLEMS if problems is None else problems
    nz = dataclasses.replace(spec.noise, encoder_mm=encoder_mm, accel_rms=accel_rms)
    noise = var = None
    if sens:
        var, noise = sensor_intensities(loop, sens, nz)
    plant, meas, (s_u, s_m) = _member_plant(loop, acts, sens, noise, scales=True)
    region = spec.region()
    nan = math.nan
    try:
        # the gains place the poles with the damping at every frequency (conservatively)
        K0 = _gain(loop, acts, region)
        L = None if meas is None else _observer(loop, sens, region)
    except BDFTError:
        bad = uncontrollable_modes(plant.A, plant.Bu)
        if meas is not None:
            bad = np.concatenate([bad, uncontrollable_modes(plant.A.T, meas.Cm.T)])
        viol = region.violation(bad[None, :])[0] if bad.size else -math.inf
        if viol > 0:
            binding = "decay rate" if bad.real.max() > -spec.decay_rate else "damping"
            why = f"a mode the loop cannot move or see lies outside the region ({viol:.3g} rad/s)"
            return _set_limit(actuators, sensors, math.inf, nan, nan, nan, binding, False, why)
        why = "undecided: no gain placing the poles in the region found"
        return _set_limit(actuators, sensors, math.inf, nan, nan, nan, UNDECIDED, False, why)
    # the lags and the poles of the loop under K0 (and of the observer), all in the region
    # by construction: the best Q often reuses the loop's own modes
    extra = [np.linalg.eigvals(plant.A + plant.Bu @ K0)]
    if meas is not None:
        extra.append(np.linalg.eigvals(plant.A - L @ meas.Cm))
    basis = pole_basis(np.concatenate([-lags] + extra))
    amp = loop.intended_amplitude(spec.limits(), spec.intent_fraction)
    R, r0, effort = _grams(plant, meas, K0, L, basis, extra, loop, spec, nz, amp, acts, s_u)
    ft, fb = _grids(spec)
    wt, wb = 2 * np.pi * ft, 2 * np.pi * fb
    # the bounds on the deviation R (the plant's tracked output) on the grids: each row of
    # the maps divided by its bound, so that every constraint is |.| <= 1
    bt, bb = _bounds(loop, spec)
    cut_t, cut_b = np.zeros(0), np.zeros(0)
    step = f"limit map ({actuators}, {sensors})"
    tight = TIGHTENING
    for cut_round in range(CUT_ROUNDS + 1):
        out = _solve_on_grid(
            plant,
            meas,
            K0,
            L,
            basis,
            spec,
            (np.concatenate([wt, cut_t]), np.concatenate([bt, _cut_bounds(loop, spec, cut_t)])),
            (np.concatenate([wb, cut_b]), np.concatenate([bb, _cut_bounds(loop, spec, cut_b)])),
            (R, r0, effort),
            problems,
            step,
            tight,
        )
        if isinstance(out, SetLimit):
            return dataclasses.replace(out, actuators=actuators, sensors=sensors)
        Theta, relaxation, predicted = out
        if meas is None:
            A, B, Cx = closed_loop(plant, K0, basis, Theta, actuators=True)
        else:
            A, B, Cx = of_closed_loop(plant, meas, K0, L, basis, Theta, actuators=True)
        C = Cx[:2]
        r_cl = (A, B[:, [0]], C[[0]], np.array([[plant.Dyw]]))
        checks = deviation_bound_checks(r_cl, loop, spec)
        if all(c.holds for c in checks) or cut_round == CUT_ROUNDS:
            break
        if np.max(np.linalg.eigvals(A).real) >= 0:
            break
        # the exact check found the bound exceeded between the grid's frequencies: add the
        # local maxima of the violation to the grid and solve again (cutting planes)
        new_t, new_b = _cuts(r_cl, loop, spec, checks)
        cut_t = np.concatenate([cut_t, new_t])[-N_CUTS:]
        cut_b = np.concatenate([cut_b, new_b])[-N_CUTS:]
        # and the grid's limits lowered by the excess found (the optimum sits on them, and
        # between the grid's frequencies it overshoots by about as much again)
        tight /= max(c.value for c in checks)
    sysl = _loop_system(loop, plant, A, B, Cx, acts, s_u, s_m)
    res = _verify(
        sysl,
        A,
        B,
        C,
        var,
        spec,
        region,
        checks,
        (loop, amp, acts),
        (actuators, sensors),
        relaxation,
        seed,
        duration_s,
        predicted,
    )
    if not realise:
        return res
    Ac, Bc, Cc = of_controller(plant, meas, K0, L, basis, Theta)
    # back to the loop's units: y_m' = y_m / s_m, u = u' / s_u
    K = ct.ss(
        Ac,
        Bc / s_m[None, :],
        Cc / s_u[:, None],
        np.zeros((len(acts), len(sens))),
        inputs=list(sens),
        outputs=list(acts),
        name=f"limit_{actuators}_{sensors}",
    )
    return res, K
