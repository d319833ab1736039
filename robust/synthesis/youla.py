"""The best full-information compensator of one known plant, by Youla/Q-parametrisation.

The limit of performance of a single, exactly known plant is a convex problem once the
closed-loop maps are written affinely in a free stable parameter (Youla, Jabr & Bongiorno
1976; Boyd & Barratt, *Linear Controller Design: Limits of Performance*, Prentice Hall
1991, ch. 7 and 15). Here the plant is

    x' = A x + B_w w + B_u u_a,      y = C_y x + D_yw w + D_yu u_a,

with a scalar exogenous input ``w`` (the operator's intended motion), actuators ``u_a``
(handle force, cylinder-reference shaping) and every state measured (full information).
With a state feedback ``K0`` that puts every eigenvalue of ``A_K = A + B_u K0`` in the
pole region, the controllers

    u_a = K0 x + v,      v = Q(s) w,      Q(s) = Theta phi(s),

with ``phi(s)`` a fixed bank of strictly proper orthonormal lags (real poles in the region,
:func:`lag_basis`) and ``Theta`` a real matrix, give closed-loop maps affine in ``Theta``::

    T_zw(s) = T_1(s) + sum_{a,k} Theta[a, k] T_2,a(s) phi_k(s),

with ``T_1 = C_K (sI - A_K)^-1 B_w + D`` and ``T_2,a = C_K (sI - A_K)^-1 B_u[:, a] + D_u,a``.
Every closed-loop pole lies among the eigenvalues of ``A_K`` and the lags' poles, so
the pole region holds by construction. The intended motion is not measured: the
controller obtains ``phi(s) w`` from the states, ``phi(s) l (x' - A x - B_u u_a)`` with
``l B_w = 1``, which a proper realisation computes because every ``phi_k`` is strictly
proper (:func:`realise_controller`). As ``phi`` grows towards a complete basis of the
region's stable transfer functions, the problem tends to the exact limit over all
full-information controllers that keep the poles in the region; with a finite ``phi`` it
is an inner approximation: a controller it finds exists, a limit it reports may be
beaten by a richer basis.

Constraints on a frequency grid are second-order cones in ``Theta``; the RMS value of an
output under ``w`` = white noise through a filter ``F`` is the Euclidean norm of an affine
function of ``Theta`` whose matrix is a square root of the exact Gram matrix
``<T_i F, T_j F>_H2`` of the basis maps (one Lyapunov equation,
:func:`h2_gram`). :class:`LimitProblem` holds the parameterised cvxpy problems (DPP), so a
map over many plants compiles once and re-solves with new parameter values.
"""

from __future__ import annotations

import dataclasses
import math

import clarabel
import cvxpy as cp
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from robust.analysis.loops import resolvent_times
from robust.analysis.region import Region
from robust.errors import InfeasibleError, ModelStructureError, ParameterError, SolverError
from robust.synthesis.region import synthesis_region
from robust.synthesis.solve import solve_problem

__all__ = [
    "YoulaPlant",
    "lag_basis",
    "pole_basis",
    "stabilising_gain",
    "affine_maps",
    "h2_gram",
    "output_gram",
    "uncontrollable_modes",
    "gram_factor",
    "LimitProblem",
    "realise_controller",
    "closed_loop",
    "Measurements",
    "observer_gain",
    "of_affine_maps",
    "of_closed_loop",
    "of_controller",
    "force_responses",
    "quadrature_grid",
    "quadrature_gram",
]


@dataclasses.dataclass(frozen=True)
class YoulaPlant:
    """A plant with one exogenous input, actuators, one tracked output and every state measured.

    Parameters
    ----------
    A : ndarray (n, n)
    Bw : ndarray (n, 1)
        Input matrix of the exogenous input ``w``.
    Bu : ndarray (n, m)
        Input matrix of the actuators.
    Cy : ndarray (1, n)
        The tracked output ``y``.
    Dyw : float
    Dyu : ndarray (1, m)
    force : int or None
        Index of the actuator whose value is the force whose RMS is limited (``None``:
        no such actuator).
    force_gain : float
        The force is ``force_gain`` times that actuator's value (actuators may be scaled
        to unit input columns for conditioning).
    """

    A: np.ndarray
    Bw: np.ndarray
    Bu: np.ndarray
    Cy: np.ndarray
    Dyw: float
    Dyu: np.ndarray
    force: int | None = None
    force_gain: float = 1.0

    def __post_init__(self):
        A = np.asarray(self.A, float)
        n = A.shape[0]
        if A.shape != (n, n) or n == 0 or not np.all(np.isfinite(A)):
            raise ModelStructureError(
                f"YoulaPlant.A: expected a finite square matrix; got {A.shape}"
            )
        Bw = np.asarray(self.Bw, float).reshape(n, 1)
        Bu = np.asarray(self.Bu, float)
        Bu = Bu.reshape(n, -1)
        Cy = np.asarray(self.Cy, float).reshape(1, n)
        Dyu = np.asarray(self.Dyu, float).reshape(1, Bu.shape[1])
        if not np.any(Bw):
            raise ModelStructureError("YoulaPlant.Bw: the exogenous input enters no state")
        if self.force is not None and not 0 <= self.force < Bu.shape[1]:
            raise ParameterError(
                "YoulaPlant.force: expected an actuator index in "
                f"[0, {Bu.shape[1]}) or None; got {self.force!r}"
            )
        g = float(self.force_gain)
        if not (math.isfinite(g) and g > 0):
            raise ParameterError(f"YoulaPlant.force_gain: expected a positive number; got {g!r}")
        object.__setattr__(self, "force_gain", g)
        for k, v in dict(A=A, Bw=Bw, Bu=Bu, Cy=Cy, Dyw=float(self.Dyw), Dyu=Dyu).items():
            object.__setattr__(self, k, v)

    @property
    def n(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    @property
    def m(self) -> int:
        """Number of actuators."""
        return self.Bu.shape[1]


def lag_basis(poles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal lags with real poles ``-a_k`` (:func:`pole_basis` of ``-a``).

    The Takenaka-Malmquist functions

        phi_k(s) = sqrt(2 a_k) / (s + a_k) * prod_{j<k} (s - a_j) / (s + a_j),

    orthonormal in H2 whatever the spacing of the poles, spanning the same space as the
    ``1 / (s + a_k)`` (Ninness & Gustafsson, "A unifying construction of orthonormal bases
    for system identification", IEEE TAC 1997).

    Parameters
    ----------
    poles : sequence of float
        The poles' magnitudes ``a_k`` (> 0), rad/s.
    """
    a = np.asarray(poles, float).ravel()
    if a.size == 0 or not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ParameterError(f"lag_basis: poles must be positive and finite; got {a}")
    return pole_basis(-a)


def _balanced_allpass(p: complex):
    """Balanced realisation ``(A, B, C, D)`` of the inner section with pole ``p`` (and conj)."""
    if p.imag == 0.0:
        a = -p.real
        r = math.sqrt(2 * a)
        return np.array([[-a]]), np.array([[r]]), np.array([[-r]]), 1.0
    # ((s + p)(s + conj p)) / ((s - p)(s - conj p)) = 1 + 4 Re(p) s / den
    m2, tr = abs(p) ** 2, 2 * p.real
    A = np.array([[0.0, 1.0], [-m2, tr]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[0.0, 2 * tr]])
    P = _controllability_gramian(A, B)
    Q = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
    L = np.linalg.cholesky(0.5 * (P + P.T))
    S, U = np.linalg.eigh(L.T @ Q @ L)
    T = L @ U @ np.diag(S**-0.25)
    Ti = np.linalg.inv(T)
    return Ti @ A @ T, Ti @ B, C @ T, 1.0


def pole_basis(poles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An H2-orthonormal bank with the given stable poles: ``(A_phi, b_phi, C_phi = I)``.

    The states of a cascade of balanced inner (all-pass) sections, one per real pole and
    one per complex pair, are orthonormal in H2 and span the rational functions with those
    poles (Heuberger, Van den Hof & Bosgra, "A generalized orthonormal basis for linear
    dynamical systems", IEEE TAC 1995; Ninness & Gustafsson 1997): however clustered or
    spread the poles, the basis is perfectly conditioned. Section ``k`` is driven by
    ``u_k = w + sum_{j<k} C_j x_j`` (every section's feedthrough is 1).

    Parameters
    ----------
    poles : array_like of complex
        Poles with negative real parts; a complex pole stands for its pair (give one of
        each pair; conjugates given as well are ignored).
    """
    p = np.asarray(poles, complex).ravel()
    if p.size == 0 or not np.all(np.isfinite(p)) or np.any(p.real >= 0):
        raise ParameterError(f"pole_basis: poles must be finite with negative real parts; got {p}")
    sections = []
    for z in p:
        if abs(z.imag) <= 1e-9 * max(1.0, abs(z)):
            sections.append(_balanced_allpass(complex(z.real, 0.0)))
        elif z.imag > 0 or not np.any(np.isclose(p, np.conj(z))):
            sections.append(_balanced_allpass(complex(z.real, abs(z.imag))))
    sizes = [sec[0].shape[0] for sec in sections]
    n = sum(sizes)
    A = np.zeros((n, n))
    b = np.zeros((n, 1))
    offs = np.concatenate([[0], np.cumsum(sizes)])
    for k, (Ak, Bk, _, _) in enumerate(sections):
        ik = slice(offs[k], offs[k + 1])
        A[ik, ik] = Ak
        b[ik] = Bk
        for j in range(k):
            A[ik, offs[j] : offs[j + 1]] = Bk @ sections[j][2]
    return A, b, np.eye(n)


def _controllability_gramian(A, B):
    return sla.solve_continuous_lyapunov(A, -B @ B.T)


def output_gram(A, B, C) -> np.ndarray:
    """``C P C'`` with ``P`` the controllability Gramian of a stable ``(A, B)``: the H2 Gram.

    The states are first scaled by powers of 2 to balance ``A``
    (:func:`scipy.linalg.matrix_balance`, exact), which keeps the Lyapunov solve accurate
    when the realisation mixes very different scales (high-gain state feedback).

    Parameters
    ----------
    A, B, C : ndarray
        A stable realisation.
    """
    A = np.asarray(A, float)
    _, (sc, _) = sla.matrix_balance(A, permute=False, separate=True)
    Ab = A * (1.0 / sc)[:, None] * sc[None, :]
    Bb = np.asarray(B, float) / sc[:, None]
    Cb = np.asarray(C, float) * sc[None, :]
    P = _controllability_gramian(Ab, Bb)
    W = Cb @ P @ Cb.T
    return 0.5 * (W + W.T)


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


def affine_maps(plant: YoulaPlant, K0, basis, omega) -> dict:
    """Frequency responses of the affine closed-loop maps on the grid ``omega`` (rad/s).


    Parameters
    ----------
    plant : YoulaPlant
        The plant.
    K0 : ndarray (m, n)
        State feedback with ``A + Bu K0`` in the region.
    basis : tuple
        ``(A_phi, b_phi, C_phi)`` of :func:`pole_basis`.
    omega : array_like
        Frequencies, rad/s.

    Returns
    -------
    dict
        ``"y0"`` (len f) and ``"y"`` (len f, m * nb): ``T_y(Theta) = y0 + y @ vec(Theta)``
        with ``vec`` row-major (actuator, lag); ``"f0"``/``"f"`` likewise for the force
        actuator's value (zeros without one).
    """
    A_phi, b_phi, C_phi = basis
    AK = plant.A + plant.Bu @ K0
    CyK = (plant.Cy + plant.Dyu @ K0)[0]
    omega = np.asarray(omega, float)
    X = resolvent_times(AK, omega, np.hstack([plant.Bw, plant.Bu]))  # (f, n, 1 + m)
    phi = np.einsum("ij,fjk->fi", C_phi, resolvent_times(A_phi, omega, b_phi))  # (f, nb)
    ty = np.einsum("j,fjk->fk", CyK, X)
    y0 = ty[:, 0] + plant.Dyw
    tyv = ty[:, 1:] + plant.Dyu[0][None]
    y = (tyv[:, :, None] * phi[:, None, :]).reshape(omega.size, -1)
    f0 = np.zeros(omega.size, complex)
    f = np.zeros_like(y)
    if plant.force is not None:
        tf = np.einsum("j,fjk->fk", K0[plant.force], X)
        f0 = tf[:, 0]
        tfv = tf[:, 1:].copy()
        tfv[:, plant.force] += 1.0
        f = (tfv[:, :, None] * phi[:, None, :]).reshape(omega.size, -1)
    g = plant.force_gain
    return {"y0": y0, "y": y, "f0": g * f0, "f": g * f}


def h2_gram(plant: YoulaPlant, K0, basis, filt) -> tuple[np.ndarray, float]:
    """Exact Gram matrix of the force maps ``[T_1,f F, (T_2,f,a phi_k F)_{a,k}]`` and ``||F||_2^2``.

    ``filt`` is ``(Af, Bf, Cf)``, a strictly proper stable filter shaping white noise into
    ``w``. The maps are stacked in one state-space system (the filter; one copy of the
    ``K0`` loop driven by ``w``; per actuator, one copy driven through that actuator and
    the lag bank behind it, since scalar maps commute) and the Gram matrix is
    ``C P C'`` with ``P`` its controllability Gramian.

    Parameters
    ----------
    plant : YoulaPlant
        The plant (with a force actuator).
    K0 : ndarray (m, n)
        State feedback.
    basis : tuple
        ``(A_phi, b_phi, C_phi)``.
    filt : tuple
        ``(Af, Bf, Cf)`` of the intent filter.
    """
    if plant.force is None:
        raise ParameterError("h2_gram: the plant has no force actuator")
    A_phi, b_phi, C_phi = basis
    nb, ns = C_phi.shape
    Af, Bf, Cf = (np.asarray(x, float) for x in filt)
    nf, n, m = Af.shape[0], plant.n, plant.m
    AK = plant.A + plant.Bu @ K0
    kf = K0[plant.force].reshape(1, n)
    N = nf + n + m * (n + ns)
    A = np.zeros((N, N))
    B = np.zeros((N, 1))
    C = np.zeros((1 + m * nb, N))
    A[:nf, :nf] = Af
    B[:nf] = Bf
    o = nf
    A[o : o + n, o : o + n] = AK
    A[o : o + n, :nf] = plant.Bw @ Cf
    C[0, o : o + n] = kf
    o += n
    for a in range(m):
        A[o : o + n, o : o + n] = AK
        A[o : o + n, :nf] = plant.Bu[:, [a]] @ Cf
        # s_a = kf x2a + [a is the force] w, into the bank
        A[o + n : o + n + ns, o : o + n] = b_phi @ kf
        if a == plant.force:
            A[o + n : o + n + ns, :nf] += b_phi @ Cf
        A[o + n : o + n + ns, o + n : o + n + ns] = A_phi
        C[1 + a * nb : 1 + (a + 1) * nb, o + n : o + n + ns] = C_phi
        o += n + ns
    W = output_gram(A, B, plant.force_gain * C)
    return W, float(output_gram(Af, Bf, Cf)[0, 0])


def gram_factor(W, rows: int) -> np.ndarray:
    """A ``(rows, k)`` matrix ``R`` with ``R' R ~= W`` (the ``rows`` largest eigen-directions).

    Parameters
    ----------
    W : ndarray (k, k)
        Symmetric positive semidefinite matrix.
    rows : int
        Rows of the factor.
    """
    lam, V = np.linalg.eigh(W)
    lam = np.clip(lam, 0.0, None)
    idx = np.argsort(lam)[::-1][:rows]
    R = np.zeros((rows, W.shape[0]))
    R[: idx.size] = np.sqrt(lam[idx])[:, None] * V[:, idx].T
    return R


class LimitProblem:
    """Two second-order cone problems over ``theta`` of fixed sizes, solved many times.

    ``"force"``: minimise ``|| R theta + r0 ||`` (the RMS force over its limit) subject to
    ``|t0_k + T_k theta| <= lim_t`` on the tracking grid, ``|g0_k + G_k theta| <= lim_f``
    on the feedthrough grid and ``|| E_j theta + e_j || <= lim_t`` for each effort Gram.
    ``"relax"``: minimise ``rho`` subject to the same cones with limits times ``rho`` (no
    force objective): the smallest uniform relaxation that any ``theta`` of the basis can
    meet. Both add ``eps || theta ||`` (default ``1e-6``, with ``theta`` in the caller's
    normalised coordinates): directions that barely move the maps are not driven to huge
    values whose cancellations no realisation could evaluate.

    The cones are written straight into Clarabel's standard form (``A x + s = b``, ``s`` in a
    product of second-order cones): the problem's structure never changes, and building it
    through cvxpy's parameterised compilation cost four times the solve (the dense parameter
    matrices' mapping into the problem data). Where Clarabel does not end solved, the same
    problem is built in cvxpy and solved by :func:`robust.synthesis.solve.solve_problem`
    (refined, then SCS): the reference formulation, which the tests compare with this one.

    Parameters
    ----------
    n_theta : int
        Coefficients of the parameter.
    n_track, n_feed : int
        Frequencies of the tracking and feedthrough grids.
    n_force : int
        Rows of the force's Gram factor.
    n_effort : int
        Effort Grams (each of size ``1 + n_theta``).
    """

    def __init__(self, n_theta: int, n_track: int, n_feed: int, n_force: int, n_effort: int = 0):
        self.sizes = (n_theta, n_track, n_feed, n_force, n_effort)
        self.data: dict = {}
        self.stats: dict = {"clarabel": 0, "cvxpy": 0}

    def set(
        self, *, track0, track, feed0, feed, lim_t, lim_f, R=None, r0=None, eps=1e-6, effort=()
    ):
        """Load one plant's data (complex grids; ``R``, ``r0`` the force's Gram factor;
        ``effort``: up to ``n_effort`` Gram matrices ``W`` of ``[1, theta]``, each
        constrained to ``[1, theta]' W [1, theta] <= lim_t^2`` (``(lim_t rho)^2`` in
        ``"relax"``) through its factor (:func:`gram_factor`))."""
        n_theta, n_track, n_feed, n_force, n_effort = self.sizes
        if len(effort) > n_effort:
            raise ParameterError(
                f"LimitProblem.set: effort must hold at most {n_effort} Grams; got {len(effort)}"
            )
        track, feed = np.asarray(track), np.asarray(feed)
        if track.shape != (n_track, n_theta) or feed.shape != (n_feed, n_theta):
            raise ParameterError(
                f"LimitProblem.set: track and feed must be ({n_track}, {n_theta}) and "
                f"({n_feed}, {n_theta}); got {track.shape} and {feed.shape}"
            )
        E = []
        for W in effort:
            F = gram_factor(W, 1 + n_theta)
            E.append((F[:, 1:], F[:, 0]))
        self.data = dict(
            track0=np.asarray(track0),
            track=track,
            feed0=np.asarray(feed0),
            feed=feed,
            lim_t=float(lim_t),
            lim_f=float(lim_f),
            R=None if R is None else np.asarray(R, float),
            r0=None if r0 is None else np.asarray(r0, float),
            eps=float(eps),
            effort=E,
        )

    def _standard_form(self, which: str):
        """``(q, A, b, cones)`` of Clarabel's ``min q'x, A x + s = b, s in cones``.

        Variables ``x = [theta, t, s_eps]`` (``"force"``: ``t`` bounds the force) or
        ``[theta, rho, s_eps]`` (``"relax"``).
        """
        d = self.data
        n = self.sizes[0]
        it, ie = n, n + 1
        relax = which == "relax"
        rows_A, rows_b, cones = [], [], []

        def soc(head_col, head_coef, head_b, M, m0):
            # the cone [head; M x + m0]: s = b - A x
            k = M.shape[0]
            blk = np.zeros((1 + k, n + 2))
            blk[0, head_col] = -head_coef if head_col is not None else 0.0
            blk[1:, :n] = -M
            rows_A.append(blk)
            rows_b.append(np.concatenate([[head_b], m0]))
            cones.append(1 + k)

        for key, lim in (("track", d["lim_t"]), ("feed", d["lim_f"])):
            M, m0 = d[key], d[key + "0"]
            for k in range(M.shape[0]):
                MM = np.vstack([M[k].real, M[k].imag])
                mm = np.array([m0[k].real, m0[k].imag])
                if relax:
                    soc(it, lim, 0.0, MM, mm)
                else:
                    soc(None, 0.0, lim, MM, mm)
        for Ek, ek in d["effort"]:
            if relax:
                soc(it, d["lim_t"], 0.0, Ek, ek)
            else:
                soc(None, 0.0, d["lim_t"], Ek, ek)
        if not relax:
            R = d["R"] if d["R"] is not None else np.zeros((1, n))
            r0 = d["r0"] if d["r0"] is not None else np.zeros(R.shape[0])
            soc(it, 1.0, 0.0, R, r0)
        soc(ie, 1.0, 0.0, np.eye(n), np.zeros(n))
        A = sp.csc_matrix(np.vstack(rows_A))
        b = np.concatenate(rows_b)
        q = np.zeros(n + 2)
        q[it], q[ie] = 1.0, d["eps"]
        if relax:
            # rho >= 0
            A = sp.vstack([sp.csc_matrix(([-1.0], ([0], [it])), shape=(1, n + 2)), A]).tocsc()
            b = np.concatenate([[0.0], b])
            cones = ["nn"] + cones
        return q, A, b, cones

    def _clarabel(self, which: str, refine: bool):
        q, A, b, cones = self._standard_form(which)
        kinds = [
            clarabel.NonnegativeConeT(1) if c == "nn" else clarabel.SecondOrderConeT(c)
            for c in cones
        ]
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.max_threads = 1
        settings.iterative_refinement_enable = refine
        P = sp.csc_matrix((q.size, q.size))
        sol = clarabel.DefaultSolver(P, q, A, b, kinds, settings).solve()
        return sol

    def _cvxpy(self, which: str, step: str):
        """The same problem in cvxpy (constants, no parameters), solved with the fallbacks."""
        d = self.data
        n = self.sizes[0]
        th = cp.Variable(n, name="theta")
        rho = cp.Variable(name="rho")

        def mags(key):
            M, m0 = d[key], d[key + "0"]
            return cp.norm(cp.vstack([M.real @ th + m0.real, M.imag @ th + m0.imag]), 2, axis=0)

        lim = (d["lim_t"], d["lim_f"])
        eff = [cp.norm(Ek @ th + ek, 2) for Ek, ek in d["effort"]]
        if which == "relax":
            cons = [mags("track") <= lim[0] * rho, mags("feed") <= lim[1] * rho, rho >= 0]
            cons += [e <= lim[0] * rho for e in eff]
            obj = rho
        else:
            cons = [mags("track") <= lim[0], mags("feed") <= lim[1]] + [e <= lim[0] for e in eff]
            R = d["R"] if d["R"] is not None else np.zeros((1, n))
            r0 = d["r0"] if d["r0"] is not None else np.zeros(R.shape[0])
            obj = cp.norm(R @ th + r0, 2)
        prob = cp.Problem(cp.Minimize(obj + d["eps"] * cp.norm(th, 2)), cons)
        try:
            solve_problem(prob, step=step, warm_start=False, refine=True)
        except InfeasibleError:
            return None
        value = float(rho.value) if which == "relax" else float(obj.value)
        return np.asarray(th.value, float), value

    def solve(self, which: str, *, step: str):
        """Solve ``"force"`` or ``"relax"``: ``(theta, objective)``, or ``None`` if infeasible.

        Afresh each time (no workspace kept: the answer must not depend on what this process
        solved before). Clarabel with iterative refinement; where that does not end solved or
        certifies infeasibility, the cvxpy formulation with its fallbacks decides.
        """
        if which not in ("force", "relax"):
            raise ParameterError(
                f"LimitProblem.solve: which must be 'force' or 'relax'; got {which!r}"
            )
        if not self.data:
            raise ParameterError("LimitProblem.solve: no data; call set() first")
        n = self.sizes[0]
        # with iterative refinement from the start: unrefined, two thirds of the map's
        # problems end only almost solved or stall, and the second solve costs more than the
        # refinement saves
        for refine in (True,):
            sol = self._clarabel(which, refine)
            if sol.status == clarabel.SolverStatus.Solved:
                self.stats["clarabel"] += 1
                x = np.asarray(sol.x, float)
                value = (
                    x[n]
                    if which == "relax"
                    else float(
                        np.linalg.norm(
                            (self.data["R"] if self.data["R"] is not None else np.zeros((1, n)))
                            @ x[:n]
                            + (self.data["r0"] if self.data["r0"] is not None else 0.0)
                        )
                    )
                )
                return x[:n], float(value)
            if refine and sol.status == clarabel.SolverStatus.PrimalInfeasible:
                self.stats["clarabel"] += 1
                return None
        self.stats["cvxpy"] += 1
        return self._cvxpy(which, step)


def realise_controller(plant: YoulaPlant, K0, basis, Theta):
    """State-space ``(Ac, Bc, Cc, Dc)`` of the controller ``x -> u_a`` (module notes).

    ``u_a = K0 x + Theta phi(s) w`` with ``phi(s) w`` computed from the states as
    ``phi(s) l (x' - A x - B_u u_a)``, ``l = B_w' / (B_w' B_w)``; the lag states are
    shifted by ``b_phi l x`` so that no derivative is needed.

    Parameters
    ----------
    plant : YoulaPlant
        The plant.
    K0 : ndarray (m, n)
        State feedback.
    basis : tuple
        ``(A_phi, b_phi, C_phi)``.
    Theta : array_like (m, nb)
        The Youla parameter's coefficients.
    """
    A_phi, b_phi, C_phi = basis
    Theta = np.asarray(Theta, float).reshape(plant.m, C_phi.shape[0]) @ C_phi
    ell = plant.Bw.T / float((plant.Bw.T @ plant.Bw)[0, 0])
    Kx = K0 + Theta @ b_phi @ ell
    bl = b_phi @ ell
    Ac = A_phi - bl @ plant.Bu @ Theta
    Bc = A_phi @ bl - bl @ plant.A - bl @ plant.Bu @ Kx
    return Ac, Bc, Theta, Kx


def closed_loop(plant: YoulaPlant, K0, basis, Theta, *, actuators: bool = False):
    """The closed loop of ``plant`` with ``u_a = K0 x + Theta phi(s) w``: ``(A, B_w, C)``.

    States ``(x, xi)`` with ``xi = phi(s) w`` the lag states, which the realised controller
    (:func:`realise_controller`) reconstructs exactly from the states (its state is
    ``zeta = xi - b_phi l x``, a similarity transform of this loop); in these coordinates
    the loop is block triangular and well conditioned, whatever the size of ``l``.
    Rows of ``C``: the tracked output ``y`` and the force actuator's value (zero without
    one); ``D`` from ``w`` is ``[D_yw, 0]``.

    Parameters
    ----------
    plant : YoulaPlant
        The plant.
    K0 : ndarray (m, n)
        State feedback.
    basis : tuple
        ``(A_phi, b_phi, C_phi)``.
    Theta : array_like (m, nb)
        The Youla parameter's coefficients.
    actuators : bool
        Append one row per actuator (its value, in the plant's units) and then the plant's
        states (an identity on the first ``n`` states) to ``C``.
    """
    A_phi, b_phi, C_phi = basis
    nb = A_phi.shape[0]
    Theta = np.asarray(Theta, float).reshape(plant.m, C_phi.shape[0]) @ C_phi
    n = plant.n
    A = np.block([[plant.A + plant.Bu @ K0, plant.Bu @ Theta], [np.zeros((nb, n)), A_phi]])
    B = np.vstack([plant.Bw, b_phi])
    Cu = np.hstack([K0, Theta])
    Cy = np.hstack([plant.Cy, np.zeros((1, nb))]) + plant.Dyu @ Cu
    Cf = plant.force_gain * Cu[[plant.force]] if plant.force is not None else np.zeros((1, n + nb))
    if not np.all(np.isfinite(A)):
        raise SolverError("closed_loop: the controller is not finite")
    if actuators:
        return A, B, np.vstack([Cy, Cf, Cu, np.eye(n, n + nb)])
    return A, B, np.vstack([Cy, Cf])


@dataclasses.dataclass(frozen=True)
class Measurements:
    """Measured outputs of a :class:`YoulaPlant` for output feedback, with white noise.

    ``y_m = Cm x + Dmw w + n``, ``n`` white with two-sided intensities ``noise`` (one per
    measurement, units of the measurement squared per Hz... per rad/s: ``E n(t) n(t+tau)
    = diag(noise) delta(tau)``).

    Parameters
    ----------
    Cm : ndarray (p, n)
    Dmw : ndarray (p, 1)
    noise : ndarray (p,)
        Intensities (> 0: a noiseless measurement makes the H2 problem singular).
    names : tuple of str
        Names of the measurements.
    """

    Cm: np.ndarray
    Dmw: np.ndarray
    noise: np.ndarray
    names: tuple = ()

    def __post_init__(self):
        Cm = np.atleast_2d(np.asarray(self.Cm, float))
        p = Cm.shape[0]
        Dmw = np.asarray(self.Dmw, float).reshape(p, 1)
        noise = np.asarray(self.noise, float).reshape(p)
        if not (np.all(np.isfinite(noise)) and np.all(noise > 0)):
            raise ParameterError(f"Measurements.noise: expected positive intensities; got {noise}")
        object.__setattr__(self, "Cm", Cm)
        object.__setattr__(self, "Dmw", Dmw)
        object.__setattr__(self, "noise", noise)

    @property
    def p(self) -> int:
        """Number of measurements."""
        return self.Cm.shape[0]


def observer_gain(plant: YoulaPlant, meas: Measurements, region: Region) -> np.ndarray:
    """An observer gain ``L`` with every eigenvalue of ``A - L Cm`` inside ``region``.

    The dual of :func:`stabilising_gain` on the measurements scaled to unit row norm (so
    their units do not matter): the least-gain observer that moves only what the region
    requires. The noise enters the problem through ``Q``, not through ``L``.

    Parameters
    ----------
    plant : YoulaPlant
        The plant.
    meas : Measurements
        The measurements.
    region : robust.analysis.region.Region
        The region (its damping enforced at every frequency).
    """
    s = np.linalg.norm(meas.Cm, axis=1)
    s = np.where(s > 0, s, 1.0)
    K = stabilising_gain(plant.A.T, (meas.Cm / s[:, None]).T, region)
    return -(K.T) / s[None, :]


def _of_blocks(plant, meas, K0, L):
    AK = plant.A + plant.Bu @ K0
    AL = plant.A - L @ meas.Cm
    return AK, AL, plant.Cy + plant.Dyu @ K0


def of_affine_maps(plant: YoulaPlant, meas: Measurements, K0, L, basis, omega) -> dict:
    """Frequency responses of ``w -> y`` under ``u_a = K0 xhat + Q(s) e`` (output feedback).

    ``xhat`` is the observer state (gain ``L``), ``e = y_m - Cm xhat`` the innovation and
    ``Q = sum Theta[a, j, k] phi_k`` maps measurement ``j``'s innovation to actuator ``a``.


    Parameters
    ----------
    plant : YoulaPlant
        The plant.
    meas : Measurements
        The measurements.
    K0 : ndarray (m, n)
        State feedback.
    L : ndarray (n, p)
        Observer gain.
    basis : tuple
        ``(A_phi, b_phi, C_phi)``.
    omega : array_like
        Frequencies, rad/s.

    Returns
    -------
    dict
        ``"y0"`` (len f) and ``"y"`` (len f, m * p * nb), ``vec`` row-major (a, j, k).
    """
    A_phi, b_phi, C_phi = basis
    AK, AL, CyK = _of_blocks(plant, meas, K0, L)
    omega = np.asarray(omega, float)
    Ew = resolvent_times(AL, omega, plant.Bw - L @ meas.Dmw)[:, :, 0]  # (f, n)
    Xv = resolvent_times(AK, omega, plant.Bu)  # (f, n, m)
    Xw = resolvent_times(AK, omega, plant.Bw)[:, :, 0] - np.einsum("fij,fj->fi", Xv, Ew @ K0.T)
    y0 = Xw @ CyK[0] - Ew @ (plant.Dyu @ K0)[0] + plant.Dyw
    yv = np.einsum("j,fjm->fm", CyK[0], Xv) + plant.Dyu[0][None]
    ew = Ew @ meas.Cm.T + meas.Dmw[:, 0][None]
    phi = np.einsum("ij,fjk->fi", C_phi, resolvent_times(A_phi, omega, b_phi))
    y = np.einsum("fa,fi,fk->faik", yv, ew, phi).reshape(omega.size, -1)
    return {"y0": y0, "y": y}


def _bank_output(plant: YoulaPlant, meas: Measurements, C_phi, Theta) -> np.ndarray:
    """``G = [Theta_1 C_phi, ..., Theta_p C_phi]``: the actuators from the per-measurement banks."""
    Th = np.asarray(Theta, float).reshape(plant.m, meas.p, C_phi.shape[0])
    return np.hstack([Th[:, j, :] @ C_phi for j in range(meas.p)])


def of_closed_loop(
    plant: YoulaPlant, meas: Measurements, K0, L, basis, Theta, *, actuators: bool = False
):
    """The output-feedback loop: ``(A, B, C)``, inputs ``[w, n_1..n_p]``, rows y, f.

    Controller: observer ``xhat' = A xhat + Bu u + L e``, ``e = y_m - Cm xhat``; per
    measurement a bank ``xi_j' = A_phi xi_j + b_phi e_j``; ``u = K0 xhat + sum_j Theta_j
    C_phi xi_j``. The loop is returned in the states ``(x, eps = x - xhat, xi_1..xi_p)``,
    a fixed well-conditioned change of coordinates from ``(x, xhat, xi)`` in which the
    estimation error is autonomous; ``D`` from ``w`` is ``[D_yw, 0]`` and from the noise
    zero (the controller is strictly proper).

    Parameters
    ----------
    plant : YoulaPlant
        The plant.
    meas : Measurements
        The measurements.
    K0 : ndarray (m, n)
        State feedback.
    L : ndarray (n, p)
        Observer gain.
    basis : tuple
        ``(A_phi, b_phi, C_phi)``.
    Theta : array_like (m, p, nb)
        The Youla parameter's coefficients.
    actuators : bool
        Append one row per actuator and then the plant's states to ``C`` (as
        :func:`closed_loop`).
    """
    A_phi, b_phi, C_phi = basis
    ns = C_phi.shape[1]
    n, p = plant.n, meas.p
    G = _bank_output(plant, meas, C_phi, Theta)  # u = K0 (x - eps) + G xi
    N = 2 * n + p * ns
    A = np.zeros((N, N))
    B = np.zeros((N, 1 + p))
    ix, ie, ib = slice(0, n), slice(n, 2 * n), slice(2 * n, N)
    A[ix, ix] = plant.A + plant.Bu @ K0
    A[ix, ie] = -plant.Bu @ K0
    A[ix, ib] = plant.Bu @ G
    B[ix, 0] = plant.Bw.ravel()
    # eps' = (A - L Cm) eps + (Bw - L Dmw) w - L n
    A[ie, ie] = plant.A - L @ meas.Cm
    B[ie, 0] = (plant.Bw - L @ meas.Dmw).ravel()
    B[ie, 1:] = -L
    for j in range(p):
        r = slice(2 * n + j * ns, 2 * n + (j + 1) * ns)
        # e_j = Cm_j eps + Dmw_j w + n_j
        A[r, ie] = b_phi @ meas.Cm[[j]]
        A[r, r] = A_phi
        B[r, 0] = b_phi.ravel() * meas.Dmw[j, 0]
        B[r, 1 + j] = b_phi.ravel()
    Cu = np.hstack([K0, -K0, G])
    Cy = np.hstack([plant.Cy, np.zeros((1, n + p * ns))]) + plant.Dyu @ Cu
    Cf = plant.force_gain * Cu[[plant.force]] if plant.force is not None else np.zeros((1, N))
    if actuators:
        return A, B, np.vstack([Cy, Cf, Cu, np.eye(n, N)])
    return A, B, np.vstack([Cy, Cf])


def of_controller(plant: YoulaPlant, meas: Measurements, K0, L, basis, Theta):
    """State-space ``(Ac, Bc, Cc)`` of the output-feedback controller ``y_m -> u`` (``D = 0``).

    The controller of :func:`of_closed_loop` on its own: states ``(xhat, xi_1..xi_p)``,
    ``xhat' = (A - L Cm + Bu K0) xhat + Bu G xi + L y_m``, ``xi_j' = A_phi xi_j + b_phi
    (y_m,j - Cm_j xhat)``, ``u = K0 xhat + G xi`` with ``G = [Theta_j C_phi]_j``. Closed
    around the plant it gives the poles of :func:`of_closed_loop` (a change of
    coordinates).

    Parameters
    ----------
    plant : YoulaPlant
        The plant.
    meas : Measurements
        The measurements.
    K0 : ndarray (m, n)
        State feedback.
    L : ndarray (n, p)
        Observer gain.
    basis : tuple
        ``(A_phi, b_phi, C_phi)``.
    Theta : array_like (m, p, nb)
        The Youla parameter's coefficients.
    actuators : bool
        Append one row per actuator and then the plant's states to ``C`` (as
        :func:`closed_loop`).
    """
    A_phi, b_phi, C_phi = basis
    ns = C_phi.shape[1]
    n, p = plant.n, meas.p
    G = _bank_output(plant, meas, C_phi, Theta)
    N = n + p * ns
    Ac = np.zeros((N, N))
    Bc = np.zeros((N, p))
    Ac[:n, :n] = plant.A - L @ meas.Cm + plant.Bu @ K0
    Ac[:n, n:] = plant.Bu @ G
    Bc[:n] = L
    for j in range(p):
        r = slice(n + j * ns, n + (j + 1) * ns)
        Ac[r, :n] = -b_phi @ meas.Cm[[j]]
        Ac[r, r] = A_phi
        Bc[r, j] = b_phi.ravel()
    return Ac, Bc, np.hstack([K0, G])


def force_responses(plant: YoulaPlant, K0, basis, omega, meas=None, L=None) -> dict:
    """The force actuator's responses, affine in ``vec(Theta)``, on the grid ``omega``.


    Parameters
    ----------
    plant : YoulaPlant
        The plant (with a force actuator).
    K0 : ndarray (m, n)
        State feedback.
    basis : tuple
        ``(A_phi, b_phi, C_phi)``.
    omega : array_like
        Frequencies, rad/s.
    meas : Measurements, optional
        The measurements (output feedback); ``None``: full information.
    L : ndarray (n, p), optional
        Observer gain (output feedback).

    Returns
    -------
    dict
        ``"w"``: (f, 1 + N) with ``f(jw) = [1, vec(Theta)] . row`` for the exogenous input;
        ``"n"``: (f, p, 1 + N) the same per measurement noise (absent for full
        information). ``N = m nb`` (full information) or ``m p nb`` (output feedback).
    """
    if plant.force is None:
        raise ParameterError("force_responses: the plant has no force actuator")
    A_phi, b_phi, C_phi = basis
    omega = np.asarray(omega, float)
    AK = plant.A + plant.Bu @ K0
    kf = K0[plant.force]
    phi = np.einsum("ij,fjk->fi", C_phi, resolvent_times(A_phi, omega, b_phi))  # (f, nb)
    Xv = resolvent_times(AK, omega, plant.Bu)  # (f, n, m)
    fv = np.einsum("j,fjm->fm", kf, Xv)
    fv[:, plant.force] += 1.0
    if meas is None:
        Xw = resolvent_times(AK, omega, plant.Bw)[:, :, 0]
        f0 = Xw @ kf
        lin = (fv[:, :, None] * phi[:, None, :]).reshape(omega.size, -1)
        return {"w": plant.force_gain * np.hstack([f0[:, None], lin])}
    p = meas.p
    AL = plant.A - L @ meas.Cm
    Ew = resolvent_times(AL, omega, plant.Bw - L @ meas.Dmw)[:, :, 0]  # (f, n)
    En = resolvent_times(AL, omega, -L)  # (f, n, p)
    Xw = resolvent_times(AK, omega, plant.Bw)[:, :, 0] - np.einsum("fij,fj->fi", Xv, Ew @ K0.T)
    f0w = Xw @ kf - Ew @ kf
    ew = np.einsum("ij,fj->fi", meas.Cm, Ew) + meas.Dmw[:, 0][None]
    Xn = -np.einsum("fim,fmj->fij", Xv, np.einsum("mk,fkj->fmj", K0, En))
    f0n = np.einsum("i,fij->fj", kf, Xn) - np.einsum("i,fij->fj", kf, En)  # (f, p)
    en = np.einsum("ij,fjk->fik", meas.Cm, En) + np.eye(p)[None]  # (f, p meas, p noise)
    lin_w = np.einsum("fa,fi,fk->faik", fv, ew, phi).reshape(omega.size, -1)
    lin_n = np.einsum("fa,fij,fk->fjaik", fv, en, phi).reshape(omega.size, p, -1)
    g = plant.force_gain
    return {
        "w": g * np.hstack([f0w[:, None], lin_w]),
        "n": g * np.concatenate([f0n[:, :, None], lin_n], axis=2),
    }


def quadrature_grid(poles, *, per_decade: int = 80):
    """A log-spaced grid and trapezoid weights for ``(1/pi) int_0^inf g(w) dw``.

    From ``1e-3`` times the smallest to ``100`` times the largest pole magnitude; the
    tails are added as ``g(w_min) w_min`` (flat below) and ``g(w_max) w_max`` (decaying
    as ``w^-2`` above, as a strictly proper map's squared magnitude does).


    Parameters
    ----------
    poles : array_like of complex
        The poles of the integrand's maps.
    per_decade : int
        Grid points per decade.

    Returns
    -------
    omega, weights : ndarray
    """
    a = np.abs(np.asarray(poles, complex))
    a = a[a > 0]
    lo, hi = 1e-3 * max(a.min(), 1e-3), 100.0 * a.max()
    k = int(math.ceil(per_decade * math.log10(hi / lo))) + 1
    w = np.geomspace(lo, hi, k)
    wt = np.zeros(k)
    d = np.diff(w)
    wt[:-1] += d / 2
    wt[1:] += d / 2
    wt[0] += w[0]
    wt[-1] += w[-1]
    return w, wt / math.pi


def quadrature_gram(resp: dict, weights, *, intent, noise=None) -> np.ndarray:
    """``W`` with ``[1, theta]' W [1, theta]`` the force variance, from :func:`force_responses`.

    ``intent`` (f,) is ``|k F(jw)|^2`` (the intent's spectrum shaping ``w``); ``noise``
    (p,) the measurement noise intensities.

    Parameters
    ----------
    resp : dict
        :func:`force_responses` on the grid.
    weights : ndarray
        Quadrature weights of the grid (:func:`quadrature_grid`).
    intent : ndarray
        ``|k F(j w)|^2`` on the grid.
    noise : array_like, optional
        Measurement noise intensities.
    """
    Vw = resp["w"] * np.sqrt(weights * intent)[:, None]
    W = (Vw.conj().T @ Vw).real
    if noise is not None and "n" in resp:
        for j, nj in enumerate(noise):
            Vn = resp["n"][:, j, :] * np.sqrt(weights * nj)[:, None]
            W += (Vn.conj().T @ Vn).real
    return 0.5 * (W + W.T)
