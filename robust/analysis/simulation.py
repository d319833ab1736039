"""Time responses of the Figure 5 loop (the paper's Figures 11 and 12).

Responses are computed on a minimal realisation of the loop with
``control.forced_response``; nothing is clipped or saturated, so an unstable
loop shows as a growing response.
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np
from scipy.signal import chirp

from robust.analysis.realization import minimal_realization
from robust.checks import POSITIVE, check_scalar
from robust.errors import ParameterError
from robust.model.loop import BDFTLoop

__all__ = ["SweptSine", "swept_sine", "TimeResponse", "simulate_swept_sine", "simulate"]


@dataclasses.dataclass(frozen=True)
class SweptSine:
    """A linear swept sine (chirp) of intended handle motion ``u``.

    Parameters
    ----------
    f0_hz, f1_hz : float
        Start and end frequency in Hz.
    duration_s : float
        Length of the sweep in s.
    amplitude : float
        Amplitude in handle units (the units of ``u``).
    fs_hz : float
        Sample rate of the simulation in Hz (the paper's rig: 1000 Hz).
    """

    f0_hz: float = 0.1
    f1_hz: float = 8.0
    duration_s: float = 20.0
    amplitude: float = 1.0
    fs_hz: float = 1000.0

    def __post_init__(self):
        for name in ("f0_hz", "f1_hz", "duration_s", "amplitude", "fs_hz"):
            object.__setattr__(
                self, name, check_scalar(name, getattr(self, name), POSITIVE, owner="SweptSine")
            )
        if self.f1_hz <= self.f0_hz:
            raise ParameterError(
                f"SweptSine.f1_hz must exceed f0_hz={self.f0_hz}; got {self.f1_hz}"
            )
        if self.f1_hz >= self.fs_hz / 2:
            raise ParameterError(
                f"SweptSine.f1_hz must be below the Nyquist frequency {self.fs_hz / 2}; got {self.f1_hz}"
            )

    def signal(self) -> tuple[np.ndarray, np.ndarray]:
        t = np.arange(int(round(self.duration_s * self.fs_hz)) + 1) / self.fs_hz
        u = self.amplitude * chirp(
            t, f0=self.f0_hz, t1=self.duration_s, f1=self.f1_hz, method="linear", phi=-90
        )
        return t, u


def swept_sine(**kwargs) -> SweptSine:
    return SweptSine(**kwargs)


@dataclasses.dataclass(frozen=True)
class TimeResponse:
    """Time histories of one simulation: ``t`` (s), input ``u`` and named outputs."""

    t: np.ndarray
    u: np.ndarray
    outputs: dict
    bdft: bool
    k_psf: float

    def __getitem__(self, name: str) -> np.ndarray:
        return self.outputs[name]


def simulate(
    loop: BDFTLoop, t: np.ndarray, u: np.ndarray, *, bdft: bool = True, controller=None
) -> TimeResponse:
    """Response of the loop outputs to intended motion ``u(t)`` from rest."""
    sys = loop.system(bdft=bdft, controller=controller)
    m = minimal_realization(sys.A, sys.B, sys.C, sys.D)
    # only the input u is driven here
    iu = sys.input_labels.index("u")
    red = ct.ss(m.A, m.B[:, [iu]], m.C, m.D[:, [iu]])
    resp = ct.forced_response(red, T=t, U=u)
    y = np.atleast_2d(resp.outputs)
    outs = {name: y[i] for i, name in enumerate(sys.output_labels)}
    return TimeResponse(t=np.asarray(t), u=np.asarray(u), outputs=outs, bdft=bdft, k_psf=loop.k_psf)


def simulate_swept_sine(
    loop: BDFTLoop, sweep: SweptSine | None = None, *, controller=None
) -> tuple[TimeResponse, TimeResponse]:
    """Cylinder response to a swept sine with and without BDFT (Figures 11 and 12)."""
    sweep = sweep or SweptSine()
    t, u = sweep.signal()
    return simulate(loop, t, u, bdft=True, controller=controller), simulate(loop, t, u, bdft=False)
