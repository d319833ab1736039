"""The achievable-limit map: what fraction of operators can any compensator protect?

For each member of a seeded sample of the default family, and for each set of actuators
and sensors, :func:`member_limit` finds the compensator that knows that member exactly
and meets the specification's bounds on the intended-motion response (the deviation from
the BDFT-free response, :mod:`designs.response`), its noise and reference-effort limits,
with the least RMS handle force and every closed-loop pole in the specification's region
by construction (:mod:`robust.synthesis.youla`: Youla/Q-parametrisation, Boyd & Barratt
1991). The frequency-wise bounds are imposed on a design grid (0-1000 Hz) and the
controller found is realised, closed around the member and re-checked independently of the
optimisation: its eigenvalues against the region, the deviation's bounds at *every*
frequency (:func:`designs.response.deviation_bound_checks`), the exact RMS force, noise and
reference effort (Lyapunov, with the remnant and the sensor noise) and the peak force of a
simulated realistic intended motion. Where the exact check finds a bound exceeded between
the grid's frequencies, those frequencies join the grid and the problem is solved again
(cutting planes, :data:`CUT_ROUNDS`). The member's *required force multiple* is the
smallest multiple of the Omni's force limits (peak and continuous together) within which
that controller meets the whole specification.

Sets
----
Actuators (:data:`ACTUATOR_SETS`): the handle force ``f`` (today's handle-force designs),
the cylinder-reference shaping ``r_corr`` (no force), both. Sensors
(:data:`SENSOR_SETS`): ``full`` (every state of the loop, noiseless: full information, the
most any compensator could know), ``handle`` (the handle position through the Omni's
encoder, quantisation noise of :data:`ENCODER_MM`) and ``handle+cab`` (plus a cab
accelerometer with noise :data:`ACCEL_NOISE_RMS`); with measured signals the compensator
is an observer-based output feedback with its own Youla parameter.

What the map bounds
-------------------
* A member counted as covered at force multiple ``s`` has a verified controller: the map's
  coverage is a *lower bound* on what compensators of that set, knowing the member, can
  cover.
* Where no controller of the basis meets the bounds and the effort limits at any force,
  the smallest uniform relaxation ``rho`` of all of them that the basis can meet is
  reported, with the constraint furthest from its limit there as ``binding``; where force
  binds, the required multiple. Both are *upper bounds* of the exact limit (a richer basis
  can only lower them; :func:`basis_check` measures by how much), computed for the basis.
  A member whose controller fails the re-check is ``"undecided"``, one whose solver failed
  ``"solver failed"``: every uncovered member is counted under exactly one name.
* Knowing the member exactly is more than any one compensator for a family knows: a
  robust design, or a scheduled bank with identification errors, cannot beat the map of
  its set, up to the basis' approximation.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import control as ct
import numpy as np
import scipy.linalg as sla
import scipy.signal as sig
from joblib import delayed

from designs.constants import (
    ACTUATOR_SETS,
    ALL_SETS,
    DEFAULT_SETS,
    FORCE_SCALES,
    LIMIT_SAMPLES,
    SENSOR_SETS,
)
from designs.effort import (
    Noise,
    correction_limits,
    cylinder_filters,
    effort_utilisations,
    operator_filter,
    operator_spectrum,
    sensor_intensities,
)
from designs.evaluate import intended_motion
from designs.relaxation import effort_lower_bound
from designs.response import deviation_bound_checks, deviation_maps
from designs.spec_forces import peak_time_grid
from designs.specification import N_TRACKING_FREQS, Specification
from robust.analysis.bounds import siso_response
from robust.analysis.loops import resolvent_times
from robust.analysis.simulation import lifted_response
from robust.checks import check_int
from robust.engine import map_tasks
from robust.errors import BDFTError, ModelStructureError, ParameterError
from robust.model.wiring import connect
from robust.synthesis.limit_problem import LimitProblem, gram_factor
from robust.synthesis.solve import deterministic_solvers
from robust.synthesis.stabilising import stabilising_gain, uncontrollable_modes
from robust.synthesis.youla import (
    Measurements,
    YoulaPlant,
    affine_maps,
    closed_loop,
    force_responses,
    observer_gain,
    of_affine_maps,
    of_closed_loop,
    of_controller,
)
from robust.synthesis.youla_basis import pole_basis, quadrature_gram, quadrature_grid
from uncertainty import sample
from uncertainty.search import worst_member

__all__ = [
    "ALL_SETS",
    "DEFAULT_SETS",
    "SENSOR_SETS",
    "split_set",
    "set_contains",
    "sensor_noise",
    "FORCE_FLOOR_N",
    "FORCE_SCALES",
    "LIMIT_SAMPLES",
    "ACTUATOR_SETS",
    "BASIS_POLES",
    "SetLimit",
    "member_limit",
    "member_controller",
    "limit_map",
    "LimitMap",
    "basis_check",
    "design_set",
    "limit_coverage_of",
]

# ACTUATOR_SETS and SENSOR_SETS (name -> the loop's actuator signals, the measured signals),
# and the map's defaults ALL_SETS, DEFAULT_SETS, FORCE_SCALES and LIMIT_SAMPLES, are defined
# in designs.constants (the command line reads them without NumPy)
#: Encoder resolution, mm (the Omni's): quantisation noise of the handle position.
ENCODER_MM = 0.055
#: Accelerometer noise RMS at the 1 kHz servo rate, in the paper's units of ``c`` (the
#: force-feedback synthesis' default accelerometer weight, :mod:`robust.synthesis.forcefb`).
ACCEL_NOISE_RMS = 0.05
#: Poles of the orthonormal lag basis, rad/s: 32 from 0.3 to 1000 rad/s (about 9 per
#: decade), inside the region (above its decay rate, real). Doubling the basis lowers a
#: member's handle-force limit by a few per cent (measured; the page reports the check).
BASIS_POLES = tuple(float(x) for x in np.geomspace(0.3, 1000.0, 32))
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


@functools.lru_cache(maxsize=4)
def _open_loop(loop):
    """The member's open loop, inputs ``u, f, r_corr``, outputs ``y, x, c``, balanced.

    Cached: a member's sets share it. States scaled by powers of 2 (exact) so that ``A``
    is balanced: the gains and the closed-loop maps are computed without needless
    cancellation.
    """
    blocks = loop.blocks(bdft=True, reference_correction=True)
    P = connect(blocks, inputs=["u", "f", "r_corr"], outputs=["y", "x", "c"], name="limit_plant")
    A, B, C, D = (np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
    A, (sc, _) = sla.matrix_balance(A, permute=False, separate=True)
    return A, B / sc[:, None], C * sc[None, :], D


@functools.lru_cache(maxsize=4)
def _bounds(loop, spec: Specification):
    """The specification's bounds on ``|R|`` on the tracking and feedthrough grids."""
    ft, fb = _grids(spec)
    wt, wb = 2 * np.pi * ft, 2 * np.pi * fb
    _, r0 = deviation_maps(loop, reference_k_psf=spec.reference_k_psf)
    bt = spec.deviation_bound(wt, siso_response(r0, wt))
    bb = spec.deviation_bound(wb, siso_response(r0, wb))
    return bt, bb


@functools.lru_cache(maxsize=8)
def _gain(loop, actuators, region):
    """The state feedback ``K0`` of a member and actuator set (shared by its sensor sets)."""
    plant, _ = _member_plant(loop, actuators)
    return stabilising_gain(plant.A, plant.Bu, region)


@functools.lru_cache(maxsize=8)
def _observer(loop, sensors, region):
    """The observer gain of a member and sensor set (shared by its actuator sets)."""
    plant, meas = _member_plant(loop, ("f",), sensors, np.ones(len(sensors)))
    return observer_gain(plant, meas, region)


def _schur_response(A, b, c, omega, form=None) -> np.ndarray:
    """``c (j w I - A)^-1 b`` on a grid, through the complex Schur form (stable, O(n^2) each).

    With ``A = Z T Z^H`` (``T`` upper triangular), ``(j w I - T) x = Z^H b`` is solved by back
    substitution for every frequency at once (one row of ``x`` per step, a vector over the
    grid): the re-check's own route, independent of the designs' Hessenberg resolvents.
    ``form``: ``A``'s ``(T, Z)`` when the caller has it (the same numbers as computing it
    here; a re-check takes two grids of one matrix).
    """
    T, Z = sla.schur(A, output="complex") if form is None else form
    bt, ct_ = Z.conj().T @ b, c @ Z
    n = A.shape[0]
    s = 1j * np.asarray(omega, float)
    X = np.zeros((n, s.size), complex)
    for k in range(n - 1, -1, -1):
        X[k] = (bt[k] + T[k, k + 1 :] @ X[k + 1 :]) / (s - T[k, k])
    return ct_ @ X


def _member_plant(loop, actuators, sensors=None, noise=None, *, scales: bool = False):
    """The member's open loop: actuators, the tracked output ``y`` and the measurements.

    Returns ``(plant, meas)`` with ``meas`` ``None`` for full information; with ``scales``
    also the actuators' and measurements' unit changes ``(s_u, s_m)`` (an actuator in loop
    units is ``u / s_u``, a measurement in the plant's units ``y_m / s_m``).
    """
    A, B, C, D = _open_loop(loop)
    cols = [1 + ("f", "r_corr").index(a) for a in actuators]
    # each actuator in units that give it a unit input column (the handle force in N
    # moves the states a thousand times less than the reference): u = u' / s
    s_u = np.linalg.norm(B[:, cols], axis=0)
    force = actuators.index("f") if "f" in actuators else None
    # the tracked output is the deviation from the BDFT-free response,
    # R = Y/Y_ref - 1 = (x - u) + r_corr / K_PSF (designs.spec.deviation_maps)
    Dr = D[[1]].copy()
    Dr[0, 0] -= 1.0
    Dr[0, 2] += 1.0 / loop.k_psf
    plant = YoulaPlant(
        A=A,
        Bw=B[:, [0]],
        Bu=B[:, cols] / s_u,
        Cy=C[[1]],
        Dyw=float(Dr[0, 0]),
        Dyu=Dr[:, cols] / s_u,
        force=force,
        force_gain=1.0 if force is None else 1.0 / float(s_u[force]),
    )
    meas = None
    sc = np.ones(0)
    if sensors:
        rows = [1 + ("x", "c").index(x) for x in sensors]
        if np.any(D[rows][:, 1:]):
            raise ModelStructureError("limit map: a measurement feeds through from an actuator")
        # each measurement in units that make its row of [Cm, Dmw] of unit norm (a change
        # of units only: the handle and the accelerometer differ by orders of magnitude)
        Cm, Dmw = C[rows], D[rows][:, [0]]
        sc = np.linalg.norm(np.hstack([Cm, Dmw]), axis=1)
        meas = Measurements(
            Cm / sc[:, None], Dmw / sc[:, None], np.asarray(noise) / sc**2, tuple(sensors)
        )
    if scales:
        return plant, meas, (s_u, sc)
    return plant, meas


def sensor_noise(loop, sensors, *, encoder_mm: float, accel_rms: float) -> np.ndarray:
    """White-noise intensities of the measurements (two-sided, per s).

    The encoder quantises the handle position to ``encoder_mm``: uniform error of RMS
    ``q / sqrt(12)`` in handle units; the accelerometer adds ``accel_rms`` (the paper's
    units of ``c``). Both are sampled at the 1 kHz servo rate, so a sample-to-sample
    independent error of variance ``sigma^2`` is white noise of intensity ``sigma^2 T``
    (:func:`designs.effort.sensor_intensities`).

    Parameters
    ----------
    loop : robust.model.loop.BDFTLoop
        The member (its handle units).
    sensors : sequence of str
        ``"x"`` and/or ``"c"``.
    encoder_mm : float
        Encoder resolution, mm.
    accel_rms : float
        Accelerometer noise RMS, the paper's units of ``c``.
    """
    for s_ in sensors:
        if s_ not in ("x", "c"):
            raise ParameterError(f"sensor_noise: unknown measurement {s_!r}")
    nz = Noise(encoder_mm=encoder_mm, accel_rms=accel_rms)
    return sensor_intensities(loop, sensors, nz)[1]


def _grids(spec: Specification):
    grid = spec.check_frequencies_hz()
    return grid[:N_TRACKING_FREQS], grid[N_TRACKING_FREQS:]


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


@functools.lru_cache(maxsize=8)
def _unit_motion(seed: int, bandwidth_hz: float, duration_s: float) -> np.ndarray:
    """The intended motion of unit amplitude (it scales linearly), shared by a member's sets."""
    return intended_motion(peak_time_grid(duration_s), 1.0, bandwidth_hz, seed=seed)


def _simulate_peak(A, B, C, amplitude, spec, seed, duration_s):
    """Peak force of the loop ``(A, B[:, 0], C[-1])`` under a seeded intended motion (1 kHz)."""
    t = peak_time_grid(duration_s)
    u = amplitude * _unit_motion(seed, spec.intent_bandwidth_hz, duration_s)
    dt = t[1] - t[0]
    sys = (A, B[:, [0]], C[[-1]], np.zeros((1, 1)))
    Ad, Bd, Cd, Dd, _ = sig.cont2discrete(sys, dt, method="foh")
    f = lifted_response(Ad, Bd[:, 0], Cd[0], float(Dd[0, 0]), u)
    return float(np.max(np.abs(f))) if np.all(np.isfinite(f)) else math.inf


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
    loop : robust.model.loop.BDFTLoop
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
    ready for :meth:`robust.model.loop.BDFTLoop.system` and the specification check.

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


def split_set(name: str) -> tuple[str, str]:
    """``"actuators/sensors"`` -> ``(actuators, sensors)``, checked.

    Parameters
    ----------
    name : str
        A set name of :data:`ALL_SETS`.

    Raises
    ------
    robust.errors.ParameterError
        If it names no set.
    """
    if not isinstance(name, str) or name not in ALL_SETS:
        raise ParameterError(f"limit map: a set must be one of {list(ALL_SETS)}; got {name!r}")
    a, s_ = name.split("/")
    return a, s_


#: Information order of the sensor sets: each knows what the earlier ones know.
_INFORMATION = ("handle", "handle+cab", "full")


def set_contains(big: str, small: str) -> bool:
    """Whether every controller of set ``small`` is a controller of set ``big``.

    Its actuators are among ``big``'s, and its sensors tell no more than ``big``'s
    (``handle`` < ``handle+cab`` < ``full``).

    Parameters
    ----------
    big, small : str
        Sets of :data:`ALL_SETS`.
    """
    (a1, s1), (a2, s2) = split_set(big), split_set(small)
    acts = set(ACTUATOR_SETS[a2]) <= set(ACTUATOR_SETS[a1])
    return acts and _INFORMATION.index(s2) <= _INFORMATION.index(s1)


def _member_task(family, row, sets, spec, seed, basis_poles, duration_s):
    # one BLAS and one solver thread: the same member gives the same bytes in this process
    # or a worker, whatever OPENBLAS_NUM_THREADS says
    with deterministic_solvers():
        return _member_limits(family, row, sets, spec, seed, basis_poles, duration_s)


def _member_limits(family, row, sets, spec, seed, basis_poles, duration_s):
    loop = family.member(row)
    out = []
    for name in sets:
        a, s_ = split_set(name)
        out.append(
            member_limit(
                loop,
                a,
                spec,
                sensors=s_,
                seed=seed,
                basis_poles=basis_poles,
                duration_s=duration_s,
            )
        )
    return out


def _call(task):
    fn, args, kw = task
    return tuple(fn(*args, **kw))


def _run(tasks, n_jobs: int, progress=None, total: int | None = None, scheduler=None) -> list:
    """Run joblib-style tasks in order: in this process (``n_jobs`` 1), in ``n_jobs``
    processes or on a Dask cluster (:func:`robust.engine.map_tasks`)."""
    done = [0]

    def step(_i):
        done[0] += 1
        if progress:
            progress(done[0], total or len(tasks))

    return map_tasks(_call, list(tasks), jobs=n_jobs, scheduler=scheduler, progress=step)


@dataclasses.dataclass(frozen=True)
class LimitMap:
    """The limit map: per member and set, what the best verified controller needs.

    Parameters
    ----------
    names : tuple of str
        Parameter names (``family.names``).
    values : numpy.ndarray (N, d)
        The members: the Latin hypercube first, then the critical members.
    labels : tuple of str
        Per member, ``"lhs"`` or the critical member's label (``"nominal"``,
        ``"open-loop worst"``).
    sets : tuple of str
        Sets ``"actuators/sensors"`` (:data:`ALL_SETS`).
    limits : tuple of tuple of SetLimit
        ``limits[i][j]``: member ``i``, set ``j``.
    force_scales : tuple of float
        Multiples of the device's force limits reported.
    samples, seed : int
        Latin-hypercube size and seed.
    basis_poles : tuple of float
        Lags of the basis, rad/s.
    specification : dict
        The specification (:meth:`Specification.to_json`).
    noise : dict
        Sensor noise: encoder resolution, mm, and accelerometer RMS.
    """

    names: tuple
    values: np.ndarray
    labels: tuple
    sets: tuple
    limits: tuple
    force_scales: tuple
    samples: int
    seed: int
    basis_poles: tuple
    specification: dict
    noise: dict

    def lhs_index(self) -> np.ndarray:
        """Boolean mask of the Latin-hypercube members (the critical members excluded)."""
        return np.array([lab == "lhs" for lab in self.labels])

    def own_required(self, name: str) -> np.ndarray:
        """Required force multiple per member from the set's own problem (``inf``: none found).

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        """
        j = self.sets.index(name)
        return np.array(
            [row[j].required_force if row[j].verified else math.inf for row in self.limits]
        )

    def required(self, name: str) -> np.ndarray:
        """Required force multiple per member for one set, the best of the sets it contains.

        A controller of a smaller set is a controller of ``name`` (an unused actuator held
        at zero, an unused sensor ignored; full information knows every measured signal
        without noise), so each member's requirement is the least over the map's sets
        contained in ``name`` (:func:`set_contains`) of their verified requirements.

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        """
        own = [self.own_required(x) for x in self.sets if set_contains(name, x)]
        return np.min(np.vstack(own), axis=0)

    def lower(self, name: str) -> np.ndarray:
        """Lower bound of the force multiple any compensator of the set needs, per member.

        The frequency-wise relaxation of the set's actuators (:mod:`designs.relaxation`;
        it holds for every sensor set and for the sets it contains): with a force actuator
        its ``force_lower``; a reference correction alone needs no force, or is ``inf``
        where its effort bound exceeds the limits (no force makes it feasible).

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        """
        j = self.sets.index(name)
        a, _ = split_set(name)
        if "f" in ACTUATOR_SETS[a]:
            return np.array([row[j].force_lower for row in self.limits])
        return np.array([0.0 if row[j].reference_lower <= 1.0 else math.inf for row in self.limits])

    def coverage(self, name: str, force_scale: float) -> float:
        """Fraction of the Latin hypercube covered by one set at ``force_scale``.

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        force_scale : float
            Multiple of the device's force limits.
        """
        req = self.required(name)[self.lhs_index()]
        return float(np.mean(req <= force_scale))

    def binding(self, name: str, force_scale: float) -> dict:
        """Per constraint, the Latin-hypercube members it keeps uncovered at ``force_scale``.

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        force_scale : float
            Multiple of the device's force limits.
        """
        j = self.sets.index(name)
        req = self.required(name)
        out = {}
        for row, lhs, r in zip(self.limits, self.lhs_index(), req):
            if not lhs or r <= force_scale:
                continue
            key = row[j].binding or "unverified"
            out[key] = out.get(key, 0) + 1
        return out

    def scale_for(self, name: str, fraction: float = 0.95) -> float:
        """Smallest force multiple covering ``fraction`` of the Latin hypercube (``inf``: none).

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        fraction : float
            Coverage wanted, in (0, 1].
        """
        return _quantile(self.required(name)[self.lhs_index()], fraction)

    def bracket_for(self, name: str, fraction: float = 0.95) -> dict:
        """``{"lower", "upper"}`` of the force multiple covering ``fraction`` of the Latin
        hypercube: the upper from verified controllers (:meth:`scale_for`), the lower from
        the relaxation's bounds (:meth:`lower`: a member no compensator covers below its
        bound, so the fraction with bounds below ``s`` bounds the coverage at ``s``).

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        fraction : float
            Coverage wanted, in (0, 1].
        """
        low = _quantile(self.lower(name)[self.lhs_index()], fraction)
        return {"lower": low, "upper": self.scale_for(name, fraction)}

    def sets_json(self) -> list:
        """Per set and force multiple: name, force_scale, coverage, samples, seed, binding."""
        out = []
        lhs = self.lhs_index()
        for name in self.sets:
            a, s_ = split_set(name)
            for sc in self.force_scales:
                cov = self.coverage(name, sc)
                out.append(
                    {
                        "name": name,
                        "actuators": list(ACTUATOR_SETS[a]),
                        "sensors": s_,
                        "force_scale": sc,
                        "coverage": cov,
                        "coverage_own": float(np.mean(self.own_required(name)[lhs] <= sc)),
                        "covered": int(round(cov * self.samples)),
                        "samples": self.samples,
                        "seed": self.seed,
                        "binding": self.binding(name, sc),
                        # members that no compensator of the set covers at this multiple
                        "proven_uncovered": int(np.sum(self.lower(name)[lhs] > sc)),
                    }
                )
        return out

    def to_json(self) -> dict:
        """The ``bdft limit --json`` object (without the basis check and the page's path)."""
        crit = []
        for i, lab in enumerate(self.labels):
            if lab == "lhs":
                continue
            crit.append(
                {
                    "label": lab,
                    "parameters": dict(zip(self.names, map(float, self.values[i]))),
                    "limits": [dataclasses.asdict(x) for x in self.limits[i]],
                }
            )
        gaps = [
            abs(x.gap) for row in self.limits for x in row if x.verified and math.isfinite(x.gap)
        ]
        return {
            "sets": self.sets_json(),
            "force_for_95": {name: self.bracket_for(name, 0.95) for name in self.sets},
            "critical": crit,
            "samples": self.samples,
            "seed": self.seed,
            "method": "lhs",
            "basis_poles": list(self.basis_poles),
            "noise": dict(self.noise),
            "solver_gap": {
                "median": float(np.median(gaps)) if gaps else math.nan,
                "max": float(np.max(gaps)) if gaps else math.nan,
            },
            "specification": self.specification,
        }


def _quantile(values: np.ndarray, fraction: float) -> float:
    """The smallest value at or below which ``fraction`` of ``values`` lie."""
    v = np.sort(np.asarray(values, float))
    k = int(math.ceil(fraction * v.size)) - 1
    return float(v[max(k, 0)])


def limit_map(
    family,
    spec: Specification | None = None,
    *,
    samples: int = LIMIT_SAMPLES,
    seed: int = 0,
    sets=DEFAULT_SETS,
    force_scales=FORCE_SCALES,
    critical: bool = True,
    basis_poles=BASIS_POLES,
    duration_s: float = 20.0,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
    scheduler: str | None = None,
) -> LimitMap:
    """The limit map of ``family`` (module notes): every member's limit for every set.

    Parameters
    ----------
    family : uncertainty.Family
        A family with the physical human.
    spec : Specification, optional
        The specification (default :class:`Specification` ``()``).
    samples : int
        Latin-hypercube members (>= 1).
    seed : int
        Seed of the Latin hypercube (and, ``seed + i``, of member ``i``'s simulation).
    sets : sequence of str
        Sets ``"actuators/sensors"`` of :data:`ALL_SETS`.
    force_scales : sequence of float
        Multiples of the device's force limits reported.
    critical : bool
        Add the nominal member and the open loop's worst member of the box for the
        specification's pole region (:func:`uncertainty.search.worst_member`).
    basis_poles : sequence of float
        The lag basis, rad/s.
    duration_s : float
        Peak-force simulation length, s.
    n_jobs : int
        Parallel processes.
    progress : callable, optional
        ``progress(done, total)`` members.
    scheduler : str, optional
        A Dask scheduler's address (or ``$DASK_SCHEDULER_ADDRESS``): the members run on
        its workers; the same map.

    Returns
    -------
    LimitMap
    """
    spec = Specification() if spec is None else spec
    samples = check_int("samples", samples, low=1, owner="limit_map")
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="limit_map")
    sets = tuple(dict.fromkeys(sets))
    if not sets:
        raise ParameterError("limit_map: sets must name at least one set; got none")
    for name in sets:
        split_set(name)
    scales = tuple(float(x) for x in force_scales)
    if not scales or any(not (math.isfinite(x) and x > 0) for x in scales):
        raise ParameterError(
            f"limit_map: force_scales must be positive numbers; got {force_scales!r}"
        )
    rows = list(sample(family.parameters, samples, method="lhs", seed=seed).values)
    labels = ["lhs"] * samples
    if critical:
        rows.append(family.nominal_values())
        labels.append("nominal")
        _, worst = worst_member(family, 1.0, region=spec.region(), seed=seed)
        rows.append(worst)
        labels.append("open-loop worst")
    values = np.asarray(rows, float)
    poles = tuple(float(x) for x in basis_poles)
    tasks = [
        delayed(_member_task)(family, values[i], sets, spec, seed + i, poles, duration_s)
        for i in range(len(values))
    ]
    results = _run(tasks, n_jobs, progress, scheduler=scheduler)
    return LimitMap(
        names=tuple(family.names),
        values=values,
        labels=tuple(labels),
        sets=sets,
        limits=tuple(results),
        force_scales=scales,
        samples=samples,
        seed=seed,
        basis_poles=poles,
        specification=spec.to_json(),
        noise={"encoder_mm": ENCODER_MM, "accel_rms": ACCEL_NOISE_RMS},
    )


def basis_check(
    family,
    lm: LimitMap,
    *,
    members: int = 8,
    sets=None,
    spec: Specification | None = None,
    n_jobs: int = 1,
    scheduler: str | None = None,
) -> dict:
    """How much a richer basis lowers the map's limits: the first members with twice the lags.

    The basis is an inner approximation (module notes): a richer one can only lower a
    member's required force multiple (up to the solver's accuracy). The first ``members``
    members of the Latin hypercube are re-run with the map's lags and their geometric
    midpoints (a basis that contains the map's), so the decrease measures how far the map
    is from the limit of an infinite basis.

    Parameters
    ----------
    family : uncertainty.Family
        The map's family.
    lm : LimitMap
        The map.
    members : int
        Members re-run (>= 1).
    sets : sequence of str, optional
        Sets re-run (default: the map's sets with a force actuator).
    spec : Specification, optional
        The map's specification.
    n_jobs : int
        Parallel processes.
    scheduler : str, optional
        A Dask scheduler's address (see :func:`limit_map`).

    Returns
    -------
    dict
        Per set: ``members``, ``poles`` (before, after), the required force multiples
        before and after, and the median and largest relative decrease among members
        finite in both.
    """
    spec = Specification() if spec is None else spec
    members = check_int("members", members, low=1, owner="basis_check")
    if sets is None:
        sets = tuple(x for x in lm.sets if "f" in ACTUATOR_SETS[split_set(x)[0]])
    sets = tuple(sets)
    a = np.asarray(lm.basis_poles)
    mids = np.sqrt(a[:-1] * a[1:])
    rich = tuple(float(x) for x in np.sort(np.concatenate([a, mids])))
    idx = np.flatnonzero(lm.lhs_index())[:members]
    tasks = [
        delayed(_member_task)(family, lm.values[i], sets, spec, lm.seed + int(i), rich, 20.0)
        for i in idx
    ]
    runner = _run(tasks, n_jobs, scheduler=scheduler)
    out = {}
    for j, name in enumerate(sets):
        k = lm.sets.index(name)
        before = np.array(
            [lm.limits[i][k].required_force if lm.limits[i][k].verified else math.inf for i in idx]
        )
        after = np.array([r[j].required_force if r[j].verified else math.inf for r in runner])
        ok = np.isfinite(before) & np.isfinite(after) & (before > 1e-3)
        dec = 1.0 - after[ok] / before[ok]
        out[name] = {
            "members": int(idx.size),
            "poles": [len(lm.basis_poles), len(rich)],
            "required_before": before.tolist(),
            "required_after": after.tolist(),
            "median_decrease": float(np.median(dec)) if dec.size else math.nan,
            "largest_decrease": float(np.max(dec)) if dec.size else math.nan,
        }
    return out


def design_set(controller) -> str | None:
    """The smallest set of the map that contains a compensator's actuators and sensors.

    Outputs ``f`` / ``r_corr`` give the actuators; inputs within ``x`` give ``handle``,
    within ``x, c`` give ``handle+cab``, any other measured signal (the cylinder position
    ``y``) ``full``.

    Parameters
    ----------
    controller : control.StateSpace or None
        A compensator in the loop's convention; ``None`` (no compensator) gives ``None``.

    Returns
    -------
    str or None
        A name of :data:`ALL_SETS`.
    """
    if controller is None:
        return None
    outs = set(controller.output_labels)
    ins = set(controller.input_labels)
    acts = {("f",): "force", ("r_corr",): "reference", ("f", "r_corr"): "force+reference"}.get(
        tuple(sorted(outs & {"f", "r_corr"}))
    )
    if acts is None:
        return None
    if ins <= {"x"}:
        sens = "handle"
    elif ins <= {"x", "c"}:
        sens = "handle+cab"
    else:
        sens = "full"
    return f"{acts}/{sens}"


def limit_coverage_of(sets_json: list, name: str, force_scale: float = 1.0):
    """The map's coverage for set ``name``, or for the smallest computed set containing it.

    Parameters
    ----------
    sets_json : list of dict
        :meth:`LimitMap.sets_json` (or the ``sets`` of ``bdft limit --json``).
    name : str
        A set of :data:`ALL_SETS`.
    force_scale : float
        The force multiple.

    Returns
    -------
    (str, dict) or None
        The set used and its entry; ``None`` when no computed set contains ``name``.
    """
    entries = [e for e in sets_json if e["force_scale"] == force_scale]
    inside = [e for e in entries if set_contains(e["name"], name)]
    if not inside:
        return None
    best = min(inside, key=lambda e: e["coverage"])
    return best["name"], best
