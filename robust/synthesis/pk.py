"""Multi-model, multi-objective synthesis by sequential LMIs: the P-K iteration on a family.

One fixed-order controller ``u = K y`` for a set of members. Each member has three
plants that share the controls ``u`` and measurements ``y`` (:class:`SynthesisMember`):
the *region* plant (the loop whose closed-loop poles must lie in a
:class:`~robust.analysis.region.Region`, its damping enforced at every frequency), the
*H-infinity* plant (a performance channel ``w -> z``) and, optionally, the *H2* plant (a
white-noise channel whose output power is bounded, e.g. the handle force under the
realistic intended motion).

Problem::

    minimise gamma  over  K, P_i, Q_i, Z_i
    s.t. for every member i:
         BRL(A_i(K) + alpha I, B_i(K), C_i(K), D_i(K); P_i) < 0      (H-infinity <= gamma, decay)
         [[A_i' Q_i + Q_i A_i, Q_i B_i], [., -I]] < 0, [[Q_i, C_i'], [., Z_i]] > 0,
         trace Z_i <= h2_bound^2                                          (H2 <= h2_bound)
         every closed-loop pole of the region plant in the damping cone.

The bounded-real lemma is written for the closed loop shifted by the decay rate
``alpha``: its certificate proves every pole has real part below ``-alpha`` *and*
``||G(s - alpha)||_inf <= gamma``, which bounds ``||G||_inf`` (maximum modulus on
``Re s >= -alpha``). The H2 conditions are those of Scherer, Gahinet & Chilali (IEEE
TAC 42(7), 1997), the bounded-real lemma that of Boyd, El Ghaoui, Feron &
Balakrishnan (SIAM 1994, Sec. 2.7.3).

Method: the P-K iteration (El Ghaoui & Balakrishnan, "Synthesis of fixed-structure
controllers via numerical optimization", IEEE CDC 1994), the workbench's one (the
generalized plants of :func:`robust.synthesis.multi.hinfsyn_multi` run through it). With the
controller fixed, every inequality is an LMI in the Lyapunov matrices (P-step, one
small SDP per member and objective, at a level ``1 + LEVEL_SLACK`` above the norm
computed directly, maximising the margin); with the Lyapunov matrices fixed, an LMI in
the controller data ``Omega = [[Ak, Bk], [Ck, Dk]]`` (K-step, one SDP over all members),
since ``A(Omega) = A0 + Bb Omega Cb``. The K-step is feasible at the current controller,
so the certified level never increases. Three changes make it work on lightly damped
loops whose data spread over decades: each member's certificates are kept as state
coordinates in which they are the identity (``T' P T = I``; the closed loop is
transformed by ``T``, the controller data are untouched since ``T^-1 Bb Omega Cb T``),
the K-step stays in a trust region, and the P-step's levels come from the exact norms
(Bruinsma-Steinbuch, Gramian) so that a solver's inaccuracy never inflates a bound. The
damping cone of [CG96] doubles the LMI size and would dominate every solve; inside
the K-step it is kept by first-order eigenvalue constraints
(``d lambda = l^H Bb dOmega Cb r / l^H r``) within the trust region, as are the
members' response bounds (:class:`ResponseBound`); every step is re-checked with exact
eigenvalues and responses before it is kept, and the final controller gets a
cone-and-decay certificate per member from the region LMI
(:func:`robust.synthesis.region.certify_region`).

Every answer is verified before it is returned: each certificate's LMI matrices
rebuilt in numpy, each member's closed-loop eigenvalues, its H-infinity norm
(:func:`robust.analysis.norms.hinf_norm`) and its H2 norm
(:func:`robust.analysis.norms.h2_norm`, controllability Gramian).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import time
from collections.abc import Callable, Sequence

import control
import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from robust.analysis.norms import h2_norm, hinf_norm
from robust.analysis.region import Region
from robust.analysis.resolvent import siso_responses
from robust.checks import POSITIVE, Spec, check_int, check_scalar
from robust.engine import jobs_available, map_tasks
from robust.errors import (
    InfeasibleError,
    ModelStructureError,
    ParameterError,
    SolverError,
    VerificationError,
)
from robust.synthesis.lmi import PlantBlocks
from robust.synthesis.region import (
    RegionCertificate,
    certify_region,
    recentring,
    sym,
    synthesis_region,
)
from robust.synthesis.scaling import ChannelScaling, TimeScaling
from robust.synthesis.scaling_base import ControllerMatrices
from robust.synthesis.solve import (
    DEFAULT_SOLVERS,
    check_solvers,
    deterministic_solvers,
    solve_problem,
    solver_threads,
)
from robust.synthesis.state_scaling import StateScaling

__all__ = [
    "ResponseBound",
    "SynthesisMember",
    "MemberCertificates",
    "MultiObjectiveResult",
    "pksyn_multi",
    "certify_regions",
    "eigen_derivatives",
    "eigen_derivatives_many",
    "eigen_region_rows",
    "responses",
    "scale_members",
    "to_scaled",
    "from_scaled",
]

#: Strictness margin of the LMIs in the recentred coordinates (certificates near I).
LMI_MARGIN = 1e-7
#: Eigenvalues whose region violation is below ``-ACTIVE`` (scaled time) get no
#: linearised constraint in a step.
ACTIVE = 0.5
#: Relative slack of the levels the P-step certifies above the exact norms.
LEVEL_SLACK = 0.02
#: Weight of the relative H2 excess in the merit (relative to the scaled gamma).
SLACK_WEIGHT = 10.0


# ------------------------------------------------------------------------- members
@dataclasses.dataclass(frozen=True)
class ResponseBound:
    """A bound ``|offset + gain T(jw)| <= bound`` on the H-infinity channel on a grid.

    ``T`` is the member's closed-loop H-infinity channel (one input, one output). In
    the BDFT designs it bounds the feedthrough ``|Y/Y_ref|`` near the structure mode by
    that of the uncompensated loop.

    Parameters
    ----------
    w : numpy.ndarray, shape (n,)
        Frequencies, rad/s (original time).
    offset, gain : numpy.ndarray of complex, shape (n,)
        The affine map of ``T``.
    bound : numpy.ndarray, shape (n,)
        Positive bounds.
    """

    w: np.ndarray
    offset: np.ndarray
    gain: np.ndarray
    bound: np.ndarray

    def __post_init__(self):
        arrs = [np.asarray(getattr(self, k)) for k in ("w", "offset", "gain", "bound")]
        if len({a.shape for a in arrs}) != 1 or arrs[0].ndim != 1:
            raise ModelStructureError(
                "ResponseBound: w, offset, gain, bound must be 1-D, equal size"
            )
        if not all(np.all(np.isfinite(a)) for a in arrs) or np.any(arrs[3] <= 0):
            raise ModelStructureError("ResponseBound: entries must be finite, bounds positive")
        for k, a in zip(("w", "offset", "gain", "bound"), arrs):
            a = a.copy()
            a.setflags(write=False)
            object.__setattr__(self, k, a)

    def values(self, T) -> np.ndarray:
        """``|offset + gain T| / bound`` for responses ``T`` on the grid (``<= 1``: met)."""
        return np.abs(self.offset + self.gain * np.asarray(T)) / self.bound


@dataclasses.dataclass(frozen=True)
class SynthesisMember:
    """One member: three plants with the same controls ``u`` and measurements ``y``.

    Each plant is a :class:`robust.synthesis.lmi.PlantBlocks` (``x' = A x + B1 w + B2 u``,
    ``z = C1 x + D11 w + D12 u``, ``y = C2 x + D21 w``).

    Parameters
    ----------
    region : PlantBlocks
        The loop whose closed-loop poles must lie in the region (its ``B1, C1``
        unused).
    hinf : PlantBlocks
        The H-infinity channel ``w -> z``.
    h2 : PlantBlocks, optional
        The H2 channel (white ``w``); needs ``D11 = 0`` and ``D21 = 0`` so the
        closed loop is strictly proper whatever the controller.
    label : str
        A name for messages and reports.
    response : ResponseBound, optional
        A frequency-wise bound on the H-infinity channel (needs a SISO channel).
    """

    region: PlantBlocks
    hinf: PlantBlocks
    h2: PlantBlocks | None = None
    label: str = ""
    response: ResponseBound | None = None

    def __post_init__(self):
        plants = {"region": self.region, "hinf": self.hinf}
        if self.h2 is not None:
            plants["h2"] = self.h2
        for name, b in plants.items():
            if not isinstance(b, PlantBlocks):
                raise ModelStructureError(
                    f"SynthesisMember.{name} must be a PlantBlocks; got {type(b).__name__}"
                )
            for f in dataclasses.fields(b):
                if not np.all(np.isfinite(getattr(b, f.name))):
                    raise ModelStructureError(
                        f"SynthesisMember.{name}.{f.name} must be finite ({self.label})"
                    )
        sizes = {name: (b.sizes[2], b.sizes[4]) for name, b in plants.items()}
        if len(set(sizes.values())) != 1:
            raise ModelStructureError(
                f"SynthesisMember: the plants must share (controls, measurements); got {sizes}"
            )
        if self.response is not None and (
            not isinstance(self.response, ResponseBound)
            or self.hinf.sizes[1] != 1
            or self.hinf.sizes[3] != 1
        ):
            raise ModelStructureError(
                "SynthesisMember.response must be a ResponseBound on a SISO H-infinity channel"
            )
        if self.h2 is not None and (np.any(self.h2.D11 != 0) or np.any(self.h2.D21 != 0)):
            raise ModelStructureError(
                "SynthesisMember.h2 must have D11 = 0 and D21 = 0 (a white-noise channel "
                "without direct feedthrough)"
            )

    @property
    def nu(self) -> int:
        """Number of controls."""
        return self.hinf.sizes[2]

    @property
    def ny(self) -> int:
        """Number of measurements."""
        return self.hinf.sizes[4]


class _Affine:
    """A closed loop affine in the controller data: ``A = A0 + Bb Om Cb`` etc. ([GA94] (2.5))."""

    def __init__(self, b: PlantBlocks, nk: int):
        n, nw, nu, nz, ny = b.sizes
        self.N = n + nk
        self.A0 = sla.block_diag(b.A, np.zeros((nk, nk)))
        self.B0 = np.vstack([b.B1, np.zeros((nk, nw))])
        self.C0 = np.hstack([b.C1, np.zeros((nz, nk))])
        self.D0 = b.D11
        self.Bb = np.block([[np.zeros((n, nk)), b.B2], [np.eye(nk), np.zeros((nk, nu))]])
        self.Cb = np.block([[np.zeros((nk, n)), np.eye(nk)], [b.C2, np.zeros((ny, nk))]])
        self.D12b = np.hstack([np.zeros((nz, nk)), b.D12])
        self.D21b = np.vstack([np.zeros((nk, nw)), b.D21])

    def shifted(self, a: float) -> _Affine:
        out = self._copy()
        out.A0 = self.A0 + a * np.eye(self.N)
        return out

    def _copy(self) -> _Affine:
        out = _Affine.__new__(_Affine)
        out.__dict__.update(self.__dict__)
        return out

    def transformed(self, T) -> _Affine:
        """The same loop in state coordinates ``x = T xt``."""
        Ti = np.linalg.inv(T)
        out = self._copy()
        out.A0, out.Bb, out.B0 = Ti @ self.A0 @ T, Ti @ self.Bb, Ti @ self.B0
        out.Cb, out.C0 = self.Cb @ T, self.C0 @ T
        return out

    def scaled_output(self, c: float) -> _Affine:
        out = self._copy()
        out.C0, out.D0, out.D12b = self.C0 / c, self.D0 / c, self.D12b / c
        return out

    def matrices(self, Om):
        # (Bb Om) and (D12b Om) once each: the products associate from the left, so these
        # are the same numbers as writing each term out
        BO, DO = self.Bb @ Om, self.D12b @ Om
        return (
            self.A0 + BO @ self.Cb,
            self.B0 + BO @ self.D21b,
            self.C0 + DO @ self.Cb,
            self.D0 + DO @ self.D21b,
        )


def _bmat(rows):
    if any(isinstance(b, cp.Expression) for r in rows for b in r):
        return cp.bmat(rows)
    return np.block(rows)


def _brl_parts(cl: _Affine, P, Om, g):
    """``(F0, U, V)`` of the bounded-real inequality at level ``g`` (BMI ``F0 + U'V + V'U``)."""
    nw, nz, N = cl.B0.shape[1], cl.C0.shape[0], cl.N
    C = cl.C0 + cl.D12b @ Om @ cl.Cb
    D = cl.D0 + cl.D12b @ Om @ cl.D21b
    PA, PB = P @ cl.A0, P @ cl.B0
    F0 = _bmat([[PA + PA.T, PB, C.T], [PB.T, -g * np.eye(nw), D.T], [C, D, -g * np.eye(nz)]])
    E = np.hstack([np.eye(N), np.zeros((N, nw + nz))])
    V = Om @ np.hstack([cl.Cb, cl.D21b, np.zeros((cl.Cb.shape[0], nz))])
    return F0, cl.Bb.T @ P @ E, V


def _h2_parts(cl: _Affine, Q, Om):
    """``(F0, U, V)`` of ``[[A'Q + QA, QB], [B'Q, -I]] < 0``."""
    nw, N = cl.B0.shape[1], cl.N
    QA, QB = Q @ cl.A0, Q @ cl.B0
    F0 = _bmat([[QA + QA.T, QB], [QB.T, -np.eye(nw)]])
    E = np.hstack([np.eye(N), np.zeros((N, nw))])
    return F0, cl.Bb.T @ Q @ E, Om @ np.hstack([cl.Cb, cl.D21b])


def _h2_output(cl: _Affine, Q, Om, Z):
    """``[[Q, C'], [C, Z]]`` (must be positive definite)."""
    C = cl.C0 + cl.D12b @ Om @ cl.Cb
    return _bmat([[Q, C.T], [C, Z]])


def responses(cl: _Affine, Om, w) -> tuple[np.ndarray, np.ndarray]:
    """A SISO closed loop's frequency response and its derivative in the controller data.

    ``T(jw) = C R B + D`` with ``R = (jw - A)^-1``; since ``A, B, C, D`` are affine in
    ``Om``, ``dT = (D12b + C R Bb) dOm (Cb R B + D21b)``. The three products come from one
    Hessenberg form of ``A`` (:func:`robust.analysis.resolvent.siso_responses`).

    Parameters
    ----------
    cl : _Affine
        The closed loop (one input, one output).
    Om : numpy.ndarray
        Controller data.
    w : numpy.ndarray
        Frequencies (in the loop's time unit).

    Returns
    -------
    T : numpy.ndarray of complex, shape (n_w,)
    dT : numpy.ndarray of complex, shape (n_w, *Om.shape)
    """
    A, B, C, D = cl.matrices(Om)
    crb, cRBb, CbRb = siso_responses(A, B[:, 0], C[0], cl.Bb, cl.Cb, w)
    T = crb + D[0, 0]
    p = cl.D12b[0][None, :] + cRBb  # (n_w, m)
    q = CbRb + cl.D21b[:, 0][None, :]  # (n_w, p)
    return T, p[:, :, None] * q[:, None, :]


def _bmi(F0, U, V):
    return sym(F0 + U.T @ V + V.T @ U)


def _max_eig(M) -> float:
    return float(np.linalg.eigvalsh(sym(np.asarray(M, float))).max())


# --------------------------------------------------------------------- results
@dataclasses.dataclass(frozen=True)
class MemberCertificates:
    """One member's certificates and their independent checks (original coordinates).

    Parameters
    ----------
    region : RegionCertificate or None
        Decay-and-cone certificate of the region plant's closed loop ([CG96]); ``None``
        until :func:`certify_regions` runs when ``pksyn_multi`` deferred it.
    P : numpy.ndarray
        Bounded-real certificate of the decay-shifted H-infinity closed loop at level
        ``gamma_bound`` (plant states, then controller states).
    Q, Z : numpy.ndarray or None
        H2 certificate in the solve's coordinates (recentred, balanced plant states,
        time ``tau = w0 t``; ``None`` without an H2 plant).
    lmi_max_eig : dict
        Largest eigenvalue of each inequality rebuilt in numpy in the solve's
        coordinates (all negative), by name.
    gamma : float
        The member's H-infinity norm, computed independently.
    gamma_bound : float
        The level ``P`` certifies for the decay-shifted channel (so for the channel).
    gamma_shifted : float
        The norm of the decay-shifted closed loop (what ``P`` certifies).
    h2 : float
        The member's H2 norm from the Gramian (0 without an H2 plant).
    h2_bound : float
        The H2 bound the certificate ``Q, Z`` proves, original units
        (``sqrt(w0 trace Z)``).
    region_violation : float
        Largest region violation of the closed-loop poles (negative), rad/s.
    """

    region: RegionCertificate | None
    P: np.ndarray
    Q: np.ndarray | None
    Z: np.ndarray | None
    lmi_max_eig: dict
    gamma: float
    gamma_bound: float
    gamma_shifted: float
    h2: float
    h2_bound: float
    region_violation: float

    def to_json(self) -> dict:
        """The checks (no matrices)."""
        return {
            "region": None if self.region is None else self.region.to_json(),
            "lmi_max_eig": dict(self.lmi_max_eig),
            "gamma": self.gamma,
            "gamma_bound": self.gamma_bound,
            "gamma_shifted": self.gamma_shifted,
            "h2": self.h2,
            "h2_bound": self.h2_bound,
            "region_violation": self.region_violation,
        }


@dataclasses.dataclass(frozen=True)
class MultiObjectiveResult:
    """A verified multi-model design by sequential LMIs.

    Parameters
    ----------
    K : control.StateSpace
        The common controller ``u = K y``.
    gamma_bound : float
        Certified common bound of the decay-shifted H-infinity norms (so of the norms).
    h2_bound : float or None
        The H2 bound imposed (``None`` without H2 plants).
    h2_met : bool
        Whether every member's certified H2 bound is within ``h2_bound``.
    certificates : tuple of MemberCertificates
        One per member, in order.
    region : robust.analysis.region.Region
        The region certified for every member, its damping at every frequency.
    history : tuple of dict
        Per accepted step: ``gamma`` (certified), ``h2_excess`` (relative slack),
        ``trust`` radius.
    iterations : int
        Steps tried (accepted and rejected).
    solve_times : tuple of float
        Seconds of every SDP solve (analysis and steps), in order.
    wall_time : float
        Seconds for the whole call.
    method : str
        The method and its guarantee, in words.
    notes : tuple of str
        Rejected steps, why the iteration stopped.
    w0 : float
        Time scale of the SDPs, rad/s.
    omega_scaled : numpy.ndarray or None
        The controller data in the SDPs' coordinates (what :func:`certify_regions`
        certifies when the region certificates were deferred).
    """

    K: control.StateSpace
    gamma_bound: float
    h2_bound: float | None
    h2_met: bool
    certificates: tuple
    region: Region
    history: tuple
    iterations: int
    solve_times: tuple
    wall_time: float
    method: str
    notes: tuple = ()
    w0: float = 20.0
    omega_scaled: np.ndarray | None = None

    @property
    def gammas(self) -> np.ndarray:
        """Each member's independently computed H-infinity norm."""
        return np.array([c.gamma for c in self.certificates])

    @property
    def h2s(self) -> np.ndarray:
        """Each member's independently computed H2 norm."""
        return np.array([c.h2 for c in self.certificates])

    def to_json(self) -> dict:
        """The facts of the result (no matrices)."""
        return {
            "method": self.method,
            "members": len(self.certificates),
            "order": self.K.nstates,
            "gamma_bound": self.gamma_bound,
            "gammas": self.gammas.tolist(),
            "h2_bound": self.h2_bound,
            "h2_met": self.h2_met,
            "h2s": self.h2s.tolist(),
            "region": self.region.describe(),
            "certificates": [c.to_json() for c in self.certificates],
            "history": list(self.history),
            "iterations": self.iterations,
            "lmi_solves": len(self.solve_times),
            "solve_time_s": float(sum(self.solve_times)),
            "solve_time_per_lmi_s": float(np.mean(self.solve_times)) if self.solve_times else 0.0,
            "wall_time_s": self.wall_time,
            "notes": list(self.notes),
        }


# ------------------------------------------------------------------- internals
class _Scaled:
    """A member in scaled coordinates: common time and channel scaling, own state scaling."""

    def __init__(self, m: SynthesisMember, nk: int, w0: float, channels: ChannelScaling):
        def prep(b):
            st = StateScaling.fit(b)
            return channels.apply(TimeScaling(w0).apply(st.apply(b))), st

        self.region_b, self.region_st = prep(m.region)
        self.hinf_b, self.hinf_st = prep(m.hinf)
        self.region = _Affine(self.region_b, nk)
        self.hinf = _Affine(self.hinf_b, nk)
        self.response = m.response
        self.w_resp = None if m.response is None else m.response.w / w0
        self.h2 = None
        if m.h2 is not None:
            self.h2_b, self.h2_st = prep(m.h2)
            self.h2 = _Affine(self.h2_b, nk)


def scale_members(members, nk: int, w0: float):
    """Common time and channel scaling of the members, each plant's own state scaling.

    The channel scaling is fitted to the first member's region plant (after its state and
    time scaling), so one controller serves every member.

    Parameters
    ----------
    members : sequence of SynthesisMember
        The members.
    nk : int
        Controller order.
    w0 : float
        Time scale, rad/s.

    Returns
    -------
    channels : ChannelScaling
    scaled : list
        Per member, the three closed loops affine in the scaled controller data.
    """
    first = TimeScaling(w0).apply(StateScaling.fit(members[0].region).apply(members[0].region))
    channels = ChannelScaling.fit(first)
    return channels, [_Scaled(m, nk, w0, channels) for m in members]


def to_scaled(Om, nk: int, w0: float, channels: ChannelScaling) -> np.ndarray:
    """Controller data of the original plants, for the scaled ones.

    Parameters
    ----------
    Om : numpy.ndarray
        Controller data ``[[Ak, Bk], [Ck, Dk]]`` for the original plants.
    nk : int
        Controller order.
    w0 : float
        Time scale, rad/s.
    channels : ChannelScaling
        The members' common channel scaling (:func:`scale_members`).
    """
    K = ControllerMatrices.from_omega(np.asarray(Om, float), nk)
    return channels.apply_controller(TimeScaling(w0).apply_controller(K)).omega()


def from_scaled(Om_s, nk: int, w0: float, channels: ChannelScaling) -> np.ndarray:
    """Controller data of the scaled plants, for the original ones.

    Parameters
    ----------
    Om_s : numpy.ndarray
        Controller data for the scaled plants (time ``tau = w0 t``).
    nk : int
        Controller order.
    w0 : float
        Time scale, rad/s.
    channels : ChannelScaling
        The members' common channel scaling (:func:`scale_members`).
    """
    K = channels.invert_controller(ControllerMatrices.from_omega(np.asarray(Om_s, float), nk))
    return TimeScaling(w0).invert_controller(K).omega()


def _controller_data(K0) -> tuple[np.ndarray, int]:
    if isinstance(K0, control.StateSpace):
        K = ControllerMatrices(*(np.asarray(M, float) for M in (K0.A, K0.B, K0.C, K0.D)))
    elif isinstance(K0, ControllerMatrices):
        K = ControllerMatrices(*(np.asarray(M, float) for M in K0))
    else:
        raise ModelStructureError(
            f"pksyn_multi: K0 must be a control.StateSpace or ControllerMatrices; "
            f"got {type(K0).__name__}"
        )
    if not all(np.all(np.isfinite(M)) for M in K):
        raise ModelStructureError("pksyn_multi: K0 has non-finite entries")
    return K.omega(), K.Ak.shape[0]


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


@dataclasses.dataclass
class _Point:
    """The current iterate: controller data and per-member certificates.

    Each member's certificates are kept as recentring transforms: in coordinates
    ``x = T xt`` the bounded-real certificate at level ``g`` (outputs scaled by ``g``) is
    the identity, and so is the H2 certificate ``Q`` (with output level ``z``).
    """

    Om: np.ndarray
    T_hinf: list
    g_member: list
    T_h2: list
    z_member: list


class _AnalysisSDP:
    """A P-step SDP built once per size, the closed loop's matrices its parameters.

    cvxpy compiles a problem written with :class:`cvxpy.Parameter` data once (disciplined
    parametrised programming) and maps new values into the solver's data without
    compiling again; the P-steps of every member and iteration share one problem per size.
    """

    def __init__(self, problem, data, P, t, level=None):
        self.problem, self.data, self.P, self.t, self.level = problem, data, P, t, level


@functools.lru_cache(maxsize=16)
def _hinf_analysis_sdp(n: int, nw: int, nz: int) -> _AnalysisSDP:
    """``max t`` s.t. ``trace P <= 10 n``, BRL(A, B, C, D; P) at level 1 ``<= -t I``.

    ``P > 0`` is not a constraint of its own: with ``t > 0`` the inequality's first block
    gives ``PA + A'P < 0``, so ``P > 0`` whenever ``A`` is Hurwitz (Lyapunov), and no
    certificate exists when it is not; the answer's ``P`` is checked to be positive
    definite (:func:`_analyse_hinf`). The optimum is the same, and without a cone that
    the solution never touches each solve takes about half the time.
    """
    A, B = cp.Parameter((n, n), name="A"), cp.Parameter((n, nw), name="B")
    C, D = cp.Parameter((nz, n), name="C"), cp.Parameter((nz, nw), name="D")
    P, t = cp.Variable((n, n), symmetric=True), cp.Variable()
    PA, PB = P @ A, P @ B
    M = sym(cp.bmat([[PA + PA.T, PB, C.T], [PB.T, -np.eye(nw), D.T], [C, D, -np.eye(nz)]]))
    problem = cp.Problem(cp.Maximize(t), [cp.trace(P) <= 10 * n, M << -t * np.eye(n + nw + nz)])
    return _AnalysisSDP(problem, (A, B, C, D), P, t)


@functools.lru_cache(maxsize=16)
def _h2_analysis_sdp(n: int, nw: int, nz: int) -> _AnalysisSDP:
    """``max t``: the H2 inequalities in ``(Q, Z)`` with margin ``t``, ``trace Z <= level``.

    ``Q > 0`` is implied by ``[[Q, C'], [C, Z]] >= t I`` with ``t > 0`` (``Q >= t I``), so
    it is not a cone of its own (the same optimum, about half the solve time).
    """
    A, B = cp.Parameter((n, n), name="A"), cp.Parameter((n, nw), name="B")
    C, level = cp.Parameter((nz, n), name="C"), cp.Parameter(nonneg=True, name="level")
    Q, Z, t = (
        cp.Variable((n, n), symmetric=True),
        cp.Variable((nz, nz), symmetric=True),
        cp.Variable(),
    )
    QA, QB = Q @ A, Q @ B
    M = sym(cp.bmat([[QA + QA.T, QB], [QB.T, -np.eye(nw)]]))
    N2 = cp.bmat([[Q, C.T], [C, Z]])
    problem = cp.Problem(
        cp.Maximize(t),
        [
            cp.trace(Q) <= 10 * n,
            M << -t * np.eye(n + nw),
            N2 >> t * np.eye(n + nz),
            cp.trace(Z) <= level,
        ],
    )
    return _AnalysisSDP(problem, (A, B, C), Q, t, level)


def _sizes(data) -> tuple[int, int, int]:
    """``(n, nw, nz)`` of an analysis SDP's data ``(A, B, C, ...)``."""
    A, B, C = data[:3]
    return A.shape[0], B.shape[1], C.shape[0]


def _hinf_analysis_data(cl: _Affine, Om, T_prev):
    """The H-infinity P-step's coordinates, level and SDP data for one member:
    ``(T, g0, (A, B, C, D))``, the closed loop in the coordinates ``T`` (of the previous
    certificate or, first, of the Riccati solution) with its output scaled by the level."""
    A, B, C, D = cl.matrices(Om)
    g = hinf_norm(control.ss(A, B, C, D))
    g0 = (1 + LEVEL_SLACK) * g + 1e-12
    n = A.shape[0]
    if T_prev is None:
        Cs, Ds = C / g0, D / g0
        R = -(np.eye(B.shape[1]) - Ds.T @ Ds)
        try:
            X = sla.solve_continuous_are(A, B, Cs.T @ Cs, R, s=Cs.T @ Ds)
            T_prev = recentring(sym(X) + 1e-6 * np.abs(X).max() * np.eye(n))
        except (np.linalg.LinAlgError, ValueError, VerificationError):
            T_prev = recentring(sla.solve_continuous_lyapunov(A.T, -(Cs.T @ Cs + np.eye(n))))
    return T_prev, g0, cl.transformed(T_prev).scaled_output(g0).matrices(Om)


def _h2_analysis_data(cl: _Affine, Om, T_prev):
    """The H2 P-step's coordinates, level and SDP data for one member: ``(T, z0, (A, B,
    C))`` in the coordinates ``T`` (of the previous certificate or, first, of the inverse
    controllability Gramian)."""
    A, B, C, _ = cl.matrices(Om)
    n = A.shape[0]
    z0 = (1 + LEVEL_SLACK) ** 2 * h2_norm(A, B, C) ** 2 + 1e-300
    if T_prev is None:
        BB = B @ B.T
        S = sla.solve_continuous_lyapunov(A, -(BB + 1e-9 * np.linalg.norm(BB, 2) * np.eye(n)))
        T_prev = recentring(np.linalg.inv(sym(S)))
    return T_prev, z0, cl.transformed(T_prev).matrices(Om)[:3]


def _analyse_hinf(cl: _Affine, Om, T_prev, solvers):
    """P-step for one member: a centred certificate of the shifted H-infinity channel.

    The level is ``(1 + LEVEL_SLACK)`` times the channel's norm (computed directly); the
    SDP maximises the margin of the bounded-real inequality at that level in the
    coordinates of the previous certificate (or, first, of the Riccati solution).
    """
    T_prev, g0, data = _hinf_analysis_data(cl, Om, T_prev)
    sdp = _hinf_analysis_sdp(*_sizes(data))
    sdp.t.value = None
    for par, val in zip(sdp.data, data):
        par.value = val
    # afresh (no reuse of the previous solve's workspace): the answer must not depend on
    # what this process solved before
    sol = solve_problem(
        sdp.problem,
        step="pksyn_multi: H-infinity analysis (P) step",
        solvers=solvers,
        warm_start=False,
    )
    P, t = sdp.P, sdp.t
    if t.value is None or not t.value > 0:
        raise InfeasibleError(
            f"pksyn_multi: no bounded-real certificate at level {g0:.6g} (margin {t.value})"
        )
    # P > 0 is implied for a Hurwitz A only (the SDP does not impose it)
    p_min = float(np.linalg.eigvalsh(sym(P.value))[0])
    if not p_min > 0:
        raise InfeasibleError(
            f"pksyn_multi: no bounded-real certificate at level {g0:.6g}: the member's closed "
            f"loop is not stable (the certificate's smallest eigenvalue is {p_min:.3g})"
        )
    return T_prev @ recentring(sym(P.value)), g0, sol.solve_time


def _analyse_h2(cl: _Affine, Om, T_prev, solvers):
    """P-step for one member: a centred H2 certificate at ``(1 + LEVEL_SLACK)^2`` the norm^2."""
    T_prev, z0, data = _h2_analysis_data(cl, Om, T_prev)
    sdp = _h2_analysis_sdp(*_sizes(data))
    sdp.t.value = None
    for par, val in zip(sdp.data, data):
        par.value = val
    sdp.level.value = z0
    sol = solve_problem(
        sdp.problem, step="pksyn_multi: H2 analysis (P) step", solvers=solvers, warm_start=False
    )
    Q, t = sdp.P, sdp.t
    if t.value is None or not t.value > 0:
        raise InfeasibleError(f"pksyn_multi: no H2 certificate at level {z0:.6g} ({t.value})")
    return T_prev @ recentring(sym(Q.value)), z0, sol.solve_time


def _analyse_task(task):
    """One certificate of a P-step (module level: it runs in worker processes).

    ``task = (kind, cl, Om, T_prev, solvers, threads)``, ``kind`` ``"hinf"`` or ``"h2"``;
    ``threads == 1`` solves on one thread (:func:`deterministic_solvers`), as the caller did.
    """
    kind, cl, Om, T_prev, solvers, threads = task
    with deterministic_solvers() if threads == 1 else contextlib.nullcontext():
        return (_analyse_hinf if kind == "hinf" else _analyse_h2)(cl, Om, T_prev, solvers)


def _p_step(members, Om, prev: _Point | None, solvers, times) -> _Point:
    """The members' certificates for ``Om``: independent SDPs, in the processes granted by
    :func:`robust.engine.nested_jobs` (the same answers in any of them, combined in order)."""
    threads = solver_threads()
    tasks = []
    for i, m in enumerate(members):
        tasks.append(
            ("hinf", m.hinf_shifted, Om, None if prev is None else prev.T_hinf[i], solvers, threads)
        )
        if m.h2 is not None:
            tasks.append(("h2", m.h2, Om, None if prev is None else prev.T_h2[i], solvers, threads))
    jobs = min(jobs_available(), len(tasks))
    answers = iter(map_tasks(_analyse_task, tasks, jobs=jobs, scheduler=None))
    T_h, g_m, T_2, z_m = [], [], [], []
    for m in members:
        T, g, st = next(answers)
        T_h.append(T)
        g_m.append(g)
        times.append(st)
        if m.h2 is not None:
            T, z, st = next(answers)
            times.append(st)
        else:
            T, z = None, 0.0
        T_2.append(T)
        z_m.append(z)
    return _Point(Om, T_h, g_m, T_2, z_m)


def _k_step(members, pt: _Point, region_s, h2cap, trust, solvers):
    """K-step: the certificates fixed (identity in their coordinates), the controller free.

    Every inequality is then affine in the controller data; each member's level ``g_i``
    (relative to its current one) and the H2 output level are variables. The damping
    cone and the response bounds enter as first-order constraints, softened by one
    penalised slack. Returns the new controller data and the solve time.
    """
    Om_k = pt.Om
    Om = cp.Variable(Om_k.shape, name="Omega")
    gam = cp.Variable(name="gamma")
    excess = cp.Variable(nonneg=True, name="h2_excess")
    soft = cp.Variable(nonneg=True, name="linearised_slack")
    gref = max(pt.g_member)
    cons = [cp.norm(Om - Om_k, "fro") <= trust * max(1.0, float(np.linalg.norm(Om_k)))]
    step = cp.vec(Om - Om_k, order="F")
    for i, m in enumerate(members):
        cl = m.hinf_shifted.transformed(pt.T_hinf[i]).scaled_output(pt.g_member[i])
        g = cp.Variable()
        M = _bmi(*_brl_parts(cl, np.eye(cl.N), Om, g))
        cons += [M << -LMI_MARGIN * np.eye(M.shape[0]), g * pt.g_member[i] <= gam]
        if m.h2 is not None:
            cl2 = m.h2.transformed(pt.T_h2[i])
            Z = cp.Variable((cl2.C0.shape[0],) * 2, symmetric=True)
            M = _bmi(*_h2_parts(cl2, np.eye(cl2.N), Om))
            cons += [
                M << -LMI_MARGIN * np.eye(M.shape[0]),
                _h2_output(cl2, np.eye(cl2.N), Om, Z) >> LMI_MARGIN * np.eye(cl2.N + Z.shape[0]),
                cp.trace(Z) <= h2cap * (1 + excess),
            ]
        # the first-order rows as one vector inequality each (one row per eigenvalue or
        # frequency, the gradient flattened in the order of cp.vec): compiled at once
        rows = [(v0, g) for v0, g in eigen_region_rows(m.region, Om_k, region_s) if v0 > -ACTIVE]
        if rows:
            v0s = np.array([v0 for v0, _ in rows])
            G = np.array([np.ravel(grad, order="F") for _, grad in rows])
            cons.append(v0s + G @ step <= -0.05 * ACTIVE + soft)
        if m.response is not None:
            T, dT = responses(m.hinf, Om_k, m.w_resp)
            rb = m.response
            r = rb.offset + rb.gain * T
            # |r + gain dT|^2 <= bound^2, first order: |r|^2 + 2 Re(conj(r) gain dT)
            coef = 2 * (np.conj(r)[:, None, None] * rb.gain[:, None, None] * dT).real
            G = coef.reshape(T.size, -1, order="F")
            b2 = rb.bound**2
            cons.append(np.abs(r) ** 2 + G @ step <= b2 + b2 * soft)
    obj = gam / gref + SLACK_WEIGHT * excess + 100.0 * soft
    sol = solve_problem(
        cp.Problem(cp.Minimize(obj), cons), step="pksyn_multi: synthesis (K) step", solvers=solvers
    )
    if Om.value is None:
        raise SolverError("pksyn_multi: K-step returned no controller")
    return np.asarray(Om.value, float), sol.solve_time


def _response_excess(members, Om) -> float:
    worst = 0.0
    for m in members:
        if m.response is not None:
            T, _ = responses(m.hinf, Om, m.w_resp)
            worst = max(worst, float(np.max(m.response.values(T))) - 1.0)
    return max(worst, 0.0)


def _check_options(region, h2_bound, w0, max_iter, trust, rtol) -> Region:
    region = synthesis_region(region, "pksyn_multi")
    if h2_bound is not None:
        check_scalar("h2_bound", h2_bound, POSITIVE, owner="pksyn_multi")
    check_scalar("w0", w0, POSITIVE, owner="pksyn_multi")
    check_int("max_iter", max_iter, low=0, owner="pksyn_multi")
    check_scalar("trust", trust, Spec(low=0.0, low_open=True), owner="pksyn_multi")
    check_scalar("rtol", rtol, Spec(0.0, 1.0, False, True), owner="pksyn_multi")
    return region


def pksyn_multi(
    members: Sequence[SynthesisMember],
    K0,
    region: Region,
    *,
    h2_bound: float | None = None,
    w0: float = 20.0,
    max_iter: int = 10,
    trust: float = 0.2,
    rtol: float = 1e-3,
    solvers=DEFAULT_SOLVERS,
    progress: Callable[[int, dict], None] | None = None,
    region_certificates: bool = True,
) -> MultiObjectiveResult:
    """One controller for every member: poles in ``region``, certified H-infinity and H2 bounds.

    See the module notes for the problem and the method. The iteration is local: it
    starts from ``K0``, which must place every member's region-plant poles in
    ``region`` (:func:`robust.synthesis.tuning.tune_members` can supply it). Each
    K-step minimises the common level of the decay-shifted H-infinity certificates plus
    a penalty on the H2 level's excess over ``h2_bound`` (so a ``K0`` whose H2 norm is
    too large is driven into the bound) within a trust region of relative radius
    ``trust``; the P-step then certifies the new controller member by member. A step is
    kept only if every pole stays in the region, the response bounds are not worsened
    and the merit (certified level relative to the first, plus the weighted H2 excess)
    decreases; otherwise the radius is halved.

    Parameters
    ----------
    members : sequence of SynthesisMember
        The design members (same controls and measurements).
    K0 : control.StateSpace or ControllerMatrices
        Initial controller ``y -> u``.
    region : robust.analysis.region.Region
        The pole region (decay rate and damping cone). Its damping is enforced at every
        frequency, whatever its band (conservative for a band-limited region, which the
        analyses check exactly in its band).
    h2_bound : float, optional
        Bound on every member's H2 norm, original units (required when members have
        H2 plants; ignored otherwise).
    w0 : float
        Time scale of the SDPs, rad/s (a frequency inside the band of interest).
    max_iter : int
        Largest number of K-steps (0: certify ``K0``).
    trust : float
        Initial relative trust-region radius of the K-step.
    rtol : float
        Stop when an accepted step improves the merit by less than this fraction.
    solvers : sequence of str
        cvxpy SDP solvers, in order.
    progress : callable, optional
        Called after each accepted step as ``progress(step, entry)``.
    region_certificates : bool
        Solve each member's region LMI for the final controller (the costliest part of the
        final checks). ``False`` defers them (``certificates[i].region`` is ``None``; the
        closed-loop poles are still checked): for a caller that runs many syntheses and
        keeps one, which it then certifies with :func:`certify_regions`.

    Returns
    -------
    MultiObjectiveResult

    Raises
    ------
    ModelStructureError
        Empty or inconsistent members, a ``K0`` of the wrong size.
    ParameterError
        An option out of range, or H2 plants without ``h2_bound``.
    InfeasibleError
        ``K0`` leaves a member's poles outside the region (members named), or an
        initial certificate cannot be found.
    VerificationError
        A final certificate fails its numpy re-check or an independent check.
    """
    t_start = time.perf_counter()
    region = _check_options(region, h2_bound, w0, max_iter, trust, rtol)
    solvers = check_solvers(solvers, name="pksyn_multi: solvers", sdp=True)
    members = list(members)
    if not members or not all(isinstance(m, SynthesisMember) for m in members):
        raise ModelStructureError(
            "pksyn_multi: members must be a non-empty sequence of SynthesisMember"
        )
    if len({(m.nu, m.ny) for m in members}) != 1:
        raise ModelStructureError("pksyn_multi: members must share controls and measurements")
    with_h2 = [m.h2 is not None for m in members]
    if any(with_h2) and not all(with_h2):
        raise ModelStructureError("pksyn_multi: either every member has an H2 plant or none")
    if all(with_h2) and h2_bound is None:
        raise ParameterError("pksyn_multi: h2_bound is required with H2 plants; got None")
    Om, nk = _controller_data(K0)
    nu, ny = members[0].nu, members[0].ny
    if Om.shape != (nk + nu, nk + ny):
        raise ModelStructureError(
            f"pksyn_multi: K0 must map {ny} measurement(s) to {nu} control(s); got "
            f"{Om.shape[1] - nk} -> {Om.shape[0] - nk}"
        )
    bad = []
    for i, m in enumerate(members):
        v = region.worst_violation(np.linalg.eigvals(_Affine(m.region, nk).matrices(Om)[0]))
        if v >= 0:
            bad.append(f"{m.label or i} (violation {v:.3g} rad/s)")
    if bad:
        raise InfeasibleError(
            f"pksyn_multi: K0 leaves members outside the region ({region.describe()}): "
            + ", ".join(bad)
        )
    channels, scaled = scale_members(members, nk, w0)
    region_s = region.scaled(w0)
    for m in scaled:
        m.hinf_shifted = m.hinf.shifted(region_s.decay_rate)
    h2cap = (h2_bound**2 / w0) if all(with_h2) else 0.0
    solve_times, notes = [], []
    try:
        pt = _p_step(scaled, to_scaled(Om, nk, w0, channels), None, solvers, solve_times)
    except SolverError as exc:
        raise InfeasibleError(f"pksyn_multi: no initial certificates: {exc}") from None
    g_first = max(pt.g_member)

    def merit(p: _Point) -> float:
        return max(p.g_member) / g_first + SLACK_WEIGHT * _excess(p, h2cap)

    history = [_entry(pt, h2cap, trust, _response_excess(scaled, pt.Om))]
    radius = trust
    it = 0
    for it in range(1, max_iter + 1):
        try:
            Om_new, st = _k_step(scaled, pt, region_s, h2cap, radius, solvers)
            solve_times.append(st)
        except (SolverError, InfeasibleError) as exc:
            notes.append(f"step {it}: K-step failed ({str(exc)[:120]}); radius halved")
            radius /= 2
            if radius < 1e-4 * trust:
                break
            continue
        reason = _reject_reason(scaled, pt, Om_new, region_s)
        new = None
        if reason is None:
            try:
                new = _p_step(scaled, Om_new, pt, solvers, solve_times)
            except (SolverError, InfeasibleError) as exc:
                reason = f"P-step failed ({str(exc)[:120]})"
        if new is not None and not merit(new) < merit(pt):
            reason = f"no decrease of the merit ({merit(new):.6g} vs {merit(pt):.6g})"
        if reason is not None:
            notes.append(f"step {it}: {reason}; radius halved")
            radius /= 2
            if radius < 1e-4 * trust:
                break
            continue
        before = merit(pt)
        pt = new
        history.append(_entry(pt, h2cap, radius, _response_excess(scaled, pt.Om)))
        if progress is not None:
            progress(it, history[-1])
        radius = min(2 * radius, 4 * trust)
        if before - merit(pt) < rtol * before:
            notes.append(f"step {it}: relative improvement below rtol = {rtol:g}")
            break
    else:
        if max_iter:
            notes.append(f"stopped after max_iter = {max_iter} steps")

    certificates = _final_certificates(
        members, scaled, pt, nk, w0, channels, region, solvers, solve_times, region_certificates
    )
    Om_o = from_scaled(pt.Om, nk, w0, channels)
    K = control.ss(Om_o[:nk, :nk], Om_o[:nk, nk:], Om_o[nk:, :nk], Om_o[nk:, nk:])
    return MultiObjectiveResult(
        K=K,
        gamma_bound=max(c.gamma_bound for c in certificates),
        h2_bound=h2_bound if all(with_h2) else None,
        h2_met=bool(
            all(with_h2) and max(c.h2_bound for c in certificates) <= h2_bound * (1 + 1e-9)
        ),
        certificates=tuple(certificates),
        region=region,
        history=tuple(history),
        iterations=it,
        solve_times=tuple(solve_times),
        wall_time=time.perf_counter() - t_start,
        method=(
            "P-K iteration (El Ghaoui & Balakrishnan, IEEE CDC 1994) on the decay-shifted "
            "bounded-real and the H2 inequalities of every member (Boyd et al. 1994; Scherer, "
            "Gahinet & Chilali 1997), each member's certificates in recentred coordinates, "
            "trust region; damping cone and feedthrough bounds as first-order constraints, "
            "the cone certified per member by the region LMI (Chilali & Gahinet, IEEE TAC "
            "41(3), 1996)"
        ),
        notes=tuple(notes),
        w0=float(w0),
        omega_scaled=np.array(pt.Om, float),
    )


def certify_regions(members, result: MultiObjectiveResult, *, solvers=DEFAULT_SOLVERS):
    """``result`` with every deferred region certificate solved and checked.

    Parameters
    ----------
    members : sequence of SynthesisMember
        The members ``result`` was synthesised on, in the same order.
    result : MultiObjectiveResult
        From :func:`pksyn_multi` (with ``region_certificates=False``, or not: certificates
        already present are kept).
    solvers : sequence of str
        cvxpy SDP solvers, in order.

    Returns
    -------
    MultiObjectiveResult
        The same result, each member's region certificate filled in (its solve times
        appended), as :func:`pksyn_multi` with ``region_certificates=True`` returns it.

    Raises
    ------
    ModelStructureError
        If ``members`` does not match the result.
    VerificationError
        If a member has no region certificate for the controller.
    """
    members = list(members)
    if len(members) != len(result.certificates) or result.omega_scaled is None:
        raise ModelStructureError(
            f"certify_regions: expected the {len(result.certificates)} members of the result "
            f"(and a result of pksyn_multi); got {len(members)}"
        )
    if all(c.region is not None for c in result.certificates):
        return result
    nk = result.K.nstates
    _, scaled = scale_members(members, nk, result.w0)
    times = list(result.solve_times)
    out = []
    for i, (m, s, c) in enumerate(zip(members, scaled, result.certificates)):
        if c.region is None:
            rc = _region_certificate(
                m,
                s,
                result.omega_scaled,
                nk,
                result.w0,
                result.region,
                solvers,
                times,
                i,
                c.region_violation,
            )
            c = dataclasses.replace(c, region=rc, region_violation=rc.violation)
        out.append(c)
    return dataclasses.replace(result, certificates=tuple(out), solve_times=tuple(times))


def _region_certificate(m, s, Om_s, nk, w0, region, solvers, solve_times, i, violation=math.nan):
    """The region certificate of one member's closed loop (scaled solve, original ``X``);
    ``violation``: that of its poles, computed by the caller."""
    try:
        t0 = time.perf_counter()
        rs = certify_region(s.region.matrices(Om_s)[0], region.scaled(w0), solvers=solvers)
        solve_times.append(time.perf_counter() - t0)
    except (InfeasibleError, SolverError) as exc:
        raise VerificationError(
            f"pksyn_multi: member {m.label or i}: no region certificate for the final "
            f"controller: {exc}"
        ) from None
    # the region inequalities are homogeneous in X and scale with 1/w0 in time tau: the
    # same X in the original coordinates x = blkdiag(T_state, I) x_s
    Tr = np.linalg.inv(sla.block_diag(s.region_st.T, np.eye(nk)))
    return RegionCertificate(sym(Tr.T @ rs.X @ Tr), rs.lmi_max_eig, violation, rs.method)


def _entry(pt: _Point, h2cap: float, radius: float, response_excess: float) -> dict:
    return {
        "gamma": max(pt.g_member),
        "h2_excess": _excess(pt, h2cap),
        "response_excess": response_excess,
        "trust": radius,
    }


def _reject_reason(scaled, pt: _Point, Om_new, region_s) -> str | None:
    """Why a K-step's controller is not kept (poles leave the region, bounds worsen)."""
    for i, m in enumerate(scaled):
        v = region_s.worst_violation(
            np.linalg.eigvals(m.region.A0 + m.region.Bb @ Om_new @ m.region.Cb)
        )
        if v >= 0:
            return f"member {i} leaves the region (violation {v:.3g}, scaled time)"
    before = _response_excess(scaled, pt.Om)
    after = _response_excess(scaled, Om_new)
    if after > max(before, 0.0) + 1e-9:
        return f"response bounds worsen (excess {after:.3g} vs {before:.3g})"
    return None


def _excess(p: _Point, h2cap: float) -> float:
    return max(max(p.z_member) / h2cap - 1.0, 0.0) if h2cap else 0.0


def _final_certificates(
    members, scaled, pt, nk, w0, channels, region, solvers, solve_times, with_regions=True
):
    """Certificates of the final point in original coordinates, each checked independently."""
    Om = from_scaled(pt.Om, nk, w0, channels)
    out = []
    for i, (m, s) in enumerate(zip(members, scaled)):
        name = m.label or str(i)
        eigs = {}
        # bounded-real certificate: the identity at level g in the solve's coordinates
        cl = s.hinf_shifted.transformed(pt.T_hinf[i]).scaled_output(pt.g_member[i])
        eigs["bounded_real"] = _max_eig(_bmi(*_brl_parts(cl, np.eye(cl.N), pt.Om, 1.0)))
        # back to the original coordinates x = Tc xt, Tc = blkdiag(T_state, I) T_rec, and
        # time t (P -> P / w0); at level g the certificate is g I in the solve's coordinates
        Tci = np.linalg.inv(sla.block_diag(s.hinf_st.T, np.eye(nk)) @ pt.T_hinf[i])
        P = sym(Tci.T @ Tci) * pt.g_member[i] / w0
        A, B, C, D = _Affine(m.hinf, nk).matrices(Om)
        gamma = hinf_norm(control.ss(A, B, C, D))
        gamma_sh = hinf_norm(control.ss(A + region.decay_rate * np.eye(A.shape[0]), B, C, D))
        Q = Z = None
        h2 = h2b = 0.0
        if s.h2 is not None:
            cl2 = s.h2.transformed(pt.T_h2[i])
            nz = cl2.C0.shape[0]
            Zs = np.eye(nz) * pt.z_member[i] / nz
            eigs["h2_state"] = _max_eig(_bmi(*_h2_parts(cl2, np.eye(cl2.N), pt.Om)))
            eigs["h2_output"] = -float(
                np.linalg.eigvalsh(sym(_h2_output(cl2, np.eye(cl2.N), pt.Om, Zs))).min()
            )
            # Q and Z in the solve's coordinates (plant states balanced, time tau = w0 t)
            Q, Z = np.eye(cl2.N), Zs
            h2b = math.sqrt(pt.z_member[i] * w0)
            h2 = h2_norm(*_Affine(m.h2, nk).matrices(Om)[:3])
        rc = None
        violation = region.worst_violation(np.linalg.eigvals(_Affine(m.region, nk).matrices(Om)[0]))
        if with_regions:
            rc = _region_certificate(
                m, s, pt.Om, nk, w0, region, solvers, solve_times, i, violation
            )
        elif not violation < 0:
            raise VerificationError(
                f"pksyn_multi: member {name}: a closed-loop pole lies outside the region "
                f"(violation {violation:.3g} rad/s)"
            )
        failed = {k: e for k, e in eigs.items() if e >= 0}
        if failed:
            raise VerificationError(
                f"pksyn_multi: member {name} fails the re-check of its certificates: {failed}"
            )
        if gamma_sh > pt.g_member[i] * (1 + 1e-6) or (s.h2 is not None and h2 > h2b * (1 + 1e-6)):
            raise VerificationError(
                f"pksyn_multi: member {name}: independent norms exceed the certified bounds "
                f"(shifted H-infinity {gamma_sh:.6g} vs {pt.g_member[i]:.6g}, H2 {h2:.6g} vs "
                f"{h2b:.6g})"
            )
        out.append(
            MemberCertificates(
                region=rc,
                P=P,
                Q=Q,
                Z=Z,
                lmi_max_eig=eigs,
                gamma=gamma,
                gamma_bound=pt.g_member[i],
                gamma_shifted=gamma_sh,
                h2=h2,
                h2_bound=h2b,
                region_violation=violation if rc is None else rc.violation,
            )
        )
    return out
