"""Evaluation of a compensator on a family: the numbers every design reports (BRIEF section 7).

* family stability: fraction stable, worst largest real part, minimum damping in the
  BDFT band, and the worst member's parameters (batched poles, :mod:`backhoe.families.batched`);
* BDFT suppression: ``|Y/Y_ref|`` in dB near the structure mode (5-7.5 Hz), where
  ``Y_ref`` is the cylinder response without BDFT and without compensation;
* tracking of intended motion: ``max |Y/Y_ref - 1|`` over 0.05-2 Hz;
* handle force: peak and RMS over simulations of the worst stable members with a
  chirp and with a realistic (seeded, band-limited) intended motion, against the
  device limits.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import control as ct
import numpy as np

from backhoe.analysis.loops import loop_poles
from backhoe.analysis.simulation import SweptSine, foh_response, simulate
from backhoe.model.components import K_PSF_NOMINAL, REALISATIONS_KEPT
from backhoe.model.device import DeviceLimits, check_force
from backhoe.model.loop import BDFTLoop
from backhoe.synthesis.forcefb import intent_filter
from robust.analysis.loops import frequency_response
from robust.checks import NONNEGATIVE, check_vector
from robust.errors import ModelStructureError
from uncertainty import validate_family

__all__ = [
    "DesignEvaluation",
    "evaluate_design",
    "SUPPRESSION_BAND_HZ",
    "TRACKING_BAND_HZ",
    "INTENT_FRACTION",
    "intended_motion",
    "output_ratio",
    "output_ratios",
    "frequency_metrics",
    "force_histories",
]

#: Band of the BDFT suppression figure, Hz (around the structure modes at 6.3-6.5 Hz).
SUPPRESSION_BAND_HZ = (5.0, 7.5)
#: Band of the intended-motion tracking figure, Hz (the band people command in).
TRACKING_BAND_HZ = (0.05, 2.0)
#: Intended-motion amplitude: this fraction of the half-workspace (0.25: +-8.9 mm of 71 mm).
INTENT_FRACTION = 0.25


@dataclasses.dataclass(frozen=True)
class DesignEvaluation:
    """Everything a design reports; see the module notes for definitions.

    Parameters
    ----------
    name : str
        Design name.
    samples : int
        Number of family members validated.
    seed : int
        Seed of the sample set.
    method : str
        Sampling method (``"lhs"``, ``"mc"``, ``"grid"``, ``"vertices"``).
    k_psf : float
        Position scale factor of the family the design was evaluated on (its workspace).
    fraction_stable : float
        Fraction of the members whose closed-loop poles all lie left of the stability
        threshold.
    max_real_pole : float
        Largest real part of any member's closed-loop pole, rad/s.
    min_damping : float
        Smallest damping ratio of the members' poles in the damping band
        (:data:`backhoe.constants.DAMPING_BAND_HZ`; ``inf`` if no pole lies in it).
    worst : dict
        Parameters (name -> value) of the member with the largest real part.
    suppression_db : float
        Largest ``|20 log10 |Y/Y_ref||`` over :data:`SUPPRESSION_BAND_HZ` on the nominal
        member, dB, to 1e-9 dB (0: no BDFT left; ``inf`` if the nominal member is unstable).
    tracking_error : float
        Largest ``|Y/Y_ref - 1|`` over :data:`TRACKING_BAND_HZ` on the nominal member, to
        1e-10 (``inf`` if it is unstable).
    peak_force_n : float
        Peak handle force over the simulated histories, N (0 for a design without
        handle force, ``inf`` if no member could be simulated).
    rms_force_n : float
        Largest RMS handle force of one simulated history, N.
    force_within_limits : bool
        Whether the peak and RMS forces respect the device's peak and continuous limits.
    force_members : int
        Number of members whose force was simulated (the nominal and up to
        ``n_force_members`` worst stable ones).
    order : int
        Order of the evaluated controller (0 without a controller).
    notes : tuple of str
        Caveats: the design's own and those of the evaluation.
    """

    name: str
    samples: int
    seed: int
    method: str
    k_psf: float
    fraction_stable: float
    max_real_pole: float
    min_damping: float
    worst: dict
    suppression_db: float
    tracking_error: float
    peak_force_n: float
    rms_force_n: float
    force_within_limits: bool
    force_members: int
    order: int
    notes: tuple[str, ...] = ()

    def to_json(self) -> dict:
        """Every field, as a dict (``dataclasses.asdict``)."""
        return dataclasses.asdict(self)


def intended_motion(
    t: np.ndarray, amplitude: float, bandwidth_hz: float, *, seed: int
) -> np.ndarray:
    """Realistic intended handle motion: seeded white noise through the intent filter.

    Scaled so its RMS is ``amplitude / sqrt(2)`` (that of a sine of that amplitude).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Time grid, s (equally spaced; the noise is interpolated linearly between samples).
    amplitude : float
        Amplitude of the equivalent sine, in the loop's handle units.
    bandwidth_hz : float
        Cut-off of the second-order Butterworth intent filter
        (:func:`backhoe.synthesis.forcefb.intent_filter`), Hz; 2 Hz in the evaluation.
    seed : int
        Seed of the white noise.

    Returns
    -------
    ndarray, shape (n,)
        The intended motion ``u`` at ``t``.
    """
    rng = np.random.default_rng(seed)
    w = rng.standard_normal(t.size)
    filt = intent_filter(bandwidth_hz, 1.0)
    dt = (t[-1] - t[0]) / (t.size - 1)
    u = foh_response(filt.A, filt.B[:, 0], filt.C, filt.D[:, 0], dt, w)[0]
    return u * (amplitude / math.sqrt(2) / max(np.sqrt(np.mean(u**2)), 1e-300))


@functools.lru_cache(maxsize=64)
def _reference(k_psf: float, valve, calibration, f_key: bytes) -> np.ndarray:
    # the loop without BDFT has neither structure nor human: every member with the same
    # valve shares it, so its response is computed once per valve and grid
    loop = BDFTLoop(k_psf=k_psf, valve=valve, calibration=calibration)
    out = frequency_response(loop.system(bdft=False), np.frombuffer(f_key))
    out.setflags(write=False)
    return out


def _reference_response(loop: BDFTLoop, f_hz) -> np.ndarray:
    """``Y_ref`` at ``f_hz``: the cylinder response without BDFT and without compensation
    (read-only; it depends on the loop's valve, calibration and workspace only)."""
    f = np.ascontiguousarray(check_vector("output_ratios: f_hz", f_hz, NONNEGATIVE), dtype=float)
    return _reference(loop.k_psf, loop.valve, loop.calibration, f.tobytes())


def output_ratio(loop: BDFTLoop, controller, f_hz: np.ndarray) -> np.ndarray:
    """``Y / Y_ref`` at ``f_hz``, the paper's Figure 13 measure.

    The cylinder response to the intended motion with BDFT (and ``controller``) over
    that without BDFT and without compensation.

    Parameters
    ----------
    loop : BDFTLoop
        One member.
    controller : control.StateSpace or None
        The compensator.
    f_hz : ndarray
        Frequencies, Hz.

    Returns
    -------
    ndarray of complex, shape of ``f_hz``
        The ratio at each frequency.
    """
    with_k = frequency_response(loop.system(bdft=True, controller=controller), f_hz)
    return with_k / _reference_response(loop, f_hz)


def output_ratios(
    loop: BDFTLoop, controller, f_hz: np.ndarray, *, closed: ct.StateSpace | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`output_ratio` with ``controller`` and without it, sharing one ``Y_ref``.

    Parameters
    ----------
    loop : BDFTLoop
        One member.
    controller : control.StateSpace or None
        The compensator.
    f_hz : ndarray
        Frequencies, Hz.
    closed : control.StateSpace, optional
        ``loop.system(bdft=True, controller=controller)`` when the caller has built it
        already (it is not built again).

    Returns
    -------
    (ndarray, ndarray) of complex
        ``Y / Y_ref`` with the compensator and without it (the same array for ``None``).
    """
    if closed is None:
        closed = loop.system(bdft=True, controller=controller)
    ref = _reference_response(loop, f_hz)
    with_k = frequency_response(closed, f_hz) / ref
    if controller is None:
        return with_k, with_k
    f = np.ascontiguousarray(f_hz, dtype=float)
    try:
        hash(loop)
    except TypeError:  # (a human model that is not hashable)
        return with_k, frequency_response(loop.system(bdft=True), f) / ref
    return with_k, _uncompensated(loop, f.tobytes()) / ref


@functools.lru_cache(maxsize=REALISATIONS_KEPT)
def _uncompensated(loop: BDFTLoop, f_key: bytes) -> np.ndarray:
    # the member's response without a compensator: every design's coverage checks the same
    # members, and a process of the report's pool checks several designs
    out = frequency_response(loop.system(bdft=True), np.frombuffer(f_key))
    out.setflags(write=False)
    return out


def frequency_metrics(loop: BDFTLoop, controller) -> tuple[float, float]:
    """``(suppression_db, tracking_error)`` of one stable member (see module notes).

    Parameters
    ----------
    loop : BDFTLoop
        One member; its closed loop must be stable.
    controller : control.StateSpace or None
        The compensator.

    Returns
    -------
    suppression_db : float
        Largest ``|20 log10 |Y/Y_ref||`` over :data:`SUPPRESSION_BAND_HZ` (60
        frequencies), dB.
    tracking_error : float
        Largest ``|Y/Y_ref - 1|`` over :data:`TRACKING_BAND_HZ` (80 log-spaced
        frequencies).
    """
    fs = np.linspace(*SUPPRESSION_BAND_HZ, 60)
    ft = np.geomspace(*TRACKING_BAND_HZ, 80)
    sup = float(np.max(np.abs(20 * np.log10(np.abs(output_ratio(loop, controller, fs))))))
    trk = float(np.max(np.abs(output_ratio(loop, controller, ft) - 1.0)))
    return sup, trk


def force_histories(
    loop: BDFTLoop,
    controller,
    *,
    amplitude: float,
    seed: int,
    duration_s: float = 20.0,
    fs_hz: float = 1000.0,
    intent_bandwidth_hz: float = 2.0,
) -> list[np.ndarray]:
    """Handle force for a chirp and for a realistic intended motion on one member.

    Parameters
    ----------
    loop : BDFTLoop
        One member (physical human: the force acts on the hand).
    controller : control.StateSpace or None
        The compensator; without a force output ``f`` there is no force to simulate.
    amplitude : float
        Intended-motion amplitude, in the loop's handle units.
    seed : int
        Seed of the realistic intended motion (:func:`intended_motion`).
    duration_s : float
        Length of each simulation, s.
    fs_hz : float
        Sampling rate of the simulations, Hz.
    intent_bandwidth_hz : float
        Bandwidth of the realistic intended motion, Hz.

    Returns
    -------
    list of ndarray
        ``[force for a 0.1-8 Hz chirp, force for the realistic motion]``, N, sampled
        at ``fs_hz``; empty when ``controller`` does not drive ``f``.
    """
    if controller is None or "f" not in controller.output_labels:
        return []
    sweep = SweptSine(f0_hz=0.1, f1_hz=8.0, duration_s=duration_s, amplitude=amplitude, fs_hz=fs_hz)
    t, u = sweep.signal()
    out = [simulate(loop, t, u, controller=controller)["f"]]
    u2 = intended_motion(t, amplitude, intent_bandwidth_hz, seed=seed)
    out.append(simulate(loop, t, u2, controller=controller)["f"])
    return out


def evaluate_design(
    name: str,
    family,
    samples,
    controller=None,
    *,
    limits: DeviceLimits | None = None,
    n_force_members: int = 3,
    intent_fraction: float = INTENT_FRACTION,
    notes=(),
) -> DesignEvaluation:
    """Validate ``controller`` on ``family`` (members ``samples``) and measure its cost.

    Parameters
    ----------
    name : str
        Design name.
    family : backhoe.Family
        The family (its ``k_psf`` is the design's workspace).
    samples : uncertainty.SampleSet
        Members to validate; the seed is reported.
    controller : control.StateSpace, optional
        Compensator in the loop convention (inputs among ``x, c, y``; outputs among
        ``f, r_corr``); ``None`` evaluates the loop alone.
    limits : DeviceLimits, optional
        Device limits (default: the Omni's).
    n_force_members : int
        How many of the worst stable members are simulated for the force figures
        (the nominal member is simulated too when it is stable).
    intent_fraction : float
        Intended-motion amplitude as a fraction of half the handle workspace.
    notes : sequence of str
        Caveats carried into the result (the design's own), before the evaluation's.

    Returns
    -------
    DesignEvaluation
    """
    lim = limits or DeviceLimits()
    val = validate_family(family, samples, controller=controller)
    nominal = family.member(family.nominal_values())
    notes = list(notes)
    if loop_poles(nominal, controller=controller).stable:
        sup, trk = frequency_metrics(nominal, controller)
        # to 1e-9 dB and 1e-10: an exact cancellation leaves only rounding (1e-14 to
        # 1e-12), whose digits depend on the CPU's BLAS kernel; it is reported as 0
        sup, trk = round(sup, 9), round(trk, 10)
    else:
        sup = trk = math.inf
        notes.append("the nominal member is unstable: suppression and tracking are undefined (inf)")
    # force: the nominal member and the worst stable members
    stable_idx = np.flatnonzero(val.max_real < val.stability_threshold)
    worst_stable = stable_idx[np.argsort(val.max_real[stable_idx])[::-1][:n_force_members]]
    members = [nominal] + [family.member(samples.values[i]) for i in worst_stable]
    forces = []
    for i, m in enumerate(members):
        if not loop_poles(m, controller=controller).stable:
            continue
        amp = _amplitude(m, lim, intent_fraction)
        forces += force_histories(m, controller, amplitude=amp, seed=samples.seed + i)
    if forces:
        allf = np.concatenate(forces)
        fc = check_force(allf, lim)
        peak, rms = fc.peak_force_n, max(float(np.sqrt(np.mean(f**2))) for f in forces)
        within = peak <= lim.peak_force_n and rms <= lim.continuous_force_n
    else:
        peak = rms = 0.0
        within = True
        if controller is not None and "f" in controller.output_labels:
            peak = rms = math.inf
            within = False
            notes.append("no stable member to simulate: force undefined")
    return DesignEvaluation(
        name=name,
        samples=val.samples,
        seed=val.seed,
        method=val.method,
        k_psf=family.k_psf,
        fraction_stable=val.fraction_stable,
        max_real_pole=val.max_real_pole,
        min_damping=val.min_damping,
        worst=val.worst,
        suppression_db=sup,
        tracking_error=trk,
        peak_force_n=peak,
        rms_force_n=rms,
        force_within_limits=within,
        force_members=len(forces) // 2,
        order=0 if controller is None else int(controller.nstates),
        notes=tuple(notes),
    )


def _amplitude(loop: BDFTLoop, limits: DeviceLimits, fraction: float) -> float:
    """Intended-motion amplitude in the loop's handle units.

    The literal Eqn 5 human has no metric handle units; its handle units are then
    taken as metres (one unit per metre).
    """
    try:
        return loop.intended_amplitude(limits, fraction)
    except ModelStructureError:
        factor = K_PSF_NOMINAL / loop.k_psf
        return limits.intended_amplitude_m(fraction, workspace_factor=factor)
