"""A member's plant for the achievable-limit map: its open loop, the Youla plant of an
actuator set, its gains, observers and sensor noise.

What :mod:`designs.limit` solves on, for one member: the balanced open loop, the
specification's bounds and design grids, the stabilising gain and the observer of a set
(each kept for the member's sets), the measurements' noise (:func:`sensor_noise`: the
encoder's quantisation, :data:`ENCODER_MM`, and the accelerometer's,
:data:`ACCEL_NOISE_RMS`) and the peak force of a simulated intended motion. Apart from the
optimisation that uses them.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.linalg as sla
import scipy.signal as sig

from backhoe.analysis.simulation import lifted_response
from backhoe.model.wiring import connect
from designs.effort import Noise, sensor_intensities
from designs.evaluate import intended_motion
from designs.response import deviation_maps
from designs.spec_forces import peak_time_grid
from designs.specification import N_TRACKING_FREQS, Specification
from robust.analysis.bounds import siso_response
from robust.errors import ModelStructureError, ParameterError
from robust.synthesis.stabilising import stabilising_gain
from robust.synthesis.youla import Measurements, YoulaPlant, observer_gain

__all__ = ["ENCODER_MM", "ACCEL_NOISE_RMS", "sensor_noise"]


#: Encoder resolution, mm (the Omni's): quantisation noise of the handle position.
ENCODER_MM = 0.055

#: Accelerometer noise RMS at the 1 kHz servo rate, in the paper's units of ``c`` (the
#: force-feedback synthesis' default accelerometer weight, :mod:`backhoe.synthesis.forcefb`).
ACCEL_NOISE_RMS = 0.05


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
    loop : backhoe.model.loop.BDFTLoop
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
