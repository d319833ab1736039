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
    "bounded_real_lmi",
    "PlantBlocks",
    "ProjectionLMIs",
    "nullspace",
    "projection_certificate",
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
    lmi_r, lmi_s, coupling : cvxpy constraint or None
        The projected LMI in ``R`` (``N12``), the one in ``S`` (``N21``; None when
        ``N21`` is empty) and ``[[R, I], [I, S]] >= 0``: their dual values feed
        :func:`projection_certificate`.
    """

    R: cp.Variable
    S: cp.Variable
    gamma: cp.Variable
    gamma_floor: cp.Parameter
    constraints: list
    objective: cp.Minimize
    lmi_r: object = None
    lmi_s: object = None
    coupling: object = None


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
    lmi_r, lmi_s = cons[0], None
    if N21.shape[1] > 0:
        T2 = sla.block_diag(N21, Iz)
        M2 = cp.bmat(
            [[A.T @ S + S @ A, S @ B1, C1.T], [B1.T @ S, -g * Iw, D11.T], [C1, D11, -g * Iz]]
        )
        L2 = _sym(T2.T @ M2 @ T2)
        cons.append(L2 << -margin * np.eye(L2.shape[0]))
        lmi_s = cons[-1]
    In = np.eye(n)
    cons.append(cp.bmat([[R, In], [In, S]]) >> 0)
    coupling = cons[-1]
    cons.append(g >= gfloor)
    if gamma_cap is not None:
        cons.append(g <= gamma_cap)
    return ProjectionLMIs(R, S, g, gfloor, cons, cp.Minimize(g), lmi_r, lmi_s, coupling)


def _jacobi_max_eig(M, *, smallest: bool = False) -> float:
    """Largest (or smallest) eigenvalue of ``D^-1/2 M D^-1/2``, ``D = |diag(M)|``.

    The diagonal congruence keeps the inertia, so the sign of the result decides
    definiteness as for ``M`` itself, but the number is relative to the scale of
    each row and column: a tolerance on it means the same for a well and a badly
    scaled matrix (unlike a tolerance relative to ``||M||``).
    """
    M = _sym(np.asarray(M, float))
    if M.size == 0:
        return -1.0 if not smallest else 1.0
    if not np.all(np.isfinite(M)):
        return float("nan")
    d = np.abs(np.diag(M))
    d = np.sqrt(np.maximum(d, 1e-300 + 1e-14 * d.max()))
    w = np.linalg.eigvalsh(M / d[:, None] / d[None, :])
    return float(w.min() if smallest else w.max())


def projection_certificate(
    blocks: PlantBlocks, R, S, gamma: float, *, duals=None
) -> dict[str, float]:
    """Independent numpy check of a solution ``(R, S, gamma)`` of :func:`projection_lmis`.

    Nothing is decided here (the caller applies its tolerances); the numbers are
    computed from the plant data and the solver's variables only, with other
    null-space bases than the SDP used (orthonormal ones, :func:`nullspace`), so
    they check the solver's answer and cvxpy's formulation together.

    Primal side -- is ``gamma`` attained?  [GA94] Thm 4.3 asks for ``R > 0``,
    ``S > 0``, ``[[R, I], [I, S]] >= 0`` and both projected LMIs ``< 0`` (without
    the strictness margin).  Eigenvalues of matrices that must be definite are
    reported after the diagonal congruence ``D^-1/2 M D^-1/2`` (``D = |diag M|``),
    which keeps their sign but makes them relative to each row's scale.

    Dual side -- is ``gamma`` optimal?  For any ``Z1, Z2 >= 0`` (shaped like the
    projected LMIs) weak duality gives a lower bound on every feasible gamma of the
    problem *without* margin, i.e. on the H-infinity norm of every controller:
    with ``W = T1 Z1 T1'`` (``T1 = blkdiag(N12, I)``, the SDP's basis), ``V = T2 Z2
    T2'`` and the gradients ``G_R = A' W11 + W11 A + W12 C1 + C1' W12'``, ``G_S = A
    V11 + V11 A' + V12 B1' + B1 V12'``, the coupling multiplier ``Z3 = [[G_R, X],
    [X', G_S]]`` cancels every ``R`` and ``S`` term, and the best ``X`` with
    ``Z3 >= 0`` (``X = -L_R Q L_S'``, ``G = L L'``, ``Q`` the orthogonal polar factor)
    leaves::

        gamma >= (2<W13, B1> + 2<W23, D11> + 2<V13, C1'> + 2<V23, D11'>
                  + 2 ||L_S' L_R||_*) / (tr W22 + tr W33 + tr V22 + tr V33).

    The bound is exact when ``G_R, G_S >= 0``; the solver's duals satisfy this only
    to its tolerance, so negative eigenvalues are clipped and the term they leave,
    ``<G_R-, R> + <G_S-, S>`` at the solver's ``R, S``, is subtracted (a first-order
    account of the clipping, reported as ``dual_clip``).

    Parameters
    ----------
    blocks : PlantBlocks
        Plant data the LMIs were built from (``D22 = 0``).
    R, S : numpy.ndarray, shape (n, n)
        Values of the variables.
    gamma : float
        The level to check (the solver's optimum).
    duals : tuple of (numpy.ndarray or None), optional
        Dual values ``(Z1, Z2)`` of :attr:`ProjectionLMIs.lmi_r` and
        :attr:`ProjectionLMIs.lmi_s` (``Z2`` None when ``N21`` is empty); without
        them the dual bound is NaN.

    Returns
    -------
    dict of str to float
        ``finite`` (1.0 or 0.0), ``R_min_eig``, ``S_min_eig`` (smallest eigenvalues),
        ``coupling_min_eig`` (smallest normalised eigenvalue of ``[[R, I], [I, S]]``),
        ``lmi_r_max_eig``, ``lmi_s_max_eig`` (largest normalised eigenvalues of the
        projected LMIs at ``gamma``), ``dual_bound`` (lower bound on gamma, NaN if
        not available), ``dual_bound_clipped`` (before the clipping correction) and
        ``dual_clip`` (largest clipped eigenvalue relative to the gradient's norm).
    """
    A, B1, B2, C1, C2, D11, D12, D21 = (
        getattr(blocks, k) for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21")
    )
    n, nw, _nu, nz, _ny = blocks.sizes
    nan = float("nan")
    out = {
        "finite": 0.0,
        "R_min_eig": nan,
        "S_min_eig": nan,
        "coupling_min_eig": nan,
        "lmi_r_max_eig": nan,
        "lmi_s_max_eig": nan,
        "dual_bound": nan,
        "dual_bound_clipped": nan,
        "dual_clip": nan,
    }
    R, S = np.asarray(R, float), np.asarray(S, float)
    g = float(gamma)
    if (
        R.shape != (n, n)
        or S.shape != (n, n)
        or not (np.all(np.isfinite(R)) and np.all(np.isfinite(S)) and np.isfinite(g))
    ):
        return out
    out["finite"] = 1.0
    R, S = _sym(R), _sym(S)
    In = np.eye(n)
    # overflow (absurdly large solver values) leaves NaN entries, which fail every check
    with np.errstate(all="ignore"):
        out["R_min_eig"] = float(np.linalg.eigvalsh(R).min()) if n else 1.0
        out["S_min_eig"] = float(np.linalg.eigvalsh(S).min()) if n else 1.0
        out["coupling_min_eig"] = _jacobi_max_eig(np.block([[R, In], [In, S]]), smallest=True)
        Iw, Iz = np.eye(nw), np.eye(nz)
        M1 = np.block(
            [[A @ R + R @ A.T, R @ C1.T, B1], [C1 @ R, -g * Iz, D11], [B1.T, D11.T, -g * Iw]]
        )
        M2 = np.block(
            [[A.T @ S + S @ A, S @ B1, C1.T], [B1.T @ S, -g * Iw, D11.T], [C1, D11, -g * Iz]]
        )
        T1 = sla.block_diag(nullspace(np.hstack([B2.T, D12.T])), Iw)
        T2 = sla.block_diag(nullspace(np.hstack([C2, D21])), Iz)
        out["lmi_r_max_eig"] = _jacobi_max_eig(T1.T @ M1 @ T1)
        out["lmi_s_max_eig"] = _jacobi_max_eig(T2.T @ M2 @ T2)
        if duals is not None:
            try:
                out.update(_dual_bound(blocks, R, S, *duals))
            except (np.linalg.LinAlgError, ValueError):
                pass  # non-finite intermediate results: no bound (NaN)
    return out


def _psd_split(Z):
    """``(Z+, Z-)``: the positive and negative semidefinite parts of ``sym(Z)``."""
    w, V = np.linalg.eigh(_sym(np.asarray(Z, float)))
    return (V * np.maximum(w, 0.0)) @ V.T, (V * np.minimum(w, 0.0)) @ V.T, w


def _dual_bound(blocks, R, S, Z1, Z2):
    """The weak-duality lower bound of :func:`projection_certificate` (see there)."""
    A, B1, B2, C1, C2, D11, D12, D21 = (
        getattr(blocks, k) for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21")
    )
    n, nw, _nu, nz, _ny = blocks.sizes
    T1 = sla.block_diag(structured_nullspace(B2.T, D12.T), np.eye(nw))
    T2 = sla.block_diag(structured_nullspace(C2, D21), np.eye(nz))
    Z1 = np.zeros((T1.shape[1],) * 2) if Z1 is None else np.asarray(Z1, float)
    Z2 = np.zeros((T2.shape[1],) * 2) if Z2 is None else np.asarray(Z2, float)
    nan = float("nan")
    bad = {"dual_bound": nan, "dual_bound_clipped": nan, "dual_clip": nan}
    if Z1.shape != (T1.shape[1],) * 2 or Z2.shape != (T2.shape[1],) * 2:
        return bad
    if not (np.all(np.isfinite(Z1)) and np.all(np.isfinite(Z2))):
        return bad
    W = T1 @ _psd_split(Z1)[0] @ T1.T
    V = T2 @ _psd_split(Z2)[0] @ T2.T
    x, z1, w1 = slice(0, n), slice(n, n + nz), slice(n + nz, n + nz + nw)
    GR = _sym(A.T @ W[x, x] + W[x, x] @ A + W[x, z1] @ C1 + C1.T @ W[x, z1].T)
    w2, z2 = slice(n, n + nw), slice(n + nw, n + nw + nz)
    GS = _sym(A @ V[x, x] + V[x, x] @ A.T + V[x, w2] @ B1.T + B1 @ V[x, w2].T)
    const = 2.0 * (
        np.sum(W[x, w1] * B1)
        + np.sum(W[z1, w1] * D11)
        + np.sum(V[x, z2] * C1.T)
        + np.sum(V[w2, z2] * D11.T)
    )
    tau = np.trace(W[z1, z1]) + np.trace(W[w1, w1]) + np.trace(V[w2, w2]) + np.trace(V[z2, z2])
    if not tau > 0:
        return bad
    GRp, GRm, eR = _psd_split(GR)
    GSp, GSm, eS = _psd_split(GS)
    clip = max(
        0.0,
        float(-eR.min(initial=0.0) / max(np.abs(eR).max(initial=0.0), 1e-300)),
        float(-eS.min(initial=0.0) / max(np.abs(eS).max(initial=0.0), 1e-300)),
    )
    LR = _psd_factor(GRp)
    LS = _psd_factor(GSp)
    nuc = float(np.linalg.svd(LS.T @ LR, compute_uv=False).sum()) if n else 0.0
    clipped = (const + 2.0 * nuc) / tau
    correction = (np.sum(GRm * R) + np.sum(GSm * S)) / tau  # <= 0
    return {
        "dual_bound": float(max(clipped + correction, 0.0)),
        "dual_bound_clipped": float(max(clipped, 0.0)),
        "dual_clip": clip,
    }


def _psd_factor(G):
    """``L`` with ``L L' = G`` for a positive semidefinite ``G`` (from its eigenvalues)."""
    w, V = np.linalg.eigh(_sym(G))
    return V * np.sqrt(np.maximum(w, 0.0))


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
