"""Closed-loop analysis of the Figure 5 loop: poles, stability, BDFT ratio.

Poles are those of a minimal realisation of the interconnection (see
:mod:`robust.analysis.realization`); modes removed because they are uncontrollable or
unobservable (the exact s^2 cancellation between Eqns 4 and 5 with the literal
human) are kept and reported as *hidden modes*, never silently dropped.
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np

from robust.analysis.norms import hinf_norm
from robust.analysis.realization import minimal_realization
from robust.analysis.reduction import balanced_truncation
from robust.analysis.resolvent import resolvent_solve, siso_responses
from robust.analysis.stability import poles_stable, unstable_mask
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
from robust.model.components import pi_controller, structure, valve_cylinder
from robust.model.loop import BDFTLoop

__all__ = [
    "PoleSet",
    "closed_loop_poles",
    "loop_poles",
    "bdft_ratio",
    "frequency_response",
    "resolvent_times",
    "critical_k_psf",
    "bdft_loop_gain",
    "reduce_controller",
]


@dataclasses.dataclass(frozen=True)
class PoleSet:
    """Closed-loop poles of a minimal realisation, plus the hidden modes removed.

    Attributes
    ----------
    poles : ndarray of complex
        Poles of the minimal realisation, sorted by decreasing real part.
    hidden : ndarray of complex
        Eigenvalues of the uncontrollable/unobservable modes that were removed.
    n_states_full : int
        Number of states of the interconnection before reduction.
    """

    poles: np.ndarray
    hidden: np.ndarray
    n_states_full: int

    @property
    def n_unstable(self) -> int:
        """Number of poles in the open right half-plane (:mod:`robust.analysis.stability`)."""
        return int(np.count_nonzero(unstable_mask(self.poles)))

    @property
    def stable(self) -> bool:
        """Every pole stable (:mod:`robust.analysis.stability`)."""
        return poles_stable(self.poles)

    @property
    def max_real(self) -> float:
        """Largest real part of the poles, rad/s (``-inf`` without poles)."""
        return float(self.poles.real.max()) if self.poles.size else -np.inf

    @property
    def unstable_poles(self) -> np.ndarray:
        """The poles in the open right half-plane."""
        return self.poles[unstable_mask(self.poles)]

    def damping(self) -> np.ndarray:
        """Damping ratio ``-Re(p)/|p|`` of each pole (1 for a pole at the origin)."""
        mag = np.abs(self.poles)
        with np.errstate(invalid="ignore", divide="ignore"):
            z = np.where(mag > 0, -self.poles.real / np.where(mag > 0, mag, 1.0), 1.0)
        return z


def closed_loop_poles(sys: ct.StateSpace, *, rtol: float = 1e-9) -> PoleSet:
    """Poles of a minimal realisation of ``sys`` and the hidden modes removed to get it.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous-time system.
    rtol : float
        Relative rank tolerance of the minimal realisation
        (:func:`robust.analysis.realization.minimal_realization`).

    Raises
    ------
    ModelStructureError
        If ``sys`` has no finite, conformal ``A, B, C, D`` (the message names the matrix).
    ParameterError
        If ``rtol`` is not finite and positive.
    """
    A, B, C, D = check_state_space("closed_loop_poles: sys", sys)
    m = minimal_realization(A, B, C, D, rtol=rtol)
    p = np.linalg.eigvals(m.A) if m.nstates else np.zeros(0, complex)
    order = np.lexsort((p.imag, -p.real))
    return PoleSet(
        poles=p[order], hidden=np.sort_complex(m.removed_eigenvalues), n_states_full=A.shape[0]
    )


def _check_loop(where: str, loop) -> None:
    if not isinstance(loop, BDFTLoop):
        raise ParameterError(f"{where}: loop must be a BDFTLoop; got {type(loop).__name__}")


def _freqs(where: str, freqs_hz) -> np.ndarray:
    return check_vector(f"{where}: freqs_hz", freqs_hz, NONNEGATIVE)


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
        If ``loop`` is not a :class:`~robust.model.loop.BDFTLoop`.
    """
    _check_loop("loop_poles", loop)
    return closed_loop_poles(loop.system(bdft=bdft, controller=controller))


def resolvent_times(A, omega, B) -> np.ndarray:
    """``(j omega_k I - A)^-1 B`` at every frequency ``omega_k``.

    Real data through one Hessenberg form of ``A`` and an ``O(n^2)`` elimination per
    frequency (:func:`robust.analysis.resolvent.resolvent_solve`); complex data by one
    stacked LU solve.

    Parameters
    ----------
    A : numpy.ndarray, shape (n, n)
        State matrix.
    omega : numpy.ndarray, shape (f,)
        Angular frequencies, rad/s.
    B : numpy.ndarray, shape (n, k)
        Right-hand side.

    Returns
    -------
    numpy.ndarray of complex, shape (f, n, k)

    Raises
    ------
    numpy.linalg.LinAlgError
        If ``j omega_k I - A`` is singular at a frequency.
    """
    A, B = np.asarray(A), np.asarray(B)
    if A.dtype.kind in "biuf" and B.dtype.kind in "biuf" and np.isrealobj(omega):
        return resolvent_solve(A, omega, B)
    n = A.shape[0]
    M = 1j * omega[:, None, None] * np.eye(n)[None] - A[None]
    return np.linalg.solve(M, np.broadcast_to(B, (omega.size,) + B.shape))


def frequency_response(
    sys: ct.StateSpace, freqs_hz: np.ndarray, *, inp: str = "u", out: str = "y"
) -> np.ndarray:
    """Complex frequency response of one channel of ``sys`` at ``freqs_hz`` (Hz).

    ``C_o (j w I - A)^-1 B_i + D_oi`` from one Hessenberg form of ``A`` and an ``O(n^2)``
    solve per frequency (:func:`robust.analysis.resolvent.siso_responses`); SLICOT's
    evaluation through python-control (the same method, with a Python loop over the
    frequencies) is kept for a frequency on a pole.

    Parameters
    ----------
    sys : control.StateSpace
        Named-signal system.
    freqs_hz : array_like
        Frequencies, Hz.
    inp, out : str
        Input and output signal names.

    Raises
    ------
    ParameterError
        If ``freqs_hz`` is empty, not 1-D or holds a negative or non-finite frequency.
    ModelStructureError
        If ``sys`` has no signal ``inp`` or ``out``.

    Returns
    -------
    numpy.ndarray of complex, shape (f,)
        The response at each frequency.
    """
    w = 2.0 * np.pi * _freqs("frequency_response", freqs_hz)
    for label, name, have in (
        ("input", inp, list(sys.input_labels)),
        ("output", out, list(sys.output_labels)),
    ):
        if name not in have:
            raise ModelStructureError(
                f"frequency_response: the system has no {label} {name!r}; its {label}s are {have}"
            )
    i = sys.input_labels.index(inp)
    o = sys.output_labels.index(out)
    A = np.asarray(sys.A, float)
    d = complex(np.asarray(sys.D, float)[o, i])
    if A.shape[0] == 0:
        return np.full(w.size, d)
    B = np.asarray(sys.B, float)
    C = np.asarray(sys.C, float)
    try:
        # C_o (j w I - A)^-1 B_i + D_oi through one Hessenberg form of A
        crb, _, _ = siso_responses(A, B[:, i], C[o], np.zeros((A.shape[0], 0)), C[:0], w)
    except np.linalg.LinAlgError:  # a frequency on a pole: SLICOT's evaluation reports it
        resp = sys(1j * w, squeeze=False)  # shape (noutputs, ninputs, nfreq)
        return np.asarray(resp)[o, i, :]
    return crb + d


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
        If ``loop`` is not a :class:`~robust.model.loop.BDFTLoop` or ``freqs_hz`` is not a
        non-empty 1-D array of finite frequencies >= 0.
    """
    _check_loop("bdft_ratio", loop)
    freqs_hz = _freqs("bdft_ratio", freqs_hz)
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
        If ``loop`` is not a :class:`~robust.model.loop.BDFTLoop`, ``k_min`` and ``k_max``
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
        If ``loops`` is not a sequence of :class:`~robust.model.loop.BDFTLoop` or ``rtol``
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
