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
    Largest real part of the closed-loop poles (:func:`backhoe.analysis.loops.loop_poles`),
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
    valve's command range (:class:`backhoe.model.components.HydraulicLimits`); holds at
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
import math
from collections.abc import Sequence

import control as ct
import numpy as np

from backhoe.model.loop import BDFTLoop
from designs.effort import member_effort
from designs.response import deviation_checks
from designs.spec_forces import peak_force, peak_time_grid, rms_force
from designs.specification import CONSTRAINTS, Specification
from robust.analysis.loops import closed_loop_poles
from robust.analysis.stability import damping_in_band, poles_stable, stability_bound
from robust.checks import Spec, check_int, check_scalar
from robust.errors import ModelStructureError, ParameterError
from robust.jsonio import to_jsonable

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
        (:meth:`backhoe.model.loop.BDFTLoop.system`).
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
        rms_f, noise[i], effort[i] = member_effort(m, controller, spec, amplitude[i], checked=True)
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
