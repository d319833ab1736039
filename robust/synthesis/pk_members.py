"""The members of the P-K iteration and their closed loops, affine in the controller data.

:class:`SynthesisMember` (three plants sharing the controls and measurements) and its
:class:`ResponseBound` are what :func:`robust.synthesis.pk.pksyn_multi` is given;
``_Affine`` writes a member's closed loop as ``A0 + Bb Omega Cb`` (and so on), from which
the bounded-real and H2 blocks of the LMIs and the frequency responses
(:func:`responses`) are built; :func:`scale_members`, :func:`to_scaled` and
:func:`from_scaled` carry members and controller data to the common time and channel
scaling the iteration works in. The P-step, the K-step and the certificates all build on
these forms, which are therefore apart from each of them.
"""

from __future__ import annotations

import dataclasses

import control
import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from robust.analysis.resolvent import siso_responses
from robust.errors import ModelStructureError
from robust.synthesis.lmi import PlantBlocks
from robust.synthesis.region import sym
from robust.synthesis.scaling import ChannelScaling, TimeScaling
from robust.synthesis.scaling_base import ControllerMatrices
from robust.synthesis.state_scaling import StateScaling

__all__ = [
    "ResponseBound",
    "SynthesisMember",
    "responses",
    "scale_members",
    "to_scaled",
    "from_scaled",
]


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


# -------------------------------------------------------------- scaled members
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
