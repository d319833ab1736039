"""Sensor noise, the operator's remnant, and the effort they and the intent cause.

The specification's effort and noise checks (:mod:`designs.spec`) are stationary RMS values
of closed-loop signals driven by three kinds of input:

* the **intended motion**: white noise through the unit intent filter ``F``
  (:func:`backhoe.synthesis.forcefb.intent_filter`), scaled to RMS ``amplitude / sqrt(2)``
  (as :func:`designs.evaluate.intended_motion` simulates it);
* the operator's **remnant**, the part of a person's command that is not a linear response
  to anything (McRuer & Jex 1967; Levison, Baron & Kleinman, "A model for human controller
  remnant", IEEE Trans. Man-Machine Systems 10(4), 1969): white noise through a first-order
  low-pass at :attr:`Noise.remnant_bandwidth_hz`, with RMS :attr:`Noise.remnant_fraction`
  of the intended motion's, added to ``u``;
* **sensor noise** on every signal the compensator measures: the Omni's encoder quantises
  the handle position (uniform error, RMS ``q / sqrt(12)``), the cab accelerometer has a white
  noise floor, the cylinder's position sensor a resolution. Each is sampled at the 1 kHz
  servo rate, so a sample-to-sample independent error of variance ``sigma^2`` is white noise
  of intensity ``sigma^2 T``; where a compensator passes a measurement straight through
  (``D != 0``), that part is counted with the sample variance ``sigma^2``.

RMS values are exact: Lyapunov equations of the closed loop cascaded with the filters.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import control as ct
import numpy as np

from backhoe.model.components import REALISATIONS_KEPT
from backhoe.model.loop import BDFTLoop
from backhoe.model.wiring import Junction, connect, renamed
from backhoe.synthesis.forcefb import intent_filter
from robust.analysis.bounds import siso_response
from robust.analysis.lyapunov import lyapunov_solver
from robust.analysis.norms import h2_norm
from robust.analysis.realization import matrices_key, minimal_realization
from robust.checks import NONNEGATIVE, POSITIVE, validate_fields
from robust.errors import ModelStructureError

__all__ = [
    "Noise",
    "cylinder_filters",
    "member_effort",
    "effort_utilisations",
    "correction_limits",
    "operator_filter",
    "unit_intent",
    "operator_spectrum",
    "SERVO_RATE_HZ",
    "noisy_loop",
    "rms_responses",
    "sensor_intensities",
]

#: Rate at which the sensors are sampled, Hz (the Omni's servo rate).
SERVO_RATE_HZ = 1000.0


@dataclasses.dataclass(frozen=True)
class Noise:
    """The noise a compensator's loop runs with.

    Parameters
    ----------
    encoder_mm : float
        The Omni's encoder resolution, mm (0.055: the published figure).
    accel_rms : float
        Accelerometer noise RMS at the servo rate, in the paper's units of ``c`` (0.05, the
        force-feedback synthesis' accelerometer weight; an ADXL330 at 1 kHz bandwidth has
        about 0.03 m/s^2 RMS).
    cylinder_sensor_mm : float
        RMS error of the cylinder position sensor, mm of cylinder travel (0.01: a
        magnetostrictive sensor such as the paper's Balluff BTL resolves a few micrometres).
    remnant_fraction : float
        RMS of the operator's remnant over that of the intended motion (0.1, stated
        assumption: remnant power about 1 % of the operator's output in tracking tasks).
    remnant_bandwidth_hz : float
        Corner of the remnant's first-order spectrum, Hz (1.6: 10 rad/s, the neuromuscular
        lag of about 0.1 s that shapes a person's output; stated assumption).
    """

    encoder_mm: float = 0.055
    accel_rms: float = 0.05
    cylinder_sensor_mm: float = 0.01
    remnant_fraction: float = 0.1
    remnant_bandwidth_hz: float = 1.6

    def __post_init__(self):
        validate_fields(
            self,
            {
                "encoder_mm": POSITIVE,
                "accel_rms": POSITIVE,
                "cylinder_sensor_mm": POSITIVE,
                "remnant_fraction": NONNEGATIVE,
                "remnant_bandwidth_hz": POSITIVE,
            },
        )


def sensor_intensities(loop: BDFTLoop, sensors, noise: Noise) -> tuple[np.ndarray, np.ndarray]:
    """Sample variances and white-noise intensities of the measurements ``sensors``.

    Parameters
    ----------
    loop : BDFTLoop
        The member (its handle and cylinder units; a physical human).
    sensors : sequence of str
        Among ``"x"``, ``"c"``, ``"y"``.
    noise : Noise

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Variances ``sigma^2`` (loop units squared) and intensities ``sigma^2 T``.
    """
    var = []
    for s in sensors:
        if s == "x":
            q = noise.encoder_mm * 1e-3 * loop.handle_units_per_m()
            var.append((q / math.sqrt(12.0)) ** 2)
        elif s == "c":
            var.append(noise.accel_rms**2)
        elif s == "y":
            var.append((noise.cylinder_sensor_mm * 1e-3 * loop.cylinder_units_per_m()) ** 2)
        else:
            raise ModelStructureError(f"sensor_intensities: unknown measurement {s!r}")
    var = np.asarray(var, float)
    return var, var / SERVO_RATE_HZ


def noisy_loop(loop: BDFTLoop, controller, outputs, *, checked: bool = False) -> ct.StateSpace:
    """The member's loop with ``controller``, noise added to each signal it measures.

    Inputs ``u`` then ``n_<s>`` for each measured signal ``s`` (in the controller's input
    order); the controller reads ``s + n_<s>``.

    Parameters
    ----------
    loop : BDFTLoop
        One member.
    controller : control.StateSpace or None
        The compensator (loop convention); ``None``: the loop alone.
    outputs : sequence of str
        Loop signals to output (``y``, ``e``, ``f``, ``r_corr``, ...).
    checked : bool
        The controller's signals were checked against the loop's convention already (its
        closed loop was built): skip that check.
    """
    if controller is None:
        return loop.system(bdft=True, outputs=list(outputs))
    outs = list(controller.output_labels)
    blocks = loop.blocks(bdft=True, reference_correction="r_corr" in outs)
    if not checked:
        # validate the controller against the loop's convention, as a closed loop would
        loop.blocks(bdft=True, controller=controller)
    meas = list(controller.input_labels)
    blocks.append(renamed(controller, {s: f"{s}_m" for s in meas}))
    for s in meas:
        blocks.append(Junction(f"noise_{s}", f"{s}_m", ((s, 1.0), (f"n_{s}", 1.0))).system())
    ignore = ["f"] if loop.human.has_force_port and "f" not in outs else []
    return connect(
        blocks,
        inputs=["u"] + [f"n_{s}" for s in meas],
        outputs=list(outputs),
        name="noisy_loop",
        ignore_inputs=ignore,
    )


@functools.lru_cache(maxsize=16)
def unit_intent(bandwidth_hz: float) -> tuple:
    """``A, B, C`` of the unit intent filter (read-only) and its H2 norm, made once per
    bandwidth (every member checked at one bandwidth shares them).

    Parameters
    ----------
    bandwidth_hz : float
        The intent's bandwidth, Hz (:func:`backhoe.synthesis.forcefb.intent_filter`).
    """
    F = intent_filter(bandwidth_hz, 1.0)
    Af, Bf, Cf = (np.array(m, float) for m in (F.A, F.B, F.C))
    for m in (Af, Bf, Cf):
        m.setflags(write=False)
    return Af, Bf, Cf, h2_norm(Af, Bf, Cf)


def operator_filter(bandwidth_hz: float, amplitude: float, noise: Noise):
    """``(A, B, C)`` of the operator's command, intent plus remnant, from two unit white
    noises (states of ``F``, then the remnant's one).

    Parameters
    ----------
    bandwidth_hz : float
        The intent's bandwidth, Hz.
    amplitude : float
        The intent's amplitude (RMS ``amplitude / sqrt(2)``), handle units.
    noise : Noise
        The remnant's parameters.
    """
    Af, Bf, Cf, norm_f = unit_intent(float(bandwidth_hz))
    rms_u = amplitude / math.sqrt(2.0)
    k = rms_u / norm_f
    a = 2 * math.pi * noise.remnant_bandwidth_hz
    # remnant: sqrt(2 a) / (s + a) has unit RMS from unit white noise
    kr = noise.remnant_fraction * rms_u * math.sqrt(2 * a)
    nf = Af.shape[0]
    A = np.zeros((nf + 1, nf + 1))
    A[:nf, :nf], A[nf, nf] = Af, -a
    B = np.zeros((nf + 1, 2))
    B[:nf, [0]] = k * Bf
    B[nf, 1] = kr
    C = np.hstack([Cf, [[1.0]]])
    return A, B, C


def rms_responses(
    sys: ct.StateSpace,
    amplitude: float,
    bandwidth_hz: float,
    noise: Noise,
    variances: np.ndarray,
    *,
    operator: bool = True,
    sensors: bool = True,
) -> np.ndarray:
    """Stationary RMS of every output of ``sys`` under the operator's command and the noise.

    Parameters
    ----------
    sys : control.StateSpace
        :func:`noisy_loop`'s system (input ``u`` first, then one noise per measurement).
    amplitude : float
        Intended-motion amplitude, handle units.
    bandwidth_hz : float
        Its bandwidth, Hz.
    noise : Noise
        The remnant's parameters.
    variances : ndarray
        Sample variances of the measurement noises (:func:`sensor_intensities`).
    operator : bool
        Count the intended motion and the remnant.
    sensors : bool
        Count the sensor noise.

    Returns
    -------
    numpy.ndarray
        One RMS per output (``inf`` where the loop is unstable or a white noise reaches an
        output without filtering and no sample variance applies).
    """
    return _rms_cases(sys, amplitude, bandwidth_hz, noise, variances, [(operator, sensors)])[0]


def _rms_cases(
    sys: ct.StateSpace, amplitude: float, bandwidth_hz: float, noise: Noise, variances, cases
) -> list:
    """:func:`rms_responses` for each ``(operator, sensors)`` of ``cases``, from one Schur form
    of the loop cascaded with the operator's filter (each the bits of its own call)."""
    A, B, C, D = (np.asarray(m, float) for m in (sys.A, sys.B, sys.C, sys.D))
    n = A.shape[0]
    if n and np.max(np.linalg.eigvals(A).real) >= 0:
        return [np.full(C.shape[0], math.inf) for _ in cases]
    Ao, Bo, Co = operator_filter(bandwidth_hz, amplitude, noise)
    no = Ao.shape[0]
    p = B.shape[1] - 1
    inten = np.asarray(variances, float) / SERVO_RATE_HZ
    # states (loop, operator filter); inputs (two unit white noises, the sensor noises)
    Aa = np.block([[A, B[:, [0]] @ Co], [np.zeros((no, n)), Ao]])
    Ca = np.hstack([C, D[:, [0]] @ Co])
    solver = lyapunov_solver(Aa)
    out = []
    for operator, sensors in cases:
        Ba = np.zeros((n + no, 2 + p))
        if operator:
            Ba[n:, :2] = Bo
        if sensors and p:
            Ba[:n, 2:] = B[:, 1:] * np.sqrt(inten)[None, :]
        P = solver.solve(-Ba @ Ba.T)
        var = np.diag(Ca @ P @ Ca.T).copy()
        if sensors and p:
            # a measurement passed straight through: its sample variance
            var += (D[:, 1:] ** 2) @ np.asarray(variances, float)
        out.append(np.sqrt(np.maximum(var, 0.0)))
    return out


def operator_spectrum(omega, amplitude: float, bandwidth_hz: float, noise: Noise) -> np.ndarray:
    """``|H(jw)|^2`` summed over :func:`operator_filter`'s two inputs: the spectrum of the
    operator's command per unit white-noise intensity, at ``omega`` (rad/s).

    Parameters
    ----------
    omega : array_like
        Frequencies, rad/s.
    amplitude, bandwidth_hz : float
        As for :func:`operator_filter`.
    noise : Noise
    """
    A, B, C = operator_filter(bandwidth_hz, amplitude, noise)
    omega = np.asarray(omega, float)
    zero = np.zeros((1, 1))
    return sum(
        np.abs(siso_response((A, B[:, [j]], C, zero), omega)) ** 2 for j in range(B.shape[1])
    )


@functools.lru_cache(maxsize=REALISATIONS_KEPT)
def cylinder_filters(loop: BDFTLoop) -> tuple:
    """``(A, B, C, D)`` from a reference correction to the cylinder speed and the valve
    command it causes (rows ``y'``, ``e``): the cylinder loop alone, ``y = T r``.

    Parameters
    ----------
    loop : BDFTLoop
        The member (its valve and PI gains).

    Returns
    -------
    tuple
        Read-only ``(A, B, C, D)``.
    """
    ref = loop.system(bdft=False, outputs=["y", "e"])
    A, B, C, D = (np.asarray(m, float) for m in (ref.A, ref.B, ref.C, ref.D))
    B, D = B[:, [0]] / loop.k_psf, D[:, [0]] / loop.k_psf  # per unit of reference
    if D[0, 0] != 0.0 or np.any(C[[0]] @ B):
        raise ModelStructureError("the cylinder position must have relative degree > 1")
    Cd = np.vstack([C[[0]] @ A, C[[1]]])
    Dd = np.vstack([[[0.0]], D[[1]]])
    out = (A, B, Cd, Dd)
    for m in out:
        m.setflags(write=False)
    return out


@functools.lru_cache(maxsize=16)
def _minimal_matrices(key: tuple) -> tuple:
    """The minimal realisation's ``(A, B, C, D)`` of a controller given by its
    :func:`robust.analysis.realization.matrices_key` (read-only; every member checked with
    one controller shares it)."""
    A, B, C, D = (np.frombuffer(b, float).reshape(shape) for b, shape in key)
    mr = minimal_realization(A, B, C, D)
    out = tuple(np.array(m, float) for m in (mr.A, mr.B, mr.C, mr.D))
    for m in out:
        m.setflags(write=False)
    return out


def _minimal_controller(controller: ct.StateSpace) -> ct.StateSpace:
    """``controller``'s minimal realisation with its signal names (made once per controller
    and reused while the same matrices come back)."""
    A, B, C, D = _minimal_matrices(
        matrices_key((controller.A, controller.B, controller.C, controller.D))
    )
    return ct.ss(
        A.copy(),
        B.copy(),
        C.copy(),
        D.copy(),
        inputs=list(controller.input_labels),
        outputs=list(controller.output_labels),
        name=controller.name,
    )


def member_effort(
    loop: BDFTLoop, controller, spec, amplitude: float, *, checked: bool = False
) -> tuple:
    """Continuous force, noise and reference-effort figures of one stable member.

    Parameters
    ----------
    loop : BDFTLoop
        The member (physical human when the controller measures or drives anything).
    controller : control.StateSpace or None
    spec : Specification
    amplitude : float
        Intended-motion amplitude, handle units.
    checked : bool
        ``controller`` fits the loop's convention (its closed loop was built already).

    Returns
    -------
    (float, float, float)
        * RMS handle force under the intended motion, the remnant and the sensor noise, N
          (0 without a force output);
        * the noise utilisation: the larger of the RMS cylinder position and the RMS handle
          force caused by the sensor noise alone over ``noise_cylinder_mm`` and
          ``noise_force_n`` (0 without a controller);
        * the reference-effort utilisation: ``peak_factor`` times the RMS of the cylinder
          speed and of the valve command that the reference correction asks for (under the
          intended motion, the remnant and the noise), over ``correction_flow_share`` times
          the flow limit and the valve's command range (0 without a correction).
    """
    if controller is None:
        return 0.0, 0.0, 0.0
    if controller.nstates:
        # the controller's minimal realisation: a state wired to nothing is no mode of the
        # loop's signals (the check's poles drop it too)
        controller = _minimal_controller(controller)
    outs = list(controller.output_labels)
    sys = noisy_loop(loop, controller, ["y", *outs], checked=checked)
    var, _ = sensor_intensities(loop, controller.input_labels, spec.noise)
    return effort_utilisations(sys, outs, loop, spec, amplitude, var)


def effort_utilisations(
    sys: ct.StateSpace, actuators, loop: BDFTLoop, spec, amplitude: float, var
) -> tuple:
    """:func:`member_effort`'s figures of a closed loop given as a system.

    Parameters
    ----------
    sys : control.StateSpace
        Inputs ``u`` then one noise per measurement (loop units); outputs ``y`` then the
        ``actuators`` (``"f"``, ``"r_corr"``), in loop units.
    actuators : sequence of str
        The actuators' names, in the order of ``sys``'s outputs after ``y``.
    loop : BDFTLoop
        The member (its units and hydraulic limits).
    spec : Specification
    amplitude : float
        Intended-motion amplitude, handle units.
    var : array_like
        Sample variances of the measurement noises (:func:`designs.effort.sensor_intensities`).

    Returns
    -------
    (float, float, float)
        As :func:`member_effort`.
    """
    outs = list(actuators)
    bw = spec.intent_bandwidth_hz
    total, noise_only = _rms_cases(
        sys, amplitude, bw, spec.noise, var, [(True, True), (False, True)]
    )
    lim_y = spec.noise_cylinder_mm * 1e-3 * loop.cylinder_units_per_m()
    util_noise = noise_only[0] / lim_y
    rms_f = 0.0
    if "f" in outs:
        j = 1 + outs.index("f")
        rms_f = float(total[j])
        util_noise = max(util_noise, noise_only[j] / spec.noise_force_n)
    util_ref = 0.0
    if "r_corr" in outs:
        j = 1 + outs.index("r_corr")
        A, B = np.asarray(sys.A, float), np.asarray(sys.B, float)
        Cr, Dr = np.asarray(sys.C, float)[[j]], np.asarray(sys.D, float)[[j]]
        Ac, Bc, Cc, Dc = cylinder_filters(loop)
        n, nc = A.shape[0], Ac.shape[0]
        casc = ct.ss(
            np.block([[A, np.zeros((n, nc))], [Bc @ Cr, Ac]]),
            np.vstack([B, Bc @ Dr]),
            np.hstack([Dc @ Cr, Cc]),
            Dc @ Dr,
        )
        speed, command = rms_responses(casc, amplitude, bw, spec.noise, var)
        limits = correction_limits(loop, spec)
        util_ref = max(speed / limits[0], command / limits[1])
    return rms_f, float(util_noise), float(util_ref)


def correction_limits(loop: BDFTLoop, spec) -> tuple[float, float]:
    """The RMS cylinder speed and valve command a reference correction may ask for, loop units:
    ``correction_flow_share`` of the flow limit and of the valve's command range, over
    ``peak_factor``.

    Parameters
    ----------
    loop : BDFTLoop
        The member (its units, valve gain and hydraulic limits).
    spec : designs.spec.Specification
        The specification (its share and peak factor).
    """
    share = spec.correction_flow_share / spec.peak_factor
    v_max = loop.hydraulics.max_speed_m_s * loop.cylinder_units_per_m()
    return share * v_max, share * loop.valve_command_limit()
