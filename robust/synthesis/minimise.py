"""Minimisers of the tuning's objectives, apart from the controller they tune.

Two methods that know nothing of plants or regions: BFGS with a weak Wolfe line search
(Lewis & Overton, Math. Programming 141, 2013), for the smooth-almost-everywhere objective
of :func:`robust.synthesis.tuning.tune_members`, and :func:`slp_minimise`, sequential
linear programming with a trust region (Madsen's minimax method) on the largest of several
functions, for :func:`robust.synthesis.tuning.minimax_start`. Kept here so that the tuning
module holds the control problem and this one the numerical search.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robust.synthesis.lp import solve_lp

__all__ = ["SLPResult", "bfgs_minimise", "slp_minimise"]


def _weak_wolfe(fun, x, f, g, d, c1=1e-4, c2=0.9, max_steps=60):
    """Line search for the weak Wolfe conditions by bracketing and bisection.

    Lewis & Overton (Math. Programming 141, 2013, Alg. 4.6): unlike a strong Wolfe search
    it does not ask the slope to shrink in magnitude, which a nonsmooth function (a
    maximum of eigenvalues, eigenvalues that meet) cannot give at a kink.
    Returns ``(t, x_new, f_new, g_new)`` or ``None``.
    """
    lo, hi, t = 0.0, np.inf, 1.0
    slope = float(g @ d)
    if not slope < 0:
        return None
    for _ in range(max_steps):
        xn = x + t * d
        fn, gn = fun(xn)
        if not np.isfinite(fn) or fn > f + c1 * t * slope:
            hi = t
        elif float(gn @ d) < c2 * slope:
            lo = t
        else:
            return t, xn, fn, gn
        t = 2 * lo if hi == np.inf else 0.5 * (lo + hi)
    return None


def bfgs_minimise(fun, x0, max_iter: int):
    """BFGS with a weak Wolfe line search, for nonsmooth objectives.

    Lewis & Overton ("Nonsmooth optimization via quasi-Newton methods", Math. Programming
    141, 2013): BFGS with a weak (not strong) Wolfe search keeps descending on functions
    that are smooth almost everywhere, such as spectral abscissas. Stops when a line search
    fails (a kink it cannot leave), the step stalls, or after ``max_iter`` iterations. The
    workbench's tuners (:mod:`robust.synthesis.tuning`, :mod:`designs.multimodel`) all
    minimise with it.

    Parameters
    ----------
    fun : callable
        ``fun(x) -> (f, grad)``: the objective and its gradient at ``x``.
    x0 : array_like, shape (n,)
        The starting point.
    max_iter : int
        Largest number of iterations.

    Returns
    -------
    (numpy.ndarray, float, int)
        The final point, the objective there and the iterations run.

    Examples
    --------
    >>> import numpy as np
    >>> x, f, it = bfgs_minimise(lambda x: (abs(x[0]) + x[1] ** 2, np.array(
    ...     [np.sign(x[0]), 2 * x[1]])), [1.0, 1.0], 200)
    >>> bool(f < 1e-6)
    True
    """
    x = np.asarray(x0, float).copy()
    f, g = fun(x)
    if not np.isfinite(f):
        return x, f, 0
    H = np.eye(x.size)
    it = 0
    while it < max_iter:
        it += 1
        d = -H @ g
        if not float(g @ d) < 0:
            H = np.eye(x.size)
            d = -g
        ls = _weak_wolfe(fun, x, f, g, d)
        if ls is None:
            break
        t, xn, fn, gn = ls
        s_, y = xn - x, gn - g
        x, f, g = xn, fn, gn
        sy = float(s_ @ y)
        if sy > 1e-300:
            rho = 1.0 / sy
            V = np.eye(x.size) - rho * np.outer(s_, y)
            H = V @ H @ V.T + rho * np.outer(s_, s_)
        if np.linalg.norm(s_) <= 1e-12 * max(1.0, np.linalg.norm(x)):
            break
    return x, f, it


@dataclasses.dataclass(frozen=True)
class SLPResult:
    """Result of :func:`slp_minimise`.

    Parameters
    ----------
    x : numpy.ndarray
        The final point.
    worst : float
        Largest constraint value there (``max v``).
    penalty : float
        The penalty there.
    merit : float
        The merit there.
    iterations : int
        Linear programs solved.
    accepted : int
        Steps kept.
    """

    x: np.ndarray
    worst: float
    penalty: float
    merit: float
    iterations: int
    accepted: int


def slp_minimise(
    evaluate,
    x0,
    unit,
    *,
    target: float,
    reference=None,
    prox: float = 1e-3,
    trust: float = 0.1,
    max_iter: int = 60,
    active: float = np.inf,
    constraints=None,
) -> SLPResult:
    """Sequential linear programming with a trust region: a deterministic local minimiser.

    Minimises the merit ``max(max_j v_j(x), target) + prox * mean |x - reference| / unit
    + p(x)`` of constraint functions ``v_j`` (e.g. closed-loop eigenvalue real parts) and a
    penalty ``p`` (e.g. budgets' squared excess). Each step linearises ``v`` and ``p`` at
    the current point and solves

        minimise  u + prox * mean(a) + <grad p, D>
        s.t.      v_j + <grad v_j, D> <= u,  u >= target,
                  |x + D - reference| / unit <= a,  |D| <= radius * unit

    and, with ``constraints``, ``c_i + <grad c_i, D> <= 0``, by HiGHS
    (:func:`robust.synthesis.lp.solve_lp`: :func:`scipy.optimize.linprog`'s answers); the
    step is kept when the merit falls by at least a tenth of the fall the linear model
    predicts (Fletcher's SL1QP test,
    *Practical Methods of Optimization*, 2nd ed., 1987, Sec. 14.5), the radius doubles
    after a step that achieves three quarters of it and halves after a rejected one.
    Unlike a quasi-Newton method, whose inverse-Hessian estimate grows ill-conditioned at
    the kinks of a largest eigenvalue (Lewis & Overton, Math. Programming 141, 2013) and
    so turns the rounding differences of BLAS kernels into different end points, every
    step here depends continuously on the data: the same data give the same answer, on
    any machine, up to the last digits.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(x) -> (v, G, p, g)``: constraint values ``v`` (m,), their gradients
        ``G`` (m, size of x), the penalty ``p`` (float) and its gradient ``g`` (size of x).
    x0 : numpy.ndarray
        Start.
    unit : numpy.ndarray
        Positive scale of every entry of ``x`` (trust region and distance).
    target : float
        Constraint level below which the constraints no longer count.
    reference : numpy.ndarray, optional
        The point the distance term is measured from (default ``x0``).
    prox : float
        Weight of the mean scaled L1 distance to ``reference``.
    trust : float
        Initial trust-region radius, in units of ``unit``.
    max_iter : int
        Largest number of linear programs.
    active : float
        Constraints below ``target - active`` are left out of the linear programs
        (they cannot reach the target within a trust region).
    constraints : callable, optional
        ``constraints(x) -> (c, C)``: values ``c`` (k,) that must stay ``<= 0`` and their
        gradients ``C`` (k, size of x); ``x0`` must satisfy them. Each linear program
        keeps their linear model, and a step that breaks them in fact is rejected (the
        radius halves), so every iterate satisfies them.

    Returns
    -------
    SLPResult
    """
    x = np.asarray(x0, float).copy()
    shape = x.shape
    xf = x.ravel()
    unit = np.broadcast_to(np.asarray(unit, float), shape).ravel()
    ref = xf.copy() if reference is None else np.asarray(reference, float).ravel()
    n = xf.size

    def merit_at(z):
        v, G, p, g = evaluate(z.reshape(shape))
        v = np.asarray(v, float)
        m = max(float(v.max()), target) + prox * float(np.mean(np.abs(z - ref) / unit)) + p
        return m, v, np.asarray(G, float).reshape(v.size, n), float(p), np.ravel(g)

    def cons_at(z):
        if constraints is None:
            return np.zeros(0), np.zeros((0, n))
        cv, Cg = constraints(z.reshape(shape))
        cv = np.asarray(cv, float)
        return cv, np.asarray(Cg, float).reshape(cv.size, n)

    merit, v, G, p, g = merit_at(xf)
    cv, Cg = cons_at(xf)
    radius, it, kept = trust, 0, 0
    while it < max_iter and radius > 1e-6 * trust:
        it += 1
        keep = v >= target - active
        Gk, vk = G[keep], v[keep]
        m = int(keep.sum())
        # variables: D (n), a (n), u
        c = np.concatenate([g, np.full(n, prox / n), [1.0]])
        k = cv.size
        A_ub = np.vstack(
            [
                np.hstack([Gk, np.zeros((m, n)), -np.ones((m, 1))]),
                np.hstack([np.diag(1 / unit), -np.eye(n), np.zeros((n, 1))]),
                np.hstack([-np.diag(1 / unit), -np.eye(n), np.zeros((n, 1))]),
                np.hstack([Cg, np.zeros((k, n + 1))]),
            ]
        )
        b_ub = np.concatenate([-vk, (ref - xf) / unit, (xf - ref) / unit, -cv])
        bounds = [(-radius * u, radius * u) for u in unit] + [(0.0, None)] * n + [(target, None)]
        res = solve_lp(c, A_ub, b_ub, bounds)
        if res.status != 0 or res.x is None:
            radius /= 2
            continue
        D = res.x[:n]
        # the model's merit at x + D: the LP's objective plus the penalty's value
        predicted = float(res.fun) + p
        expected = merit - predicted
        if not expected > 1e-12 * max(1.0, abs(merit)):
            break
        new = merit_at(xf + D)
        new_c = cons_at(xf + D)
        fall = merit - new[0]
        if fall >= 0.1 * expected and not np.any(new_c[0] > 0):
            xf = xf + D
            merit, v, G, p, g = new
            cv, Cg = new_c
            kept += 1
            if fall >= 0.75 * expected:
                radius = min(2 * radius, 8 * trust)
        else:
            radius /= 2
    return SLPResult(xf.reshape(shape), float(v.max()), p, merit, it, kept)
