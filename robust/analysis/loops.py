"""Poles of a minimal realisation, with the hidden modes kept, and frequency responses of a
state-space system (the Figure 5 loop's own analyses are :mod:`backhoe.analysis.loops`).

Poles are those of a minimal realisation of the interconnection (see
:mod:`robust.analysis.realization`); modes removed because they are uncontrollable or
unobservable (the exact s^2 cancellation between Eqns 4 and 5 with the literal
human) are kept and reported as *hidden modes*, never silently dropped.
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np

from robust.analysis.realization import minimal_realization
from robust.analysis.resolvent import resolvent_solve, siso_responses
from robust.analysis.stability import poles_stable, unstable_mask
from robust.checks import (
    NONNEGATIVE,
    check_state_space,
    check_vector,
)
from robust.errors import ModelStructureError

__all__ = [
    "PoleSet",
    "closed_loop_poles",
    "frequency_response",
    "resolvent_times",
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


def _freqs(where: str, freqs_hz) -> np.ndarray:
    return check_vector(f"{where}: freqs_hz", freqs_hz, NONNEGATIVE)


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
