"""Levenberg-Marquardt least squares in numpy: the same answer for the same data, always.

MINPACK's ``lmder`` as scipy ships it (:func:`scipy.optimize.leastsq`, and
:func:`scipy.optimize.least_squares` with ``method="lm"``) can take a different first step
from identical residuals and Jacobians: on the calibration fits of the per-operator design,
eight repeated solves from one start, with other arrays allocated between them, came back
with two or three different answers in 39 of 312 starts (differences up to ``3e-7`` in the
estimate, at the solver's tolerance). Its answer depends on where its work arrays land in
memory, so a design made from it could differ from machine to machine. This module's
iteration uses only numpy and LAPACK calls whose result depends on their arguments alone.

The method is Moré's (J. J. Moré, "The Levenberg-Marquardt algorithm: implementation and
theory", *Numerical Analysis*, Lecture Notes in Mathematics 630, Springer 1978): the step
``p`` minimises ``||J p + f||^2 + lam ||D p||^2`` with ``D`` the running maximum of the
Jacobian's column norms (MINPACK's scaling), solved from its normal equations (``n``
unknowns; the damping keeps them positive definite, and the accuracy of a step only
decides how fast the iteration gets there, not where it stops: the stopping tests are on
the residual and the Jacobian); the damping ``lam`` follows the ratio of
the actual to the predicted reduction as in H. B. Nielsen, "Damping parameter in
Marquardt's method", IMM-REP-1999-05, Technical University of Denmark, 1999 (decrease by
``max(1/3, 1 - (2 rho - 1)^3)`` after a successful step, double-and-more after a failed
one). The stopping tests are MINPACK's: relative reductions of the cost (actual and
predicted) at most ``ftol``, a scaled step at most ``xtol`` of the scaled point, or every
column of the Jacobian at most ``gtol`` in cosine from the residual.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from robust.errors import ParameterError

__all__ = ["LMResult", "levenberg_marquardt"]

#: Statuses of :class:`LMResult` (MINPACK's ``info`` in words).
STATUS = {
    0: "the evaluation budget ran out",
    1: "the relative reductions of the cost are at most ftol",
    2: "the scaled step is at most xtol of the scaled point",
    3: "the residual is orthogonal to the Jacobian's columns within gtol",
    4: "the residual is zero",
    -1: "the damping overflowed, or the Jacobian is not finite at an accepted point",
}


@dataclasses.dataclass(frozen=True)
class LMResult:
    """The answer of :func:`levenberg_marquardt`.

    Parameters
    ----------
    x : numpy.ndarray
        The last accepted point, shape (n,).
    cost : float
        ``0.5 ||f(x)||^2``.
    fun : numpy.ndarray
        The residual at ``x``, shape (m,).
    jac : numpy.ndarray
        The Jacobian at ``x``, shape (m, n).
    status : int
        A key of :data:`STATUS`: positive when a stopping test held.
    nfev, njev : int
        Residual and Jacobian evaluations.
    """

    x: np.ndarray
    cost: float
    fun: np.ndarray
    jac: np.ndarray
    status: int
    nfev: int
    njev: int

    @property
    def converged(self) -> bool:
        """Whether a stopping test held (``status > 0``)."""
        return self.status > 0

    @property
    def message(self) -> str:
        """The status in words."""
        return STATUS[self.status]


def _check_evaluation(where: str, what: str, value, shape) -> np.ndarray:
    v = np.asarray(value, float)
    if v.shape != shape:
        raise ParameterError(f"{where}: {what} must have shape {shape}; got {v.shape}")
    return v


def levenberg_marquardt(
    fun: Callable[[np.ndarray], np.ndarray],
    jac: Callable[[np.ndarray], np.ndarray],
    x0,
    *,
    ftol: float = 1e-8,
    xtol: float = 1e-8,
    gtol: float = 1e-8,
    max_nfev: int | None = None,
) -> LMResult:
    """Minimise ``0.5 ||fun(x)||^2`` from ``x0`` by Levenberg-Marquardt (module notes).

    Parameters
    ----------
    fun : callable
        ``fun(x)``: the residual, shape (m,), ``m >= n``.
    jac : callable
        ``jac(x)``: its Jacobian, shape (m, n).
    x0 : array_like, shape (n,)
        The start.
    ftol, xtol, gtol : float
        The stopping tolerances (module notes), each in ``[eps, 1)``.
    max_nfev : int, optional
        Residual evaluations allowed (default ``100 n``, MINPACK's for an analytic
        Jacobian).

    Returns
    -------
    LMResult
        The last accepted point; ``status`` 0 when the budget ran out. A non-finite
        residual at a trial point counts as a failed step (the damping grows).

    Raises
    ------
    ParameterError
        If ``x0`` is not a finite vector, a tolerance or ``max_nfev`` is out of range,
        ``fun`` or ``jac`` returns the wrong shape, there are fewer residuals than unknowns,
        or the residual or the Jacobian at ``x0`` is not finite.
    """
    where = "levenberg_marquardt"
    x = np.array(x0, float)
    if x.ndim != 1 or x.size == 0 or not np.all(np.isfinite(x)):
        raise ParameterError(f"{where}: x0 must be a non-empty finite vector; got {x0!r}")
    eps = np.finfo(float).eps
    for name, tol in (("ftol", ftol), ("xtol", xtol), ("gtol", gtol)):
        if not (isinstance(tol, (int, float)) and eps <= tol < 1):
            raise ParameterError(f"{where}: {name} must lie in [eps, 1); got {tol!r}")
    n = x.size
    max_nfev = 100 * n if max_nfev is None else max_nfev
    if not (isinstance(max_nfev, int) and max_nfev >= 1):
        raise ParameterError(f"{where}: max_nfev must be a positive integer; got {max_nfev!r}")
    f = np.asarray(fun(x), float)
    if f.ndim != 1 or f.size < n:
        raise ParameterError(
            f"{where}: fun(x0) must be a vector of at least {n} residuals; got shape {f.shape}"
        )
    m = f.size
    J = _check_evaluation(where, "jac(x0)", jac(x), (m, n))
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(J))):
        raise ParameterError(f"{where}: the residual or its Jacobian at x0 is not finite")
    nfev = njev = 1
    cost = 0.5 * float(f @ f)
    d2 = np.einsum("ij,ij->j", J, J)  # squared scales: the running maximum of the column norms
    d2 = np.where(d2 > 0, d2, 1.0)
    lam, nu = 1e-3, 2.0  # Marquardt's start: a thousandth of the scaled curvature
    status = 0
    while status == 0:
        if cost == 0.0:
            status = 4
            break
        H = J.T @ J
        g = J.T @ f
        col2 = np.diag(H).copy()
        d2 = np.maximum(d2, col2)
        with np.errstate(divide="ignore", invalid="ignore"):
            cosine = np.where(col2 > 0, np.abs(g) / np.sqrt(col2 * (2.0 * cost)), 0.0)
        if cosine.max() <= gtol:
            status = 3
            break
        xnorm = math.sqrt(float(d2 @ (x * x)))
        accepted = False
        while not accepted:
            if nfev >= max_nfev:
                return LMResult(x=x, cost=cost, fun=f, jac=J, status=0, nfev=nfev, njev=njev)
            if not lam < 1e300:
                status = -1
                break
            # the step minimises ||J p + f||^2 + lam ||D p||^2 (normal equations of n unknowns)
            p = -np.linalg.solve(H + np.diag(lam * d2), g)
            Hp = H @ p
            pred = -(float(g @ p) + 0.5 * float(p @ Hp))  # predicted reduction
            small_step = math.sqrt(float(d2 @ (p * p))) <= xtol * xnorm
            x_new = x + p
            f_new = np.asarray(fun(x_new), float)
            nfev += 1
            if f_new.shape != (m,):
                raise ParameterError(f"{where}: fun(x) must have shape {(m,)}; got {f_new.shape}")
            cost_new = 0.5 * float(f_new @ f_new)
            actual = cost - cost_new
            rho = actual / pred if pred > 0 and math.isfinite(cost_new) else -1.0
            if rho > 1e-4:
                x, f, cost = x_new, f_new, cost_new
                J = _check_evaluation(where, "jac(x)", jac(x), (m, n))
                njev += 1
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                accepted = True
                if not np.all(np.isfinite(J)):
                    status = -1
                elif abs(actual) <= ftol * (cost + actual) and pred <= ftol * (cost + actual):
                    status = 1
                elif small_step:
                    status = 2
            else:
                lam, nu = lam * nu, 2.0 * nu
                if small_step:  # the steps no longer move the point: nothing left to gain
                    status = 2
                    break
    return LMResult(x=x, cost=cost, fun=f, jac=J, status=status, nfev=nfev, njev=njev)
