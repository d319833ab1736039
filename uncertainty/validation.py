"""Validation of an uncertain system's members: closed-loop pole metrics of every member.

:func:`validate_family` takes the members' closed-loop state matrices chunk by chunk, so
memory stays bounded, and their eigenvalues by the compiled loop of
:func:`robust.analysis.small_eig.eigvals_stack` (LAPACK's to rounding); each member's
largest real part and smallest damping ratio in a band make the :class:`ValidationResult`.
It dispatches on its first argument's type (:func:`functools.singledispatch`): an uncertain
system (:func:`uncertainty.uss`) is validated here through its own state matrices; a
machine's family registers its own batched matrices (the BDFT family's are registered by
:mod:`backhoe.families.validation`, with its parallel engines). ``chunk`` is capped by
:data:`MAX_CHUNK_BYTES`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import control as ct
import numpy as np

from robust.analysis.small_eig import eigvals_stack
from robust.analysis.stability import damping_in_band, stability_bound
from robust.checks import FINITE, check_callable, check_int, check_scalar
from robust.errors import ModelStructureError, ParameterError
from uncertainty.constants import DEFAULT_CHUNK
from uncertainty.parameters import BOUNDS_RTOL
from uncertainty.region import EVERY_FREQUENCY_HZ
from uncertainty.sampling import SampleSet
from uncertainty.uss import USS

__all__ = [
    "STABILITY_THRESHOLD",
    "DEFAULT_CHUNK",
    "ValidationResult",
    "validate_family",
    "MAX_CHUNK_BYTES",
]

#: A member is stable when every closed-loop pole has real part below this, rad/s
#: (the definition of :mod:`robust.analysis.stability`).
STABILITY_THRESHOLD = stability_bound(0.0)
# DEFAULT_CHUNK (members per chunk) is defined in uncertainty.constants (the command line
# reads it without NumPy)
#: Memory budget of one chunk, bytes (about ``chunk * n^2 * 40`` for an ``n``-state loop): a
#: larger ``chunk`` is reduced to fit, so a huge ``chunk`` never allocates more than this
#: (chunking does not change any result).
MAX_CHUNK_BYTES = 2**30


@dataclasses.dataclass(frozen=True)
class ValidationResult:
    """Family-wide closed-loop pole metrics.

    Attributes
    ----------
    samples : int
        Number of members validated.
    seed : int
        Seed of the sample set.
    method : str
        Sampling method.
    human : str or None
        Human variant (None for a user's uncertain system).
    k_psf : float or None
        Position scale factor (None for a user's uncertain system).
    fraction_stable : float
        Fraction of members whose poles all have real part below ``stability_threshold``.
    n_unstable : int
        Number of unstable members.
    max_real_pole : float
        Largest real part of any closed-loop pole of any member, 1/s.
    min_damping : float
        Smallest damping ratio ``-Re(p)/|p|`` of the poles with ``|Im(p)|/(2 pi)``
        in ``band_hz`` (``inf`` if no member has a pole in the band).
    worst : dict
        Parameters (name -> value) of the member with the largest real part.
    worst_index : int
        Row of that member in the sample set.
    stability_threshold : float
        Threshold on the real part used for ``fraction_stable``, 1/s.
    band_hz : (float, float)
        The band of ``min_damping``, Hz: the BDFT band by default for a family, every
        frequency ``(0, inf)`` for a user's uncertain system.
    nstates : int
        Closed-loop order.
    controller_states : int
        Order of the controller (0 without one).
    max_real : ndarray, shape (N,)
        Per-member largest real part (read-only).
    member_min_damping : ndarray, shape (N,)
        Per-member smallest damping ratio in the band (``inf`` if none; read-only).
    """

    samples: int
    seed: int
    method: str
    human: str | None
    k_psf: float | None
    fraction_stable: float
    n_unstable: int
    max_real_pole: float
    min_damping: float
    worst: dict
    worst_index: int
    stability_threshold: float
    band_hz: tuple[float, float]
    nstates: int
    controller_states: int
    max_real: np.ndarray = dataclasses.field(repr=False)
    member_min_damping: np.ndarray = dataclasses.field(repr=False)

    def to_json(self) -> dict:
        """The JSON object of ``bdft validate --json`` (per-member arrays left out)."""
        d = {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if f.name not in ("max_real", "member_min_damping")
        }
        d["band_hz"] = list(self.band_hz)
        return d


def member_pole_metrics(poles: np.ndarray, band_hz) -> tuple[np.ndarray, np.ndarray]:
    """Each member's largest real part and smallest damping ratio in ``band_hz``.

    Parameters
    ----------
    poles : ndarray, shape (N, n)
        The members' closed-loop poles.
    band_hz : (float, float)
        The band of the damping ratio, Hz.
    """
    return poles.real.max(axis=1), damping_in_band(poles, band_hz)


def check_batch_options(where: str, chunk, band_hz, progress) -> tuple[int, tuple[float, float]]:
    """``chunk``, ``band_hz`` and ``progress`` of a batched call, checked.

    Parameters
    ----------
    where : str
        The caller's name, for error messages.
    chunk, band_hz, progress
        As for :func:`validate_family`.
    """
    chunk = check_int(f"{where}: chunk", chunk, low=1)
    try:
        lo, hi = band_hz
    except (TypeError, ValueError):
        raise ParameterError(
            f"{where}: band_hz must be a pair (low, high) in Hz; got {band_hz!r}"
        ) from None
    lo = check_scalar(f"{where}: band_hz[0]", lo, FINITE)
    hi = math.inf if hi == math.inf else check_scalar(f"{where}: band_hz[1]", hi, FINITE)
    if not (0.0 <= lo < hi):
        raise ParameterError(
            f"{where}: band_hz must satisfy 0 <= low < high; got {band_hz!r} (high may be inf)"
        )
    check_callable("progress", progress, owner=where)
    return chunk, (lo, hi)


@functools.singledispatch
def validate_family(
    family,
    samples: SampleSet,
    *,
    controller: ct.StateSpace | None = None,
    chunk: int = DEFAULT_CHUNK,
    band_hz: tuple[float, float] | None = None,
    stability_threshold: float = STABILITY_THRESHOLD,
    progress: Callable[[int], None] | None = None,
    check_bounds: bool = True,
    jobs: int = 1,
    scheduler: str | None = None,
) -> ValidationResult:
    """Closed-loop poles of every member of ``samples``, and the family metrics.

    Member values must be finite (a family's: physical too) and lie within the bounds
    (within :data:`~uncertainty.parameters.BOUNDS_RTOL`); every member is checked,
    vectorised, before any pole is computed, so a bad member costs no work.

    Parameters
    ----------
    family : USS or a registered family
        An uncertain system (:func:`uncertainty.uss`; its members are the values of its
        uncertain reals), or a family whose type is registered with this single-dispatch
        function (``validate_family.register``: the BDFT family, :class:`backhoe.Family`,
        by :mod:`backhoe.families.validation`).
    samples : SampleSet
        Members; its names must equal ``family.names`` (a system's: the names of
        ``system.parameters``, in any order).
    controller : control.StateSpace, optional
        Compensator (a family: inputs among ``x, c, y``, outputs among ``f, r_corr``; a
        system: in its feedback path, ``system.feedback(controller)``).
    chunk : int
        Members per batch (bounds memory: about ``chunk * n^2 * 40`` bytes; reduced to
        keep within :data:`MAX_CHUNK_BYTES`, which changes no result).
    band_hz : (float, float), optional
        Frequency band of the poles whose damping is reported, Hz (``high`` may be
        ``inf``). Default: the BDFT band (:data:`DAMPING_BAND_HZ`, 0.5-10 Hz) for a
        family, every frequency (``(0, inf)``) for an uncertain system.
    stability_threshold : float
        A member is stable when all its poles have real part below this, 1/s.
    progress : callable, optional
        Called with the number of members finished after each chunk.
    check_bounds : bool
        Require every member within the family's bounds (default). Pass False to
        validate members beyond them (a scaled box for robust margins); non-finite and
        non-physical values (a negative mass, frequency or damping ratio) are refused
        either way.
    jobs : int
        Threads of this process that validate tasks of :data:`TASK_MEMBERS` members side by
        side (the compiled loops release the GIL, so no worker process is needed); 1
        (default) validates in this thread.
    scheduler : str, optional
        A Dask scheduler's address (or ``$DASK_SCHEDULER_ADDRESS``): the members are
        validated on its workers in tasks of :data:`TASK_MEMBERS` (see
        :func:`robust.engine.map_tasks`). Every engine gives the same result, bit for
        bit: each member's poles are computed alone and the metrics are combined in order.

    Returns
    -------
    ValidationResult

    Raises
    ------
    ParameterError
        If ``samples`` is not a :class:`~uncertainty.sampling.SampleSet` whose names
        match the family's, a member is non-finite, non-physical or (with
        ``check_bounds``) outside the family's bounds (the message names the row and the
        parameter), ``chunk`` is not a positive integer, ``band_hz`` is not
        ``0 <= low < high`` or ``stability_threshold`` is not finite.
    ModelStructureError
        For an invalid controller, an ill-posed loop or non-finite poles.
    """
    raise ParameterError(
        "validate_family: expected an uncertain system (uncertainty.uss) or a family whose "
        f"type is registered with uncertainty.validate_family; got {type(family).__name__}"
    )


@validate_family.register
def _(
    system: USS,
    samples,
    *,
    controller=None,
    chunk: int = DEFAULT_CHUNK,
    band_hz=None,
    stability_threshold: float = STABILITY_THRESHOLD,
    progress=None,
    check_bounds: bool = True,
    jobs: int = 1,
    scheduler=None,
):
    # validate_family of an uncertain system (closed with ``controller``; small systems: in
    # this process, whatever ``jobs`` and ``scheduler``)
    band_hz = EVERY_FREQUENCY_HZ if band_hz is None else band_hz
    threshold = stability_threshold
    where = "validate_family"
    if not isinstance(samples, SampleSet):
        raise ParameterError(
            f"{where}: samples must be an uncertainty.SampleSet; got {type(samples).__name__}"
        )
    names = tuple(system.parameters)
    if sorted(samples.names) != sorted(names):
        raise ParameterError(
            f"{where}: sample names {list(samples.names)} do not match the system's "
            f"parameters {list(names)}"
        )
    chunk, (lo, hi) = check_batch_options(where, chunk, band_hz, progress)
    threshold = check_scalar(f"{where}: stability_threshold", threshold, FINITE)
    # the columns in the system's order (a sample of the same parameters in another order,
    # e.g. of the transfer function the system realises, is the same members)
    values = np.asarray(samples.values, float)[:, [samples.names.index(n) for n in names]]
    N = values.shape[0]
    if N == 0:
        raise ParameterError(f"{where}: samples holds no members; got 0 rows")
    bad = ~np.isfinite(values)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ParameterError(f"{where}: member {i}: {names[j]} must be finite; got {values[i, j]}")
    if check_bounds:
        low = np.array([p.low for p in system.parameters.values()])
        high = np.array([p.high for p in system.parameters.values()])
        tol = BOUNDS_RTOL * np.maximum(np.abs(low), np.abs(high))
        out = (values < low - tol) | (values > high + tol)
        if out.any():
            i, j = np.argwhere(out)[0]
            raise ParameterError(
                f"{where}: member {i}: {names[j]} must lie in [{low[j]:g}, {high[j]:g}]; "
                f"got {values[i, j]!r}"
            )
    closed = system if controller is None else system.feedback(controller, sign=-1)
    if closed.nstates == 0:
        raise ModelStructureError(f"{where}: the system has no state (a static gain)")
    n = closed.nstates
    chunk = max(1, min(chunk, MAX_CHUNK_BYTES // (40 * n * n)))
    max_real, min_damp = np.empty(N), np.empty(N)
    for start in range(0, N, chunk):
        stop = min(N, start + chunk)
        poles = eigvals_stack(closed.state_matrices(values[start:stop]))
        max_real[start:stop], min_damp[start:stop] = member_pole_metrics(poles, (lo, hi))
        if progress is not None:
            progress(stop - start)
    if not np.all(np.isfinite(max_real)):
        raise ModelStructureError(f"{where}: non-finite closed-loop poles for some members")
    ctrl_states = 0 if controller is None else int(ct.ss(controller).nstates)
    return validation_result(
        samples, max_real, min_damp, threshold, (lo, hi), n, ctrl_states, None, None
    )


def validation_result(
    samples, max_real, min_damp, threshold, band, nstates, ctrl_states, human, k_psf
) -> ValidationResult:
    """The :class:`ValidationResult` of per-member metrics.

    Parameters
    ----------
    samples : SampleSet
        The members.
    max_real, min_damp : ndarray, shape (N,)
        Per-member largest real part and smallest in-band damping ratio (made read-only).
    threshold : float
        The stability threshold, 1/s.
    band : (float, float)
        The damping band, Hz.
    nstates, ctrl_states : int
        Closed-loop and controller orders.
    human, k_psf : str or None, float or None
        A family's human variant and position scale factor (None for a system).
    """
    N = len(max_real)
    stable = max_real < threshold
    worst = int(np.argmax(max_real))
    for arr in (max_real, min_damp):
        arr.setflags(write=False)
    return ValidationResult(
        samples=N,
        seed=samples.seed,
        method=samples.method,
        human=human,
        k_psf=k_psf,
        fraction_stable=float(np.mean(stable)),
        n_unstable=int(N - np.count_nonzero(stable)),
        max_real_pole=float(max_real[worst]),
        min_damping=float(np.min(min_damp)),
        worst=samples.row(worst),
        worst_index=worst,
        stability_threshold=float(threshold),
        band_hz=band,
        nstates=int(nstates),
        controller_states=ctrl_states,
        max_real=max_real,
        member_min_damping=min_damp,
    )
