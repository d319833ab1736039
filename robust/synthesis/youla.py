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

import numpy as np

from robust.analysis.loops import resolvent_times
from robust.analysis.region import Region
from robust.errors import ModelStructureError, ParameterError, SolverError
from robust.synthesis.limit_problem import LimitProblem, gram_factor
from robust.synthesis.stabilising import RICCATI_RTOL as RICCATI_RTOL
from robust.synthesis.stabilising import _riccati_residual as _riccati_residual
from robust.synthesis.stabilising import stabilising_gain, uncontrollable_modes
from robust.synthesis.youla_basis import (
    lag_basis,
    output_gram,
    pole_basis,
    quadrature_gram,
    quadrature_grid,
)

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
