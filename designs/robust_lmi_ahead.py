"""The robust LMI ladder's speed plumbing: the rung cache, and a worker trying a scale ahead.

``_cached_rung`` reads a rung of the ladder (``_try_scale`` of
:mod:`designs.robust_lmi_rung`) back from the cache (:func:`robust.cache.caching`) when the
same inputs were tried before, and keeps it otherwise: ``_rung_inputs`` is its key,
``_keep_rung`` and ``_stored_rung`` store and read it. ``_Ahead`` is a worker process that
tries the first bisection scale while the ladder tries its next rung (``_rung_task``); the
ladder writes the scale it wants into a temporary file, and a guess no longer wanted reads
it and stops (``_Stale``). Neither changes the design: a rung read back or guessed has
exactly the inputs of the one the ladder would try, so the same result to the bit. Kept
apart from the ladder (:mod:`designs.robust_lmi_ladder`): it only saves time.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import tempfile

import control as ct
import numpy as np
from joblib.externals.loky import ProcessPoolExecutor

from designs.robust_lmi_rung import _try_scale
from robust.cache import caching_enabled, lookup, store
from robust.synthesis.solve import deterministic_solvers

#: Nothing public: the ladder's own (:mod:`designs.robust_lmi_ladder`).
__all__: list[str] = []


class _Stale(Exception):
    """Raised in :class:`_Ahead`'s worker when the ladder no longer wants the scale it tries."""


def _wanted(path) -> str:
    """The key the ladder wants tried beside it (written by :meth:`_Ahead.guess`)."""
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except OSError:
        return ""


def _rung_inputs(family, k, K, rows, spec, options, limits) -> dict:
    """What one rung (:func:`_try_scale`) depends on besides the code, as a cache key.

    The options the ladder alone reads (``ladder``, ``bisection``, ``margin_boxes``) are left
    out, so a rung of the force trade-off (no bisection, fewer boxes) and the same rung of
    the design share one entry; the controller counts by its matrices. The key is made of
    values only: the dataclasses' ``repr`` (floats written exactly) and the arrays' bytes,
    not pickles, whose bytes depend on which equal strings are one object (a family sent
    to a worker process pickles otherwise than the same family built there).
    """
    mats = (K.A, K.B, K.C, K.D) if isinstance(K, ct.StateSpace) else tuple(K)
    opts = dataclasses.replace(options, ladder=(1.0,), bisection=0, margin_boxes=1)
    h = hashlib.sha256(repr((family, float(k), type(K).__name__, spec, opts, limits)).encode())
    for m in (*mats, rows):
        a = np.ascontiguousarray(m, dtype=float)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return {"rung": h.hexdigest()}


def _keep_rung(args, result) -> None:
    """Store a rung's result (``args`` as :func:`_try_scale`'s, ``progress`` aside) when
    :func:`robust.cache.caching` is on."""
    if caching_enabled():
        store("robust-lmi-rung", _rung_inputs(*args), result)


def _stored_rung(args):
    """The cached result of the rung ``args`` (:func:`_try_scale`'s, ``progress`` aside), or
    ``None`` (not stored, or :func:`robust.cache.caching` off)."""
    if not caching_enabled():
        return None
    found, result = lookup("robust-lmi-rung", _rung_inputs(*args))
    return result if found else None


def _cached_rung(family, k, K, rows, spec, options, limits, progress):
    """:func:`_try_scale`, or its result from the cache when :func:`robust.cache.caching` is
    on and the same rung was tried before (by the force trade-off's point at the same
    limits, or an earlier run): the same inputs give the same result to the bit."""
    args = (family, k, K, rows, spec, options, limits)
    result = _stored_rung(args)
    if result is not None:
        if progress:
            progress(f"scale {k:.3g}: tried before, taken from the cache")
        return result
    result = _try_scale(*args, progress)
    _keep_rung(args, result)
    return result


def _rung_task(task, key=None, wanted=None):
    """One scale of the ladder in a worker process (:class:`_Ahead`): ``_try_scale``'s
    arguments but ``progress``; solved on one thread, as :func:`maximise_margin` does.

    With ``wanted`` (a file holding the key the ladder wants), the task stops, raising
    :class:`_Stale`, at its start or after any round once that file names another key.
    """

    def still_wanted(_message=None):
        if wanted is not None and _wanted(wanted) != repr(key):
            raise _Stale(key)

    still_wanted()
    with deterministic_solvers():
        return _try_scale(*task, still_wanted)


class _Ahead:
    """A worker process that tries the first bisection scale while the ladder tries the next
    rung: if that rung fails, the bisection from the last scale reached is already done.

    The guess has exactly the inputs the bisection would have (the same controller, design
    members and scale), so the design is the same to the bit with or without it; a guess
    whose rung is reached is discarded. Each rung wants its own guess: one still running
    for an earlier rung stops after its current round (it reads the key wanted from a
    file), so the worker is free for the long rung, the one that fails, however long the
    short rungs before it took. The worker is terminated when the ladder is done. Used
    when :func:`robust.engine.nested_jobs` grants two processes or more.
    """

    def __init__(self):
        # loky's executor (joblib's): cloudpickle carries the controllers; a private one, so
        # that the worker can be stopped without touching joblib's pool
        self._pool = ProcessPoolExecutor(max_workers=1)
        self._dir = tempfile.mkdtemp(prefix="bdft-ahead-")
        self._file = os.path.join(self._dir, "wanted")
        self._job = None
        self._key = None

    def _want(self, text: str) -> None:
        tmp = self._file + ".tmp"
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, self._file)

    def guess(self, key, task) -> None:
        """Start ``task`` (the scale ``key``); a guess still running stops at its next round."""
        self._want(repr(key))
        self._job, self._key = self._pool.submit(_rung_task, task, key, self._file), key

    def idle(self) -> None:
        """No guess is wanted (the next scales are in the cache): one running stops."""
        self._want("")
        self._job = self._key = None

    def answer(self, key):
        """The result for the scale ``key`` if it was guessed, else ``None``."""
        return self._job.result() if self._job is not None and self._key == key else None

    def close(self) -> None:
        """Stop the worker (a guess still running is not needed)."""
        self._pool.shutdown(wait=True, kill_workers=True)
        shutil.rmtree(self._dir, ignore_errors=True)
