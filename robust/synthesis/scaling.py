"""Plant scaling for H-infinity synthesis, as explicit apply/invert pairs.

The LMIs of :mod:`robust.synthesis.nominal` and :mod:`robust.synthesis.multi` are
solved for a scaled copy of the plant, and their answers are mapped back.  Each
scaling is a small frozen dataclass with forward maps (``apply`` for the plant,
``apply_controller``, ``apply_certificate``, ``apply_gamma``) and their inverses
(``invert``, ``invert_controller``, ``invert_certificate``, ``invert_gamma``), after
cvxpy's ``Reduction.apply`` / ``Reduction.invert``; a stage writes out only the maps it
changes and inherits identities for the others.  The synthesis uses ``apply`` on
the plant and the inverse maps on its answers; the other maps exist for warm starts
and for round-trip tests.

:class:`PlantScaling` chains four stages, in this order:

1. :class:`StateScaling` -- ``x = T xs``: a diagonal balancing of ``A``, then the
   balanced realization of the plant shifted to stability;
2. :class:`TimeScaling` -- ``tau = w0 t``: frequencies in units of ``w0`` rad/s;
3. :class:`ChannelScaling` -- ``u = diag(su) us``, ``ys = diag(sy)^-1 y``: unit-norm
   control and measurement channels (the controller absorbs them);
4. :class:`PerformanceScaling` -- ``w = sw ws``, ``zs = z / sz``: one scalar each for
   the exogenous inputs and performance outputs, so ``gamma_s = gamma sw / sz``.

Each stage is computed from the plant the previous stages produced.
:class:`D22Removal` is the loop shift ``y0 = y - D22 u`` that takes a nonzero
``D22`` out of the plant; it follows the same pattern.

Conventions: a plant is a :class:`robust.synthesis.lmi.PlantBlocks` (``D22``
excluded), a controller a :class:`ControllerMatrices` ``(Ak, Bk, Ck, Dk)`` for
``u = K y``, and a certificate a bounded-real Lyapunov matrix ``P`` of the closed
loop ``F_l(P, K)`` in the coordinates of
:meth:`robust.synthesis.genplant.GeneralizedPlant.closed_loop` (plant states, then
controller states)::

    [Acl' P + P Acl   P Bcl   Ccl' ]
    [Bcl' P          -g I     Dcl' ]  <  0,   P > 0.
    [Ccl              Dcl    -g I  ]
"""

from __future__ import annotations

import dataclasses

import numpy as np

from robust.synthesis.d22 import D22_MAX_COND, D22Removal
from robust.synthesis.lmi import PlantBlocks
from robust.synthesis.scaling_base import ControllerMatrices, _Identities
from robust.synthesis.state_scaling import (
    BALANCE_MAX_COND,
    GRAMIAN_FLOOR,
    StateScaling,
    diagonal_balance,
)

__all__ = [
    "BALANCE_MAX_COND",
    "D22_MAX_COND",
    "GRAMIAN_FLOOR",
    "ChannelScaling",
    "ControllerMatrices",
    "D22Removal",
    "PerformanceScaling",
    "PlantScaling",
    "StateScaling",
    "TimeScaling",
    "diagonal_balance",
]


# ---------------------------------------------------------------------------------- stages
@dataclasses.dataclass(frozen=True)
class TimeScaling(_Identities):
    """Time scaling ``tau = w0 t``: ``A, B1, B2`` are divided by ``w0``.

    Maps changed: the plant (``A, B1, B2 -> A / w0, B1 / w0, B2 / w0``), the
    controller (``Ak, Bk -> Ak / w0, Bk / w0``) and the certificate
    (``P -> w0 P``: the bounded-real inequality is invariant up to that factor).
    The gamma map is the identity: the H-infinity norm is invariant (frequency is
    rescaled).

    Parameters
    ----------
    w0 : float
        Time scale, rad/s.
    """

    w0: float

    @classmethod
    def fit(cls, blocks: PlantBlocks) -> TimeScaling:
        """``w0``: the spectral radius of ``A``, or ``|A|/100`` when ``A`` is nearly nilpotent.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant (after the state scaling).
        """
        A = blocks.A
        n = A.shape[0]
        rho = float(np.max(np.abs(np.linalg.eigvals(A)))) if n else 0.0
        w0 = max(rho, 1e-2 * float(np.linalg.norm(A, 2)) if n else 0.0)
        return cls(w0 if w0 > 1e-12 else 1.0)

    def apply(self, blocks: PlantBlocks) -> PlantBlocks:
        """``A, B1, B2 -> A / w0, B1 / w0, B2 / w0``.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in time t.
        """
        w0 = self.w0
        return dataclasses.replace(blocks, A=blocks.A / w0, B1=blocks.B1 / w0, B2=blocks.B2 / w0)

    def invert(self, blocks: PlantBlocks) -> PlantBlocks:
        """``A, B1, B2 -> w0 A, w0 B1, w0 B2``.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in time tau.
        """
        w0 = self.w0
        return dataclasses.replace(blocks, A=blocks.A * w0, B1=blocks.B1 * w0, B2=blocks.B2 * w0)

    def apply_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """``Ak, Bk -> Ak / w0, Bk / w0``.

        Parameters
        ----------
        K : ControllerMatrices
            Controller in time t.
        """
        return ControllerMatrices(K.Ak / self.w0, K.Bk / self.w0, K.Ck, K.Dk)

    def invert_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """``Ak, Bk -> w0 Ak, w0 Bk``.

        Parameters
        ----------
        K : ControllerMatrices
            Controller in time tau.
        """
        return ControllerMatrices(K.Ak * self.w0, K.Bk * self.w0, K.Ck, K.Dk)

    def apply_certificate(self, P) -> np.ndarray:
        """``P -> w0 P``.

        Parameters
        ----------
        P : numpy.ndarray
            Certificate in time t.
        """
        return np.asarray(P, float) * self.w0

    def invert_certificate(self, P) -> np.ndarray:
        """``P -> P / w0``.

        Parameters
        ----------
        P : numpy.ndarray
            Certificate in time tau.
        """
        return np.asarray(P, float) / self.w0


@dataclasses.dataclass(frozen=True, eq=False)
class ChannelScaling(_Identities):
    """Channel-by-channel scaling of the controls and measurements.

    ``u = diag(su) us`` and ``ys = diag(sy)^-1 y``: ``B2, D12 -> B2 diag(su),
    D12 diag(su)``, ``C2, D21 -> diag(sy)^-1 C2, diag(sy)^-1 D21``.  The
    controller absorbs it, ``Ks = diag(su)^-1 K diag(sy)``.

    Maps changed: the plant and the controller.  Certificate and gamma maps are
    identities: the closed loop from w to z, states included, is unchanged.

    Parameters
    ----------
    su : numpy.ndarray, shape (nu,)
        Control scale factors.
    sy : numpy.ndarray, shape (ny,)
        Measurement scale factors.
    """

    su: np.ndarray
    sy: np.ndarray

    @classmethod
    def fit(cls, blocks: PlantBlocks) -> ChannelScaling:
        """Unit-norm columns of ``[B2; D12]`` and rows of ``[C2, D21]``.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant (after the state and time scalings).
        """
        su = 1.0 / np.maximum(np.linalg.norm(np.vstack([blocks.B2, blocks.D12]), axis=0), 1e-300)
        sy = np.maximum(np.linalg.norm(np.hstack([blocks.C2, blocks.D21]), axis=1), 1e-300)
        return cls(su, sy)

    @classmethod
    def identity(cls, nu: int, ny: int) -> ChannelScaling:
        """No channel scaling.

        Parameters
        ----------
        nu, ny : int
            Numbers of controls and measurements.
        """
        return cls(np.ones(nu), np.ones(ny))

    def apply(self, blocks: PlantBlocks) -> PlantBlocks:
        """``B2, D12 -> B2 diag(su), D12 diag(su)``; ``C2, D21 -> C2 / sy, D21 / sy``.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in original channel units.
        """
        su, sy = self.su, self.sy
        return dataclasses.replace(
            blocks,
            B2=blocks.B2 * su[None, :],
            D12=blocks.D12 * su[None, :],
            C2=blocks.C2 / sy[:, None],
            D21=blocks.D21 / sy[:, None],
        )

    def invert(self, blocks: PlantBlocks) -> PlantBlocks:
        """Inverse of :meth:`apply`.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in scaled channel units.
        """
        su, sy = self.su, self.sy
        return dataclasses.replace(
            blocks,
            B2=blocks.B2 / su[None, :],
            D12=blocks.D12 / su[None, :],
            C2=blocks.C2 * sy[:, None],
            D21=blocks.D21 * sy[:, None],
        )

    def apply_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """``K -> diag(su)^-1 K diag(sy)``.

        Parameters
        ----------
        K : ControllerMatrices
            Controller from y to u.
        """
        su, sy = self.su, self.sy
        return ControllerMatrices(
            K.Ak, K.Bk * sy[None, :], K.Ck / su[:, None], K.Dk * sy[None, :] / su[:, None]
        )

    def invert_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """``Ks -> diag(su) Ks diag(sy)^-1``.

        Parameters
        ----------
        K : ControllerMatrices
            Controller from ys to us.
        """
        su, sy = self.su, self.sy
        return ControllerMatrices(
            K.Ak, K.Bk / sy[None, :], su[:, None] * K.Ck, su[:, None] * K.Dk / sy[None, :]
        )


@dataclasses.dataclass(frozen=True)
class PerformanceScaling(_Identities):
    """One scalar each for the exogenous inputs and the performance outputs.

    ``w = sw ws`` and ``zs = z / sz``: ``B1, D21 -> sw B1, sw D21``,
    ``C1, D12 -> C1 / sz, D12 / sz`` and ``D11 -> D11 sw / sz``.  The closed loop
    is multiplied by ``sw / sz``, so ``gamma_s = gamma sw / sz`` exactly; one
    scalar per side keeps the H-infinity problem equivalent (channel-wise
    scaling of w or z would change the norm being minimised).

    Maps changed: the plant, the certificate (``P -> P / (sz sw)``) and gamma
    (``gamma -> gamma sw / sz``).  The controller map is the identity: the
    controller sees only u and y.

    Parameters
    ----------
    sw : float
        Exogenous-input scale.
    sz : float
        Performance-output scale.
    """

    sw: float
    sz: float

    @classmethod
    def fit(cls, blocks: PlantBlocks) -> PerformanceScaling:
        """``sw``: unit ``||[B1; D21]||_2``; then ``sz``: unit ``||[C1, D11, D12]||_2``.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant (after the state, time and channel scalings).
        """
        sw = 1.0 / max(np.linalg.norm(np.vstack([blocks.B1, blocks.D21]), 2), 1e-300)
        D11 = blocks.D11 * sw
        sz = max(np.linalg.norm(np.hstack([blocks.C1, D11, blocks.D12]), 2), 1e-300)
        return cls(sw, sz)

    def apply(self, blocks: PlantBlocks) -> PlantBlocks:
        """``w = sw ws``, ``zs = z / sz``.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in original w and z units.
        """
        sw, sz = self.sw, self.sz
        B1, D21, D11 = blocks.B1 * sw, blocks.D21 * sw, blocks.D11 * sw
        C1, D11, D12 = blocks.C1 / sz, D11 / sz, blocks.D12 / sz
        return dataclasses.replace(blocks, B1=B1, C1=C1, D11=D11, D12=D12, D21=D21)

    def invert(self, blocks: PlantBlocks) -> PlantBlocks:
        """Inverse of :meth:`apply`.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in scaled w and z units.
        """
        sw, sz = self.sw, self.sz
        C1, D11, D12 = blocks.C1 * sz, blocks.D11 * sz, blocks.D12 * sz
        B1, D21, D11 = blocks.B1 / sw, blocks.D21 / sw, D11 / sw
        return dataclasses.replace(blocks, B1=B1, C1=C1, D11=D11, D12=D12, D21=D21)

    def apply_certificate(self, P) -> np.ndarray:
        """``P -> P / (sz sw)`` (with ``gamma -> gamma sw / sz``).

        Parameters
        ----------
        P : numpy.ndarray
            Certificate in original w and z units.
        """
        return np.asarray(P, float) / (self.sz * self.sw)

    def invert_certificate(self, P) -> np.ndarray:
        """``P -> sz sw P``: a congruence of the bounded-real inequality.

        Parameters
        ----------
        P : numpy.ndarray
            Certificate in scaled w and z units.
        """
        return np.asarray(P, float) * (self.sz * self.sw)

    def apply_gamma(self, gamma: float) -> float:
        """``gamma -> gamma sw / sz``.

        Parameters
        ----------
        gamma : float
            H-infinity bound in original units.
        """
        return gamma * self.sw / self.sz

    def invert_gamma(self, gamma: float) -> float:
        """``gamma_s -> gamma_s sz / sw``.

        Parameters
        ----------
        gamma : float
            H-infinity bound of the scaled problem.
        """
        return gamma * self.sz / self.sw


# ---------------------------------------------------------------------------------- composite
@dataclasses.dataclass(frozen=True, eq=False)
class PlantScaling:
    """The four stages of the synthesis scaling, applied in the order of the fields.

    Every map is the composition of the stages' maps: forward maps in the
    order state, time, channels, performance; plant and gamma inverses in the
    reverse order.  Controllers are mapped back time first, then channels, and
    certificates state first, then the scalar factors (the orders the
    synthesis has always used, so its numbers are unchanged to the last bit;
    the stages' maps commute, so this is the same composition up to rounding).

    Parameters
    ----------
    state : StateScaling
        ``x = T xs``.
    time : TimeScaling
        ``tau = w0 t``.
    channels : ChannelScaling
        ``u = diag(su) us``, ``ys = diag(sy)^-1 y``.
    performance : PerformanceScaling
        ``w = sw ws``, ``zs = z / sz``.
    """

    state: StateScaling
    time: TimeScaling
    channels: ChannelScaling
    performance: PerformanceScaling

    @classmethod
    def fit(cls, blocks: PlantBlocks, *, common: PlantScaling | None = None) -> PlantScaling:
        """Fit each stage to the plant the previous stages produced.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant to scale.
        common : PlantScaling, optional
            Multi-model design: take the time, channel and performance stages from
            ``common`` (so that one controller serves every member); only the
            state transformation is fitted to ``blocks``.
        """
        state = StateScaling.fit(blocks)
        if common is not None:
            return cls(state, common.time, common.channels, common.performance)
        b = state.apply(blocks)
        time = TimeScaling.fit(b)
        b = time.apply(b)
        channels = ChannelScaling.fit(b)
        performance = PerformanceScaling.fit(channels.apply(b))
        return cls(state, time, channels, performance)

    @classmethod
    def state_only(cls, blocks: PlantBlocks) -> PlantScaling:
        """Only the state transformation of :meth:`fit`; time, channels and gamma unscaled.

        A fallback of :func:`robust.synthesis.nominal.hinfsyn_lmi`: when the time
        scale of :meth:`fit` (the spectral radius) spreads a plant's poles over
        many decades (near-integrators next to fast poles), the balanced
        coordinates alone may give the better-conditioned SDP.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant to scale.
        """
        _n, _nw, nu, _nz, ny = blocks.sizes
        return cls(
            StateScaling.fit(blocks),
            TimeScaling(1.0),
            ChannelScaling.identity(nu, ny),
            PerformanceScaling(1.0, 1.0),
        )

    @classmethod
    def identity(cls, n: int, nu: int, ny: int) -> PlantScaling:
        """No scaling at all (every map is the identity, exactly).

        Parameters
        ----------
        n : int
            Plant order.
        nu, ny : int
            Numbers of controls and measurements.
        """
        return cls(
            StateScaling.identity(n),
            TimeScaling(1.0),
            ChannelScaling.identity(nu, ny),
            PerformanceScaling(1.0, 1.0),
        )

    @property
    def stages(self) -> tuple:
        """``(state, time, channels, performance)``, in the order they are applied."""
        return (self.state, self.time, self.channels, self.performance)

    def apply(self, blocks: PlantBlocks) -> PlantBlocks:
        """The scaled plant.

        Parameters
        ----------
        blocks : PlantBlocks
            Plant in original coordinates.
        """
        for stage in self.stages:
            blocks = stage.apply(blocks)
        return blocks

    def invert(self, blocks: PlantBlocks) -> PlantBlocks:
        """The plant in original coordinates.

        Parameters
        ----------
        blocks : PlantBlocks
            Scaled plant.
        """
        for stage in reversed(self.stages):
            blocks = stage.invert(blocks)
        return blocks

    def apply_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """A controller of the original plant, for the scaled plant.

        Parameters
        ----------
        K : ControllerMatrices
            Controller ``u = K y`` in original coordinates.
        """
        for stage in self.stages:
            K = stage.apply_controller(K)
        return K

    def invert_controller(self, K: ControllerMatrices) -> ControllerMatrices:
        """A controller of the scaled plant, for the original plant.

        Parameters
        ----------
        K : ControllerMatrices
            Controller ``us = Ks ys`` of the scaled plant (time tau).
        """
        return self.channels.invert_controller(self.time.invert_controller(K))

    def apply_certificate(self, P) -> np.ndarray:
        """A certificate of the original closed loop, for the scaled one.

        Parameters
        ----------
        P : numpy.ndarray, shape (n + nk, n + nk)
            Certificate of ``F_l(P, K)`` at level ``gamma``; the result certifies the
            scaled closed loop at ``apply_gamma(gamma)``.
        """
        for stage in self.stages:
            P = stage.apply_certificate(P)
        return P

    def invert_certificate(self, P) -> np.ndarray:
        """A certificate of the scaled closed loop, for the original one.

        ``P -> (sz sw / w0) Tc^-T P Tc^-1`` with ``Tc = blkdiag(T, I_nk)``: the
        state congruence first, then the time and performance factors combined
        into one scalar (the order the synthesis has always used; it equals the
        composition of the stages' maps, which commute, up to rounding).

        Parameters
        ----------
        P : numpy.ndarray, shape (n + nk, n + nk)
            Certificate of the scaled closed loop at level ``gamma_s`` (scaled
            plant states, then controller states); the result certifies
            ``F_l(P, K)`` at ``invert_gamma(gamma_s)``.
        """
        P = self.channels.invert_certificate(self.state.invert_certificate(P))
        return P * (self.performance.sz * self.performance.sw / self.time.w0)

    def apply_gamma(self, gamma: float) -> float:
        """A bound in original units, in scaled units.

        Parameters
        ----------
        gamma : float
            H-infinity bound of the original closed loop.
        """
        for stage in self.stages:
            gamma = stage.apply_gamma(gamma)
        return gamma

    def invert_gamma(self, gamma: float) -> float:
        """A bound in scaled units, in original units.

        Parameters
        ----------
        gamma : float
            H-infinity bound of the scaled closed loop.
        """
        for stage in reversed(self.stages):
            gamma = stage.invert_gamma(gamma)
        return gamma

    def as_dict(self) -> dict:
        """The scalars and channel factors, for reports.

        Time scale ``w0`` (rad/s), ``sw``, ``sz`` (``gamma_s = gamma sw / sz``) and
        copies of ``su``, ``sy``.
        """
        return {
            "w0": self.time.w0,
            "sw": self.performance.sw,
            "sz": self.performance.sz,
            "su": self.channels.su.copy(),
            "sy": self.channels.sy.copy(),
        }
