"""The Figure 5 loop's poles, BDFT ratio, loop gain and critical gain, and controllers
reduced against a set of loops.

Poles are those of a minimal realisation of the interconnection
(:func:`robust.analysis.loops.closed_loop_poles`); modes removed because they are
uncontrollable or unobservable (the exact s^2 cancellation between Eqns 4 and 5 with the
literal human) are kept and reported as *hidden modes*, never silently dropped.
"""

from __future__ import annotations

import control as ct
import numpy as np

from backhoe.model.components import pi_controller, structure, valve_cylinder
from backhoe.model.loop import BDFTLoop
from robust.analysis.loops import (
    PoleSet,
    closed_loop_poles,
    frequency_response,
)
from robust.analysis.norms import hinf_norm
from robust.analysis.reduction import balanced_truncation
from robust.analysis.stability import poles_stable
from robust.checks import (
    NONNEGATIVE,
    POSITIVE,
    Spec,
    check_int,
    check_scalar,
    check_state_space,
    check_vector,
)
from robust.errors import ModelStructureError, ParameterError

__all__ = [
    "loop_poles",
    "bdft_ratio",
    "critical_k_psf",
    "bdft_loop_gain",
    "reduce_controller",
]


def _check_loop(where: str, loop) -> None:
    if not isinstance(loop, BDFTLoop):
        raise ParameterError(f"{where}: loop must be a BDFTLoop; got {type(loop).__name__}")


def loop_poles(loop: BDFTLoop, *, bdft: bool = True, controller=None) -> PoleSet:
    """Closed-loop poles of the Figure 5 loop (minimal realisation, all inputs and outputs).

    Parameters
    ----------
    loop : BDFTLoop
        The loop.
    bdft : bool
        With the feedthrough path.
    controller : control.StateSpace, optional
        Compensator in the loop's convention.

    Raises
    ------
    ParameterError
        If ``loop`` is not a :class:`~backhoe.model.loop.BDFTLoop`.
    """
    _check_loop("loop_poles", loop)
    return closed_loop_poles(loop.system(bdft=bdft, controller=controller))


def bdft_ratio(loop: BDFTLoop, freqs_hz: np.ndarray, *, controller=None) -> np.ndarray:
    """Complex ratio of cylinder output with BDFT to without, ``Y_bdft(jw) / Y_nobdft(jw)``.

    The paper's Figure 13 plots its magnitude; 1 means the feedthrough has no
    effect at that frequency. Only meaningful where the BDFT loop is stable.

    Parameters
    ----------
    loop : BDFTLoop
        The loop.
    freqs_hz : array_like
        Frequencies, Hz.
    controller : control.StateSpace, optional
        Compensator in the BDFT loop (the reference has none).

    Raises
    ------
    ParameterError
        If ``loop`` is not a :class:`~backhoe.model.loop.BDFTLoop` or ``freqs_hz`` is not a
        non-empty 1-D array of finite frequencies >= 0.
    """
    _check_loop("bdft_ratio", loop)
    freqs_hz = check_vector("bdft_ratio: freqs_hz", freqs_hz, NONNEGATIVE)
    with_b = frequency_response(loop.system(bdft=True, controller=controller), freqs_hz)
    without = frequency_response(loop.system(bdft=False), freqs_hz)
    return with_b / without


def critical_k_psf(
    loop: BDFTLoop,
    *,
    k_min: float = 1e-4,
    k_max: float = 10.0,
    n_grid: int = 120,
    xtol: float = 1e-6,
) -> float:
    """Smallest ``K_PSF`` at which the BDFT loop loses stability (``inf`` if none in range).

    Scans ``K_PSF`` on a log grid from ``k_min`` to ``k_max`` and refines the first
    stable-to-unstable transition by bisection in log space to relative tolerance ``xtol``.

    Parameters
    ----------
    loop : BDFTLoop
        The loop (its ``k_psf`` is replaced).
    k_min, k_max : float
        Range of ``K_PSF`` scanned.
    n_grid : int
        Points of the log grid.
    xtol : float
        Relative tolerance of the bisection.

    Raises
    ------
    ParameterError
        If ``loop`` is not a :class:`~backhoe.model.loop.BDFTLoop`, ``k_min`` and ``k_max``
        are not ``0 < k_min < k_max``, ``n_grid`` is not an integer >= 2 or ``xtol`` is
        not in (0, 1).
    """
    _check_loop("critical_k_psf", loop)
    k_min = check_scalar("critical_k_psf: k_min", k_min, POSITIVE)
    k_max = check_scalar("critical_k_psf: k_max", k_max, POSITIVE)
    if not k_min < k_max:
        raise ParameterError(f"critical_k_psf: k_min must be below k_max; got {k_min=}, {k_max=}")
    n_grid = check_int("critical_k_psf: n_grid", n_grid, low=2)
    xtol = check_scalar(
        "critical_k_psf: xtol", xtol, Spec(low=0.0, high=1.0, low_open=True, high_open=True)
    )
    grid = np.geomspace(k_min, k_max, n_grid)

    def unstable(k: float) -> bool:
        return not loop_poles(loop.replace(k_psf=float(k))).stable

    prev = grid[0]
    if unstable(prev):
        return float(prev)
    for k in grid[1:]:
        if unstable(k):
            lo, hi = prev, k
            while hi / lo - 1.0 > xtol:
                mid = np.sqrt(lo * hi)
                lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
            return float(np.sqrt(lo * hi))
        prev = k
    return float("inf")


def bdft_loop_gain(loop: BDFTLoop, freqs_hz: np.ndarray) -> dict[str, np.ndarray]:
    """Frequency response of the BDFT loop broken at the handle, and of its factors.

    Returns complex arrays ``loop`` (``sigma*kappa*K_PSF * H * S * T``), ``human``
    (``H = h/c``), ``structure`` (``S = c/y``) and ``cylinder_loop`` (``T = y/r``, the
    closed cylinder loop). Where ``|loop|`` is largest is where the feedthrough
    matters most.

    Parameters
    ----------
    loop : BDFTLoop
        The loop.
    freqs_hz : array_like
        Frequencies, Hz.
    """

    cal = loop.calibration
    inner = ct.feedback(pi_controller(cal.pi) * valve_cylinder(loop.valve), 1)
    inner = ct.ss(inner.A, inner.B, inner.C, inner.D, inputs="r", outputs="y")
    s = 2j * np.pi * np.asarray(freqs_hz, float)
    H = frequency_response(loop.human.system(), freqs_hz, inp="c", out="h")
    S = np.asarray(structure(loop.struct)(s, squeeze=False))[0, 0]
    T = np.asarray(inner(s, squeeze=False))[0, 0]
    L = loop.handle_gain * loop.k_psf * H * S * T
    return {"loop": L, "human": H, "structure": S, "cylinder_loop": T}


def reduce_controller(K: ct.StateSpace, loops, *, rtol: float = 0.01):
    """Balanced truncation of ``K`` to the smallest order that keeps every loop stable.

    Orders are tried downwards from ``K.nstates - 1``; the search stops at the first
    order whose balanced-truncation error bound exceeds ``rtol * ||K||_inf`` or that
    leaves a loop of ``loops`` unstable (:func:`loop_poles`). An unstable ``K`` is
    not reduced.

    Parameters
    ----------
    K : control.StateSpace
        The controller (loop convention).
    loops : sequence of BDFTLoop
        Loops that must stay stable with the reduced controller.
    rtol : float
        Allowed error bound relative to ``||K||_inf``.

    Returns
    -------
    (control.StateSpace, float)
        The reduced controller and its error bound (``K`` itself and 0.0 if no smaller
        order qualifies).

    Raises
    ------
    ModelStructureError
        If ``K`` is not a :class:`control.StateSpace` with finite matrices (named).
    ParameterError
        If ``loops`` is not a sequence of :class:`~backhoe.model.loop.BDFTLoop` or ``rtol``
        is not finite and positive.
    """
    if not isinstance(K, ct.StateSpace):
        raise ModelStructureError(
            f"reduce_controller: K must be a control.StateSpace; got {type(K).__name__}"
        )
    check_state_space("reduce_controller: K", K)
    rtol = check_scalar("reduce_controller: rtol", rtol, POSITIVE)
    try:
        loops = list(loops)
    except TypeError:
        raise ParameterError(
            f"reduce_controller: loops must be a sequence of BDFTLoop; got {type(loops).__name__}"
        ) from None
    for i, m in enumerate(loops):
        _check_loop(f"reduce_controller: loops[{i}]", m)
    if K.nstates <= 1:
        return K, 0.0
    size = hinf_norm(K) if poles_stable(K.poles()) else np.inf
    best = (K, 0.0)
    for order in range(K.nstates - 1, 0, -1):
        try:
            red = balanced_truncation(K, order=order)
        except ValueError:
            break
        if not np.isfinite(size) or red.error_bound > rtol * size:
            break
        if not all(loop_poles(m, controller=red.sys).stable for m in loops):
            break
        best = (red.sys, red.error_bound)
    return best
