"""LMI pole regions (Chilali & Gahinet 1996): a decay rate and a damping cone, one certificate.

The region is the workbench's one :class:`robust.analysis.region.Region`. Its cone is an
LMI region only at every frequency (a cone over one band is not convex): synthesis and
these certificates enforce the damping of every pole (:func:`synthesis_region`), which for
a band-limited region is conservative; the analyses check it exactly in its band.

A real matrix ``A`` has every eigenvalue in the region

    D = { s : Re s <= -alpha }  intersected with  { s : Re s <= -zeta |s| }

(decay rate ``alpha``, damping ratio ``zeta``) if and only if there is one symmetric
``X > 0`` with ([CG96] Theorem 2.2; the intersection of LMI regions is the LMI region
of the block-diagonal characteristic function, Property 2.2)::

    decay:  A' X + X A + 2 alpha X < 0
    cone:   [ s (A' X + X A)    c (X A - A' X) ]
            [ c (A' X - X A)    s (A' X + X A) ]  < 0,   s = sin(theta), c = cos(theta),

with ``theta = arccos(zeta)`` the half-angle of the cone about the negative real axis
(the characteristic function ``L = 0``, ``M = [[s, c], [-c, s]]``).

:func:`certify_region` first tries the modal certificate: for a diagonalisable
``A = V diag(lambda) V^-1``, ``X = (V V^H)^-1`` (real for a real ``A``, its conjugate
eigenvectors paired) turns every LMI into ``V^-H (.) V^-1`` of a block-diagonal matrix
whose blocks are the characteristic function at one eigenvalue, ``2 (Re lambda + alpha)``
and ``2 (s Re lambda +- c |Im lambda|)``: negative exactly when that eigenvalue is in the
region (the argument of [CG96] for normal matrices, in modal coordinates). Its margin
shrinks with ``cond(V)^2``; when it does not clear rounding (a nearly defective ``A``),
a small SDP finds ``X``, solved in coordinates where the decay Lyapunov matrix is the
identity (the data of lightly damped loops spread over decades; recentring keeps the SDP
well conditioned). Either answer is checked in numpy: the LMI matrices rebuilt from
``X`` and their largest eigenvalues, and the eigenvalues of ``A`` themselves.

References
----------
.. [CG96] M. Chilali, P. Gahinet, "H-infinity design with pole placement constraints:
   an LMI approach", IEEE TAC 41(3) (1996) 358-367.
"""

from __future__ import annotations

import dataclasses

import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from robust.analysis.region import Region
from robust.errors import InfeasibleError, ModelStructureError, SolverError, VerificationError
from robust.synthesis.solve import DEFAULT_SOLVERS, check_solvers, solve_problem

__all__ = [
    "synthesis_region",
    "RegionCertificate",
    "region_lmis",
    "certify_region",
    "recentring",
    "check_region_certificate",
    "sym",
]


#: Normalisation of the analysis SDP: ``I <= X``, ``trace X <= TRACE_BOUND n`` in the
#: recentred coordinates (room for a certificate far from the decay Lyapunov matrix).
TRACE_BOUND = 1e4

#: The modal certificate is kept when its checks clear ``n eps`` (times ``||A||`` for the
#: LMIs) by this factor; below it, rounding could decide the sign, and the SDP is solved.
MODAL_ROUNDING_FACTOR = 1e3


def sym(M):
    """The symmetric part ``(M + M') / 2`` of a numpy array or cvxpy expression.

    Parameters
    ----------
    M : numpy.ndarray or cvxpy expression
        A square matrix.
    """
    return (M + M.T) / 2


def _kron(a, B):
    return cp.kron(a, B) if isinstance(B, cp.Expression) else np.kron(a, B)


def synthesis_region(region, owner: str) -> Region:
    """``region`` as synthesis enforces it: its damping at every frequency.

    The LMI cone of [CG96] holds for every pole; a region whose damping band is limited
    (or left to the default of what is analysed) is enforced at every frequency,
    conservatively (:meth:`robust.analysis.region.Region.everywhere`), and the analyses
    check it exactly in its band.

    Parameters
    ----------
    region : Region
        The region asked for.
    owner : str
        The function asking, for the error message.

    Raises
    ------
    ModelStructureError
        If ``region`` is not a :class:`~robust.analysis.region.Region`.
    """
    if not isinstance(region, Region):
        raise ModelStructureError(
            f"{owner}: region must be a robust.analysis.region.Region; got {type(region).__name__}"
        )
    return region.everywhere()


def region_lmis(A, X, region: Region) -> dict:
    """The region's LMI matrices for ``A`` and ``X`` (each must be negative definite).

    Parameters
    ----------
    A : numpy.ndarray or cvxpy expression, shape (n, n)
        The matrix (numpy when ``X`` is a cvxpy variable, and vice versa).
    X : numpy.ndarray or cvxpy expression, shape (n, n)
        Symmetric Lyapunov matrix.
    region : robust.analysis.region.Region
        The region (its damping enforced at every frequency).

    Returns
    -------
    dict
        ``{"decay": ...}`` and, with a cone, ``{"cone": ...}``: symmetric matrices of
        sizes ``n`` and ``2 n``.
    """
    XA = X @ A
    out = {"decay": sym(XA + XA.T + 2 * region.decay_rate * X)}
    if region.min_damping > 0:
        s, c = region.cone
        M = np.array([[s, c], [-c, s]])
        out["cone"] = sym(_kron(M, XA) + _kron(M.T, XA.T))
    return out


def recentring(P, *, floor: float = 1e-12) -> np.ndarray:
    """``T`` with ``T' P T = I`` for a symmetric positive definite ``P``.

    Eigenvalues below ``floor`` times the largest are raised to it, so ``T`` stays
    invertible for a nearly singular ``P``.

    Parameters
    ----------
    P : numpy.ndarray, shape (n, n)
        Symmetric positive (semi)definite matrix.
    floor : float
        Relative floor of the eigenvalues.
    """
    w, V = np.linalg.eigh(sym(np.asarray(P, float)))
    if not np.all(np.isfinite(w)) or w.max() <= 0:
        raise VerificationError("recentring: the matrix is not positive definite")
    w = np.maximum(w, floor * w.max())
    return V / np.sqrt(w)[None, :]


@dataclasses.dataclass(frozen=True)
class RegionCertificate:
    """A verified region certificate for one matrix.

    Parameters
    ----------
    X : numpy.ndarray
        The Lyapunov matrix, in the coordinates of the matrix given.
    lmi_max_eig : dict
        Largest eigenvalue of each LMI matrix rebuilt in numpy from ``X`` (scaled by
        ``||X||``; all negative), and ``"X_min"``, the smallest eigenvalue of ``X``
        relative to its largest (positive).
    violation : float
        :meth:`Region.worst_violation` of the matrix's eigenvalues (negative).
    method : str
        How ``X`` was found: ``"modal"`` (from the eigenvectors) or ``"sdp"``.
    """

    X: np.ndarray
    lmi_max_eig: dict
    violation: float
    method: str = "sdp"

    def to_json(self) -> dict:
        """The checks of the certificate (no matrix) and how it was found."""
        return {
            "lmi_max_eig": dict(self.lmi_max_eig),
            "violation": self.violation,
            "method": self.method,
        }


def check_region_certificate(A, X, region: Region) -> dict:
    """Largest eigenvalue of each LMI matrix, relative to ``||X||``, and ``X``'s smallest.

    Parameters
    ----------
    A, X : numpy.ndarray
        The matrix and the candidate certificate.
    region : robust.analysis.region.Region
        The region (its damping enforced at every frequency).
    """
    X = sym(np.asarray(X, float))
    scale = float(np.linalg.norm(X, 2))
    out = {
        k: float(np.linalg.eigvalsh(M).max()) / scale
        for k, M in region_lmis(np.asarray(A, float), X, region).items()
    }
    out["X_min"] = float(np.linalg.eigvalsh(X).min()) / scale
    return out


def _modal_certificate(A, region: Region):
    """``X = (V V^H)^-1`` from the eigenvectors of ``A`` and its numpy checks, if every check
    clears rounding by a wide factor (else ``None``)."""
    try:
        _, V = np.linalg.eig(A)
        X = sym(np.linalg.inv(sym((V @ V.conj().T).real)))
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(X)):
        return None
    checks = check_region_certificate(A, X, region)
    # the rebuilt LMIs carry rounding of about n eps ||A|| (relative to ||X||)
    n = A.shape[0]
    tol = MODAL_ROUNDING_FACTOR * n * np.finfo(float).eps
    lmi_tol = tol * max(float(np.linalg.norm(A, 2)), region.decay_rate, 1.0)
    for k, e in checks.items():
        if (e < tol) if k == "X_min" else (e > -lmi_tol):
            return None
    return X, checks


def certify_region(A, region: Region, *, solvers=DEFAULT_SOLVERS) -> RegionCertificate:
    """One Lyapunov matrix proving every eigenvalue of ``A`` lies in ``region`` ([CG96]).

    First the modal certificate ``X = (V V^H)^-1`` (module notes), kept when each rebuilt
    LMI's largest eigenvalue is below ``-MODAL_ROUNDING_FACTOR n eps max(||A||, alpha, 1)``
    and ``X``'s smallest above ``MODAL_ROUNDING_FACTOR n eps`` (relative to ``||X||``).
    Otherwise an SDP maximises the margin ``t`` of ``region_lmis(A, X) <= -t I`` over
    ``I <= X``, ``trace X <= TRACE_BOUND n`` in coordinates ``x = T xt`` where the decay
    Lyapunov matrix (from ``(A + alpha I)' X0 + X0 (A + alpha I) = -I``) is the
    identity; the certificate is mapped back and checked in numpy.

    Parameters
    ----------
    A : numpy.ndarray, shape (n, n)
        A real square matrix.
    region : robust.analysis.region.Region
        The region (its damping enforced at every frequency).
    solvers : sequence of str
        cvxpy SDP solvers, in order.

    Returns
    -------
    RegionCertificate

    Raises
    ------
    ModelStructureError
        If ``A`` is not a finite real square matrix or ``region`` not a Region.
    InfeasibleError
        If an eigenvalue of ``A`` lies outside the region (no certificate can exist),
        or the SDP finds no positive margin.
    VerificationError
        If the returned certificate fails its numpy check.
    """
    region = synthesis_region(region, "certify_region")
    A = np.asarray(A, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1] or not np.all(np.isfinite(A)):
        raise ModelStructureError(
            f"certify_region: A must be a finite real square matrix; got shape {A.shape}"
        )
    solvers = check_solvers(solvers, name="certify_region: solvers", sdp=True)
    n = A.shape[0]
    v = region.worst_violation(np.linalg.eigvals(A))
    if v >= 0:
        raise InfeasibleError(
            f"certify_region: an eigenvalue lies outside the region ({region.describe()}): "
            f"violation {v:.3g} rad/s"
        )
    modal = _modal_certificate(A, region)
    if modal is not None:
        return RegionCertificate(modal[0], modal[1], v, method="modal")
    Ash = A + region.decay_rate * np.eye(n)
    T = recentring(sla.solve_continuous_lyapunov(Ash.T, -np.eye(n)))
    At = np.linalg.solve(T, A @ T)
    X = cp.Variable((n, n), symmetric=True)
    t = cp.Variable()
    cons = [X >> np.eye(n), cp.trace(X) <= TRACE_BOUND * n]
    cons += [M << -t * np.eye(M.shape[0]) for M in region_lmis(At, X, region).values()]
    try:
        solve_problem(
            cp.Problem(cp.Maximize(t), cons), step="certify_region: analysis", solvers=solvers
        )
    except SolverError as exc:
        raise InfeasibleError(f"certify_region: no certificate found: {exc}") from None
    if t.value is None or not t.value > 0:
        raise InfeasibleError(
            f"certify_region: the analysis SDP found no positive margin (t = {t.value})"
        )
    Ti = np.linalg.inv(T)
    Xo = sym(Ti.T @ sym(X.value) @ Ti)
    checks = check_region_certificate(A, Xo, region)
    failed = {k: e for k, e in checks.items() if (e <= 0 if k == "X_min" else e >= 0)}
    if failed:
        raise VerificationError(
            f"certify_region: the certificate fails its numpy check: {failed} "
            f"(region {region.describe()}, eigenvalue violation {v:.3g} rad/s)"
        )
    return RegionCertificate(Xo, checks, v)
