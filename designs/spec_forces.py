"""The handle forces the specification bounds: the exact stationary RMS force and the peak
force of one simulated intended motion.

:func:`rms_force` (an H2 norm of the closed loop ``u -> f`` through the intent filter) and
:func:`peak_force` (a simulation on :func:`peak_time_grid`, at the device's servo rate) are
the two measures behind the continuous and peak force constraints of
:func:`designs.spec.check_specification`; the coverage certificates and the achievable-limit
map use the same grid. They are measurements on one loop, apart from the specification's
parameters (:mod:`designs.specification`) and from its check (:mod:`designs.spec`).
"""

from __future__ import annotations

import math

import control as ct
import numpy as np

from backhoe.analysis.simulation import simulate
from backhoe.model.loop import BDFTLoop
from designs.effort import unit_intent
from designs.evaluate import intended_motion
from robust.analysis.norms import h2_norm
from robust.analysis.realization import minimal_realization
from robust.analysis.stability import poles_stable
from robust.checks import POSITIVE, check_scalar
from robust.errors import ParameterError

__all__ = ["rms_force", "peak_force", "peak_time_grid"]


#: Sampling rate of the peak-force simulations, Hz (the device's servo rate).
SIMULATION_RATE_HZ = 1000.0


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
    (:func:`backhoe.synthesis.forcefb.intent_filter`) scaled to RMS
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
