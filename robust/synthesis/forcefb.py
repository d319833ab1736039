"""Generalized plant for haptic force feedback against biodynamic feedthrough.

::

        w_u ──► W_u ──► u ─┐                        ┌──────────► z_e = W_e (y - y_ref)
        n_x ─────────────┐ │   ┌──────────────────┐ │
        n_c ───────────┐ │ └──►│  Figure 5 loop   │─┤ y ───────► z_f = W_f f
                       │ └────►│  with the human's├─┤ x + s_x n_x ──► x_m ─┐
               f ─────────────►│  force port      │─┘ c + s_c n_c ──► c_m ─┤
         (r_corr) ────────────►└──────────────────┘                        │
               ▲                                                           │
               └──────────────────────── K ◄───────────────────────────────┘

``y_ref`` is the cylinder response the intended motion would give without BDFT
(the Figure 5 loop with the outer path removed), so ``z_e`` is the error the
feedthrough causes; ``z_f`` is the handle force relative to the device's peak
force, with a high-frequency emphasis that keeps the controller implementable at
the servo rate; ``z_h`` (optional) is the BDFT channel, the handle motion the hand
causes.

Units. The handle force ``f`` acts on the physical human model in newtons. The
handle position ``x`` is in the loop's handle units; since the handle moves with
the hand, one metre of hand motion is ``|kappa*h_gain|`` handle units
(:func:`handle_units_per_m`), which fixes the encoder noise (resolution 0.055 mm)
and the intended-motion amplitude (a fraction of the 71 mm workspace) in the
model's units.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct

from robust.checks import POSITIVE, Spec, validate_fields
from robust.errors import ModelStructureError
from robust.model.device import DeviceLimits
from robust.model.loop import BDFTLoop

__all__ = [
    "ForceFeedbackWeights",
    "force_feedback_plant",
    "handle_units_per_m",
    "intent_filter",
    "as_loop_controller",
    "FORCE_PLANT_SIGNALS",
]

#: Partition of the generalized plant (without the optional channels).
FORCE_PLANT_SIGNALS = {
    "w": ["w_u", "n_x", "n_c"],
    "u": ["f"],
    "z": ["z_e", "z_f"],
    "y": ["x_m", "c_m"],
}


def handle_units_per_m(loop: BDFTLoop) -> float:
    """Handle units per metre of handle (= hand) motion: ``|kappa * h_gain|``.

    Needs a human variant whose parameters carry the unit gain ``h_gain`` (paper's
    ``h`` units per metre), i.e. the physical human.
    """
    params = getattr(loop.human, "params", None)
    h_gain = getattr(params, "h_gain", None)
    if h_gain is None:
        raise ModelStructureError(
            f"handle units need a human model with a metric unit gain (h_gain); the {loop.human.variant!r} "
            "variant has none. Use the physical human."
        )
    return abs(loop.calibration.loop_scale * h_gain)


@dataclasses.dataclass(frozen=True)
class ForceFeedbackWeights:
    """Weights of the force-feedback generalized plant (all named, all documented).

    Parameters
    ----------
    intent_bandwidth_hz : float
        Corner of the second-order low-pass that shapes the intended motion: people
        command the backhoe at 0-2 Hz (default 2).
    intent_fraction : float
        Intended-motion amplitude as a fraction of the handle workspace (default 0.25,
        i.e. +-17.75 mm of the 71 mm workspace).
    tracking_error : float
        Allowed tracking error ``y - y_ref`` relative to the intended cylinder motion
        in the intent band (default 0.2); the weight is its inverse.
    tracking_bandwidth_hz : float
        Corner of the first-order low-pass of the tracking weight (default 3).
    force_emphasis_hz : float
        Frequency above which handle force is penalised more, rising 10x by ten times
        that frequency (default 30 Hz; keeps the controller slow enough for 1 kHz).
    accel_noise : float
        Accelerometer noise (engine vibration) in the paper's units of ``c`` (default 0.05).
    encoder_resolution_mm : float
        Encoder noise as its resolution, mm (default 0.055, the Omni's).
    bdft_weight : float
        Weight of the BDFT channel ``z_h`` relative to the intended motion (default 0:
        channel off).
    correction_weight : float
        Weight of the cylinder-reference correction ``z_r = correction_weight * r_corr /
        (K_PSF * amplitude)`` (relative to the intended cylinder motion), used when the
        plant has the ``r_corr`` control input (default 1).
    """

    intent_bandwidth_hz: float = 2.0
    intent_fraction: float = 0.25
    tracking_error: float = 0.2
    tracking_bandwidth_hz: float = 3.0
    force_emphasis_hz: float = 30.0
    accel_noise: float = 0.05
    encoder_resolution_mm: float = 0.055
    bdft_weight: float = 0.0
    correction_weight: float = 1.0

    def __post_init__(self):
        specs = {f.name: POSITIVE for f in dataclasses.fields(self)}
        specs["intent_fraction"] = Spec(low=0.0, high=1.0, low_open=True)
        specs["bdft_weight"] = Spec(low=0.0)
        validate_fields(self, specs)


def intent_filter(bandwidth_hz: float, amplitude: float, *, name: str = "intent") -> ct.StateSpace:
    """Second-order Butterworth low-pass ``w_u -> u`` with DC gain ``amplitude``."""
    w = 2 * math.pi * bandwidth_hz
    g = ct.tf([amplitude * w * w], [1.0, math.sqrt(2.0) * w, w * w])
    return ct.ss(g, inputs="w_u", outputs="u", name=name)


def _static(gain: float, inp: str, out: str, name: str) -> ct.StateSpace:
    return ct.ss([], [], [], [[gain]], inputs=inp, outputs=out, name=name)


def force_feedback_plant(
    loop: BDFTLoop,
    weights: ForceFeedbackWeights | None = None,
    limits: DeviceLimits | None = None,
    *,
    reference_correction: bool = False,
):
    """Generalized plant ``P`` for handle-force feedback on ``loop`` (physical human).

    Returns
    -------
    robust.synthesis.genplant.GeneralizedPlant
        ``w = [w_u, n_x, n_c]``, ``u = [f]`` (+ ``r_corr`` with ``reference_correction``),
        ``z = [z_e, z_f]`` (+ ``z_h`` when ``bdft_weight > 0``, + ``z_r`` with
        ``reference_correction``), ``y = [x_m, c_m]``. A controller synthesised on it takes
        ``[x_m, c_m]`` and gives ``f``; :func:`as_loop_controller` renames it to the
        loop's ``x, c -> f``.
    """
    from robust.model.components import pi_controller, position_scale, structure, valve_cylinder
    from robust.synthesis.genplant import GeneralizedPlant

    wts = weights or ForceFeedbackWeights()
    lim = limits or DeviceLimits()
    if not loop.human.has_force_port:
        raise ModelStructureError(
            f"force feedback needs a human with a force port; {loop.human.variant!r} has none"
        )
    upm = handle_units_per_m(loop)
    amp = wts.intent_fraction * (lim.workspace_mm / 2) * 1e-3 * upm  # handle units
    cal = loop.calibration
    y_scale = loop.k_psf * amp  # intended cylinder motion amplitude
    blocks = [
        intent_filter(wts.intent_bandwidth_hz, amp),
        position_scale(loop.k_psf),
        ct.summing_junction(
            inputs=["r", "r_corr", "-y"] if reference_correction else ["r", "-y"],
            output="err",
            name="cyl_err",
        ),
        pi_controller(cal.pi),
        valve_cylinder(loop.valve),
        structure(loop.struct),
        loop.human.system(),
        _static(cal.handle_sign * cal.loop_scale, "h", "h_cmd", "loop_scale"),
        ct.summing_junction(inputs=["u", "h_cmd"], output="x", name="handle"),
    ]
    ref = loop.system(bdft=False, outputs=["y"])
    blocks.append(ct.ss(ref.A, ref.B, ref.C, ref.D, inputs="u", outputs="y_ref", name="reference"))
    blocks.append(ct.summing_junction(inputs=["y", "-y_ref"], output="e_trk", name="trk_err"))
    wt = 2 * math.pi * wts.tracking_bandwidth_hz
    we = ct.tf([wt / (wts.tracking_error * y_scale)], [1.0, wt])
    blocks.append(ct.ss(we, inputs="e_trk", outputs="z_e", name="W_e"))
    wf1 = 2 * math.pi * wts.force_emphasis_hz
    wf = ct.tf([10.0 / wf1, 1.0], [1.0 / wf1, 1.0]) * (1.0 / lim.peak_force_n)
    blocks.append(ct.ss(wf, inputs="f", outputs="z_f", name="W_f"))
    s_x = lim.resolution_mm * 1e-3 * upm
    blocks.append(ct.summing_junction(inputs=["x", "n_xs"], output="x_m", name="enc"))
    blocks.append(_static(s_x, "n_x", "n_xs", "W_nx"))
    blocks.append(ct.summing_junction(inputs=["c", "n_cs"], output="c_m", name="acc"))
    blocks.append(_static(wts.accel_noise, "n_c", "n_cs", "W_nc"))
    z = ["z_e", "z_f"]
    if wts.bdft_weight > 0:
        blocks.append(_static(wts.bdft_weight / amp, "h_cmd", "z_h", "W_h"))
        z.append("z_h")
    u = ["f"]
    if reference_correction:
        blocks.append(_static(wts.correction_weight / y_scale, "r_corr", "z_r", "W_r"))
        z.append("z_r")
        u.append("r_corr")
    w, y = ["w_u", "n_x", "n_c"], ["x_m", "c_m"]
    sys = _balanced(
        ct.interconnect(blocks, inputs=w + u, outputs=z + y, name="force_feedback_plant")
    )
    return GeneralizedPlant.from_system(sys, w=w, u=u, z=z, y=y)


def _balanced(sys: ct.StateSpace) -> ct.StateSpace:
    """The same system in diagonally balanced state coordinates (``scipy.linalg.matrix_balance``).

    The blocks' companion-form realisations mix state scales over many decades;
    balancing makes rank decisions (stabilisability, detectability) and the LMI
    solve better conditioned without changing any input-output behaviour.
    """
    import scipy.linalg as sla

    _, (scale, _) = sla.matrix_balance(sys.A, permute=False, separate=True)
    A = sys.A * (1.0 / scale)[:, None] * scale[None, :]
    return ct.ss(
        A,
        sys.B / scale[:, None],
        sys.C * scale[None, :],
        sys.D,
        inputs=sys.input_labels,
        outputs=sys.output_labels,
        name=sys.name,
    )


def as_loop_controller(K: ct.StateSpace, *, name: str = "K") -> ct.StateSpace:
    """Rename a controller synthesised on :func:`force_feedback_plant` (``x_m, c_m -> f[, r_corr]``) to ``x, c -> ...``."""
    rename = {"x_m": "x", "c_m": "c", "y_m": "y"}
    ins = [rename.get(s, s) for s in K.input_labels]
    outs = list(K.output_labels)
    if K.noutputs == 1:
        outs = ["f"]
    if len(ins) != K.ninputs or outs not in (["f"], ["f", "r_corr"]):
        raise ModelStructureError(
            f"expected a controller x_m, c_m -> f (or f, r_corr); got {K.input_labels} -> {K.output_labels}"
        )
    return ct.ss(K.A, K.B, K.C, K.D, inputs=ins, outputs=outs, name=name)
