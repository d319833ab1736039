"""The one place the workbench calls a conic solver.

:func:`solve_problem` tries Clarabel first and SCS as fallback, maps the
solver's status to :mod:`robust.errors` exceptions and returns the statistics.
An answer flagged inaccurate is returned (with ``accurate=False``) so that the
caller's independent verification decides; it is never trusted on its own.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import cvxpy as cp

from robust.errors import InfeasibleError, ParameterError, SolverError

__all__ = ["DEFAULT_SOLVERS", "SOLVER_TOL", "SolveResult", "solve_problem"]

DEFAULT_SOLVERS = ("CLARABEL", "SCS")

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
    },
    "SCS": lambda tol: {"eps_abs": tol, "eps_rel": tol, "max_iters": 50000},
}


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

    Returns
    -------
    SolveResult

    Raises
    ------
    InfeasibleError
        If a solver certifies infeasibility (or unboundedness) of the problem.
    SolverError
        If every solver failed to return a usable answer.
    """
    if not solvers:
        raise ParameterError("solvers must name at least one cvxpy solver; got an empty sequence")
    installed = set(cp.installed_solvers())
    attempts = []
    t0 = time.perf_counter()
    for name in solvers:
        if name not in installed:
            attempts.append((name, "not installed"))
            continue
        opts = _SOLVER_OPTS.get(name, lambda t: {})(SOLVER_TOL.get(name, 1e-7))
        if name == "CLARABEL" and gap_tol is not None:
            opts.update(tol_gap_abs=gap_tol, tol_gap_rel=gap_tol)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                problem.solve(solver=name, verbose=verbose, **opts)
        except cp.error.SolverError as exc:
            attempts.append((name, f"solver error: {exc}"))
            continue
        status = problem.status
        attempts.append((name, status))
        if status in (cp.INFEASIBLE, cp.UNBOUNDED):
            raise InfeasibleError(
                f"{step}: solver {name} certifies the problem {status}; attempts: {attempts}"
            )
        if status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and problem.value is not None:
            st = problem.solver_stats
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
