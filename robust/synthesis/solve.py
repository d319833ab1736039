"""The one place the workbench calls a conic solver.

:func:`solve_problem` tries Clarabel first and SCS as fallback, maps the
solver's status to :mod:`robust.errors` exceptions and returns the statistics.
An answer flagged inaccurate is returned (with ``accurate=False``) so that the
caller's independent verification decides; it is never trusted on its own.
:func:`check_solvers` validates a list of solver names before any work is done.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import functools
import sys
import time
import warnings
import weakref

import cvxpy as cp
import numpy as np
from cvxpy.reductions.solvers.defines import SOLVER_MAP_CONIC
from threadpoolctl import ThreadpoolController

from robust.checks import Spec, check_scalar
from robust.errors import InfeasibleError, ParameterError, SolverError

__all__ = [
    "DEFAULT_SOLVERS",
    "SOLVER_TOL",
    "SolveResult",
    "check_solvers",
    "deterministic_solvers",
    "solve_problem",
    "solver_threads",
]

DEFAULT_SOLVERS = ("CLARABEL", "SCS")

#: Clarabel's thread count (0: its own choice); :func:`deterministic_solvers` sets 1.
_THREADS: contextvars.ContextVar[int] = contextvars.ContextVar("clarabel_threads", default=0)

#: feasibility tolerance requested from each solver; LMI strictness margins are tied to it
SOLVER_TOL = {"CLARABEL": 1e-8, "SCS": 1e-6}

_SOLVER_OPTS = {
    "CLARABEL": lambda tol: {
        "tol_feas": tol,
        "tol_gap_abs": tol,
        "tol_gap_rel": tol,
        "max_iter": 200,
        "direct_solve_method": "faer",
        "iterative_refinement_enable": False,
        "max_threads": _THREADS.get(),
    },
    "SCS": lambda tol: {"eps_abs": tol, "eps_rel": tol, "max_iters": 50000},
}


@contextlib.contextmanager
def deterministic_solvers():
    """Within the block, Clarabel factorises on one thread and the BLAS runs on one thread.

    faer's parallel factorisation sums in an order that depends on the machine's load, and
    a threaded BLAS sums in an order that depends on ``OPENBLAS_NUM_THREADS``, so the same
    problem can come back with answers that differ in the last digits; a nonsmooth design
    that runs many solves and line searches in sequence amplifies that into different
    controllers. The robust designs (the BFGS-tuned and the LMI-made ones) run inside this
    block, so the same seed gives the same controller on any thread count and any load.
    """
    token = _THREADS.set(1)
    try:
        with _blas_controller().limit(limits=1, user_api="blas"):
            yield
    finally:
        _THREADS.reset(token)


#: (modules imported when it was made, the controller) of :func:`_blas_controller`
_CONTROLLER: list = [-1, None]


def _blas_controller() -> ThreadpoolController:
    """threadpoolctl's view of the BLAS libraries loaded in this process, kept between calls.

    Making it scans the process's shared libraries (about 0.7 ms; the calibrations and the
    coverage checks enter :func:`deterministic_solvers` thousands of times per report); it
    is made again when a module has been imported since, as a new BLAS library comes with
    the module that loads it.
    """
    if _CONTROLLER[0] != len(sys.modules):
        controller = ThreadpoolController()
        _CONTROLLER[:] = [len(sys.modules), controller]
    return _CONTROLLER[1]


def solver_threads() -> int:
    """Clarabel's thread count in this context: 1 inside :func:`deterministic_solvers`, else 0
    (its own choice)."""
    return _THREADS.get()


@functools.cache
def _installed() -> frozenset[str]:
    """The cvxpy solvers installed here (cvxpy probes them on every call: 3 ms, once per
    solve of a design's hundreds; what is installed does not change within a process)."""
    return frozenset(cp.installed_solvers())


#: Per problem, the twin each fallback solver solves (see :func:`_for_solver`).
_TWINS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _for_solver(problem: cp.Problem, name: str, first: bool) -> cp.Problem:
    """The problem object that solver ``name`` solves: ``problem`` itself for the first
    solver of the list, else a twin (the same objective and constraints, so the same
    variables and parameters) kept for that solver.

    cvxpy keeps one compiled form per problem: solving it with another solver compiles it
    again and drops the first solver's. A parameterised problem that Clarabel solves
    hundreds of times, SCS now and then, was compiled afresh twice at each fallback (about
    0.4 s each for the achievable-limit map's cones); each solver now keeps its own. The
    answers are those of compiling afresh: the compiled form is the same, and a twin is
    solved without a warm start.
    """
    if first:
        return problem
    twins = _TWINS.setdefault(problem, {})
    if name not in twins:
        twins[name] = cp.Problem(problem.objective, problem.constraints)
    return twins[name]


def _sdp_capable() -> set[str]:
    """Names of the cvxpy conic solvers that accept semidefinite (PSD) cones."""
    return {
        name
        for name, solver in SOLVER_MAP_CONIC.items()
        if any(c.__name__ in ("PSD", "SvecPSD") for c in solver.SUPPORTED_CONSTRAINTS)
    }


def check_solvers(solvers, *, name: str = "solvers", sdp: bool = False) -> tuple[str, ...]:
    """Validate a sequence of cvxpy solver names; return them upper-cased, in order.

    A name cvxpy does not know is an error (a typo would otherwise only show up as
    "not installed" after the problem was built); a known solver that is not
    installed here is accepted (:func:`solve_problem` skips it and says so).

    Parameters
    ----------
    solvers : sequence of str
        Solver names in order of preference, e.g. ``("CLARABEL", "SCS")``; case
        does not matter.  A bare string is refused (wrap a single name in a tuple).
    name : str
        Name of the parameter, for messages (e.g. ``"hinfsyn_lmi: solvers"``).
    sdp : bool
        Also require every solver to handle semidefinite cones (the LMI problems).

    Returns
    -------
    tuple of str

    Raises
    ------
    ParameterError
        If ``solvers`` is not a non-empty sequence of strings, names a solver cvxpy
        does not know, or (``sdp=True``) a solver that cannot solve SDPs.
    """
    installed = sorted(_installed())
    if isinstance(solvers, (str, bytes)):
        raise ParameterError(
            f"{name} must be a sequence of cvxpy solver names such as {DEFAULT_SOLVERS}; "
            f"got the string {solvers!r} (wrap a single name in a tuple: ({solvers!r},))"
        )
    try:
        names = list(solvers)
    except TypeError:
        raise ParameterError(
            f"{name} must be a sequence of cvxpy solver names such as {DEFAULT_SOLVERS}; "
            f"got {solvers!r} ({type(solvers).__name__})"
        ) from None
    if not names:
        raise ParameterError(
            f"{name} must name at least one cvxpy solver (e.g. {DEFAULT_SOLVERS}); "
            "got an empty sequence"
        )
    bad = [s for s in names if not isinstance(s, str)]
    if bad:
        raise ParameterError(
            f"{name} must contain solver names (str); got {bad[0]!r} ({type(bad[0]).__name__})"
        )
    names = [s.upper() for s in names]
    known = set(cp.settings.SOLVERS) | set(SOLVER_MAP_CONIC) | set(installed)
    unknown = [s for s in names if s not in known]
    if unknown:
        raise ParameterError(
            f"{name}: {unknown} {'is not a solver' if len(unknown) == 1 else 'are not solvers'} "
            f"cvxpy knows; expected names such as {DEFAULT_SOLVERS} (installed here: {installed})"
        )
    if sdp:
        capable = _sdp_capable()
        no_sdp = [s for s in names if s not in capable]
        if no_sdp:
            raise ParameterError(
                f"{name}: {no_sdp} cannot solve semidefinite programs (the LMIs need PSD "
                f"cones); installed solvers that can: {sorted(capable & set(installed))}"
            )
    return tuple(dict.fromkeys(names))


@dataclasses.dataclass(frozen=True)
class SolveResult:
    """What a solve returned.

    Attributes
    ----------
    solver : str
        Name of the solver that produced the answer.
    status : str
        cvxpy status string (``"optimal"`` or ``"optimal_inaccurate"``).
    accurate : bool
        False when the solver reported reduced accuracy.
    iterations : int or None
    solve_time : float
        Seconds inside the solver (as reported by it, else wall time).
    wall_time : float
        Seconds for the whole call, including cvxpy compilation.
    objective : float
    attempts : tuple of (str, str)
        ``(solver, outcome)`` for every solver tried, in order.
    """

    solver: str
    status: str
    accurate: bool
    iterations: int | None
    solve_time: float
    wall_time: float
    objective: float
    attempts: tuple


def solve_problem(
    problem: cp.Problem,
    *,
    step: str,
    solvers=DEFAULT_SOLVERS,
    gap_tol: float | None = None,
    verbose: bool = False,
    warm_start: bool = True,
    refine: bool = False,
) -> SolveResult:
    """Solve ``problem``, falling back through ``solvers``; map failure to exceptions.

    Parameters
    ----------
    problem : cvxpy.Problem
        A DPP problem may be solved repeatedly: cvxpy reuses its compilation.
    step : str
        Name of the step, used in messages (e.g. ``"hinfsyn_lmi: gamma minimisation"``).
    solvers : sequence of str
        cvxpy solver names, tried in order.
    gap_tol : float, optional
        Relative/absolute duality-gap tolerance for Clarabel (default: its
        feasibility tolerance ``SOLVER_TOL``).  Feasibility tolerances are never
        loosened: the LMI strictness margins rely on them.
    verbose : bool
        Passed to the solver.
    warm_start : bool
        cvxpy's ``warm_start``: with it, a re-solved parameterised problem reuses the
        solver's previous workspace (Clarabel's ``update``), so its answer depends in the
        last digits on what was solved before; ``False`` solves afresh each time.
    refine : bool
        Clarabel's iterative refinement of each step's linear solve (off by default: the
        LMI syntheses' SDPs do without it at half the cost). Second-order cone programs
        whose primal residual stalls and then grows near the optimum (Clarabel stops with
        ``InsufficientProgress``) converge with it.

    Returns
    -------
    SolveResult

    Raises
    ------
    ParameterError
        If ``problem`` is not a cvxpy Problem, ``step`` not a string, ``gap_tol``
        not a number in (0, 1), ``verbose`` not a bool, or ``solvers`` invalid
        (:func:`check_solvers`).
    InfeasibleError
        If a solver certifies infeasibility (or unboundedness) of the problem.
    SolverError
        If every solver failed to return a usable answer.
    """
    if not isinstance(problem, cp.Problem):
        raise ParameterError(
            f"solve_problem: problem must be a cvxpy.Problem; got {type(problem).__name__}"
        )
    if not isinstance(step, str):
        raise ParameterError(
            f"solve_problem: step must be a str naming the step; got {type(step).__name__}"
        )
    solvers = check_solvers(solvers, name=f"{step}: solvers")
    if gap_tol is not None:
        check_scalar("gap_tol", gap_tol, Spec(0.0, 1.0, True, True), owner="solve_problem")
    if not isinstance(verbose, (bool, np.bool_)):
        raise ParameterError(f"{step}: verbose must be a bool; got {verbose!r}")
    if not isinstance(refine, (bool, np.bool_)):
        raise ParameterError(f"{step}: refine must be a bool; got {refine!r}")
    installed = _installed()
    attempts = []
    t0 = time.perf_counter()
    for i, name in enumerate(solvers):
        if name not in installed:
            attempts.append((name, "not installed"))
            continue
        target = _for_solver(problem, name, i == 0)
        opts = _SOLVER_OPTS.get(name, lambda t: {})(SOLVER_TOL.get(name, 1e-7))
        if name == "CLARABEL" and gap_tol is not None:
            opts.update(tol_gap_abs=gap_tol, tol_gap_rel=gap_tol)
        if name == "CLARABEL" and refine:
            opts.update(iterative_refinement_enable=True)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                # a fallback starts cold, as it did when it compiled the problem afresh
                warm = warm_start and target is problem
                target.solve(solver=name, verbose=verbose, warm_start=warm, **opts)
        except cp.error.SolverError as exc:
            attempts.append((name, f"solver error: {exc}"))
            continue
        except BaseException as exc:
            # a solver written in Rust (Clarabel, via pyo3) reports an internal failure as a
            # PanicException, which derives from BaseException: a failed solve, not a reason
            # to bring the whole program down
            if type(exc).__name__ != "PanicException":
                raise
            attempts.append((name, f"solver crashed: {str(exc).splitlines()[0][:200]}"))
            continue
        if target is not problem and target.status in (
            *cp.settings.SOLUTION_PRESENT,
            *cp.settings.INF_OR_UNB,
        ):
            # the twin's answer (its variables are the problem's) becomes the problem's
            problem.unpack(target.solution)
        status = target.status
        attempts.append((name, status))
        if status in (cp.INFEASIBLE, cp.UNBOUNDED):
            raise InfeasibleError(
                f"{step}: solver {name} certifies the problem {status}; attempts: {attempts}"
            )
        if status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and problem.value is not None:
            st = target.solver_stats
            return SolveResult(
                solver=name,
                status=status,
                accurate=status == cp.OPTIMAL,
                iterations=getattr(st, "num_iters", None),
                solve_time=float(st.solve_time)
                if st.solve_time is not None
                else time.perf_counter() - t0,
                wall_time=time.perf_counter() - t0,
                objective=float(problem.value),
                attempts=tuple(attempts),
            )
    raise SolverError(
        f"{step}: no solver returned a usable answer; attempts: {attempts}. "
        "Try rescaling the problem or loosening the requested performance"
    )
