"""Chirp experiments on any workbench model, with known truth.

The paper identified each block from chirp (swept-sine) responses: the valve
command and cylinder position for Eqn 3, cylinder position and cab acceleration
for Eqn 4, seat acceleration and hand motion for Eqn 5. This module reproduces
that protocol on any SISO python-control system so every identification path can
be checked against the transfer function that generated the data:

* :class:`ChirpProtocol`: record count, length, sampling rate and sweep;
* :class:`MeasurementNoise`: white sensor noise plus optional tones (an
  accelerometer on a tractor with its engine running picks up the firing
  frequency and its harmonics);
* :func:`simulate_experiment`: the simulated records, with the seed that drew
  the noise.

The system is discretised with a first-order hold (the sampled input is
interpolated linearly between samples), which is exact for the piecewise-linear
input and matches the continuous response to within ``(pi f / fs)^2 / 3`` in
magnitude at frequency ``f`` (below 0.01 dB at 20 Hz for ``fs`` = 1 kHz).
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np
import scipy.signal as sps

from backhoe.model.components import (
    StructureParams,
    ValveCylinderParams,
    pi_controller,
    structure,
    valve_cylinder,
)
from backhoe.model.human import LiteralHuman, LiteralHumanParams
from backhoe.model.loop import DEFAULT_CALIBRATION
from robust.analysis.realization import minimal_realization
from robust.checks import (
    NONNEGATIVE,
    POSITIVE,
    check_abcd,
    check_array,
    check_scalar,
    validate_fields,
)
from robust.errors import DataError, ModelStructureError, ParameterError

__all__ = [
    "ENGINE_TONES_HZ",
    "PAPER_COMPONENTS",
    "ChirpProtocol",
    "Experiment",
    "MeasurementNoise",
    "chirp_excitation",
    "paper_experiment",
    "select_path",
    "simulate_experiment",
    "simulate_response",
]

#: Components of the paper that :func:`paper_experiment` can simulate.
PAPER_COMPONENTS = ("valve", "structure", "human")

#: Engine pick-up for the accelerometer on a running tractor: a four-cylinder diesel
#: at about 900 rpm fires at 30 Hz; its first harmonic is at 60 Hz.
ENGINE_TONES_HZ = (30.0, 60.0)

_CHIRP_METHODS = ("logarithmic", "linear", "quadratic", "hyperbolic")


@dataclasses.dataclass(frozen=True)
class ChirpProtocol:
    """The chirp test protocol (defaults: the paper's 20 records of 25 s at 1 kHz).

    Parameters
    ----------
    fs : float
        Sampling rate in Hz, default 1000 (the rig's xPC rate).
    duration : float
        Length of one record in s, default 25.
    n_records : int
        Number of repeated records, default 20 (the paper used 20-50).
    f0_hz, f1_hz : float
        Start and end frequency of the sweep in Hz, defaults 0.1 and 50;
        ``f1_hz`` must lie below the Nyquist frequency ``fs / 2``.
    amplitude : float
        Peak amplitude of the excitation, in the input channel's units, default 1.
    method : str
        Sweep law passed to :func:`scipy.signal.chirp`, default ``"logarithmic"``
        (equal time per decade, so low frequencies get as much energy per decade
        as high ones).
    tail_s : float
        Silent time in s at the end of each record (inside ``duration``), default 0.
        With a tail long enough for a stable system to ring down, the whole record
        taken as one rectangular-window segment gives H1 without leakage.
    """

    fs: float = 1000.0
    duration: float = 25.0
    n_records: int = 20
    f0_hz: float = 0.1
    f1_hz: float = 50.0
    amplitude: float = 1.0
    method: str = "logarithmic"
    tail_s: float = 0.0

    def __post_init__(self):
        validate_fields(
            self,
            {
                "fs": POSITIVE,
                "duration": POSITIVE,
                "f0_hz": POSITIVE,
                "f1_hz": POSITIVE,
                "amplitude": POSITIVE,
                "tail_s": NONNEGATIVE,
            },
        )
        if self.tail_s >= self.duration:
            raise ParameterError(
                "ChirpProtocol.tail_s must be shorter than duration; "
                f"got tail_s={self.tail_s:g} s, duration={self.duration:g} s"
            )
        if (
            isinstance(self.n_records, bool)
            or not isinstance(self.n_records, (int, np.integer))
            or self.n_records < 1
        ):
            raise ParameterError(
                f"ChirpProtocol.n_records must be a positive integer; got {self.n_records!r}"
            )
        object.__setattr__(self, "n_records", int(self.n_records))
        if self.f1_hz <= self.f0_hz:
            raise ParameterError(
                "ChirpProtocol.f1_hz must exceed f0_hz; "
                f"got f0_hz={self.f0_hz:g}, f1_hz={self.f1_hz:g}"
            )
        if self.f1_hz >= self.fs / 2.0:
            raise ParameterError(
                "ChirpProtocol.f1_hz must lie below the Nyquist frequency "
                f"fs/2 = {self.fs / 2:g} Hz; got f1_hz={self.f1_hz:g}"
            )
        if self.method not in _CHIRP_METHODS:
            raise ParameterError(
                f"ChirpProtocol.method must be one of {_CHIRP_METHODS}; got {self.method!r}"
            )
        if self.n_samples < 16:
            raise ParameterError(
                f"ChirpProtocol gives {self.n_samples} samples per record (duration*fs); "
                "need at least 16"
            )

    @property
    def n_samples(self) -> int:
        """Samples per record, ``round(duration * fs)``."""
        return round(self.duration * self.fs)

    def time(self) -> np.ndarray:
        """Sample times of one record in s, shape ``(n_samples,)``."""
        return np.arange(self.n_samples) / self.fs

    def excitation(self) -> np.ndarray:
        """The excitation of one record, shape ``(n_samples,)`` (see :func:`chirp_excitation`).

        The sweep fills ``duration - tail_s``; the tail is zero.
        """
        t = self.time()
        n_sweep = round((self.duration - self.tail_s) * self.fs)
        out = np.zeros_like(t)
        out[:n_sweep] = chirp_excitation(
            t[:n_sweep],
            f0_hz=self.f0_hz,
            f1_hz=self.f1_hz,
            amplitude=self.amplitude,
            method=self.method,
        )
        return out


def chirp_excitation(
    t: np.ndarray,
    *,
    f0_hz: float,
    f1_hz: float,
    amplitude: float = 1.0,
    method: str = "logarithmic",
) -> np.ndarray:
    """Swept sine from ``f0_hz`` to ``f1_hz`` over the span of ``t``.

    Built on :func:`scipy.signal.chirp`.

    The sweep starts at phase -90 degrees (a sine, so the excitation starts at
    zero and the system starts at rest without a step).

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times in s, increasing, starting at 0.
    f0_hz, f1_hz : float
        Instantaneous frequency at ``t[0]`` and ``t[-1]`` in Hz.
    amplitude : float
        Peak amplitude.
    method : str
        ``"logarithmic"`` (default), ``"linear"``, ``"quadratic"`` or ``"hyperbolic"``.

    Returns
    -------
    numpy.ndarray, shape (n,)
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ParameterError(
            f"t must be a 1-D array of at least 2 sample times; got shape {t.shape}"
        )
    f0 = check_scalar("f0_hz", f0_hz, POSITIVE)
    f1 = check_scalar("f1_hz", f1_hz, POSITIVE)
    a = check_scalar("amplitude", amplitude, POSITIVE)
    return a * sps.chirp(t, f0=f0, t1=float(t[-1]), f1=f1, method=method, phi=-90.0)


@dataclasses.dataclass(frozen=True)
class MeasurementNoise:
    """Additive sensor noise on one measured channel.

    Parameters
    ----------
    std : float
        Standard deviation of white Gaussian noise, in the channel's units, default 0.
    tone_hz : tuple of float
        Frequencies in Hz of sinusoidal pick-up (e.g. an engine's firing frequency
        and harmonics), default none.
    tone_amplitude : float
        Amplitude of each tone; each record draws its tones' phases at random.
    """

    std: float = 0.0
    tone_hz: tuple[float, ...] = ()
    tone_amplitude: float = 0.0

    def __post_init__(self):
        validate_fields(self, {"std": NONNEGATIVE, "tone_amplitude": NONNEGATIVE})
        tones = tuple(
            check_scalar(f"tone_hz[{i}]", f, POSITIVE, owner="MeasurementNoise")
            for i, f in enumerate(self.tone_hz)
        )
        object.__setattr__(self, "tone_hz", tones)

    @property
    def is_zero(self) -> bool:
        """Whether this noise adds nothing."""
        return self.std == 0.0 and (self.tone_amplitude == 0.0 or not self.tone_hz)

    def sample(self, shape: tuple[int, int], fs: float, rng: np.random.Generator) -> np.ndarray:
        """Noise of ``shape = (n_records, n_samples)`` at sampling rate ``fs`` (Hz)."""
        out = self.std * rng.standard_normal(shape) if self.std > 0 else np.zeros(shape)
        if self.tone_amplitude > 0 and self.tone_hz:
            t = np.arange(shape[1]) / fs
            for f in self.tone_hz:
                phase = rng.uniform(0.0, 2.0 * np.pi, size=(shape[0], 1))
                out += self.tone_amplitude * np.sin(2.0 * np.pi * f * t[None, :] + phase)
        return out


@dataclasses.dataclass(frozen=True)
class Experiment:
    """Simulated (or measured) input/output records of one identification experiment.

    Attributes
    ----------
    u, y : numpy.ndarray, shape (n_records, n_samples)
        Measured input and output (noise included), read-only.
    fs : float
        Sampling rate in Hz.
    seed : int or None
        Seed of the generator that drew the noise (``None`` if no noise was drawn
        from a seed, e.g. a generator passed in).
    protocol : ChirpProtocol or None
        The protocol that produced the excitation.
    system : control.LTI or None
        The true system (``None`` for measured data).
    input_name, output_name : str
        Channel names (the system's signal names when simulated).
    u_clean, y_clean : numpy.ndarray, shape (n_records, n_samples)
        Noise-free input and output.
    """

    u: np.ndarray
    y: np.ndarray
    fs: float
    seed: int | None = None
    protocol: ChirpProtocol | None = None
    system: object | None = None
    input_name: str = "u"
    output_name: str = "y"
    u_clean: np.ndarray | None = None
    y_clean: np.ndarray | None = None

    @property
    def n_records(self) -> int:
        """Number of records."""
        return int(self.u.shape[0])

    @property
    def n_samples(self) -> int:
        """Samples per record."""
        return int(self.u.shape[1])

    def channels(self) -> dict[str, np.ndarray]:
        """Measured channels by name, each of shape ``(n_records, n_samples)``."""
        return {self.input_name: self.u, self.output_name: self.y}


def _check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"seed must be a non-negative integer; got {seed!r}")
    return int(seed)


def _siso_labels(system) -> tuple[str, str]:
    if not isinstance(system, ct.LTI):
        raise ModelStructureError(
            f"system must be a python-control LTI system; got {type(system).__name__}"
        )
    if system.ninputs != 1 or system.noutputs != 1:
        raise ModelStructureError(
            f"system must be SISO for a single-channel experiment; got {system.ninputs} input(s), "
            f"{system.noutputs} output(s). Name the path with input=/output= (signal names)."
        )
    if not system.isctime():
        raise ModelStructureError(f"system must be continuous-time; got dt={system.dt}")
    return system.input_labels[0], system.output_labels[0]


def select_path(system, input: str | None = None, output: str | None = None):
    """The SISO path ``input -> output`` of a named-signal system.

    The system itself if it is already SISO.

    Parameters
    ----------
    system : control.LTI
        System with named inputs and outputs.
    input : str, optional
        Input name (not needed for a SISO system).
    output : str, optional
        Output name (not needed for a SISO system).

    Raises
    ------
    ModelStructureError
        If a name is not among the system's signals, or a MIMO system is given
        without naming the path.
    """
    if not isinstance(system, ct.LTI):
        raise ModelStructureError(
            f"system must be a python-control LTI system; got {type(system).__name__}"
        )
    if input is None and output is None:
        return system
    ins, outs = list(system.input_labels), list(system.output_labels)
    i = (
        ins.index(input)
        if input is not None and input in ins
        else (0 if input is None and len(ins) == 1 else None)
    )
    o = (
        outs.index(output)
        if output is not None and output in outs
        else (0 if output is None and len(outs) == 1 else None)
    )
    if i is None or o is None:
        raise ModelStructureError(
            f"path {input!r} -> {output!r} not found in system {system.name!r}: "
            f"inputs {ins}, outputs {outs}"
        )
    sub = ct.ss(system)[o, i]
    return ct.ss(
        sub.A,
        sub.B,
        sub.C,
        sub.D,
        inputs=ins[i],
        outputs=outs[o],
        name=f"{system.name}:{ins[i]}->{outs[o]}",
    )


def simulate_response(system, u: np.ndarray, fs: float) -> np.ndarray:
    """Response of a continuous SISO system, at rest at ``t = 0``, to sampled inputs.

    Parameters
    ----------
    system : control.LTI
        Continuous-time SISO system.
    u : array_like, shape (n_samples,) or (n_records, n_samples)
        Input samples; each row is one record starting at rest.
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    numpy.ndarray, same shape as ``u``
        Output samples (first-order-hold discretisation, see the module notes).

    Raises
    ------
    DataError
        If ``u`` is not numeric, not 1-D or 2-D, or holds NaN or inf (the message names
        the first bad sample).
    ModelStructureError
        If ``system`` is not a continuous SISO system with finite matrices.
    ParameterError
        If ``fs`` is not finite and positive.
    """
    _siso_labels(system)
    fs = check_scalar("fs", fs, POSITIVE)
    ss = ct.ss(system)
    a, b, c, d = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    check_abcd("simulate_response: system", a, b, c, d)
    u = check_array("simulate_response: input u", u, error=DataError)
    if u.ndim not in (1, 2):
        raise DataError(
            f"simulate_response: input u must be 1-D or 2-D (records x samples); got shape "
            f"{u.shape}"
        )
    if a.shape[0] == 0:
        return d[0, 0] * u
    ad, bd, cd, dd, _ = sps.cont2discrete((a, b, c, d), 1.0 / fs, method="foh")
    # A state-space recursion is kept (not a transfer-function filter) because the
    # models have integrators and close modes whose polynomial form loses digits.
    return _dlsim_rows(ad, bd[:, 0], cd[0], float(dd[0, 0]), np.atleast_2d(u)).reshape(u.shape)


def _dlsim_rows(ad, bd, cd, dd, u2):
    """``x[k+1] = Ad x[k] + Bd u[k]``, ``y[k] = Cd x[k] + Dd u[k]`` for every row of ``u2``."""
    n_rec, n = u2.shape
    # Diagonalise when possible: n_states independent first-order recursions run in
    # compiled code through scipy.signal.lfilter.
    evals, vecs = np.linalg.eig(ad)
    if np.linalg.cond(vecs) < 1e6:
        bm = np.linalg.solve(vecs, bd.astype(complex))
        cm = cd @ vecs
        y = dd * u2.astype(complex)
        for lam, bi, ci in zip(evals, bm, cm):
            # z_i[k] = sum_{j<k} lam^(k-1-j) b_i u[j]  -> filter b=[0, b_i], a=[1, -lam]
            z = sps.lfilter([0.0, bi], [1.0, -lam], u2, axis=-1)
            y = y + ci * z
        return y.real
    x = np.zeros((n_rec, ad.shape[0]))
    y = np.empty_like(u2)
    for k in range(n):
        y[:, k] = x @ cd + dd * u2[:, k]
        x = x @ ad.T + np.outer(u2[:, k], bd)
    return y


def _minimal_series(first, second) -> ct.StateSpace:
    g = ct.series(ct.ss(first), ct.ss(second))
    m = minimal_realization(g.A, g.B, g.C, g.D)
    return ct.ss(m.A, m.B, m.C, m.D)


def simulate_experiment(
    system,
    protocol: ChirpProtocol | None = None,
    *,
    input_noise: MeasurementNoise | float = 0.0,
    output_noise: MeasurementNoise | float = 0.0,
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    excitation: np.ndarray | None = None,
    upstream=None,
    input: str | None = None,
    output: str | None = None,
) -> Experiment:
    """Run the chirp protocol on ``system`` and return noisy measured records.

    Each record starts at rest and applies the same excitation; the measured
    input and output are the true signals plus independent sensor noise.
    Noise on the measured *input* biases H1 low (it is an errors-in-variables
    problem), as it did for the paper's accelerometer on a running tractor.

    Parameters
    ----------
    system : control.LTI
        Continuous-time system, e.g. ``backhoe.structure()``, or a named-signal
        MIMO system (the closed loop, a two-input human) with ``input``/``output``.
    protocol : ChirpProtocol, optional
        Record count, length, sampling rate and sweep; default the paper's.
    input_noise, output_noise : MeasurementNoise or float
        Sensor noise on the measured input and output; a float is the standard
        deviation of white noise.
    seed : int, optional
        Seed of the :class:`numpy.random.Generator` that draws the noise; stored
        in the result. Give either ``seed`` or ``rng``.
    rng : numpy.random.Generator, optional
        Generator to draw from (the result's ``seed`` is then ``None``).
    excitation : array_like, shape (n_samples,) or (n_records, n_samples), optional
        Replace the chirp by this input (e.g. random noise for checking theory).
    upstream : control.LTI, optional
        A SISO system the excitation passes through before it reaches ``system``
        (the paper's protocol for the human: the chirp drives the stick, and the
        structure's cab acceleration excites the body). The measured input is then
        ``upstream``'s output; the output is simulated through a minimal
        realisation of the series connection, so exact pole/zero cancellations
        (Eqn 4's double zero at 0 against Eqn 5's double pole at 0) do not drift.
    input, output : str, optional
        Signal names selecting one path of a MIMO ``system`` (e.g. ``"u"``, ``"c"``
        of :meth:`backhoe.model.loop.BDFTLoop.system`).

    Returns
    -------
    Experiment

    Raises
    ------
    ParameterError
        If ``protocol`` is not a :class:`ChirpProtocol`, ``rng`` not a numpy Generator,
        both ``seed`` and ``rng`` are given, a noisy experiment has neither, or
        ``excitation`` has the wrong shape.
    DataError
        If ``excitation`` holds NaN or inf (named).
    """
    if protocol is not None and not isinstance(protocol, ChirpProtocol):
        raise ParameterError(
            f"simulate_experiment: protocol must be a ChirpProtocol or None; "
            f"got {type(protocol).__name__}"
        )
    if rng is not None and not isinstance(rng, np.random.Generator):
        raise ParameterError(
            f"simulate_experiment: rng must be a numpy.random.Generator or None; "
            f"got {type(rng).__name__}"
        )
    protocol = protocol or ChirpProtocol()
    system = select_path(system, input, output)
    in_name, out_name = _siso_labels(system)
    if seed is not None and rng is not None:
        raise ParameterError("give either seed or rng, not both")
    if seed is not None:
        seed = _check_seed(seed)
        rng = np.random.default_rng(seed)
    n_in = (
        input_noise
        if isinstance(input_noise, MeasurementNoise)
        else MeasurementNoise(std=input_noise)
    )
    n_out = (
        output_noise
        if isinstance(output_noise, MeasurementNoise)
        else MeasurementNoise(std=output_noise)
    )
    shape = (protocol.n_records, protocol.n_samples)
    if excitation is None:
        u = np.broadcast_to(protocol.excitation(), shape).copy()
    else:
        u = check_array("simulate_experiment: excitation", excitation, error=DataError)
        if u.ndim == 1:
            u = np.broadcast_to(u, (protocol.n_records, u.size)).copy()
        if u.shape != shape:
            raise ParameterError(
                f"excitation must have shape {shape} or ({shape[1]},); got {u.shape}"
            )
    if rng is None and not (n_in.is_zero and n_out.is_zero):
        raise ParameterError(
            "noisy experiments need a seed (or a numpy Generator) so they can be reproduced"
        )
    if upstream is None:
        y = simulate_response(system, u, protocol.fs)
    else:
        _siso_labels(upstream)
        chain = _minimal_series(upstream, system)
        u, y = simulate_response(upstream, u, protocol.fs), simulate_response(chain, u, protocol.fs)
    um, ym = u, y
    if not n_in.is_zero:
        um = u + n_in.sample(shape, protocol.fs, rng)
    if not n_out.is_zero:
        ym = y + n_out.sample(shape, protocol.fs, rng)
    arrays = [um, ym, u, y]
    for arr in arrays:
        arr.setflags(write=False)
    return Experiment(
        u=um,
        y=ym,
        fs=protocol.fs,
        seed=seed,
        protocol=protocol,
        system=system,
        input_name=in_name,
        output_name=out_name,
        u_clean=u,
        y_clean=y,
    )


def _pi_loop(valve_params=None):
    pi = pi_controller(DEFAULT_CALIBRATION.pi)
    valve = valve_cylinder(valve_params)
    r_to_e = ct.feedback(ct.ss(pi), ct.ss(valve))
    r_to_y = ct.feedback(ct.series(ct.ss(pi), ct.ss(valve)), 1)
    return r_to_e, r_to_y


def paper_experiment(
    component: str,
    protocol: ChirpProtocol | None = None,
    *,
    noise: float = 0.02,
    engine_tone: float = 0.0,
    seed: int,
    truth=None,
) -> Experiment:
    """Simulate the paper's identification experiment for one component.

    The chirp is the cylinder position reference of the PI loop (the paper's
    gains: :data:`backhoe.model.loop.DEFAULT_CALIBRATION`), as on the rig:

    * ``"valve"``: measured valve command ``e`` (inside the closed loop) and
      cylinder position ``y``; the true system is Eqn 3;
    * ``"structure"``: measured ``y`` and cab acceleration ``c``; Eqn 4;
    * ``"human"``: measured seat acceleration ``c`` and hand motion ``h``; Eqn 5.
      The chirp passes through valve, cylinder and structure first, so the body's
      excitation is strong near 6 Hz and weak elsewhere, as in the paper.

    Parameters
    ----------
    component : str
        ``"valve"``, ``"structure"`` or ``"human"``.
    protocol : ChirpProtocol, optional
        Default: the paper's 20 records of 25 s at 1 kHz, 0.1-50 Hz.
    noise : float
        White measurement noise on each measured channel, as a fraction of that
        channel's clean RMS value (default 0.02, i.e. 2 %).
    engine_tone : float
        Amplitude of engine pick-up tones (:data:`ENGINE_TONES_HZ`) on the measured
        acceleration (input of ``"human"``, output of ``"structure"``), as a
        fraction of the channel's clean RMS value.
    seed : int
        Seed of the noise generator (recorded in the result).
    truth : parameter object, optional
        ``ValveCylinderParams``, ``StructureParams`` or ``LiteralHumanParams`` of
        the true component (default: the paper's values).

    Returns
    -------
    Experiment
        With ``system`` the true component and channel names ``e``/``y``,
        ``y``/``c`` or ``c``/``h``.
    """
    if component not in PAPER_COMPONENTS:
        raise ParameterError(f"component must be one of {PAPER_COMPONENTS}; got {component!r}")
    check_scalar("noise", noise, NONNEGATIVE)
    check_scalar("engine_tone", engine_tone, NONNEGATIVE)
    protocol = protocol or ChirpProtocol()
    expected = {
        "valve": ValveCylinderParams,
        "structure": StructureParams,
        "human": LiteralHumanParams,
    }[component]
    if truth is not None and not isinstance(truth, expected):
        raise ParameterError(
            f"truth for {component!r} must be a {expected.__name__}; got {type(truth).__name__}"
        )
    # the loop runs with the true valve when the valve is what is being identified
    r_to_e, r_to_y = _pi_loop(truth if component == "valve" else None)
    if component == "valve":
        system = valve_cylinder(truth)
        upstream = r_to_e
    elif component == "structure":
        system = structure(truth)
        upstream = r_to_y
    else:
        system = LiteralHuman(truth or LiteralHumanParams()).system()
        upstream = _minimal_series(r_to_y, structure())
    clean = simulate_experiment(system, protocol, upstream=upstream)
    rms_in = float(np.sqrt(np.mean(clean.u_clean**2)))
    rms_out = float(np.sqrt(np.mean(clean.y_clean**2)))
    accel_in = component == "human"
    accel_out = component == "structure"
    tones = ENGINE_TONES_HZ if engine_tone > 0 else ()
    n_in = MeasurementNoise(
        std=noise * rms_in,
        tone_hz=tones if accel_in else (),
        tone_amplitude=engine_tone * rms_in if accel_in else 0.0,
    )
    n_out = MeasurementNoise(
        std=noise * rms_out,
        tone_hz=tones if accel_out else (),
        tone_amplitude=engine_tone * rms_out if accel_out else 0.0,
    )
    rng = np.random.default_rng(_check_seed(seed))
    shape = clean.u.shape
    um = clean.u_clean + n_in.sample(shape, protocol.fs, rng)
    ym = clean.y_clean + n_out.sample(shape, protocol.fs, rng)
    for arr in (um, ym):
        arr.setflags(write=False)
    in_name = {"valve": "e", "structure": "y", "human": "c"}[component]
    out_name = {"valve": "y", "structure": "c", "human": "h"}[component]
    return dataclasses.replace(
        clean, u=um, y=ym, seed=int(seed), input_name=in_name, output_name=out_name
    )
