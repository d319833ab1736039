"""Validation of a family's members: closed-loop pole metrics of every member, chunk by chunk.

:func:`validate_family` and :func:`member_metrics` take the closed-loop state matrices of
:mod:`uncertainty.batched` chunk by chunk, so memory stays bounded, and their eigenvalues by
the compiled loop of :func:`robust.analysis.small_eig.eigvals_stack` (LAPACK's to
rounding); each member's largest real part and smallest damping ratio in a band make the
family's :class:`ValidationResult`. An uncertain system (:func:`uncertainty.uss`) is
validated the same way through its own state matrices.

Bad members: every member is checked once, vectorised, before any pole is computed
(:meth:`uncertainty.family.Family.check_members`, :data:`CHECK_ROWS` rows per pass), so a
bad member costs no work. ``chunk`` is capped by :data:`MAX_CHUNK_BYTES`; with ``jobs`` or
a Dask scheduler the members are validated in tasks of
:data:`~uncertainty.batched.TASK_MEMBERS`, with the same result bit for bit.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import control as ct
import numpy as np

from robust.analysis.small_eig import eigvals_stack
from robust.analysis.stability import DAMPING_BAND_HZ, damping_in_band, stability_bound
from robust.checks import FINITE, check_callable, check_int, check_scalar
from robust.engine import map_tasks, scheduler_address
from robust.errors import ModelStructureError, ParameterError
from uncertainty.batched import TASK_MEMBERS, _check_family, _closed_loop
from uncertainty.constants import DEFAULT_CHUNK
from uncertainty.family import BOUNDS_RTOL, Family
from uncertainty.region import EVERY_FREQUENCY_HZ
from uncertainty.sampling import SampleSet
from uncertainty.uss import USS

__all__ = [
    "STABILITY_THRESHOLD",
    "DEFAULT_CHUNK",
    "ValidationResult",
    "validate_family",
    "member_metrics",
    "MAX_CHUNK_BYTES",
    "CHECK_ROWS",
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
#: Rows checked per pass by :meth:`uncertainty.family.Family.check_members` before any pole is
#: computed (bounded memory for the check of millions of members).
CHECK_ROWS = 1_000_000


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


def _member_metrics(poles: np.ndarray, band_hz) -> tuple[np.ndarray, np.ndarray]:
    return poles.real.max(axis=1), damping_in_band(poles, band_hz)


def _check_options(where: str, chunk, band_hz, progress) -> tuple[int, tuple[float, float]]:
    """Validate ``chunk``, ``band_hz`` and ``progress`` of a batched call."""
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


def _memory_chunk(family: Family, controller, chunk: int) -> int:
    """``chunk`` reduced so that one chunk's matrices stay within :data:`MAX_CHUNK_BYTES`."""
    n = 1 + 4 + 4 + (4 if family.human == "physical" else 2)
    if isinstance(controller, ct.StateSpace):
        n += int(controller.nstates)
    return max(1, min(chunk, MAX_CHUNK_BYTES // (40 * n * n)))


def _check_all(family: Family, values, check_bounds: bool, where: str) -> np.ndarray:
    """Check every member, :data:`CHECK_ROWS` rows per pass, before any pole is computed."""
    if not (isinstance(values, np.ndarray) and values.ndim == 2 and values.dtype.kind in "iuf"):
        return family.check_members(values, check_bounds=check_bounds, where=where)
    v = np.asarray(values, float)
    for start in range(0, max(1, v.shape[0]), CHECK_ROWS):
        family.check_members(
            v[start : start + CHECK_ROWS],
            check_bounds=check_bounds,
            row_offset=start,
            where=where,
        )
    return v


def member_metrics(
    family: Family,
    values: np.ndarray,
    *,
    controller: ct.StateSpace | None = None,
    chunk: int = DEFAULT_CHUNK,
    band_hz: tuple[float, float] = DAMPING_BAND_HZ,
    progress: Callable[[int], None] | None = None,
    check_bounds: bool = True,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Per-member largest real part and smallest in-band damping ratio, chunk by chunk.

    Every member is checked (:meth:`uncertainty.family.Family.check_members`) before
    any pole is computed.

    Parameters
    ----------
    family : Family
        The family the members belong to.
    values : ndarray, shape (N, d)
        Uncertain-parameter values (columns in ``family.names`` order).
    controller, chunk, band_hz, progress, check_bounds
        As for :func:`validate_family`.

    Returns
    -------
    max_real : ndarray, shape (N,)
        Largest real part of each member's closed-loop poles, 1/s.
    min_damping : ndarray, shape (N,)
        Smallest damping ratio of each member's poles in ``band_hz`` (``inf`` if none).
    nstates : int
        Closed-loop order.

    Raises
    ------
    ParameterError
        If a member is non-finite, non-physical or (with ``check_bounds``) outside the
        family's bounds (the message names the row and the parameter), ``chunk`` is not
        a positive integer, ``band_hz`` is not ``0 <= low < high`` or ``progress`` is not
        callable.
    """
    _check_family(family, "member_metrics")
    chunk, band_hz = _check_options("member_metrics", chunk, band_hz, progress)
    values = _check_all(family, values, check_bounds, "member_metrics")
    return _metrics(family, values, controller, chunk, band_hz, progress)


def _metrics(family, values, controller, chunk, band_hz, progress):
    """:func:`member_metrics` of checked values and options."""
    chunk = _memory_chunk(family, controller, chunk)
    N = values.shape[0]
    max_real = np.empty(N)
    min_damp = np.empty(N)
    nstates = 0
    for start in range(0, N, chunk):
        stop = min(N, start + chunk)
        Acl = _closed_loop(family, values[start:stop], controller)
        nstates = Acl.shape[-1]
        poles = eigvals_stack(Acl)
        del Acl
        max_real[start:stop], min_damp[start:stop] = _member_metrics(poles, band_hz)
        if progress is not None:
            progress(stop - start)
    return max_real, min_damp, int(nstates)


def _metrics_task(family, controller, chunk, band_hz, values):
    """One task of a parallel validation: the metrics of a slice of checked members."""
    return _metrics(family, values, controller, chunk, band_hz, None)


def _distributed_metrics(family, values, controller, chunk, band_hz, progress, jobs, scheduler):
    """:func:`_metrics` in tasks of :data:`TASK_MEMBERS` members on the chosen engine."""
    jobs = check_int("validate_family: jobs", jobs, low=1)
    N = values.shape[0]
    starts = list(range(0, N, TASK_MEMBERS))
    slices = [values[a : a + TASK_MEMBERS] for a in starts]
    sizes = [len(v) for v in slices]
    done = (lambda i: progress(sizes[i])) if progress is not None else None
    parts = map_tasks(
        functools.partial(_metrics_task, family, controller, chunk, band_hz),
        slices,
        jobs=jobs,
        scheduler=scheduler,
        progress=done,
        threads=True,
    )
    max_real = np.concatenate([p[0] for p in parts])
    min_damp = np.concatenate([p[1] for p in parts])
    return max_real, min_damp, parts[0][2]


def validate_family(
    family: Family | USS,
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

    Member values must be finite and physical and lie within the family's bounds
    (:meth:`uncertainty.family.Family.check_members`); every member is checked,
    vectorised, before any pole is computed, so a bad member costs no work.

    Parameters
    ----------
    family : Family or USS
        The family the members belong to, or an uncertain system
        (:func:`uncertainty.uss`; its members are the values of its uncertain reals).
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
    if isinstance(family, USS):
        band_hz = EVERY_FREQUENCY_HZ if band_hz is None else band_hz
        return _validate_system(
            family, samples, controller, chunk, band_hz, stability_threshold, progress, check_bounds
        )  # (small systems: in this process)
    band_hz = DAMPING_BAND_HZ if band_hz is None else band_hz
    _check_family(family, "validate_family")
    if not isinstance(samples, SampleSet):
        raise ParameterError(
            f"validate_family: samples must be an uncertainty.SampleSet; "
            f"got {type(samples).__name__}"
        )
    if tuple(samples.names) != family.names:
        raise ParameterError(
            f"validate_family: sample names {list(samples.names)} do not match the family's "
            f"{list(family.names)}"
        )
    chunk, (lo, hi) = _check_options("validate_family", chunk, band_hz, progress)
    stability_threshold = check_scalar(
        "validate_family: stability_threshold", stability_threshold, FINITE
    )
    N = len(samples)
    if N == 0:
        raise ParameterError("validate_family: samples holds no members; got 0 rows")
    values = _check_all(family, samples.values, check_bounds, "validate_family")
    if jobs == 1 and scheduler_address(scheduler) is None:
        max_real, min_damp, nstates = _metrics(
            family, values, controller, chunk, (lo, hi), progress
        )
    else:
        max_real, min_damp, nstates = _distributed_metrics(
            family, values, controller, chunk, (lo, hi), progress, jobs, scheduler
        )
    if not np.all(np.isfinite(max_real)):
        raise ModelStructureError(
            "non-finite closed-loop poles for some members; check parameter ranges"
        )
    return _result(
        samples,
        max_real,
        min_damp,
        stability_threshold,
        (lo, hi),
        nstates,
        0 if controller is None else int(controller.nstates),
        family.human,
        family.k_psf,
    )


def _validate_system(
    system, samples, controller, chunk, band_hz, threshold, progress, check_bounds
):
    """:func:`validate_family` of an uncertain system (closed with ``controller``)."""
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
    chunk, (lo, hi) = _check_options(where, chunk, band_hz, progress)
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
        max_real[start:stop], min_damp[start:stop] = _member_metrics(poles, (lo, hi))
        if progress is not None:
            progress(stop - start)
    if not np.all(np.isfinite(max_real)):
        raise ModelStructureError(f"{where}: non-finite closed-loop poles for some members")
    ctrl_states = 0 if controller is None else int(ct.ss(controller).nstates)
    return _result(samples, max_real, min_damp, threshold, (lo, hi), n, ctrl_states, None, None)


def _result(samples, max_real, min_damp, threshold, band, nstates, ctrl_states, human, k_psf):
    """The :class:`ValidationResult` of per-member metrics."""
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
