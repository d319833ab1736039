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

from robust.analysis.realization import minimal_realization
from robust.analysis.stability import poles_stable, unstable_mask
from robust.model.loop import BDFTLoop

__all__ = [
    "PoleSet",
    "closed_loop_poles",
    "loop_poles",
    "bdft_ratio",
    "frequency_response",
    "critical_k_psf",
    "bdft_loop_gain",
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
        return int(np.count_nonzero(unstable_mask(self.poles)))

    @property
    def stable(self) -> bool:
        """Every pole stable (:mod:`robust.analysis.stability`)."""
        return poles_stable(self.poles)

    @property
    def max_real(self) -> float:
        return float(self.poles.real.max()) if self.poles.size else -np.inf

    @property
    def unstable_poles(self) -> np.ndarray:
        return self.poles[unstable_mask(self.poles)]

    def damping(self) -> np.ndarray:
        """Damping ratio ``-Re(p)/|p|`` of each pole (1 for a pole at the origin)."""
        mag = np.abs(self.poles)
        with np.errstate(invalid="ignore", divide="ignore"):
            z = np.where(mag > 0, -self.poles.real / np.where(mag > 0, mag, 1.0), 1.0)
        return z


def closed_loop_poles(sys: ct.StateSpace, *, rtol: float = 1e-9) -> PoleSet:
    """Poles of a minimal realisation of ``sys`` and the hidden modes removed to get it."""
    m = minimal_realization(sys.A, sys.B, sys.C, sys.D, rtol=rtol)
    p = np.linalg.eigvals(m.A) if m.nstates else np.zeros(0, complex)
    order = np.lexsort((p.imag, -p.real))
    return PoleSet(
        poles=p[order], hidden=np.sort_complex(m.removed_eigenvalues), n_states_full=sys.nstates
    )


def loop_poles(loop: BDFTLoop, *, bdft: bool = True, controller=None) -> PoleSet:
    """Closed-loop poles of the Figure 5 loop (minimal realisation, all inputs and outputs)."""
    return closed_loop_poles(loop.system(bdft=bdft, controller=controller))


def frequency_response(
    sys: ct.StateSpace, freqs_hz: np.ndarray, *, inp: str = "u", out: str = "y"
) -> np.ndarray:
    """Complex frequency response of one channel of ``sys`` at ``freqs_hz`` (Hz)."""
    w = 2.0 * np.pi * np.asarray(freqs_hz, float)
    i = sys.input_labels.index(inp)
    o = sys.output_labels.index(out)
    resp = sys(1j * w, squeeze=False)  # shape (noutputs, ninputs, nfreq)
    return np.asarray(resp)[o, i, :]


def bdft_ratio(loop: BDFTLoop, freqs_hz: np.ndarray, *, controller=None) -> np.ndarray:
    """Complex ratio of cylinder output with BDFT to without, ``Y_bdft(jw) / Y_nobdft(jw)``.

    The paper's Figure 13 plots its magnitude; 1 means the feedthrough has no
    effect at that frequency. Only meaningful where the BDFT loop is stable.
    """
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
    """
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
    """
    from robust.model.components import pi_controller, structure, valve_cylinder

    cal = loop.calibration
    inner = ct.feedback(pi_controller(cal.pi) * valve_cylinder(loop.valve), 1)
    inner = ct.ss(inner.A, inner.B, inner.C, inner.D, inputs="r", outputs="y")
    s = 2j * np.pi * np.asarray(freqs_hz, float)
    H = frequency_response(loop.human.system(), freqs_hz, inp="c", out="h")
    S = np.asarray(structure(loop.struct)(s, squeeze=False))[0, 0]
    T = np.asarray(inner(s, squeeze=False))[0, 0]
    L = cal.handle_sign * cal.loop_scale * loop.k_psf * H * S * T
    return {"loop": L, "human": H, "structure": S, "cylinder_loop": T}
