"""The design specification as named parameters, and its check on a family.

:class:`Specification` collects what a compensator must meet, each requirement a bound on
a closed-loop map that is checked at every frequency or exactly as a stationary RMS value
(never on a grid that leaves bands unchecked): the closed-loop pole region, the cylinder's
response to the operator's intended motion against the BDFT-free response, the noise, and
the effort on each actuator against its device (the Omni's forces, the valve's flow and
command range). :func:`check_specification` checks one controller on a list of family
members and names the *binding* constraint (the one with the largest utilisation) and,
for the frequency-wise bounds, the frequency where it binds.

The intended-motion response
----------------------------
With ``Y`` the cylinder's response to the intended motion ``u`` and ``Y_ref`` the response
without BDFT and without compensation, the deviation ``R = Y/Y_ref - 1`` is the closed-loop
map ``u -> (x - u) + r_corr / K_PSF`` (:func:`designs.response.deviation_maps`), a proper
rational function.
The specification bounds it, at every frequency, by two stable rational weights (Skogestad
& Postlethwaite, *Multivariable Feedback Control*, ch. 2-3):

* up to :attr:`Specification.split_hz`, ``|R(jw)| <= |W_t(jw)|``: the tracking tolerance
  (``tracking_error``, 20 %) through the operator's band, rolling off to
  ``tracking_floor`` (2 %) above it;
* above it, ``|R(jw)| <= max(|W_t(jw)|, |W_f(jw) R0(jw)|)`` with ``R0`` the uncompensated
  deviation of the machine as built (the member at ``reference_k_psf``; its *formal*
  response, also where that loop is unstable) and ``W_f`` a
  notch: over the structure modes' band the feedthrough must be reduced by
  ``feedthrough_reduction_db`` (6 dB), far from it the compensated deviation may exceed the
  uncompensated one by ``max_amplification_db`` (1 dB) at most.

So a controller that amplifies the cylinder's response anywhere, at 3.5 Hz or at 20 Hz,
beyond the larger of the BDFT-free and the uncompensated response fails. Each bound is
checked by :func:`robust.analysis.bounds.bound_ratio`: the imaginary-axis crossings of
``|R| = gamma |B|`` from a Hamiltonian pencil, exact between grid points.

Constraints and their worst value over the members
--------------------------------------------------
``"decay rate"``
    Largest real part of the closed-loop poles (:func:`robust.analysis.loops.loop_poles`),
    rad/s; holds when every pole has ``Re p < -max(decay_rate, STABILITY_TOL)``
    (:func:`robust.analysis.stability.poles_stable` with that margin).
``"damping"``
    Smallest damping ratio ``-Re p / |p|`` of the poles whose frequency
    ``|Im p| / (2 pi)`` lies in ``damping_band_hz`` (``inf`` without such a pole);
    the band test is that of :class:`uncertainty.region.Region`, so the check agrees
    with :meth:`Specification.region`. Holds when it is at least ``min_damping``.
``"peak force"``
    Largest ``|f|`` of a simulated realistic intended motion
    (:func:`designs.evaluate.intended_motion`, 1 kHz, seed ``seed + i`` for member
    ``i``) on the ``simulate_peak`` stable members with the largest RMS force, N.
``"continuous force"``
    Stationary RMS handle force under the intended motion, the operator's remnant and the
    sensor noise (:mod:`designs.effort`), N, exact (Lyapunov).
``"tracking"``, ``"feedthrough"``
    ``sup |R(jw)| / bound(w)`` below and above :attr:`Specification.split_hz` (the
    bounds above), with the frequency where it is reached; holds at most 1.
``"noise"``
    The larger of the RMS cylinder position and the RMS handle force that the sensor noise
    alone causes, over ``noise_cylinder_mm`` and ``noise_force_n``; holds at most 1.
``"reference effort"``
    ``peak_factor`` times the RMS cylinder speed and valve command that a cylinder-reference
    correction asks for, over ``correction_flow_share`` of the flow limit and of the
    valve's command range (:class:`robust.model.components.HydraulicLimits`); holds at
    most 1.

Everything but the poles is undefined on a member whose closed loop is unstable: its value
there is ``inf`` (the constraint fails) and a note says so. A controller that does not
drive ``f`` (or no controller) exerts no force: both force values are 0; without a
controller there is no sensor noise and no correction.

Utilisation
-----------
A ratio that is 1 at the limit, above 1 when violated and increases monotonically
as the value gets worse:

* peak force, continuous force: ``value / limit``;
* tracking, feedthrough, noise, reference effort: the value itself (already a ratio);
* decay rate: required over achieved decay rate, ``decay_rate / (-value)`` (``inf``
  when a pole has ``Re p >= 0``; 0 for ``decay_rate = 0`` and a stable loop);
* damping: required over achieved damping ratio, ``min_damping / value`` (``inf``
  when the achieved ratio is ``<= 0``; 0 for ``min_damping = 0`` or no pole in the band).

The binding constraint is the one with the largest utilisation; ties (typically
several ``inf`` on an unstable member) go to the earlier constraint of
:data:`CONSTRAINTS`, which lists the pole-region constraints first so that an
unstable loop is reported as binding on its decay rate.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence

import control as ct
import numpy as np

from designs.effort import Noise, member_effort, unit_intent
from designs.evaluate import (
    INTENT_FRACTION,
    SUPPRESSION_BAND_HZ,
    TRACKING_BAND_HZ,
    intended_motion,
)
from designs.response import (
    check_weight,
    default_feedthrough_weight,
    default_tracking_weight,
    deviation_checks,
    weight_system,
)
from robust.analysis.loops import closed_loop_poles
from robust.analysis.norms import h2_norm
from robust.analysis.realization import minimal_realization
from robust.analysis.simulation import simulate
from robust.analysis.stability import (
    DAMPING_BAND_HZ,
    damping_in_band,
    poles_stable,
    stability_bound,
)
from robust.checks import (
    FINITE,
    NONNEGATIVE,
    POSITIVE,
    Spec,
    check_int,
    check_scalar,
    check_vector,
    validate_fields,
)
from robust.errors import ModelStructureError, ParameterError
from robust.jsonio import to_jsonable
from robust.model.components import K_PSF_NOMINAL
from robust.model.device import DeviceLimits
from robust.model.loop import BDFTLoop
from uncertainty.region import Region

__all__ = [
    "CONSTRAINTS",
    "Specification",
    "ConstraintCheck",
    "SpecCheck",
    "check_specification",
    "unstable_member_check",
    "rms_force",
    "peak_force",
    "peak_time_grid",
]

#: Names of the constraints, in the order they are reported (ties of the utilisation
#: go to the earlier one).
CONSTRAINTS = (
    "decay rate",
    "damping",
    "peak force",
    "continuous force",
    "tracking",
    "feedthrough",
    "noise",
    "reference effort",
)
#: Frequencies of the design grids below and above :attr:`Specification.split_hz` (the
#: checks are exact at every frequency; designs that optimise on frequencies use these).
N_TRACKING_FREQS = 60
N_FEEDTHROUGH_FREQS = 90
#: Sampling rate of the peak-force simulations, Hz (the device's servo rate).
SIMULATION_RATE_HZ = 1000.0

_BANDS = ("damping_band_hz", "tracking_band_hz", "feedthrough_band_hz")


@dataclasses.dataclass(frozen=True)
class Specification:
    """The handle-force design specification.

    Parameters
    ----------
    peak_force_n : float
        Largest handle force allowed, N (the Omni's peak force, 3.3).
    continuous_force_n : float
        Largest RMS handle force allowed, N (the Omni's continuous force, 0.88).
    intent_fraction : float
        Amplitude of the intended motion, as a fraction of the half-workspace, in (0, 1]
        (default :data:`designs.evaluate.INTENT_FRACTION`).
    intent_bandwidth_hz : float
        Bandwidth of the realistic intended motion (intent filter corner), Hz (2).
    decay_rate : float
        Every closed-loop pole must have real part below ``-decay_rate``, rad/s (>= 0).
    min_damping : float
        Smallest damping ratio of the poles in ``damping_band_hz``, in [0, 1).
    damping_band_hz : (float, float)
        Band of the damping requirement, Hz (poles with ``|Im p| / (2 pi)`` in it).
    tracking_error : float
        Allowed ``|Y/Y_ref - 1|`` through the operator's band (> 0): the level of the
        default tracking weight ``W_t``.
    tracking_band_hz : (float, float)
        The operator's band, Hz (default :data:`designs.evaluate.TRACKING_BAND_HZ`); its top
        is :attr:`split_hz` and places ``W_t``'s corner (an octave above).
    feedthrough_band_hz : (float, float)
        Band of the structure modes, Hz (default
        :data:`designs.evaluate.SUPPRESSION_BAND_HZ`): where the default feedthrough weight
        ``W_f`` asks for the reduction.
    max_amplification_db : float
        Far from the structure band, how much the deviation from the BDFT-free response
        may exceed the uncompensated loop's, dB (1: the compensated loop is nowhere worse
        than doing nothing, to 12 %).
    feedthrough_reduction_db : float
        Required reduction of the feedthrough over ``feedthrough_band_hz`` against the
        uncompensated loop, dB (6: half. The paper's own remedy, doubling the workspace,
        halves the BDFT loop gain; on the nominal member of the default family it lowers the
        feedthrough peak over 5-7.5 Hz from 2.28 to 0.57 of the BDFT-free response, 12 dB. A
        compensator that keeps the workspace is asked for half of that).
    tracking_floor : float
        Allowed ``|Y/Y_ref - 1|`` far above the operator's band where the feedthrough bound
        does not apply (``W_t``'s high-frequency level, 0.02).
    tracking_weight, feedthrough_weight : (num, den) or control system, optional
        The weights themselves, stable and proper rational functions with no zero on the
        imaginary axis (coefficients in descending powers of ``s``); by default
        :func:`default_tracking_weight` and :func:`default_feedthrough_weight` of the fields
        above. Stored as coefficient tuples.
    noise : designs.effort.Noise
        Sensor noise and the operator's remnant.
    noise_cylinder_mm : float
        Largest RMS cylinder position caused by the sensor noise alone, mm of cylinder travel
        (1).
    noise_force_n : float
        Largest RMS handle force caused by the sensor noise alone, N (0.1).
    correction_flow_share : float
        Share of the valve's flow and command range a reference correction may use, in
        (0, 1] (0.5: the rest is the operator's).
    peak_factor : float
        Peaks of the effort are taken as this many RMS values (3: a Gaussian signal exceeds
        it 0.27 % of the time).
    reference_k_psf : float or None
        ``K_PSF`` of the uncompensated loop the feedthrough is compared with (default the
        paper's, 0.1097: every design is judged against the machine as built, so a design
        that enlarges the workspace gets credit for the feedthrough it removes); ``None``:
        each member's own.

    Raises
    ------
    robust.errors.ParameterError
        If a field is out of range; the message names ``Specification.<field>``, the
        accepted range and the value got.
    """

    peak_force_n: float = 3.3
    continuous_force_n: float = 0.88
    intent_fraction: float = INTENT_FRACTION
    intent_bandwidth_hz: float = 2.0
    decay_rate: float = 0.1
    min_damping: float = 0.1
    damping_band_hz: tuple[float, float] = DAMPING_BAND_HZ
    tracking_error: float = 0.2
    tracking_band_hz: tuple[float, float] = TRACKING_BAND_HZ
    feedthrough_band_hz: tuple[float, float] = SUPPRESSION_BAND_HZ
    max_amplification_db: float = 1.0
    feedthrough_reduction_db: float = 6.0
    tracking_floor: float = 0.02
    tracking_weight: tuple | None = None
    feedthrough_weight: tuple | None = None
    noise: Noise = Noise()
    noise_cylinder_mm: float = 1.0
    noise_force_n: float = 0.1
    correction_flow_share: float = 0.5
    peak_factor: float = 3.0
    reference_k_psf: float | None = K_PSF_NOMINAL

    def __post_init__(self):
        validate_fields(
            self,
            {
                "peak_force_n": POSITIVE,
                "continuous_force_n": POSITIVE,
                "intent_fraction": Spec(low=0.0, high=1.0, low_open=True),
                "intent_bandwidth_hz": POSITIVE,
                "decay_rate": NONNEGATIVE,
                "min_damping": Spec(low=0.0, high=1.0, high_open=True),
                "tracking_error": POSITIVE,
                "max_amplification_db": FINITE,
                "feedthrough_reduction_db": FINITE,
                "tracking_floor": POSITIVE,
                "noise_cylinder_mm": POSITIVE,
                "noise_force_n": POSITIVE,
                "correction_flow_share": Spec(low=0.0, high=1.0, low_open=True),
                "peak_factor": POSITIVE,
            },
        )
        if self.reference_k_psf is not None:
            object.__setattr__(
                self,
                "reference_k_psf",
                check_scalar("Specification.reference_k_psf", self.reference_k_psf, POSITIVE),
            )
        if not isinstance(self.noise, Noise):
            raise ParameterError(
                "Specification.noise must be a designs.effort.Noise; "
                f"got {type(self.noise).__name__}"
            )
        for name in _BANDS:
            object.__setattr__(self, name, _band(name, getattr(self, name)))
        if self.tracking_weight is None:
            w = default_tracking_weight(
                self.tracking_error, self.tracking_floor, self.tracking_band_hz[1]
            )
        else:
            w = check_weight("tracking_weight", self.tracking_weight)
        object.__setattr__(self, "tracking_weight", w)
        if self.feedthrough_weight is None:
            w = default_feedthrough_weight(
                self.feedthrough_band_hz, self.feedthrough_reduction_db, self.max_amplification_db
            )
        else:
            w = check_weight("feedthrough_weight", self.feedthrough_weight)
        object.__setattr__(self, "feedthrough_weight", w)
        if not self.tracking_band_hz[1] < self.feedthrough_band_hz[0]:
            raise ParameterError(
                "Specification.tracking_band_hz must lie below feedthrough_band_hz (the two "
                f"checks split the axis between them); got {self.tracking_band_hz} and "
                f"{self.feedthrough_band_hz}"
            )

    @property
    def split_hz(self) -> float:
        """Frequency that splits the intent-response bound between the ``"tracking"`` check
        (up to it) and the ``"feedthrough"`` check (above), Hz: the top of
        ``tracking_band_hz``, the operator's band."""
        return self.tracking_band_hz[1]

    def weight_systems(self) -> tuple[ct.StateSpace, ct.StateSpace]:
        """``(W_t, W_f)`` as python-control state-space systems (module notes)."""
        return weight_system(self.tracking_weight), weight_system(self.feedthrough_weight)

    def deviation_bound(self, omega, r0) -> np.ndarray:
        """The bound on ``|R(jw)|`` at ``omega``: ``|W_t|`` up to :attr:`split_hz`,
        ``max(|W_t|, |W_f R0|)`` above it.

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.
        r0 : array_like of complex
            The uncompensated deviation ``R0(jw) = Y_0/Y_ref - 1`` at ``omega``
            (broadcast against ``omega``'s last axis).
        """
        s = 1j * np.asarray(omega, float)
        wt = np.abs(np.polyval(self.tracking_weight[0], s) / np.polyval(self.tracking_weight[1], s))
        wf = np.abs(
            np.polyval(self.feedthrough_weight[0], s) / np.polyval(self.feedthrough_weight[1], s)
        )
        above = np.asarray(omega, float) > 2 * math.pi * self.split_hz
        # (r0: the deviation of the uncompensated loop at reference_k_psf)
        return np.where(above, np.maximum(wt, wf * np.abs(r0)), wt)

    def region(self) -> Region:
        """The pole region: ``Region(decay_rate, min_damping, damping_band_hz)``."""
        return Region(self.decay_rate, self.min_damping, self.damping_band_hz)

    def limits(self) -> DeviceLimits:
        """Device limits with this specification's two force limits (the others default)."""
        return DeviceLimits(
            peak_force_n=self.peak_force_n, continuous_force_n=self.continuous_force_n
        )

    def check_frequencies_hz(self) -> np.ndarray:
        """The design grid of the intent-response bounds, Hz.

        For designs that optimise or choose on frequencies (the limit map, the scheduled
        damper); the checks themselves (:func:`deviation_checks`) hold at every frequency.

        Returns
        -------
        numpy.ndarray
            :data:`N_TRACKING_FREQS` from 0 Hz, then log-spaced from 0.01 Hz (or a fifth
            of the tracking band's bottom) up to :attr:`split_hz`, then
            :data:`N_FEEDTHROUGH_FREQS` from :attr:`split_hz` up to :data:`GRID_TOP_HZ`,
            log-spaced, with a third of them
            linearly spaced over ``feedthrough_band_hz``; read-only, made once per pair of
            bands.
        """
        return _check_grid(tuple(self.tracking_band_hz), tuple(self.feedthrough_band_hz))

    def to_json(self) -> dict:
        """Every field, JSON-ready (bands as lists)."""
        return to_jsonable(self)


def _band(name: str, value) -> tuple[float, float]:
    label = f"Specification.{name}"
    if isinstance(value, (str, bytes)):
        raise ParameterError(f"{label} must be a pair (low, high) in Hz; got {value!r}")
    arr = check_vector(label, value, POSITIVE, min_size=2, increasing=True)
    if arr.size != 2:
        raise ParameterError(f"{label} must be a pair (low, high) in Hz; got {value!r}")
    return float(arr[0]), float(arr[1])


@dataclasses.dataclass(frozen=True)
class ConstraintCheck:
    """One constraint of the specification, worst over the members.

    Parameters
    ----------
    name : str
        One of :data:`CONSTRAINTS`.
    value : float
        Worst value over the members, in ``units`` (``inf`` where undefined on an
        unstable member; see the module notes for each definition).
    limit : float
        The specification's limit, in ``units`` (for the decay rate the largest real
        part allowed, ``-decay_rate``).
    units : str
        Units of ``value`` and ``limit``.
    holds : bool
        Whether every member meets the constraint.
    worst_member : int
        Index into the members list of the member with the worst value.
    utilisation : float
        1 at the limit, above 1 when violated, increasing as the value gets worse
        (definitions in the module notes).
    frequency_hz : float
        Where the worst member's value is attained, Hz, for the frequency-wise bounds
        (``"tracking"``, ``"feedthrough"``; ``inf`` for the limit at infinite frequency);
        ``nan`` for the others.
    """

    name: str
    value: float
    limit: float
    units: str
    holds: bool
    worst_member: int
    utilisation: float
    frequency_hz: float = math.nan

    def describe(self) -> str:
        """One line: name, value, limit, utilisation, where it binds and verdict."""
        verdict = "holds" if self.holds else "VIOLATED"
        where = f" at {self.frequency_hz:.4g} Hz" if math.isfinite(self.frequency_hz) else ""
        if self.frequency_hz == math.inf:
            where = " at infinite frequency"
        return (
            f"{self.name}: {self.value:.4g} {self.units} (limit {self.limit:.4g}){where}, "
            f"utilisation {self.utilisation:.3g}, member {self.worst_member}: {verdict}"
        )


@dataclasses.dataclass(frozen=True)
class SpecCheck:
    """A controller checked against a :class:`Specification` on a list of members.

    Parameters
    ----------
    constraints : tuple of ConstraintCheck
        One per constraint, in the order of :data:`CONSTRAINTS`.
    members : int
        Number of members checked.
    holds : bool
        Whether every constraint holds.
    binding : str
        Name of the constraint with the largest utilisation (ties to the earlier one).
    notes : tuple of str
        Caveats (undefined metrics on unstable members, ...).
    """

    constraints: tuple[ConstraintCheck, ...]
    members: int
    holds: bool
    binding: str
    notes: tuple[str, ...] = ()

    def constraint(self, name: str) -> ConstraintCheck:
        """The check of the constraint ``name``.

        Parameters
        ----------
        name : str
            One of :data:`CONSTRAINTS`.

        Raises
        ------
        robust.errors.ParameterError
            If there is no such constraint.
        """
        for c in self.constraints:
            if c.name == name:
                return c
        raise ParameterError(
            f"SpecCheck.constraint: name must be one of {[c.name for c in self.constraints]}; "
            f"got {name!r}"
        )

    def to_json(self) -> dict:
        """Every field, JSON-ready (non-finite values as strings)."""
        return to_jsonable(self)


def rms_force(
    loop: BDFTLoop,
    controller,
    amplitude: float,
    bandwidth_hz: float,
    *,
    closed: ct.StateSpace | None = None,
) -> float:
    """Exact stationary RMS handle force under the realistic intended motion, N.

    The motion is white noise through the unit intent filter ``F``
    (:func:`robust.synthesis.forcefb.intent_filter`) scaled to RMS
    ``amplitude / sqrt(2)`` (as :func:`designs.evaluate.intended_motion`), so the RMS
    force is ``amplitude / sqrt(2) * ||G_f F||_2 / ||F||_2`` with ``G_f`` the
    closed-loop ``u -> f`` (a minimal realisation); the H2 norms come from the
    controllability Gramian (:func:`scipy.linalg.solve_continuous_lyapunov`).

    Parameters
    ----------
    loop : BDFTLoop
        One member (physical human when ``controller`` drives ``f``).
    controller : control.StateSpace or None
        The compensator; without a force output ``f`` the force is 0.
    amplitude : float
        Intended-motion amplitude, handle units.
    bandwidth_hz : float
        Bandwidth of the intended motion, Hz.
    closed : control.StateSpace, optional
        ``loop.system(bdft=True, controller=controller)`` when the caller has built it
        already (its ``u -> f`` channel is used; it is not built again).

    Returns
    -------
    float
        The RMS force, N (``inf`` if ``G_f F`` is not stable).

    Raises
    ------
    robust.errors.ParameterError
        If ``loop`` is not a BDFTLoop, or ``amplitude`` or ``bandwidth_hz`` is not
        finite and positive.
    """
    if not isinstance(loop, BDFTLoop):
        raise ParameterError(f"rms_force: loop must be a BDFTLoop; got {type(loop).__name__}")
    amplitude = check_scalar("rms_force: amplitude", amplitude, POSITIVE)
    bandwidth_hz = check_scalar("rms_force: bandwidth_hz", bandwidth_hz, POSITIVE)
    if controller is None or "f" not in controller.output_labels:
        return 0.0
    sys = closed if closed is not None else loop.system(bdft=True, controller=controller)
    iu, jf = sys.input_labels.index("u"), sys.output_labels.index("f")
    g = minimal_realization(sys.A, sys.B[:, [iu]], sys.C[[jf]], sys.D[[jf]][:, [iu]])
    Af, Bf, Cf, norm_f = unit_intent(bandwidth_hz)
    n, nf = g.A.shape[0], Af.shape[0]
    # cascade F then G_f: states (x_g, x_f); strictly proper since F is
    A = np.block([[g.A, g.B @ Cf], [np.zeros((nf, n)), Af]])
    B = np.vstack([np.zeros((n, 1)), Bf])
    C = np.hstack([g.C, g.D @ Cf])
    if not poles_stable(np.linalg.eigvals(A)):
        return math.inf
    ratio = h2_norm(A, B, C) / norm_f
    return amplitude / math.sqrt(2.0) * ratio


def peak_force(
    loop: BDFTLoop, controller, amplitude: float, bandwidth_hz: float, t, *, seed: int
) -> float:
    """Largest ``|f|`` of one simulated realistic intended motion, N.

    The motion is :func:`designs.evaluate.intended_motion` (``amplitude``,
    ``bandwidth_hz``, ``seed``) on the time grid ``t``; ``inf`` when the simulated force
    is not finite. The loop must be stable (the caller checks).

    Parameters
    ----------
    loop : BDFTLoop
        The member.
    controller : control.StateSpace
        The compensator (it drives ``f``).
    amplitude : float
        Intended-motion amplitude, handle units.
    bandwidth_hz : float
        Bandwidth of the intended motion, Hz.
    t : ndarray
        Time grid, s (:func:`peak_time_grid`).
    seed : int
        Seed of the intended motion.
    """
    u = intended_motion(t, amplitude, bandwidth_hz, seed=seed)
    f = simulate(loop, t, u, controller=controller)["f"]
    return float(np.max(np.abs(f))) if np.all(np.isfinite(f)) else math.inf


def peak_time_grid(duration_s: float) -> np.ndarray:
    """Time grid of the peak-force simulations: ``duration_s`` at :data:`SIMULATION_RATE_HZ`.

    Parameters
    ----------
    duration_s : float
        Length, s.
    """
    return np.arange(int(round(duration_s * SIMULATION_RATE_HZ)) + 1) / SIMULATION_RATE_HZ


def _ratio_required(required: float, achieved: float) -> float:
    """``required / achieved`` for a larger-is-better figure (``inf`` when achieved <= 0)."""
    if required == 0.0 and achieved > 0:
        return 0.0
    if not achieved > 0:
        return math.inf
    return required / achieved


def _worst(values: list[float], larger_is_worse: bool = True) -> tuple[float, int]:
    v = np.asarray(values, float)
    i = int(np.argmax(v) if larger_is_worse else np.argmin(v))
    return float(v[i]), i


def check_specification(
    members: Sequence[BDFTLoop],
    controller=None,
    spec: Specification | None = None,
    *,
    seed: int = 0,
    simulate_peak: int = 3,
    duration_s: float = 20.0,
) -> SpecCheck:
    """Check ``controller`` against ``spec`` on ``members``; name the binding constraint.

    Definitions of the constraints, of their values and utilisations are in the
    module notes. The feedthrough is compared with the uncompensated loop's formal
    frequency response, even where that loop is unstable.

    Parameters
    ----------
    members : sequence of BDFTLoop
        Family members (e.g. ``family.member(row)``); a physical human when the
        controller drives the handle force.
    controller : control.StateSpace or None
        Compensator in the loop convention (inputs among ``x, c, y``; outputs among
        ``f, r_corr``); ``None`` checks the loop alone.
    spec : Specification, optional
        The specification (default: :class:`Specification` ``()``).
    seed : int
        Seed of the simulated intended motion; member ``i`` gets ``seed + i``.
    simulate_peak : int
        Number of stable members (those with the largest RMS force) whose peak force
        is simulated (>= 0; 0 leaves the peak force at 0).
    duration_s : float
        Length of each peak-force simulation, s (>= 0.001).

    Returns
    -------
    SpecCheck

    Raises
    ------
    robust.errors.ParameterError
        If ``members`` is empty or not a sequence of BDFTLoop, ``spec`` is not a
        Specification, or ``seed``, ``simulate_peak`` or ``duration_s`` is out of range.
    robust.errors.ModelStructureError
        If ``controller`` does not fit the loop convention
        (:meth:`robust.model.loop.BDFTLoop.system`).
    """
    where = "check_specification"
    if isinstance(members, BDFTLoop) or not isinstance(members, Sequence):
        raise ParameterError(
            f"{where}: members must be a sequence of BDFTLoop; got {type(members).__name__}"
        )
    members = list(members)
    if not members:
        raise ParameterError(f"{where}: members must hold at least one BDFTLoop; got none")
    for i, m in enumerate(members):
        if not isinstance(m, BDFTLoop):
            raise ParameterError(
                f"{where}: members[{i}] must be a BDFTLoop; got {type(m).__name__}"
            )
    if spec is None:
        spec = Specification()
    elif not isinstance(spec, Specification):
        raise ParameterError(
            f"{where}: spec must be a Specification or None; got {type(spec).__name__}"
        )
    seed = check_int("seed", seed, low=0, owner=where)
    simulate_peak = check_int("simulate_peak", simulate_peak, low=0, owner=where)
    duration_s = check_scalar(f"{where}.duration_s", duration_s, Spec(low=1e-3))
    if controller is not None and not isinstance(controller, ct.StateSpace):
        raise ModelStructureError(
            f"{where}: controller must be a control.StateSpace or None; "
            f"got {type(controller).__name__}"
        )
    has_force = controller is not None and "f" in controller.output_labels
    limits = spec.limits()

    n = len(members)
    max_real, damping = np.empty(n), np.empty(n)
    stable = np.zeros(n, bool)
    tracking, amplification = np.full(n, math.inf), np.full(n, math.inf)
    rms = np.full(n, math.inf) if has_force else np.zeros(n)
    amplitude = np.zeros(n)
    freqs = np.full((2, n), math.nan)
    noise, effort = np.full(n, math.inf), np.full(n, math.inf)
    for i, m in enumerate(members):
        # one closed loop per member gives its poles and its output ratio on both grids
        closed = m.system(bdft=True, controller=controller)
        ps = closed_loop_poles(closed)
        max_real[i] = ps.max_real
        damping[i] = float(damping_in_band(ps.poles, spec.damping_band_hz))
        stable[i] = ps.stable
        if not stable[i]:
            continue
        tr, fb = deviation_checks(m, spec, closed=closed)
        tracking[i], freqs[0, i] = tr.value, tr.frequency_hz
        amplification[i], freqs[1, i] = fb.value, fb.frequency_hz
        amplitude[i] = m.intended_amplitude(limits, spec.intent_fraction)
        rms_f, noise[i], effort[i] = member_effort(m, controller, spec, amplitude[i])
        if has_force:
            rms[i] = rms_f

    notes = []
    if not stable.all():
        notes.append(_unstable_note(np.flatnonzero(~stable).tolist(), n, has_force))
    # peak force: inf on unstable members, simulated on the stable ones of largest RMS force
    peak = np.where(stable, 0.0, math.inf) if has_force else np.zeros(n)
    if has_force:
        order = [int(i) for i in np.argsort(-rms, kind="stable") if stable[i]]
        simulated = order[:simulate_peak]
        t = peak_time_grid(duration_s)
        for i in simulated:
            peak[i] = peak_force(
                members[i], controller, amplitude[i], spec.intent_bandwidth_hz, t, seed=seed + i
            )
        if stable.any() and simulate_peak < int(stable.sum()):
            notes.append(
                f"peak force simulated on the {len(simulated)} stable members with the "
                f"largest RMS force (members {simulated}), "
                f"{duration_s:g} s each"
            )
    return _spec_check(
        spec, max_real, damping, peak, rms, tracking, amplification, notes, freqs, noise, effort
    )


#: Top of the design grids, Hz (the checks themselves have no top).
GRID_TOP_HZ = 1000.0


@functools.lru_cache(maxsize=16)
def _check_grid(tracking_band_hz: tuple, feedthrough_band_hz: tuple) -> np.ndarray:
    """:meth:`Specification.check_frequencies_hz` of a pair of bands."""
    split = tracking_band_hz[1]
    # from DC (where the deviation of a loop with integral action is decided) up to the split
    lo = min(0.01, tracking_band_hz[0] / 5)
    ft = np.concatenate([[0.0], np.geomspace(lo, split, N_TRACKING_FREQS - 1, endpoint=False)])
    n_band = N_FEEDTHROUGH_FREQS // 3
    fb = np.sort(
        np.concatenate(
            [
                np.geomspace(split, GRID_TOP_HZ, N_FEEDTHROUGH_FREQS - n_band),
                np.linspace(*feedthrough_band_hz, n_band),
            ]
        )
    )
    grid = np.concatenate([ft, fb])
    grid.setflags(write=False)
    return grid


def _unstable_note(bad: list, n: int, has_force: bool) -> str:
    undefined = "tracking, feedthrough and forces" if has_force else "tracking and feedthrough"
    return (
        f"{len(bad)} of {n} members have an unstable closed loop (members {bad}): "
        f"their {undefined} are undefined (inf)"
    )


def unstable_member_check(
    max_real: float, damping: float, spec: Specification, has_force: bool
) -> SpecCheck:
    """What :func:`check_specification` gives for one member whose closed loop is unstable.

    On an unstable member only the poles are defined: tracking, feedthrough and (with a
    handle force) the forces are ``inf``. A caller that knows the member is unstable from
    its poles (``max_real`` at or above :func:`robust.analysis.stability.stability_bound`)
    gets the same checks without building the member's loop.

    Parameters
    ----------
    max_real : float
        Largest real part of the member's closed-loop poles, rad/s (unstable).
    damping : float
        Smallest damping ratio of its poles in ``spec.damping_band_hz`` (``inf`` if none).
    spec : Specification
        The specification.
    has_force : bool
        Whether the controller drives the handle force.

    Returns
    -------
    SpecCheck

    Raises
    ------
    robust.errors.ParameterError
        If ``max_real`` is below the stability bound (the member is stable).
    """
    if not max_real >= stability_bound(0.0):
        raise ParameterError(
            f"unstable_member_check: max_real must be at or above the stability bound "
            f"{stability_bound(0.0):g} rad/s (an unstable member); got {max_real!r}"
        )
    inf = np.array([math.inf])
    force = inf if has_force else np.zeros(1)
    return _spec_check(
        spec,
        np.array([float(max_real)]),
        np.array([float(damping)]),
        force,
        force,
        inf,
        inf,
        [_unstable_note([0], 1, has_force)],
    )


def _spec_check(
    spec,
    max_real,
    damping,
    peak,
    rms,
    tracking,
    amplification,
    notes,
    freqs=None,
    noise=None,
    effort=None,
) -> SpecCheck:
    """The :class:`SpecCheck` of the members' figures (see :func:`check_specification`)."""
    checks = []
    a = spec.decay_rate
    value, worst = _worst(max_real)
    checks.append(
        ConstraintCheck(
            "decay rate",
            value,
            -a,
            "rad/s",
            poles_stable([value], margin=a),
            worst,
            _ratio_required(a, -value) if value < stability_bound(0.0) else math.inf,
        )
    )
    z = spec.min_damping
    value, worst = _worst(damping, larger_is_worse=False)
    checks.append(
        ConstraintCheck("damping", value, z, "", bool(value >= z), worst, _ratio_required(z, value))
    )
    for name, vals, limit, units in (
        ("peak force", peak, spec.peak_force_n, "N"),
        ("continuous force", rms, spec.continuous_force_n, "N"),
    ):
        value, worst = _worst(vals)
        checks.append(
            ConstraintCheck(name, value, limit, units, bool(value <= limit), worst, value / limit)
        )
    if freqs is None:
        freqs = np.full((2, len(max_real)), math.nan)
    for k, (name, vals) in enumerate((("tracking", tracking), ("feedthrough", amplification))):
        value, worst = _worst(vals)
        checks.append(
            ConstraintCheck(
                name,
                value,
                1.0,
                "x bound",
                bool(value <= 1.0),
                worst,
                value,
                float(freqs[k, worst]),
            )
        )
    n = len(max_real)
    for name, vals in (("noise", noise), ("reference effort", effort)):
        vals = np.full(n, math.inf) if vals is None else vals
        value, worst = _worst(vals)
        checks.append(
            ConstraintCheck(name, value, 1.0, "x limit", bool(value <= 1.0), worst, value)
        )
    util = [c.utilisation for c in checks]
    binding = checks[int(np.argmax(util))].name
    return SpecCheck(
        constraints=tuple(checks),
        members=len(max_real),
        holds=all(c.holds for c in checks),
        binding=binding,
        notes=tuple(notes),
    )
