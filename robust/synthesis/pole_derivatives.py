"""First-order derivatives of closed-loop eigenvalues with respect to the controller data.

``d lambda = l^H Bb dOmega Cb r / l^H r`` for every eigenvalue of a member's closed loop
(:func:`eigen_derivatives`, :func:`eigen_derivatives_many` for many members at once), and
the linearised pole-region constraints built from them (:func:`eigen_region_rows`): the
K-step of :mod:`robust.synthesis.pk` and the tuning of :mod:`robust.synthesis.tuning`
both keep the poles in the region through these rows.
"""

from __future__ import annotations

import numpy as np

from robust.analysis.region import Region
from robust.synthesis.pk_members import _Affine

__all__ = ["eigen_derivatives", "eigen_derivatives_many", "eigen_region_rows"]


def eigen_derivatives(cl: _Affine, Om) -> tuple[np.ndarray, np.ndarray]:
    """Closed-loop eigenvalues and their derivatives in the controller data.

    ``d lambda = l^H Bb dOm Cb r / (l^H r)`` for the left and right eigenvectors ``l, r``
    of each (simple) eigenvalue of ``A0 + Bb Om Cb``.

    Parameters
    ----------
    cl : _Affine
        The closed loop.
    Om : numpy.ndarray
        Controller data.

    Returns
    -------
    lam : numpy.ndarray of complex, shape (n,)
    dlam : numpy.ndarray of complex, shape (n, *Om.shape)
    """
    A = cl.A0 + cl.Bb @ Om @ cl.Cb
    lam, R = np.linalg.eig(A)
    return _eigen_products(cl, lam, R, np.linalg.inv(R))


def _eigen_products(cl: _Affine, lam, R, R_inv):
    """:func:`eigen_derivatives`' answer from the eigenvalues, the right eigenvectors and
    their inverse."""
    L = R_inv.conj().T
    left, right = cl.Bb.T @ L.conj(), cl.Cb @ R
    denom = np.sum(L.conj() * R, axis=0)
    return lam, left.T[:, :, None] * right.T[:, None, :] / denom[:, None, None]


def eigen_derivatives_many(cls, Om) -> list:
    """:func:`eigen_derivatives` of several closed loops at one ``Om``, the same bits.

    Loops of one order are decomposed in one call of :func:`numpy.linalg.eig` (and of
    :func:`numpy.linalg.inv`) on their stack: LAPACK's routine per matrix as for one
    (tested bit for bit), without the per-call overhead (88 against 107 us per 19-state
    loop).

    Parameters
    ----------
    cls : sequence of _Affine
        The closed loops.
    Om : numpy.ndarray
        Controller data.

    Returns
    -------
    list of (lam, dlam)
        Per loop, as :func:`eigen_derivatives`.
    """
    cls = list(cls)
    mats = [cl.A0 + cl.Bb @ Om @ cl.Cb for cl in cls]
    if len({m.shape for m in mats}) != 1 or not mats[0].size:
        return [eigen_derivatives(cl, Om) for cl in cls]
    lam, R = np.linalg.eig(np.array(mats))
    R_inv = np.linalg.inv(R)
    return [_eigen_products(cl, lam[i], R[i], R_inv[i]) for i, cl in enumerate(cls)]


def eigen_region_rows(cl: _Affine, Om, region: Region) -> list:
    """Violations of the region plant's poles and their gradients w.r.t. ``Om``.

    Parameters
    ----------
    cl : _Affine
        The region plant's closed loop.
    Om : numpy.ndarray
        Controller data.
    region : robust.analysis.region.Region
        The region (in the loop's time unit).

    Returns
    -------
    list of (float, numpy.ndarray)
        Per pole, the decay violation ``Re lambda + alpha`` and, with a damping
        requirement, the cone violation ``Re lambda + zeta |lambda|``, each with its
        gradient.
    """
    lam, dl = eigen_derivatives(cl, Om)
    rows = []
    for j in range(lam.size):
        rows.append((lam[j].real + region.decay_rate, dl[j].real))
        if region.min_damping > 0:
            mag = max(abs(lam[j]), 1e-300)
            grad = dl[j].real + region.min_damping * (lam[j].conj() * dl[j]).real / mag
            rows.append((lam[j].real + region.min_damping * mag, grad))
    return rows
