"""Small linear programs solved by HiGHS without :func:`scipy.optimize.linprog`'s set-up.

The sequential linear programs of the tuning (:func:`robust.synthesis.tuning.slp_minimise`)
solve thousands of small dense programs (about 90 rows and 60 columns). Through
:func:`scipy.optimize.linprog` (``method="highs"``) most of each one's cost is not HiGHS's
own solve but the argument checks, the option manager's checks of every option and the
conversion of the results (``benchmarks/bench_lp.py`` measures both). :func:`solve_lp` hands
the same model, with the same options, to the same HiGHS library (the build SciPy ships and
``linprog`` runs, :mod:`scipy.optimize._highspy._core`), and applies ``linprog``'s test of
the answer (Sec. "Returns"), so that its answers are ``linprog``'s to the bit (tested, on
the tuning's programs and on random feasible, infeasible and unbounded ones) at HiGHS's own
cost. Where that module is missing (a SciPy that no longer ships it), :func:`solve_lp` calls
``linprog`` itself: the same answers, at ``linprog``'s cost.

HiGHS: Huangfu and Hall, "Parallelizing the dual revised simplex method", Math. Prog.
Comp. 10, 2018.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.optimize as so
from scipy.sparse import csc_array

try:  # the HiGHS build that scipy.optimize.linprog runs (not a public module of SciPy)
    from scipy.optimize._highspy import _core as _highs
    from scipy.optimize._highspy._core import simplex_constants as _simplex
except ImportError:  # pragma: no cover - a SciPy without it: linprog itself
    _highs = None

__all__ = ["LPSolution", "solve_lp"]

#: ``linprog``'s tolerance of its answer check (its default ``tol`` 1e-9, as
#: ``scipy.optimize._linprog_util._check_result`` takes it: ``10 * sqrt(tol)``).
CHECK_TOL = 10 * math.sqrt(1e-9)


@dataclasses.dataclass(frozen=True)
class LPSolution:
    """A linear program's answer, as :func:`scipy.optimize.linprog` gives it.

    Parameters
    ----------
    x : numpy.ndarray or None
        The solution (``None`` unless HiGHS found an optimum).
    fun : float or None
        The objective there.
    status : int
        ``linprog``'s code: 0 optimal (and checked feasible), 1 iteration or time limit,
        2 infeasible, 3 unbounded, 4 numerical difficulties or another failure.
    """

    x: np.ndarray | None
    fun: float | None
    status: int


def _status(model_status) -> int:
    """``linprog``'s code of a HiGHS model status (``_highs_to_scipy_status_message``)."""
    m = _highs.HighsModelStatus
    codes = {
        m.kOptimal: 0,
        m.kTimeLimit: 1,
        m.kIterationLimit: 1,
        m.kInfeasible: 2,
        m.kModelError: 2,
        m.kUnbounded: 3,
    }
    return codes.get(model_status, 4)


def _checked(c, A_ub, b_ub, bounds):
    """The arrays of :func:`solve_lp`, checked (``linprog`` refuses the same, but for NaN
    bounds, which it reads as no bound and which are refused here)."""
    c = np.asarray(c, dtype=float)
    if c.ndim != 1 or c.size == 0:
        raise ValueError(f"solve_lp: c must be a non-empty vector; got shape {c.shape}")
    A = np.asarray(A_ub, dtype=float)
    b = np.asarray(b_ub, dtype=float)
    n = c.size
    if b.ndim != 1 or A.ndim != 2 or A.shape != (b.size, n):
        raise ValueError(
            f"solve_lp: A_ub must have shape (m, {n}) and b_ub shape (m,) (c's {n} columns); "
            f"got {A.shape} and {b.shape}"
        )
    if not np.all(np.isfinite(c)):
        raise ValueError("solve_lp: c must be finite; got a NaN or infinite entry")
    if not np.all(np.isfinite(A)):
        raise ValueError("solve_lp: A_ub must be finite; got a NaN or infinite entry")
    if not np.all(np.isfinite(b)):
        raise ValueError("solve_lp: b_ub must be finite; got a NaN or infinite entry")
    try:
        pairs = [(lo, hi) for lo, hi in bounds]
    except (TypeError, ValueError):
        raise ValueError(
            f"solve_lp: bounds must be a sequence of {n} (low, high) pairs; got {bounds!r:.80}"
        ) from None
    if len(pairs) != n:
        raise ValueError(f"solve_lp: bounds must give {n} (low, high) pairs; got {len(pairs)}")
    try:
        lb = np.array([-np.inf if lo is None else lo for lo, _ in pairs], dtype=float)
        ub = np.array([np.inf if hi is None else hi for _, hi in pairs], dtype=float)
    except (TypeError, ValueError):
        raise ValueError("solve_lp: bounds must be numbers or None") from None
    if np.any(np.isnan(lb)) or np.any(np.isnan(ub)):
        raise ValueError("solve_lp: bounds must not hold NaN")
    return c, A, b, lb, ub


def solve_lp(c, A_ub, b_ub, bounds) -> LPSolution:
    """``minimise c'x`` subject to ``A_ub x <= b_ub`` and ``bounds``: ``linprog``'s answer.

    The answer of :func:`scipy.optimize.linprog` ``(c, A_ub=A_ub, b_ub=b_ub, bounds=bounds,
    method="highs")`` to the bit, from the same HiGHS with the same options (presolve on,
    the dual simplex) and the same test of the answer: an optimum whose bounds or rows are
    violated by more than :data:`CHECK_TOL` (or that holds NaN) counts as status 4.

    Parameters
    ----------
    c : array_like, shape (n,)
        Costs (finite, ``n >= 1``).
    A_ub : array_like, shape (m, n)
        Inequality rows (finite, dense).
    b_ub : array_like, shape (m,)
        Their right-hand sides (finite).
    bounds : sequence of (float or None, float or None)
        Each variable's lower and upper bound (``None``: none; NaN is refused, where
        ``linprog`` reads it as no bound).

    Returns
    -------
    LPSolution

    Raises
    ------
    ValueError
        For arrays of the wrong shape or with non-finite entries (as ``linprog`` refuses
        them), or malformed bounds.
    """
    c, A, b, lb, ub = _checked(c, A_ub, b_ub, bounds)
    if _highs is None:  # pragma: no cover - a SciPy without the module
        res = so.linprog(c, A_ub=A, b_ub=b, bounds=bounds, method="highs")
        return LPSolution(res.x, res.fun, int(res.status))
    m, n = A.shape
    # the column-wise storage linprog hands HiGHS (scipy.sparse.csc_array of the rows)
    S = csc_array(A)
    lp = _highs.HighsLp()
    lp.num_col_, lp.num_row_ = n, m
    lp.a_matrix_.num_col_, lp.a_matrix_.num_row_ = n, m
    lp.a_matrix_.format_ = _highs.MatrixFormat.kColwise
    lp.col_cost_ = c
    lp.col_lower_, lp.col_upper_ = lb, ub
    lp.row_lower_, lp.row_upper_ = np.full(m, -np.inf), b
    lp.a_matrix_.start_, lp.a_matrix_.index_, lp.a_matrix_.value_ = S.indptr, S.indices, S.data
    h = _highs._Highs()
    for key, value in (
        ("output_flag", False),
        ("log_to_console", False),
        ("highs_debug_level", 0),
        ("presolve", "on"),
        ("simplex_strategy", int(_simplex.SimplexStrategy.kSimplexStrategyDual)),
    ):
        if h.setOptionValue(key, value) != _highs.HighsStatus.kOk:  # pragma: no cover
            raise RuntimeError(f"solve_lp: HiGHS refused its option {key}={value!r}")
    if h.passModel(lp) == _highs.HighsStatus.kError:
        return LPSolution(None, None, 2)  # (linprog: a model error is status 2)
    if h.run() == _highs.HighsStatus.kError:
        # (linprog: no solution with an "optimal" status counts as numerical difficulties)
        status = _status(h.getModelStatus())
        return LPSolution(None, None, 4 if status == 0 else status)
    status = _status(h.getModelStatus())
    if status != 0:
        return LPSolution(None, None, status)
    sol = h.getSolution()
    x = np.array(sol.col_value)
    fun = h.getInfo().objective_function_value
    slack = b - np.asarray(sol.row_value)
    if (
        np.isnan(x).any()
        or np.isnan(fun)
        or np.isnan(slack).any()
        or not np.all((x >= lb - CHECK_TOL) & (x <= ub + CHECK_TOL))
        or (slack < -CHECK_TOL).any()
    ):
        return LPSolution(x, fun, 4)
    return LPSolution(x, fun, 0)
