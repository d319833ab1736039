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
import numpy as np
import scipy.linalg as sla

from backhoe.model.device import DeviceLimits
from backhoe.model.loop import BDFTLoop
from backhoe.model.wiring import connect, renamed
from robust.analysis.norms import h2_norm
from robust.checks import POSITIVE, Spec, validate_fields
from robust.errors import ModelStructureError
from robust.synthesis.genplant import GeneralizedPlant
from robust.synthesis.lmi import PlantBlocks
from robust.synthesis.pk_members import ResponseBound, SynthesisMember

__all__ = [
    "ForceFeedbackWeights",
    "force_feedback_plant",
    "weighting_blocks",
    "handle_units_per_m",
    "intent_filter",
    "as_loop_controller",
    "as_plant_controller",
    "PLANT_MEASUREMENTS",
    "synthesis_member",
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

    Shorthand for :meth:`backhoe.model.loop.BDFTLoop.handle_units_per_m`.

    Parameters
    ----------
    loop : BDFTLoop
        A loop whose human has a metric unit gain (the physical human).
    """
    return loop.handle_units_per_m()


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
    """Second-order Butterworth low-pass ``w_u -> u`` with DC gain ``amplitude``.

    Parameters
    ----------
    bandwidth_hz : float
        Corner frequency, Hz.
    amplitude : float
        DC gain (the intended-motion amplitude in handle units).
    name : str
        System name.
    """
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

    The Figure 5 loop comes from ``loop.blocks`` (the junction table of
    :mod:`backhoe.model.wiring`) with the human's force input ``f`` (and ``r_corr``)
    left open as control inputs; the weights and noise models are added around it.

    Parameters
    ----------
    loop : BDFTLoop
        The member (physical human with a force port).
    weights : ForceFeedbackWeights, optional
        Weights (default: the documented defaults).
    limits : DeviceLimits, optional
        Device limits: force scale, encoder resolution, workspace (default: the Omni's).
    reference_correction : bool
        Add the cylinder-reference correction ``r_corr`` as a second control input,
        penalised by ``z_r``.

    Returns
    -------
    robust.synthesis.genplant.GeneralizedPlant
        ``w = [w_u, n_x, n_c]``, ``u = [f]`` (+ ``r_corr`` with ``reference_correction``),
        ``z = [z_e, z_f]`` (+ ``z_h`` when ``bdft_weight > 0``, + ``z_r`` with
        ``reference_correction``), ``y = [x_m, c_m]``. A controller synthesised on it takes
        ``[x_m, c_m]`` and gives ``f``; :func:`as_loop_controller` renames it to the
        loop's ``x, c -> f``.
    """
    wts = weights or ForceFeedbackWeights()
    lim = limits or DeviceLimits()
    if not loop.human.has_force_port:
        raise ModelStructureError(
            f"force feedback needs a human with a force port; {loop.human.variant!r} has none"
        )
    amp = loop.intended_amplitude(lim, wts.intent_fraction)  # handle units
    # the Figure 5 loop with the human's force input f (and r_corr) left open
    blocks = loop.blocks(bdft=True, reference_correction=reference_correction)
    weighting, w, u, z, y = weighting_blocks(loop, wts, lim, amp, reference_correction)
    # the intent filter's states first, then the loop's, then the weights' (the order the
    # shipped designs were synthesised in: their tuning follows the state coordinates)
    blocks = weighting[:1] + blocks + weighting[1:]
    sys = _balanced(connect(blocks, inputs=w + u, outputs=z + y, name="force_feedback_plant"))
    return GeneralizedPlant.from_system(sys, w=w, u=u, z=z, y=y)


def weighting_blocks(
    loop: BDFTLoop,
    wts: ForceFeedbackWeights,
    lim: DeviceLimits,
    amp: float,
    reference_correction: bool = False,
):
    """The blocks :func:`force_feedback_plant` puts around the Figure 5 loop.

    Parameters
    ----------
    loop : BDFTLoop
        The member that gives the units (handle units per metre, ``K_PSF``) and the
        BDFT-free reference ``y_ref``.
    wts : ForceFeedbackWeights
        The weights.
    lim : DeviceLimits
        The device (peak force, encoder resolution).
    amp : float
        The intended-motion amplitude, handle units.
    reference_correction : bool
        Whether ``r_corr`` is a control input (penalised by ``z_r``).

    Returns
    -------
    (list, list, list, list, list)
        The blocks (the intent filter first, then ``y_ref``, tracking and force weights,
        sensors with their noise) and the partition ``w, u, z, y`` by signal names.
    """
    upm = loop.handle_units_per_m()
    y_scale = loop.k_psf * amp  # intended cylinder motion amplitude
    blocks = [intent_filter(wts.intent_bandwidth_hz, amp)]
    ref = loop.system(bdft=False, outputs=["y"])
    blocks.append(
        ct.ss(ref.A, ref.B, ref.C, ref.D, inputs="u", outputs="y_ref", name="y_reference")
    )
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
    return blocks, ["w_u", "n_x", "n_c"], u, z, ["x_m", "c_m"]


def _balanced(sys: ct.StateSpace) -> ct.StateSpace:
    """The same system in diagonally balanced state coordinates (``scipy.linalg.matrix_balance``).

    The blocks' companion-form realisations mix state scales over many decades;
    balancing makes rank decisions (stabilisability, detectability) and the LMI
    solve better conditioned without changing any input-output behaviour.
    """
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


#: Measured signals: names in the loop -> names in the generalized plant.
PLANT_MEASUREMENTS = {"x": "x_m", "c": "c_m", "y": "y_m"}


def as_loop_controller(K: ct.StateSpace, *, name: str = "K") -> ct.StateSpace:
    """Rename a controller synthesised on :func:`force_feedback_plant` to the loop's signals.

    ``x_m, c_m -> f[, r_corr]`` becomes ``x, c -> f[, r_corr]`` (a single output is
    the force ``f``).

    Parameters
    ----------
    K : control.StateSpace
        Controller in the generalized plant's convention.
    name : str
        Name of the result.
    """
    outs = ["f"] if K.noutputs == 1 else list(K.output_labels)
    if outs not in (["f"], ["f", "r_corr"]):
        raise ModelStructureError(
            f"expected a controller x_m, c_m -> f (or f, r_corr); got {K.input_labels} -> "
            f"{K.output_labels}"
        )
    inverse = {v: k for k, v in PLANT_MEASUREMENTS.items()}
    mapping = dict(inverse, **dict(zip(K.output_labels, outs)))
    return renamed(K, mapping, name=name)


def as_plant_controller(K: ct.StateSpace) -> ct.StateSpace:
    """Rename a loop controller (``x, c, y -> ...``) to the generalized plant's ``x_m, c_m, y_m``.

    Parameters
    ----------
    K : control.StateSpace
        Controller in the loop's convention.
    """
    return renamed(K, PLANT_MEASUREMENTS)


def _butterworth2(corner_hz: float, gain: float, inp: str, out: str, name: str) -> ct.StateSpace:
    w = 2 * math.pi * corner_hz
    return ct.ss(
        ct.tf([gain * w * w], [1.0, math.sqrt(2.0) * w, w * w]), inputs=inp, outputs=out, name=name
    )


def synthesis_member(
    loop: BDFTLoop,
    *,
    controls=("f",),
    measurements=("x", "c"),
    limits: DeviceLimits | None = None,
    intent_fraction: float = 0.25,
    intent_bandwidth_hz: float = 2.0,
    tracking_error: float = 0.2,
    tracking_bandwidth_hz: float = 3.0,
    feedthrough_band_hz: tuple[float, float] | None = (5.0, 7.5),
    max_amplification_db: float = 0.0,
    n_feedthrough: int = 12,
    label: str = "",
):
    """The three plants of one member for :func:`robust.synthesis.pk.pksyn_multi`.

    All three come from ``loop.blocks`` (the junction table of
    :mod:`backhoe.model.wiring`) with the controller's signals left open:

    * region plant: ``u, controls -> h, measurements`` (the Figure 5 loop);
    * H-infinity plant: the intended motion ``u`` (handle units) to the tracking error
      ``z_t = W_t (r + r_corr - K_PSF u) / (tracking_error K_PSF)``, ``W_t`` a unit-gain
      second-order Butterworth low-pass at ``tracking_bandwidth_hz``. Since the
      cylinder follows its reference through the same loop with and without BDFT,
      ``(r + r_corr - K_PSF u) / (K_PSF u) = Y / Y_ref - 1`` exactly, so
      ``||u -> z_t||_inf <= 1`` means ``|Y/Y_ref - 1| <= tracking_error / |W_t|``;
    * H2 plant (when the controls include the force ``f``): unit white noise ``w_u``
      through the intent filter (second-order Butterworth at ``intent_bandwidth_hz``,
      scaled so that ``u`` has the RMS ``A / sqrt(2)`` of the realistic intended motion,
      ``A`` the intended amplitude, :meth:`BDFTLoop.intended_amplitude`) to the handle
      force ``z_f = f`` in newtons: its H2 norm is the stationary RMS force
      (as :func:`designs.spec.rms_force` computes it).

    Parameters
    ----------
    loop : BDFTLoop
        The member (a human with a force port when ``"f"`` is a control).
    controls : sequence of str
        Controller outputs, among ``f``, ``r_corr``.
    measurements : sequence of str
        Controller inputs, among ``x``, ``c``, ``y``.
    limits : DeviceLimits, optional
        Device limits (workspace for the intended amplitude).
    intent_fraction : float
        Intended amplitude as a fraction of the half-workspace.
    intent_bandwidth_hz : float
        Corner of the intent filter, Hz.
    tracking_error : float
        Allowed ``|Y/Y_ref - 1|`` in the intent band.
    tracking_bandwidth_hz : float
        Corner of the tracking weight, Hz.
    feedthrough_band_hz : (float, float) or None
        Band where the feedthrough ``|Y/Y_ref - 1|`` may not exceed the peak of the
        uncompensated loop's over the band (formal response, even when that loop is
        unstable) by more than ``max_amplification_db`` (as :mod:`designs.spec`
        checks it): a :class:`robust.synthesis.pk.ResponseBound` on ``n_feedthrough``
        linearly spaced frequencies, since ``Y/Y_ref - 1 = tracking_error T / W_t``
        (``None``: no bound).
    max_amplification_db : float
        Allowed amplification, dB.
    n_feedthrough : int
        Frequencies of the bound.
    label : str
        The member's name.

    Returns
    -------
    robust.synthesis.pk.SynthesisMember
    """
    controls, measurements = list(controls), list(measurements)
    if not controls or any(c not in ("f", "r_corr") for c in controls):
        raise ModelStructureError(f"controls must be among ('f', 'r_corr'); got {controls}")
    if not measurements or any(m not in ("x", "c", "y") for m in measurements):
        raise ModelStructureError(f"measurements must be among ('x', 'c', 'y'); got {measurements}")
    if "f" in controls and not loop.human.has_force_port:
        raise ModelStructureError(
            f"force feedback needs a human with a force port; {loop.human.variant!r} has none"
        )
    lim = limits or DeviceLimits()
    rc = "r_corr" in controls
    ignore = ["f"] if loop.human.has_force_port and "f" not in controls else []
    base = loop.blocks(bdft=True, reference_correction=rc)

    def plant(extra, w, z, name):
        sys = connect(
            base + extra,
            inputs=w + controls,
            outputs=z + measurements,
            name=name,
            ignore_inputs=ignore,
        )
        gp = GeneralizedPlant.from_system(sys, w=w, u=controls, z=z, y=measurements)
        if np.any(gp.D22 != 0):
            raise ModelStructureError(f"{name}: the controls feed the measurements directly")
        return PlantBlocks.from_generalized_plant(gp)

    # the region plant's performance output is not used; the hand motion h is never a
    # controller input, so it cannot clash with the measurements
    region = plant([], ["u"], ["h"], "region_plant")
    k = loop.k_psf
    track = [
        _static(k, "u", "u_ref", "u_ref"),
        ct.summing_junction(
            inputs=["r", *(["r_corr"] if rc else []), "-u_ref"], output="e_cmd", name="cmd_err"
        ),
        _butterworth2(tracking_bandwidth_hz, 1.0 / (tracking_error * k), "e_cmd", "z_t", "W_t"),
    ]
    hinf = plant(track, ["u"], ["z_t"], "tracking_plant")
    h2 = None
    if "f" in controls:
        amp = loop.intended_amplitude(lim, intent_fraction)
        unit = intent_filter(intent_bandwidth_hz, 1.0)
        gain = amp / (math.sqrt(2.0) * h2_norm(unit))
        h2 = plant(
            [intent_filter(intent_bandwidth_hz, gain), _static(1.0, "f", "z_f", "force_out")],
            ["w_u"],
            ["z_f"],
            "force_plant",
        )
    response = None
    if feedthrough_band_hz is not None:
        w = 2 * math.pi * np.linspace(*feedthrough_band_hz, n_feedthrough)
        wt = 2 * math.pi * tracking_bandwidth_hz
        s_ = 1j * w
        W_t = wt * wt / (s_ * s_ + math.sqrt(2.0) * wt * s_ + wt * wt)
        gain = tracking_error / W_t
        T0 = np.array(
            [
                (
                    hinf.C1 @ np.linalg.solve(1j * wi * np.eye(hinf.A.shape[0]) - hinf.A, hinf.B1)
                    + hinf.D11
                )[0, 0]
                for wi in w
            ]
        )
        peak = np.max(np.abs(gain * T0)) * 10 ** (max_amplification_db / 20)
        response = ResponseBound(w, np.zeros_like(gain), gain, np.full(w.size, peak))
    return SynthesisMember(region=region, hinf=hinf, h2=h2, label=label, response=response)
