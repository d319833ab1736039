"""The per-operator design: the identified human's cancellation plus a damper of the
identified cab's less damped mode.

:func:`cab_damper` is the band-pass from the cab accelerometer to the cylinder reference;
:func:`damped_cancellation` (step 3 of :mod:`designs.scheduled`) picks its phase and gain
among :data:`DAMPER_PHASES` x :data:`DAMPER_GAINS` (or none) by the smallest largest
utilisation on the identified member, the candidates' closed loops evaluated together in
numpy (open loop, damper states, poles and utilisations); :func:`member_valve` gives a
member's own valve, which the machine's rig knows.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import control as ct
import numpy as np

from backhoe.model.blocks import VALVE_FIELDS, block_of, parameter_name
from backhoe.model.components import ValveCylinderParams, realise_siso
from backhoe.model.wiring import connect
from designs.calibration import IDENTIFIED, operator_row
from designs.scheduled_bank import _cancellations
from designs.specification import N_TRACKING_FREQS, Specification
from robust.analysis.loops import resolvent_times
from robust.analysis.small_eig import eigvals_stack
from robust.analysis.stability import damping_in_band, stability_bound
from robust.errors import ModelStructureError, ParameterError

__all__ = [
    "DAMPER_PHASES",
    "DAMPER_GAINS",
    "TIE_RTOL",
    "cab_damper",
    "member_valve",
    "damped_cancellation",
]


#: Candidates of the cab damper: phase shifts at the cab's mode (rad) and loop gains there
#: (as fractions of 1 / |c / r_corr| at that frequency); gain 0 is the plain cancellation.
DAMPER_PHASES = tuple(float(x) for x in np.linspace(-0.95 * math.pi, 0.95 * math.pi, 12))


DAMPER_GAINS = (0.05, 0.1, 0.2, 0.4)

#: Relative difference of utilisation below which two candidates count as equally good.
TIE_RTOL = 1e-6


def cab_damper(f_hz: float, gain: float, phase: float) -> ct.StateSpace:
    """A band-pass from the cab accelerometer to the reference, phase-shifted at ``f_hz``.

    ``gain * s 2 zeta w / (s^2 + 2 zeta w s + w^2)`` (``zeta = 0.5``: unit gain and zero
    phase at ``w = 2 pi f_hz``) times a first-order all-pass ``(a - s) / (a + s)`` with
    ``a = w / tan(|phase| / 2)`` (phase ``-|phase|`` at ``w``), negated for a positive
    ``phase`` (``pi - |phase|``).

    Parameters
    ----------
    f_hz : float
        The cab mode's natural frequency, Hz.
    gain : float
        Gain at ``f_hz`` (reference units per cab acceleration unit).
    phase : float
        Phase shift at ``f_hz``, rad, in (-pi, pi).
    """
    w = 2 * math.pi * float(f_hz)
    num, den = np.array([gain * w, 0.0]), np.array([1.0, w, w * w])
    if abs(phase) > 1e-9:
        a = w / math.tan(abs(phase) / 2)
        # the coefficients python-control's product of the two transfer functions has (and
        # its realisation below): the certified margins over a damped cancellation depend on
        # the controller's coordinates, so they are the same as ever; the products of
        # python-control's objects and their conversion took six times as long
        num, den = np.polymul(num, [-1.0, a]), np.polymul(den, [1.0, a])
        if phase > 0:
            num = num * -1.0
    return ct.ss(*realise_siso(num, den))


def _cab_names(cab: dict) -> dict:
    """The family's parameter carrying each identified cab quantity: the less damped mode
    as the structure's first (where :func:`damped_cancellation` puts its damper)."""
    d, o = ("low", "high") if cab["zeta_cab_low"] <= cab["zeta_cab_high"] else ("high", "low")
    return {
        parameter_name("structure", "k_s"): "k_s",
        parameter_name("structure", "f1_hz"): f"f_cab_{d}_hz",
        parameter_name("structure", "zeta1"): f"zeta_cab_{d}",
        parameter_name("structure", "f2_hz"): f"f_cab_{o}_hz",
        parameter_name("structure", "zeta2"): f"zeta_cab_{o}",
    }


def _valve_params(valve) -> ValveCylinderParams:
    """``ValveCylinderParams`` of a row of :data:`VALVE_FIELDS` values."""
    v = np.asarray(valve, float).reshape(-1)
    if v.shape != (len(VALVE_FIELDS),):
        raise ParameterError(
            f"valve must hold {len(VALVE_FIELDS)} values {VALVE_FIELDS}; got {valve!r}"
        )
    return ValveCylinderParams(**{f: float(x) for f, x in zip(VALVE_FIELDS, v)})


def calibration_box(family, where: dict, valve, name: str):
    """The family a calibration leaves: ``where``'s parameters within their bounds.

    Parameters
    ----------
    family : backhoe.Family
    where : dict
        Parameter name -> ``(estimate, (low, high))``; the estimate becomes the nominal
        (clipped into the bounds, the lower bound at least 1e-3), the distribution uniform
        over the bounds (``std`` dropped). Parameters not named keep the family's ranges.
    valve : array_like
        The machine's own valve/cylinder (:data:`VALVE_FIELDS`), which its rig knows: the
        valve's parameters leave the family.
    name : str
        The new family's name.

    Returns
    -------
    backhoe.Family
    """
    params = []
    for p in family.parameters:
        if block_of(p.name) == "valve":  # the machine's own valve, which the rig knows
            continue
        if p.name not in where:
            params.append(p)
            continue
        v, (lo, hi) = where[p.name]
        lo, hi = max(float(lo), 1e-3), float(hi)
        nominal = min(max(float(v), lo), hi)
        params.append(dataclasses.replace(p, nominal=nominal, low=lo, high=hi, std=None))
    return family.replace(parameters=tuple(params), valve=_valve_params(valve), name=name)


def member_valve(family, row) -> np.ndarray:
    """The valve/cylinder of the member ``row`` of ``family`` (:data:`VALVE_FIELDS` values;
    the family's nominal for a parameter it does not vary).

    Parameters
    ----------
    family : backhoe.Family
    row : array_like, shape (d,)
        The member's values (``family.names`` order).
    """
    a = family.model_arrays(np.atleast_2d(np.asarray(row, float)), check_bounds=False)
    return np.array([a[parameter_name("valve", f)][0] for f in VALVE_FIELDS])


def _identified_row(family, human: dict, cab: dict) -> np.ndarray:
    row = operator_row(family, human)
    for name, key in _cab_names(cab).items():
        if name in family.names:
            row[family.names.index(name)] = cab[key]
    return row


@dataclasses.dataclass(frozen=True)
class _OpenLoop:
    """One member's loop opened at the cylinder-reference correction (numpy)."""

    A: np.ndarray  # loop states
    Br: np.ndarray  # r_corr -> states
    Cc: np.ndarray  # states -> c (the cab acceleration)
    G: np.ndarray  # (n_freq, 2, 2): [y, c] / [u, r_corr] at the grid
    y_ref: np.ndarray  # y / u without BDFT at the grid
    n_track: int  # the first n_track frequencies are the tracking grid
    bound: np.ndarray  # the specification's bound on |Y/Y_ref - 1| at the grid


def _spec_grid(spec: Specification) -> tuple[np.ndarray, int]:
    return 2j * math.pi * spec.check_frequencies_hz(), N_TRACKING_FREQS


def _freq_resp(A, B, C, D, s) -> np.ndarray:
    return C @ resolvent_times(A, s.imag, B) + D


def _open_loop(loop, spec: Specification) -> _OpenLoop:
    """:class:`_OpenLoop` of ``loop`` on the specification's tracking and feedthrough grids."""
    P = connect(
        loop.blocks(bdft=True, reference_correction=True),
        inputs=["u", "r_corr"],
        outputs=["y", "c"],
        name="open_at_r_corr",
        ignore_inputs=["human.f"] if loop.human.has_force_port else (),
    )
    A, B, C, D = (np.asarray(m, float) for m in (P.A, P.B, P.C, P.D))
    if np.any(D[1, 1] != 0):  # pragma: no cover - the loop has no direct r_corr -> c path
        raise ModelStructureError("damped_cancellation: the loop has a direct r_corr -> c path")
    R = loop.system(bdft=False, outputs=["y"])
    s, nt = _spec_grid(spec)
    G = _freq_resp(A, B, C, D, s)
    y_ref = _freq_resp(*(np.asarray(m, float) for m in (R.A, R.B, R.C, R.D)), s)[:, 0, 0]
    bound = spec.deviation_bound(s.imag, G[:, 0, 0] / y_ref - 1.0)
    return _OpenLoop(A, B[:, [1]], C[[1]], G, y_ref, nt, bound)


def _damper_states(w: float, gain, phase) -> tuple:
    """Batched :func:`cab_damper` realisations (3 states each; ``phase`` never 0)."""
    gain, phase = np.asarray(gain, float), np.asarray(phase, float)
    n = gain.size
    a = w / np.tan(np.abs(phase) / 2)
    sign = np.where(phase > 0, -1.0, 1.0)
    A = np.zeros((n, 3, 3))
    A[:, 0, 1] = 1.0
    A[:, 1, 0] = -w * w
    A[:, 1, 1] = -w
    A[:, 2, 1] = gain * w  # the band-pass output drives the all-pass
    A[:, 2, 2] = -a
    B = np.zeros((n, 3, 1))
    B[:, 1, 0] = 1.0
    C = np.zeros((n, 1, 3))
    C[:, 0, 1] = -sign * gain * w
    C[:, 0, 2] = sign * 2 * a
    return A, B, C


def _damper_response(w: float, gain, phase, s) -> np.ndarray:
    """:func:`cab_damper` at ``s``, shape ``(n_candidates, n_freq)``."""
    gain, phase = np.asarray(gain, float)[:, None], np.asarray(phase, float)[:, None]
    a = w / np.tan(np.abs(phase) / 2)
    sign = np.where(phase > 0, -1.0, 1.0)
    return sign * gain * w * s / (s * s + w * s + w * w) * (a - s) / (a + s)


def _closed_loop_poles(ol: _OpenLoop, Kc, w: float, gain, phase) -> np.ndarray:
    """Poles of ``ol`` closed by ``Kc`` plus :func:`cab_damper` ``(w, gain, phase)``, per candidate.

    Every candidate's realisation is minimal up to the cancellation's own modes, which are
    the same in each; without a damper (every gain 0) one candidate, without its states.
    The stack's eigenvalues come from :func:`robust.analysis.small_eig.eigvals_stack` (half
    the time of LAPACK's one by one); the choice among the candidates does not hinge on
    their last digits (ties within :data:`TIE_RTOL`).
    """
    Ak, Bk, Ck, Dk = (np.asarray(m, float) for m in (Kc.A, Kc.B, Kc.C, Kc.D))
    Ad, Bd, Cd = _damper_states(w, gain, phase)
    n_c, n, nk = Ad.shape[0], ol.A.shape[0], Ak.shape[0]
    if not np.any(gain):  # the cancellation alone: no damper states
        Ad, Bd, Cd = Ad[:, :0, :0], Bd[:, :0], Cd[:, :, :0]
    N = n + nk + Ad.shape[1]
    A = np.zeros((n_c, N, N))
    A[:, :n, :n] = ol.A + ol.Br @ Dk @ ol.Cc
    A[:, :n, n : n + nk] = ol.Br @ Ck
    A[:, :n, n + nk :] = ol.Br @ Cd
    A[:, n : n + nk, :n] = Bk @ ol.Cc
    A[:, n : n + nk, n : n + nk] = Ak
    A[:, n + nk :, :n] = Bd @ ol.Cc
    A[:, n + nk :, n + nk :] = Ad
    return eigvals_stack(A)


def _utilisations(ol: _OpenLoop, spec: Specification, Kc, w: float, gain, phase) -> np.ndarray:
    """Utilisations of decay rate, damping, tracking and feedthrough per damper candidate.

    The closed loop of ``ol`` with ``Kc`` plus :func:`cab_damper` ``(w, gain, phase)`` per
    candidate, evaluated as :func:`designs.spec.check_specification` defines the four
    constraints, batched in numpy (:func:`_closed_loop_poles`).

    Returns
    -------
    numpy.ndarray, shape (n_candidates, 4)
    """
    Ak, Bk, Ck, Dk = (np.asarray(m, float) for m in (Kc.A, Kc.B, Kc.C, Kc.D))
    p = _closed_loop_poles(ol, Kc, w, gain, phase)
    n_c = p.shape[0]
    s, nt = _spec_grid(spec)
    Kf = _freq_resp(Ak, Bk, Ck, Dk, s)[:, 0, 0] + _damper_response(w, gain, phase, s)
    if not np.any(gain):
        Kf = Kf[:1]
    G = ol.G
    y = G[:, 0, 0] + G[:, 0, 1] * Kf * G[:, 1, 0] / (1.0 - G[:, 1, 1] * Kf)
    ratio = y / ol.y_ref
    out = np.full((n_c, 4), math.inf)
    max_real = p.real.max(axis=1)
    stable = max_real < stability_bound(0.0)
    out[stable, 0] = spec.decay_rate / -max_real[stable]
    zeta = damping_in_band(p, spec.damping_band_hz)
    out[:, 1] = np.where(zeta > 0, spec.min_damping / np.where(zeta > 0, zeta, 1.0), math.inf)
    out[:, 1] = np.where(np.isinf(zeta), 0.0, out[:, 1])
    util = np.abs(ratio - 1.0) / ol.bound
    trk, feed = util[:, :nt].max(axis=1), util[:, nt:].max(axis=1)
    out[stable, 2] = trk[stable]
    out[stable, 3] = feed[stable]
    return out


def damped_cancellation(family, human: dict, cab: dict, spec=None, *, valve=None) -> ct.StateSpace:
    """The cancellation of the identified human plus a damper of the identified cab's mode.

    The member the calibration identified (human and cab, masses nominal) is built; the
    damper acts at the cab's less damped mode (:func:`cab_damper`); its phase and gain are
    the candidates (:data:`DAMPER_PHASES` x :data:`DAMPER_GAINS`, and no damper) with the
    smallest largest utilisation of decay rate, damping, tracking and feedthrough on that
    identified member (as :func:`designs.spec.check_specification` defines them, evaluated
    for every candidate at once on the loop opened at the reference correction): a design
    made at the calibration, from the record alone.

    Parameters
    ----------
    family : backhoe.Family
    human : dict
        :data:`designs.calibration.IDENTIFIED` -> estimate.
    cab : dict
        :data:`designs.calibration.CAB_IDENTIFIED` -> estimate.
    spec : Specification, optional
    valve : array_like, optional
        The machine's valve/cylinder (:data:`VALVE_FIELDS`; :attr:`Calibrations.valves`),
        which its rig knows; the family's nominal valve when omitted.
    """
    spec = spec or Specification()
    c = _damper_candidates(family, human, cab, spec, valve)
    util = _utilisations(c.open_loop, spec, c.cancellation, c.w, c.gain, c.phase).max(axis=1)
    plain = _utilisations(c.open_loop, spec, c.cancellation, c.w, [0.0], [1.0]).max(axis=1)[0]
    # candidates within TIE_RTOL of each other are equally good on the identified member
    # (the damper leaves the binding constraint where it is): the plain cancellation is
    # kept unless a damper lowers the utilisation by more, else the first of the best,
    # so that rounding at 1e-8 does not pick the design
    Kc = c.cancellation
    if not util.min() < plain * (1.0 - TIE_RTOL):
        return Kc
    k = int(np.flatnonzero(util <= util.min() * (1.0 + TIE_RTOL))[0])
    K = ct.parallel(
        ct.ss(Kc.A, Kc.B, Kc.C, Kc.D),
        cab_damper(c.w / (2 * math.pi), float(c.gain[k]), float(c.phase[k])),
    )
    return ct.ss(K.A, K.B, K.C, K.D, inputs="c", outputs="r_corr", name="damped_cancellation")


@dataclasses.dataclass(frozen=True)
class _Candidates:
    open_loop: _OpenLoop  # the identified member, opened at r_corr
    cancellation: ct.StateSpace  # the identified human's cancellation
    w: float  # the damper's frequency, rad/s
    gain: np.ndarray  # per candidate, reference units per cab acceleration unit
    phase: np.ndarray  # per candidate, rad


def _damper_candidates(
    family, human: dict, cab: dict, spec: Specification, valve=None
) -> _Candidates:
    """The identified member's open loop, its cancellation and the damper candidates."""
    hat = family.member(_identified_row(family, human, cab), check_bounds=False)
    if valve is not None:
        hat = hat.replace(valve=_valve_params(valve))
    Kc = _cancellations(family, np.array([[human[k] for k in IDENTIFIED]]))[0]
    w = 2 * math.pi * hat.struct.f1_hz
    P = connect(
        hat.blocks(bdft=False, reference_correction=True) + [hat.structure_system()],
        inputs=["u", "r_corr"],
        outputs=["c"],
        name="cab",
    )
    scale = 1.0 / abs(complex(P(1j * w)[0, 1]))
    phase, gain = (np.array(x, float) for x in zip(*itertools.product(DAMPER_PHASES, DAMPER_GAINS)))
    return _Candidates(_open_loop(hat, spec), Kc, w, gain * scale, phase)
