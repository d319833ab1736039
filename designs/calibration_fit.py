"""The calibration fits' coordinates and their local least-squares solve.

:data:`LOG_AXES` says which quantities are fitted in logarithms (the natural frequencies:
relative errors) and which linearly; ``_coords`` and ``_values`` convert between the two;
``_fit`` runs the weighted least squares from the best of several starts within bounds
(Levenberg-Marquardt, then the bounded trust-region method where a bound is active) and
gives the covariance. The operator's fit (:mod:`designs.calibration`) and the cab's
(:mod:`designs.cab_calibration`) share them.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize as sopt

from robust.errors import ParameterError
from robust.sysid.levenberg import levenberg_marquardt

__all__ = ["LOG_AXES"]


#: Natural frequencies fitted in logarithms (relative errors), damping ratios linearly.
LOG_AXES = (True, False, True, False)


def _coords(theta, log=LOG_AXES):
    return np.where(log, np.log(np.where(log, theta, 1.0)), theta)


def _values(z, log=LOG_AXES):
    # a logarithm beyond about 709 is a value beyond the floats: inf, on purpose (the edge
    # of an error region that the data do not bound), so NumPy's overflow warning is quiet
    with np.errstate(over="ignore"):
        return np.where(log, np.exp(np.where(log, z, 0.0)), z)


def _local_fit(resid, jacobian, z0, zlo, zhi):
    """One local weighted least-squares solve from ``z0`` within ``zlo .. zhi``.

    Levenberg-Marquardt first, unbounded (:func:`robust.sysid.levenberg.levenberg_marquardt`,
    Moré 1978, deterministic): where it converges strictly inside the box, its answer is a
    local minimum of the bounded problem too (no bound is active), found at less than half
    the cost of the bounded trust-region method. Otherwise (a bound active, no convergence,
    a non-finite answer) the bounded trust-region reflective method
    (:func:`scipy.optimize.least_squares`, ``"trf"``) solves from ``z0`` again.
    """
    try:
        with np.errstate(all="ignore"):
            sol = levenberg_marquardt(resid, jacobian, z0)
    except (ParameterError, np.linalg.LinAlgError):  # a non-finite residual on the way
        sol = None
    if (
        sol is not None
        and sol.converged
        and np.isfinite(sol.cost)
        and np.all(np.isfinite(sol.jac))
        and np.all((zlo < sol.x) & (sol.x < zhi))
    ):
        return sol
    return sopt.least_squares(
        resid, z0, jac=jacobian, bounds=(zlo, zhi), x_scale="jac", method="trf"
    )


def _fit(resid, jacobian, starts, zlo, zhi, n_freq):
    """Weighted least squares from the three best of ``starts``; covariance (module notes).

    ``resid(z)`` is the weighted residual at one point, ``jacobian(z)`` its Jacobian
    (analytic: the models' log responses are differentiated term by term, the compiled
    :func:`_human_jacobian` and :func:`_cab_jacobian`); the starts are ranked by their
    residual's squared norm. Returns ``(result, jacobian, (J'J)^-1, covariance, s2)``,
    the covariance in the fit coordinates, ``s2`` the residual variance per degree of
    freedom (at least 1).
    """
    cost0 = np.array([float(r @ r) for r in map(resid, starts)])
    best = None
    for k in np.argsort(cost0, kind="stable")[:3]:
        sol = _local_fit(resid, jacobian, starts[k], zlo, zhi)
        if best is None or sol.cost < best.cost:
            best = sol
    z, J = best.x, best.jac
    dof = max(2 * n_freq - z.size, 1)
    s2 = max(2.0 * best.cost / dof, 1.0)
    try:
        JtJ_inv = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        JtJ_inv = np.full((z.size, z.size), np.inf)
    return best, J, JtJ_inv, s2 * JtJ_inv, s2
