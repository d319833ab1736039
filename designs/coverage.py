"""Coverage of a design: on what fraction of the operators and machines does the specification hold?

The certified robust margin (:func:`uncertainty.margins.robust_margin`) answers "on how
large a box about the nominal does the pole region hold for *every* member"; a safety
reviewer also asks "for what fraction of the population does the *whole* specification
hold". :func:`design_coverage` answers the second question with a probabilistic
certificate: ``samples`` members drawn independently (Monte Carlo) from the family's
distributions with a seed no design uses, the specification
(:func:`designs.spec.check_specification`) checked on each member alone, and the count
of failures turned into ``P(failure) <= epsilon`` with confidence ``1 - beta``
(:class:`uncertainty.randomized.CoverageBound`, the Clopper-Pearson bound of randomized
robustness analysis, Tempo, Calafiore & Dabbene 2005).

Per member, every constraint is evaluated as :func:`~designs.spec.check_specification`
defines it; the peak force is simulated (20 s of seeded realistic intended motion at
1 kHz, seed ``seed + i`` for member ``i``) on every member that meets all the other
constraints, since a member that already fails needs no simulation to be counted.
Members are checked in parallel (joblib, ``n_jobs`` processes); the verdicts do not
depend on how the members are split.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

import control as ct
import numpy as np

from backhoe import Family
from backhoe.families.batched import closed_loop_matrices
from designs.spec import check_specification, unstable_member_check
from designs.spec_forces import peak_force, peak_time_grid
from designs.specification import CONSTRAINTS, Specification
from robust.analysis.loops import closed_loop_poles
from robust.analysis.stability import damping_in_band
from robust.checks import check_int
from robust.engine import run_calls
from robust.errors import BDFTError, ModelStructureError, ParameterError
from robust.jsonio import to_jsonable
from robust.synthesis.solve import deterministic_solvers
from uncertainty import sample
from uncertainty.randomized import DEFAULT_CONFIDENCE, CoverageBound

__all__ = [
    "COVERAGE_SAMPLES",
    "COVERAGE_SEED_OFFSET",
    "DesignCoverage",
    "MemberVerdicts",
    "member_verdicts",
    "design_coverage",
]

#: Default number of independent members of a coverage certificate.
COVERAGE_SAMPLES = 2000
#: The coverage sample of a design run with seed ``s`` is drawn with seed ``s + 2``
#: (``s`` draws the design sample, ``s + 1`` the held-out validation sample).
COVERAGE_SEED_OFFSET = 2
#: Members per parallel task.
_CHUNK = 50


@dataclasses.dataclass(frozen=True)
class MemberVerdicts:
    """The specification checked on each member alone.

    Parameters
    ----------
    violated : numpy.ndarray of bool, shape (n, 6)
        ``violated[i, j]``: member ``i`` violates constraint :data:`CONSTRAINTS` ``[j]``
        (the peak force is only simulated where every other constraint holds, so a
        member failing elsewhere shows ``False`` there).
    binding : tuple of str
        The binding constraint of each member (largest utilisation).
    utilisation : numpy.ndarray, shape (n,)
        The binding constraint's utilisation per member (1 at the limit).
    """

    violated: np.ndarray
    binding: tuple[str, ...]
    utilisation: np.ndarray

    @property
    def holds(self) -> np.ndarray:
        """Per member: whether the whole specification holds."""
        return ~self.violated.any(axis=1)


def _check_chunk(family, rows, controller, spec, seeds, duration_s):
    # one BLAS thread: the same members give the same numbers in this process or a worker
    with deterministic_solvers():
        return _check_rows(family, rows, controller, spec, seeds, duration_s)


#: A member is screened as unstable when a pole of its full closed loop has a real part
#: above this, relative to its largest pole modulus (and at least 1): far beyond the rounding
#: that separates two realisations of the same loop (7e-12 measured on the physical human's
#: loops, 8e-9 on the literal human's).
SCREEN_RTOL = 1e-6
#: ... and when no pole lies within this (relative) of the damping band's edges and its
#: in-band damping ratio not within this of the required one (the two realisations' damping
#: ratios differed by up to 3e-7 on the literal human's loops).
SCREEN_EDGE = 1e-4


def _screen(family, rows, controller, spec):
    """Members whose closed loop is unstable beyond doubt, from their batched poles.

    Returns ``(unstable, max_real, damping, n)``: a mask of the members that
    :func:`~designs.spec.check_specification` certainly finds unstable, their poles' figures
    and the order of the full closed loop. A member is screened only when its largest real
    part exceeds :data:`SCREEN_RTOL` of its poles' scale and nothing else of the check could
    tip with the realisation's rounding: no pole within that tolerance of the origin, none
    within :data:`SCREEN_EDGE` of the damping band's edges, and its in-band damping not within
    it of the required one. The full closed loop
    (:func:`backhoe.families.batched.closed_loop_matrices`) has every mode of the minimal
    realisation the check takes its poles from, but may have more: :func:`_screened_rows`
    screens only where the check's minimal realisation drops none.
    """
    A = closed_loop_matrices(family, rows, controller=controller)
    if not np.all(np.isfinite(A)):
        raise ModelStructureError("coverage screen: non-finite closed-loop matrix")
    lam = np.linalg.eigvals(A)
    mag = np.abs(lam)
    scale = np.maximum(1.0, mag.max(axis=1))
    tol = SCREEN_RTOL * scale
    max_real = lam.real.max(axis=1)
    lo, hi = spec.damping_band_hz
    f = np.abs(lam.imag) / (2 * np.pi)
    ftol = SCREEN_EDGE * np.maximum(1.0, f)
    edge = (np.abs(f - lo) <= ftol) | (np.abs(f - hi) <= ftol) | (mag <= tol[:, None])
    damping = damping_in_band(lam, spec.damping_band_hz)
    tipping = np.abs(damping - spec.min_damping) <= SCREEN_EDGE
    unstable = (max_real > tol) & ~edge.any(axis=1) & ~tipping
    return unstable, max_real, damping, A.shape[-1]


def _verdict(check) -> tuple:
    """What a member's check contributes to the coverage: each constraint's verdict, and the
    binding constraint with its utilisation."""
    util = [c.utilisation for c in check.constraints]
    k = int(np.argmax(util))
    return tuple(c.holds for c in check.constraints), check.constraints[k].name, util[k]


def _screened_rows(family, rows, controller, spec, seeds, has_force):
    """Per member, its :class:`~designs.spec.SpecCheck` when :func:`_screen` settles it
    (else ``None``).

    The first screened member is checked in full, and nothing is screened unless its
    verdict is the screen's and the minimal realisation of its loop keeps every mode of the
    full closed loop: a mode that realisation drops (an uncontrollable or unobservable one,
    e.g. a controller state wired to nothing, or the literal human's cancelled poles) is a
    property of the loop's structure and the controller, the same for every member, and an
    unstable one would count against the screened members only.
    """
    out = [None] * len(rows)
    if not isinstance(family, Family) or len(rows) < 2:
        return out
    if controller is not None and not isinstance(controller, ct.StateSpace):
        return out  # (the full check says what is wrong with it)
    try:
        unstable, max_real, damping, n = _screen(family, rows, controller, spec)
    except (BDFTError, np.linalg.LinAlgError):
        return out  # (the full check of each member says what is wrong)
    if not unstable.any():
        return out
    first = int(np.argmax(unstable))
    loop = family.member(rows[first])
    ps = closed_loop_poles(loop.system(bdft=True, controller=controller))
    if ps.poles.size != n or ps.hidden.size:
        return out
    full = check_specification([loop], controller, spec, seed=seeds[first], simulate_peak=0)
    quick = unstable_member_check(max_real[first], damping[first], spec, has_force)
    if _verdict(full) != _verdict(quick):
        return out
    out[first] = full
    for r in np.flatnonzero(unstable):
        if r != first:
            out[r] = unstable_member_check(max_real[r], damping[r], spec, has_force)
    return out


def _check_rows(family, rows, controller, spec, seeds, duration_s):
    t = peak_time_grid(duration_s)
    i_peak = CONSTRAINTS.index("peak force")
    violated = np.zeros((len(rows), len(CONSTRAINTS)), bool)
    binding, util = [], np.empty(len(rows))
    has_force = isinstance(controller, ct.StateSpace) and "f" in controller.output_labels
    # members unstable beyond doubt need no loop of their own (their forces, tracking and
    # feedthrough are undefined, so they fail; only the damping needs their poles)
    settled = _screened_rows(family, rows, controller, spec, seeds, has_force)
    for r, (row, s) in enumerate(zip(rows, seeds)):
        loop = None
        res = settled[r]
        if res is None:
            loop = family.member(row)
            res = check_specification([loop], controller, spec, seed=s, simulate_peak=0)
        for j, c in enumerate(res.constraints):
            violated[r, j] = not c.holds
        checks = list(res.constraints)
        if not violated[r].any() and has_force:
            if loop is None:
                loop = family.member(row)
            amp = loop.intended_amplitude(spec.limits(), spec.intent_fraction)
            pk = peak_force(loop, controller, amp, spec.intent_bandwidth_hz, t, seed=s)
            violated[r, i_peak] = not pk <= spec.peak_force_n
            c = checks[i_peak]
            checks[i_peak] = dataclasses.replace(
                c, value=pk, holds=bool(pk <= spec.peak_force_n), utilisation=pk / c.limit
            )
        k = int(np.argmax([c.utilisation for c in checks]))
        binding.append(checks[k].name)
        util[r] = checks[k].utilisation
    return violated, binding, util


def member_verdicts(
    family,
    values,
    controller,
    spec: Specification | None = None,
    *,
    seed: int = 0,
    duration_s: float = 20.0,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> MemberVerdicts:
    """Check the specification on each member of ``values`` alone.

    Parameters
    ----------
    family : backhoe.Family
        The family (its :meth:`~backhoe.Family.member` builds each loop).
    values : array_like, shape (n, d)
        Member rows in the order of ``family.names``.
    controller : control.StateSpace or None
        The compensator (loop convention of :mod:`backhoe.model.loop`).
    spec : Specification, optional
        Default :class:`~designs.spec.Specification` ``()``.
    seed : int
        Member ``i``'s peak-force simulation uses seed ``seed + i``.
    duration_s : float
        Length of each peak-force simulation, s.
    n_jobs : int
        Parallel processes (joblib); 1 runs in this process.
    progress : callable, optional
        Called as ``progress(done, total)`` after each chunk of members.

    Returns
    -------
    MemberVerdicts
    """
    spec = Specification() if spec is None else spec
    if not isinstance(spec, Specification):
        raise ParameterError(
            f"member_verdicts: spec must be a Specification; got {type(spec).__name__}"
        )
    seed = check_int("seed", seed, low=0, owner="member_verdicts")
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="member_verdicts")
    rows = family.check_members(values, where="member_verdicts")
    n = rows.shape[0]
    starts = list(range(0, n, _CHUNK))
    calls = [
        functools.partial(
            _check_chunk,
            family,
            rows[a : a + _CHUNK],
            controller,
            spec,
            [seed + i for i in range(a, min(a + _CHUNK, n))],
            duration_s,
        )
        for a in starts
    ]
    done = [0]

    def step(i):
        done[0] += min(_CHUNK, n - starts[i])
        if progress:
            progress(done[0], n)

    parts = run_calls(calls, jobs=n_jobs, progress=step)
    return MemberVerdicts(
        violated=np.vstack([p[0] for p in parts]),
        binding=tuple(b for p in parts for b in p[1]),
        utilisation=np.concatenate([p[2] for p in parts]),
    )


@dataclasses.dataclass(frozen=True)
class DesignCoverage:
    """The fraction of the population on which a design meets the specification.

    Parameters
    ----------
    bound : CoverageBound
        Samples, failures, confidence, seed and the certificate ``epsilon``.
    violations : dict
        Per constraint, the members violating it (a member may violate several; the peak
        force is simulated only where all else holds).
    binding : dict
        Per constraint, the failing members on which it binds (largest utilisation).
    failing_members : tuple of dict
        Up to 10 failing members: their parameters and binding constraint.
    specification : dict
        The specification checked (:meth:`Specification.to_json`).
    """

    bound: CoverageBound
    violations: dict
    binding: dict
    failing_members: tuple = ()
    specification: dict = dataclasses.field(default_factory=dict)

    @property
    def fraction(self) -> float:
        """Observed fraction of the members meeting the specification."""
        return self.bound.fraction

    def describe(self) -> str:
        """One line: the coverage and its certificate."""
        return self.bound.describe()

    def to_json(self) -> dict:
        """``fraction``, ``samples``, ``failures``, ``epsilon``, ``confidence``, ... JSON-ready."""
        out = self.bound.to_json()
        out.update(
            violations=dict(self.violations),
            binding=dict(self.binding),
            failing_members=to_jsonable(list(self.failing_members)),
            specification=self.specification,
        )
        return out


def design_coverage(
    family,
    controller,
    spec: Specification | None = None,
    *,
    samples: int = COVERAGE_SAMPLES,
    seed: int = COVERAGE_SEED_OFFSET,
    confidence: float = DEFAULT_CONFIDENCE,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> DesignCoverage:
    """Coverage of ``controller`` on ``family`` with its probabilistic certificate.

    ``samples`` members are drawn independently from the family's distributions
    (``sample(..., method="mc", seed=seed)``); the specification is checked on each
    (:func:`member_verdicts`); ``k`` failures in ``N`` give ``P(failure) <= epsilon``
    with confidence ``confidence`` (:func:`uncertainty.randomized.failure_bound`).

    Parameters
    ----------
    family : backhoe.Family
    controller : control.StateSpace or None
    spec : Specification, optional
    samples : int
        Independent members (>= 1).
    seed : int
        Seed of the sample (use one no design used: :data:`COVERAGE_SEED_OFFSET` past the
        design seed).
    confidence : float
        ``1 - beta`` of the certificate.
    n_jobs : int
        Parallel processes.
    progress : callable, optional
        ``progress(done, total)``.

    Returns
    -------
    DesignCoverage
    """
    spec = Specification() if spec is None else spec
    samples = check_int("samples", samples, low=1, owner="design_coverage")
    members = sample(family.parameters, samples, method="mc", seed=seed)
    v = member_verdicts(
        family, members.values, controller, spec, seed=seed, n_jobs=n_jobs, progress=progress
    )
    fails = np.flatnonzero(~v.holds)
    bound = CoverageBound(samples, int(fails.size), confidence, seed=seed, method="mc")
    violations = {c: int(v.violated[:, j].sum()) for j, c in enumerate(CONSTRAINTS)}
    binding = {c: sum(1 for i in fails if v.binding[i] == c) for c in CONSTRAINTS}
    failing = tuple(
        {
            "index": int(i),
            "binding": v.binding[i],
            "utilisation": float(v.utilisation[i]),
            "parameters": dict(zip(family.names, map(float, members.values[i]))),
        }
        for i in fails[:10]
    )
    return DesignCoverage(bound, violations, binding, failing, spec.to_json())
