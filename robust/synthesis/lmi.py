"""LMI builders for H-infinity synthesis: pure functions returning cvxpy variables and constraints.

Nothing here calls a solver (that is :mod:`robust.synthesis.solve`) or decides what an
answer means (that is :mod:`robust.synthesis.nominal` and :mod:`robust.synthesis.multi`).
Plant blocks follow
:class:`robust.synthesis.genplant.GeneralizedPlant`: ``x' = A x + B1 w + B2 u``,
``z = C1 x + D11 w + D12 u``, ``y = C2 x + D21 w`` (``D22 = 0`` here; the
synthesis removes a nonzero ``D22`` by a loop transformation), ``u = K y``.

References
----------
.. [GA94] P. Gahinet, P. Apkarian, "A linear matrix inequality approach to
   H-infinity control", Int. J. Robust Nonlinear Control 4 (1994) 421-448.
.. [IS94] T. Iwasaki, R.E. Skelton, "All controllers for the general
   H-infinity control problem: LMI existence conditions and state space
   formulas", Automatica 30(8) (1994) 1307-1317.
.. [SIG98] R.E. Skelton, T. Iwasaki, K. Grigoriadis, "A Unified Algebraic
   Approach to Linear Control Design", Taylor & Francis 1998, Thm 2.3.12.
.. [SGC97] C. Scherer, P. Gahinet, M. Chilali, "Multiobjective output-feedback
   control via LMI optimization", IEEE TAC 42(7) (1997) 896-911.
"""

from __future__ import annotations

import dataclasses

import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from robust.errors import VerificationError

__all__ = [
    "PlantBlocks",
    "ProjectionLMIs",
    "bounded_real_lmi",
    "closed_loop_matrices",
    "nullspace",
    "projection_lmis",
    "reconstruct_controller",
    "structured_nullspace",
]


@dataclasses.dataclass(frozen=True)
class PlantBlocks:
    """The eight blocks of a generalized plant with ``D22 = 0`` (shapes as in the module doc).

    Parameters
    ----------
    A : numpy.ndarray, shape (n, n)
        State matrix.
    B1 : numpy.ndarray, shape (n, nw)
        Input matrix of the exogenous inputs w.
    B2 : numpy.ndarray, shape (n, nu)
        Input matrix of the controls u.
    C1 : numpy.ndarray, shape (nz, n)
        Output matrix of the performance outputs z.
    C2 : numpy.ndarray, shape (ny, n)
        Output matrix of the measurements y.
    D11 : numpy.ndarray, shape (nz, nw)
        Feedthrough from w to z.
    D12 : numpy.ndarray, shape (nz, nu)
        Feedthrough from u to z.
    D21 : numpy.ndarray, shape (ny, nw)
        Feedthrough from w to y.
    """

    A: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    C1: np.ndarray
    C2: np.ndarray
    D11: np.ndarray
    D12: np.ndarray
    D21: np.ndarray

    @property
    def sizes(self) -> tuple[int, int, int, int, int]:
        """``(n, nw, nu, nz, ny)``."""
        return (
            self.A.shape[0],
            self.B1.shape[1],
            self.B2.shape[1],
            self.C1.shape[0],
            self.C2.shape[0],
        )

    @classmethod
    def from_generalized_plant(cls, gp) -> PlantBlocks:
        """The blocks of a generalized plant, without ``D22``.

        ``D22`` is not part of the LMIs: the synthesis designs for ``y0 = y - D22 u``
        and maps the controller back
        (:class:`robust.synthesis.scaling.D22Removal`).

        Parameters
        ----------
        gp : robust.synthesis.genplant.GeneralizedPlant
            The plant.
        """
        return cls(gp.A, gp.B1, gp.B2, gp.C1, gp.C2, gp.D11, gp.D12, gp.D21)


@dataclasses.dataclass(frozen=True)
class ProjectionLMIs:
    """Variables, parameter and constraints of the [GA94] Theorem 4.3 problem.

    Attributes
    ----------
    R, S : cvxpy.Variable, shape (n, n), symmetric
        ``R`` is the (1,1) block of the inverse closed-loop Lyapunov matrix, ``S``
        the (1,1) block of the closed-loop Lyapunov matrix.
    gamma : cvxpy.Variable, scalar
        The H-infinity bound, minimised by ``objective``.
    gamma_floor : cvxpy.Parameter, scalar, nonneg
        Lower bound on ``gamma``.  0 gives the optimal gamma; a value above the
        optimum pins gamma there, and an interior-point solver then returns a
        point near the centre of that slice of the feasible set (used to get
        well-conditioned ``R, S`` before controller reconstruction).
    constraints : list of cvxpy constraints
    objective : cvxpy.Minimize
    """

    R: cp.Variable
    S: cp.Variable
    gamma: cp.Variable
    gamma_floor: cp.Parameter
    constraints: list
    objective: cp.Minimize


def nullspace(M: np.ndarray, *, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the null space of ``M`` (columns), via the SVD.

    Parameters
    ----------
    M : numpy.ndarray
        Matrix (a vector is taken as one row).
    rtol : float
        Singular values below ``rtol`` times the largest count as zero.
    """
    return sla.null_space(np.atleast_2d(M), rcond=rtol)


def structured_nullspace(X: np.ndarray, D: np.ndarray, *, rtol: float = 1e-10) -> np.ndarray:
    """A sparse basis of ``ker [X D]`` when ``D`` has full row rank (columns, unit-norm).

    ``[X D] [v; u] = 0`` holds for every ``v`` with ``u = -D^+ X v`` plus any
    ``u`` in ``ker D``, so ``[[I, 0], [-D^+ X, N_D]]`` (``N_D`` an orthonormal
    basis of ``ker D``) spans the null space.  Its top block is the identity,
    so a congruence ``N' M(R) N`` keeps the sparsity of ``M`` in the state
    block: with an orthonormal (dense) basis every entry of the projected LMI
    depends on every entry of ``R`` and the solver's KKT system fills in
    (about nine times the nonzeros at order 32).  The projected inequality
    only depends on the span, so any basis gives the same feasible set.
    Falls back to :func:`nullspace` when ``D`` is rank deficient.

    Parameters
    ----------
    X : numpy.ndarray, shape (m, n)
        Left block.
    D : numpy.ndarray, shape (m, p)
        Right block, normally of full row rank.
    rtol : float
        Relative rank threshold for ``D``.
    """
    X, D = np.atleast_2d(X), np.atleast_2d(D)
    n = X.shape[1]
    if D.shape[0] == 0:
        return np.eye(n + D.shape[1])
    s = np.linalg.svd(D, compute_uv=False)
    if s.size < D.shape[0] or s.min() <= rtol * max(1.0, s.max()):
        return nullspace(np.hstack([X, D]), rtol=rtol)
    ND = sla.null_space(D, rcond=rtol)
    N = np.block([[np.eye(n), np.zeros((n, ND.shape[1]))], [-np.linalg.pinv(D) @ X, ND]])
    return N / np.linalg.norm(N, axis=0)


def _sym(E):
    return (E + E.T) / 2


def projection_lmis(
    blocks: PlantBlocks, *, margin: float, gamma_cap: float | None = None
) -> ProjectionLMIs:
    """The two projected bounded-real LMIs and the coupling LMI of [GA94] Thm 4.3.

    ``gamma`` is feasible for some full-order controller iff there are symmetric
    R, S with (strict inequalities enforced with ``margin``)::

        [N12 0]' [A R + R A'   R C1'    B1  ] [N12 0]
        [0   I]  [C1 R        -g I      D11 ] [0   I]  <  0,   N12 = ker [B2' D12']
                 [B1'          D11'    -g I ]

        [N21 0]' [A' S + S A   S B1     C1' ] [N21 0]
        [0   I]  [B1' S       -g I      D11'] [0   I]  <  0,   N21 = ker [C2  D21]
                 [C1           D11     -g I ]

        [R  I]
        [I  S]  >=  0

    ``N12`` and ``N21`` are the sparse bases of :func:`structured_nullspace`.

    Parameters
    ----------
    blocks : PlantBlocks
        Plant data (scaled; see :func:`robust.synthesis.nominal.hinfsyn_lmi`).
    margin : float
        Strictness margin: each strict LMI is enforced as ``<= -margin * I``.
        Tie it to the solver's feasibility tolerance.
    gamma_cap : float, optional
        Upper bound on gamma (keeps the problem bounded).

    Returns
    -------
    ProjectionLMIs
    """
    A, B1, B2, C1, C2, D11, D12, D21 = (
        getattr(blocks, k) for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21")
    )
    n, nw, _nu, nz, _ny = blocks.sizes
    N12 = structured_nullspace(B2.T, D12.T)
    N21 = structured_nullspace(C2, D21)
    R = cp.Variable((n, n), symmetric=True, name="R")
    S = cp.Variable((n, n), symmetric=True, name="S")
    g = cp.Variable(name="gamma")
    gfloor = cp.Parameter(nonneg=True, name="gamma_floor", value=0.0)
    Iw, Iz = np.eye(nw), np.eye(nz)
    cons = []
    if N12.shape[1] > 0:
        T1 = sla.block_diag(N12, Iw)
        M1 = cp.bmat(
            [[A @ R + R @ A.T, R @ C1.T, B1], [C1 @ R, -g * Iz, D11], [B1.T, D11.T, -g * Iw]]
        )
        L1 = _sym(T1.T @ M1 @ T1)
        cons.append(L1 << -margin * np.eye(L1.shape[0]))
    else:
        cons.append(cp.bmat([[-g * Iw]]) << -margin * np.eye(nw))
    if N21.shape[1] > 0:
        T2 = sla.block_diag(N21, Iz)
        M2 = cp.bmat(
            [[A.T @ S + S @ A, S @ B1, C1.T], [B1.T @ S, -g * Iw, D11.T], [C1, D11, -g * Iz]]
        )
        L2 = _sym(T2.T @ M2 @ T2)
        cons.append(L2 << -margin * np.eye(L2.shape[0]))
    In = np.eye(n)
    cons.append(cp.bmat([[R, In], [In, S]]) >> 0)
    cons.append(g >= gfloor)
    if gamma_cap is not None:
        cons.append(g <= gamma_cap)
    return ProjectionLMIs(R, S, g, gfloor, cons, cp.Minimize(g))


def closed_loop_matrices(blocks: PlantBlocks, Omega, nk: int):
    """Closed-loop ``(Acl, Bcl, Ccl, Dcl)``, affine in the controller data ``Omega``.

    ``Acl = A0 + Bb Omega Cb`` etc. ([GA94] eq. (2.5)), with the plant states first,
    then the controller states.

    Parameters
    ----------
    blocks : PlantBlocks
        Plant data (``D22 = 0``).
    Omega : numpy.ndarray or cvxpy expression, shape (nk + nu, nk + ny)
        Controller data ``[[Ak, Bk], [Ck, Dk]]``.
    nk : int
        Controller order.
    """
    A, B1, B2, C1, C2, D11, D12, D21 = (
        getattr(blocks, k) for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21")
    )
    n, nw, nu, nz, ny = blocks.sizes
    A0 = sla.block_diag(A, np.zeros((nk, nk)))
    B0 = np.vstack([B1, np.zeros((nk, nw))])
    C0 = np.hstack([C1, np.zeros((nz, nk))])
    Bb = np.block([[np.zeros((n, nk)), B2], [np.eye(nk), np.zeros((nk, nu))]])
    Cb = np.block([[np.zeros((nk, n)), np.eye(nk)], [C2, np.zeros((ny, nk))]])
    D12b = np.hstack([np.zeros((nz, nk)), D12])
    D21b = np.vstack([np.zeros((nk, nw)), D21])
    return (
        A0 + Bb @ Omega @ Cb,
        B0 + Bb @ Omega @ D21b,
        C0 + D12b @ Omega @ Cb,
        D11 + D12b @ Omega @ D21b,
    )


def bounded_real_lmi(Acl, Bcl, Ccl, Dcl, P, gamma, *, margin: float):
    """Bounded-real-lemma constraint ``||Ccl (sI-Acl)^-1 Bcl + Dcl||_inf < gamma``.

    Either ``P`` or the closed-loop matrices may be cvxpy expressions, but not
    both (the product must stay affine).  Returns one cvxpy constraint::

        [Acl' P + P Acl   P Bcl    Ccl' ]
        [Bcl' P          -g I      Dcl' ]  <=  -margin I
        [Ccl              Dcl     -g I  ]

    Parameters
    ----------
    Acl, Bcl, Ccl, Dcl : numpy.ndarray or cvxpy expression
        Closed-loop state-space matrices (from w to z).
    P : numpy.ndarray or cvxpy expression, shape (nx, nx)
        Lyapunov matrix.
    gamma : float or cvxpy expression
        The bound ``g``.
    margin : float
        Strictness margin.
    """
    nx, nw, nz = Acl.shape[0], Bcl.shape[1], Ccl.shape[0]
    PA = P @ Acl
    PB = P @ Bcl
    M = cp.bmat(
        [
            [PA + PA.T, PB, Ccl.T],
            [PB.T, -gamma * np.eye(nw), Dcl.T],
            [Ccl, Dcl, -gamma * np.eye(nz)],
        ]
    )
    M = _sym(M)
    return M << -margin * np.eye(nx + nw + nz)


def reconstruct_controller(
    blocks: PlantBlocks,
    R: np.ndarray,
    S: np.ndarray,
    gamma: float,
    *,
    mu_factor: float = 2.0,
    rank_rtol: float = 1e-9,
):
    """Controller from a solution (R, S, gamma) of :func:`projection_lmis`.

    Steps:

    1. closed-loop Lyapunov matrix ([GA94] Lemma 4.2 / Sec. 4.3): with
       ``Z = S - R^-1 >= 0`` factored as ``Z = N N'`` (``N`` n-by-k, k = numerical
       rank of Z, eigenvalues below ``rank_rtol * max`` dropped -- the reduced-order
       case of [GA94] Sec. 6), ``X = [[S, N], [N', I_k]] > 0`` has ``(X^-1)_11 = R``
       up to the dropped part;
    2. with X fixed the bounded-real inequality is ``Theta + Gam Om Lam + (.)' < 0``
       in ``Om = [[Ak, Bk], [Ck, Dk]]``; its central solution is the explicit
       formula of [IS94] / [SIG98] Thm 2.3.12 with the free matrix ``L = 0``:
       ``Om = -mu Gam' Phi Lam' (Lam Phi Lam')^-1``, ``Phi = (mu Gam Gam' - Theta)^-1``,
       where ``mu`` is ``mu_factor`` (> 1) times the smallest value that makes
       ``Phi > 0``.  Every ``mu_factor > 1`` gives a solution in exact arithmetic;
       in floating point the rounding error depends on it, so callers may try several.

    Parameters
    ----------
    blocks : PlantBlocks
        Plant data (``D22 = 0``), the same as given to :func:`projection_lmis`.
    R, S : numpy.ndarray, shape (n, n)
        Values of the variables of :func:`projection_lmis`.
    gamma : float
        Level at which to rebuild (at or above the LMI's gamma).
    mu_factor : float
        Multiple (> 1) of the smallest admissible ``mu``.
    rank_rtol : float
        Relative threshold below which eigenvalues of ``S - R^-1`` are dropped.

    Returns
    -------
    (Ak, Bk, Ck, Dk) : tuple of ndarray
        Controller of order k (k <= n), for ``u = K y``.
    info : dict
        ``order``, condition numbers ``cond_X`` (closed-loop Lyapunov matrix),
        ``cond_Phi``, ``cond_LPL``, the eigenvalue check ``lmi_max_eig`` of the
        bounded-real inequality (should be negative), and ``mu``.

    Raises
    ------
    VerificationError
        If ``S - R^-1`` is not positive semidefinite (the coupling LMI fails) or
        the projected inequality needed by the formula does not hold at ``gamma``.
    """
    A, B1, B2, C1, C2, D11, D12, D21 = (
        getattr(blocks, k) for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21")
    )
    n, nw, nu, nz, ny = blocks.sizes
    R, S = _sym(np.asarray(R, float)), _sym(np.asarray(S, float))
    wR = np.linalg.eigvalsh(R)
    if wR.min() <= 0:
        raise VerificationError(
            f"reconstruction: R must be positive definite; smallest eigenvalue {wR.min():.3g}"
        )
    Z = _sym(S - np.linalg.inv(R))
    w, V = np.linalg.eigh(Z)
    scale = max(float(np.linalg.norm(S, 2)), 1.0 / float(wR.min()))
    if w.min() < -1e-7 * scale:
        raise VerificationError(
            "reconstruction: coupling S - R^-1 >= 0 fails "
            f"(smallest eigenvalue {w.min():.3g}, largest {w.max():.3g})"
        )
    keep = w > rank_rtol * max(w.max(), 1e-12 * scale)
    k = int(keep.sum())
    N = V[:, keep] * np.sqrt(w[keep])
    X = np.block([[S, N], [N.T, np.eye(k)]])
    A0 = sla.block_diag(A, np.zeros((k, k)))
    B0 = np.vstack([B1, np.zeros((k, nw))])
    C0 = np.hstack([C1, np.zeros((nz, k))])
    Bb = np.block([[np.zeros((n, k)), B2], [np.eye(k), np.zeros((k, nu))]])
    Cb = np.block([[np.zeros((k, n)), np.eye(k)], [C2, np.zeros((ny, k))]])
    D12b = np.hstack([np.zeros((nz, k)), D12])
    D21b = np.vstack([np.zeros((k, nw)), D21])
    Theta = np.block(
        [
            [A0.T @ X + X @ A0, X @ B0, C0.T],
            [B0.T @ X, -gamma * np.eye(nw), D11.T],
            [C0, D11, -gamma * np.eye(nz)],
        ]
    )
    Gam = np.vstack([X @ Bb, np.zeros((nw, k + nu)), D12b])
    Lam = np.hstack([Cb, D21b, np.zeros((k + ny, nz))])
    # smallest mu with mu Gam Gam' - Theta > 0: Schur complement on ker(Gam')
    U, sv, Vt = np.linalg.svd(Gam, full_matrices=True)
    r = Gam.shape[1]
    T = U.T @ Theta @ U
    T11, T12, T22 = T[:r, :r], T[:r, r:], T[r:, r:]
    e22 = np.linalg.eigvalsh(_sym(T22)).max() if T22.size else -1.0
    if e22 >= 0:
        raise VerificationError(
            f"reconstruction: the projected inequality on ker(Gam') fails at gamma={gamma:.6g} "
            f"(largest eigenvalue {e22:.3g} >= 0); the LMI solution is not accurate enough"
        )
    G = _sym(T11 - T12 @ np.linalg.solve(T22, T12.T)) if T22.size else _sym(T11)
    sig = sv[:r]
    thr = np.linalg.eigvalsh(G / np.outer(sig, sig)).max()
    mu = mu_factor * max(thr, 1e-12 * max(1.0, abs(thr)))
    # Phi^-1 = mu Gam Gam' - Theta, assembled and factored in the orthonormal basis U =
    # [range(Gam), ker(Gam')], where it is [[mu Sig^2 - T11, -T12], [-T21, -T22]]: forming it
    # in the original basis would add rounding of order eps*mu*|Gam|^2 to the small ker(Gam')
    # block and ruin the solution when the LMI is nearly tight.
    M = -T
    M[:r, :r] += mu * np.diag(sig**2)
    M = _sym(M)
    cf = sla.cho_factor(M)  # raises LinAlgError if not numerically positive definite
    LU = Lam @ U
    Y = sla.cho_solve(cf, LU.T)  # M^-1 U' Lam'
    LPL = _sym(LU @ Y)  # Lam Phi Lam'
    GU = np.zeros((r, U.shape[0]))
    GU[:, :r] = Vt.T * sig  # Gam' U = [V Sig, 0]
    Om = -mu * np.linalg.solve(LPL, (GU @ Y).T).T
    E = Gam @ Om @ Lam
    lmi_max = float(np.linalg.eigvalsh(_sym(Theta + E + E.T)).max())
    info = {
        "order": k,
        "cond_X": float(np.linalg.cond(X)),
        "cond_Phi": float(np.linalg.cond(M)),
        "cond_LPL": float(np.linalg.cond(LPL)),
        "lmi_max_eig": lmi_max,
        "mu": float(mu),
    }
    return (Om[:k, :k], Om[:k, k:], Om[k:, :k], Om[k:, k:]), info
