"""Validation of the BDFT family's members: closed-loop pole metrics of every member, chunk by
chunk (:func:`uncertainty.validate_family`, registered here for
:class:`~backhoe.families.family.Family`).

:func:`uncertainty.validate_family` and :func:`member_metrics` take the closed-loop state
matrices of
:mod:`backhoe.families.batched` chunk by chunk, so memory stays bounded, and their eigenvalues by
the compiled loop of :func:`robust.analysis.small_eig.eigvals_stack` (LAPACK's to
rounding); each member's largest real part and smallest damping ratio in a band make the
family's :class:`~uncertainty.validation.ValidationResult`.

Bad members: every member is checked once, vectorised, before any pole is computed
(:meth:`backhoe.families.family.Family.check_members`, :data:`CHECK_ROWS` rows per pass), so a
bad member costs no work. ``chunk`` is capped by :data:`MAX_CHUNK_BYTES`; with ``jobs`` or
a Dask scheduler the members are validated in tasks of
:data:`~backhoe.families.batched.TASK_MEMBERS`, with the same result bit for bit.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import control as ct
import numpy as np

from backhoe.constants import DAMPING_BAND_HZ
from backhoe.families.batched import TASK_MEMBERS, _check_family, _closed_loop
from backhoe.families.family import Family
from robust.analysis.small_eig import eigvals_stack
from robust.checks import FINITE, check_int, check_scalar
from robust.engine import map_tasks, scheduler_address
from robust.errors import ModelStructureError, ParameterError
from uncertainty.constants import DEFAULT_CHUNK
from uncertainty.sampling import SampleSet
from uncertainty.validation import (
    MAX_CHUNK_BYTES,
    STABILITY_THRESHOLD,
    check_batch_options,
    member_pole_metrics,
    validate_family,
    validation_result,
)

__all__ = ["member_metrics", "CHECK_ROWS"]

#: Rows checked per pass by :meth:`backhoe.families.family.Family.check_members` before any pole is
#: computed (bounded memory for the check of millions of members).
CHECK_ROWS = 1_000_000


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

    Every member is checked (:meth:`backhoe.families.family.Family.check_members`) before
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
    chunk, band_hz = check_batch_options("member_metrics", chunk, band_hz, progress)
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
        max_real[start:stop], min_damp[start:stop] = member_pole_metrics(poles, band_hz)
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


@validate_family.register
def _(
    family: Family,
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
    # uncertainty.validate_family of the BDFT family: its batched matrices, every member
    # checked first (Family.check_members), in tasks of TASK_MEMBERS on any engine
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
    chunk, (lo, hi) = check_batch_options("validate_family", chunk, band_hz, progress)
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
    return validation_result(
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
