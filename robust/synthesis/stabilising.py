"""Stabilising state feedback for the Youla parametrisation: the gain ``K0`` that puts every
eigenvalue of ``A + B_u K0`` in the pole region.

:func:`stabilising_gain` tries linear-quadratic regulators on the shifted plant, each
Riccati solution checked by its residual (:data:`RICCATI_RTOL`), and
:func:`uncontrollable_modes` names the modes no gain moves. The parametrisation of
:mod:`robust.synthesis.youla` starts from this gain, and its output-feedback observer is
the same construction on the dual; apart from both as the one step they share.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from robust.analysis.region import Region
from robust.errors import InfeasibleError
from robust.synthesis.region import synthesis_region

__all__ = ["RICCATI_RTOL", "stabilising_gain", "uncontrollable_modes"]


#: Largest relative residual of an accepted Riccati solution in :func:`stabilising_gain`
#: (accurate solutions of the limit map's members reach 1e-7 at most; those whose gains
#: depend on rounding, 1e-4 to 1e-2).
RICCATI_RTOL = 1e-5


def _riccati_residual(A, Bu, X, r: float) -> float:
    """Relative residual of ``A' X + X A - X Bu Bu' X / r + I = 0`` (1-norms, scaled by its
    terms' sizes)."""
    G = (X @ Bu) @ (Bu.T @ X) / r
    res = A.T @ X + X @ A - G + np.eye(A.shape[0])
    scale = 1.0 + 2.0 * np.linalg.norm(A, 1) * np.linalg.norm(X, 1) + np.linalg.norm(G, 1)
    return float(np.linalg.norm(res, 1) / scale)


def stabilising_gain(A, Bu, region: Region, *, margin: float = 0.05) -> np.ndarray:
    """A state feedback ``K0`` with every eigenvalue of ``A + Bu K0`` inside ``region``.

    Linear-quadratic regulators on ``A + alpha I`` (decay rate ``alpha`` above the
    region's) with identity state weight and input weights from large (least effort) to
    small, tried in turn; the first whose closed-loop eigenvalues lie at least ``margin``
    (relative) inside the region (:meth:`~robust.analysis.region.Region.violations`, its
    damping at every frequency) is returned. A Riccati
    solution whose relative residual exceeds :data:`RICCATI_RTOL` is skipped: with a large
    input weight and a mode the actuators barely move, the solution grows to 1e15 and its
    residual to 1e-3, and the gain it gives is set by rounding (on one CPU's kernels it
    placed the poles in the region, on another it did not, and the map's basis and
    required force followed).


    Parameters
    ----------
    A : ndarray (n, n)
        State matrix.
    Bu : ndarray (n, m)
        Actuator input matrix.
    region : robust.analysis.region.Region
        The region (decay rate, damping cone; the damping enforced at every frequency).
    margin : float
        Relative margin inside the region the gain must reach.

    Raises
    ------
    robust.errors.InfeasibleError
        If no weight gives such a gain (e.g. a mode outside the region that the actuators
        cannot move: see :func:`uncontrollable_modes`).
    """
    A = np.asarray(A, float)
    Bu = np.asarray(Bu, float)
    n = A.shape[0]
    region = synthesis_region(region, "stabilising_gain")
    target = Region(
        region.decay_rate * (1 + margin) + margin,
        min(0.99, region.min_damping * (1 + margin)),
        region.band_hz,
    )
    # the least control effort first: a large input weight mirrors the poles outside the
    # shifted half-plane and leaves the others; smaller weights move more of them
    inaccurate = 0
    shifts, weights = (0.2, 1.0, 3.0), 10.0 ** np.arange(8, -9, -1)
    for alpha_extra in shifts:
        As = A + (target.decay_rate + alpha_extra) * np.eye(n)
        for r in weights:
            try:
                X = sla.solve_continuous_are(As, Bu, np.eye(n), r * np.eye(Bu.shape[1]))
            except (np.linalg.LinAlgError, ValueError):
                continue
            K = -np.linalg.solve(r * np.eye(Bu.shape[1]), Bu.T @ X)
            if not np.all(np.isfinite(K)) or _riccati_residual(As, Bu, X, r) > RICCATI_RTOL:
                inaccurate += 1
                continue
            if target.worst_violation(np.linalg.eigvals(A + Bu @ K)) < 0:
                return K
    raise InfeasibleError(
        f"stabilising_gain: no LQR gain places every pole in {target.describe()} "
        "(a mode the actuators cannot move may lie outside the region); "
        f"{inaccurate} of the {len(shifts) * len(weights)} Riccati solutions were skipped as "
        f"inaccurate (relative residual above {RICCATI_RTOL:g}) or not finite"
    )


def uncontrollable_modes(A, Bu, *, tol: float = 1e-7) -> np.ndarray:
    """Eigenvalues ``lambda`` of ``A`` with ``[A - lambda I, Bu]`` rank deficient (PBH test).

    Parameters
    ----------
    A : ndarray (n, n)
        State matrix.
    Bu : ndarray (n, m)
        Input matrix.
    tol : float
        Relative rank tolerance of the smallest singular value.
    """
    A = np.asarray(A, float)
    Bu = np.asarray(Bu, float)
    out = []
    scale = max(1.0, np.linalg.norm(A, 2), np.linalg.norm(Bu, 2))
    for lam in np.linalg.eigvals(A):
        M = np.hstack([A - lam * np.eye(A.shape[0]), Bu])
        s = np.linalg.svd(M, compute_uv=False)
        if s[-1] < tol * scale:
            out.append(lam)
    return np.array(out, complex)
