"""The generalized plant: one state-space system plus named partitions w, u, z, y.

::

                 +-----------------+
      w -------->|                 |--------> z
   (exogenous)   |        P        |   (performance)
      u -------->|                 |--------> y
   (control)     +-----------------+   (measured)
        ^                                  |
        |          +-------------+         |
        +----------|      K      |<--------+
                   +-------------+

        [ z ]   [ D11  D12 ] [ w ]        x' = A x + B1 w + B2 u
        [ y ] = [ D21  D22 ] [ u ]  +  C x,   u = K y  (positive feedback)

The closed loop from w to z is the lower linear fractional transformation
``F_l(P, K)``; synthesis makes its H-infinity norm small.  The partitions are
kept by signal name, so the object can be built from any named python-control
system (for instance a force-feedback interconnection) without index arithmetic.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import control
import numpy as np

from robust.checks import check_finite_array
from robust.errors import ModelStructureError

__all__ = ["GeneralizedPlant", "as_generalized_plant"]


def _as_statespace(sys, name: str = "sys") -> control.StateSpace:
    """``control.ss(sys)`` for an LTI system; anything else is a ModelStructureError."""
    if not isinstance(sys, (control.StateSpace, control.TransferFunction)):
        raise ModelStructureError(
            f"{name} must be a control.StateSpace or control.TransferFunction (or a "
            f"GeneralizedPlant); got {type(sys).__name__}"
        )
    if isinstance(sys, control.TransferFunction):
        for part in ("num", "den"):
            coeffs = [np.asarray(c, dtype=float) for row in getattr(sys, part) for c in row]
            if not all(np.all(np.isfinite(c)) for c in coeffs):
                raise ModelStructureError(
                    f"{name}: the transfer function's {part} contains non-finite values "
                    "(NaN or inf); clean them first"
                )
    try:
        return control.ss(sys)
    except (ValueError, TypeError, np.linalg.LinAlgError) as exc:
        raise ModelStructureError(
            f"{name} could not be converted to state space: {type(exc).__name__}: {exc}"
        ) from None


@dataclasses.dataclass(frozen=True)
class GeneralizedPlant:
    """A state-space system with named exogenous, control, performance and measured signals.

    Build it with :meth:`from_system` (by signal name) or :meth:`from_counts`
    (python-control's ``hinfsyn`` convention: the last ``ncon`` inputs are
    controls, the last ``nmeas`` outputs are measurements).

    Attributes
    ----------
    sys : control.StateSpace
        Continuous- or discrete-time system whose inputs are ordered ``w + u``
        and whose outputs are ordered ``z + y``.
    w, u, z, y : tuple of str
        Signal names of each partition, in the order used by the blocks below.
    """

    sys: control.StateSpace
    w: tuple[str, ...]
    u: tuple[str, ...]
    z: tuple[str, ...]
    y: tuple[str, ...]

    def __post_init__(self):
        sys = self.sys
        if not isinstance(sys, control.StateSpace):
            raise ModelStructureError(f"sys must be a control.StateSpace; got {type(sys).__name__}")
        for name in ("A", "B", "C", "D"):
            check_finite_array(
                f"GeneralizedPlant.sys.{name}", getattr(sys, name), error=ModelStructureError
            )
        if len(self.w) + len(self.u) != sys.ninputs or len(self.z) + len(self.y) != sys.noutputs:
            raise ModelStructureError(
                f"partition sizes w={len(self.w)}, u={len(self.u)}, z={len(self.z)}, "
                f"y={len(self.y)} do not match sys with {sys.ninputs} inputs and "
                f"{sys.noutputs} outputs"
            )
        if not self.u or not self.y:
            raise ModelStructureError(
                "a generalized plant needs at least one control input and one measurement; "
                f"got u={self.u}, y={self.y}"
            )
        if not self.w or not self.z:
            raise ModelStructureError(
                "a generalized plant needs at least one exogenous input and one performance "
                f"output; got w={self.w}, z={self.z}"
            )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_system(
        cls, sys, *, w: Sequence[str], u: Sequence[str], z: Sequence[str], y: Sequence[str]
    ) -> GeneralizedPlant:
        """Partition a named system by signal names.

        Parameters
        ----------
        sys : control.StateSpace or any LTI system python-control can convert
            System whose input and output names include every name given.
        w, u : sequence of str
            Exogenous and control input names; together they must list every input once.
        z, y : sequence of str
            Performance and measured output names; together every output once.

        Raises
        ------
        ModelStructureError
            If ``sys`` is not an LTI system, a name is unknown, listed twice, or an
            input/output is left unlisted.
        """
        sys = _as_statespace(sys)
        ins, outs = list(sys.input_labels), list(sys.output_labels)
        w, u, z, y = (list(x) for x in (w, u, z, y))
        cls._check_partition("input", ins, {"w": w, "u": u})
        cls._check_partition("output", outs, {"z": z, "y": y})
        ii = [ins.index(s) for s in w + u]
        oi = [outs.index(s) for s in z + y]
        P = control.ss(
            sys.A,
            sys.B[:, ii],
            sys.C[oi, :],
            sys.D[np.ix_(oi, ii)],
            sys.dt,
            inputs=w + u,
            outputs=z + y,
            states=list(sys.state_labels),
            name=sys.name,
        )
        return cls(P, tuple(w), tuple(u), tuple(z), tuple(y))

    @classmethod
    def from_counts(cls, sys, *, nmeas: int, ncon: int) -> GeneralizedPlant:
        """Partition by counts, in the calling convention of :func:`control.hinfsyn`.

        The last ``ncon`` inputs are controls and the last ``nmeas`` outputs measurements.

        Parameters
        ----------
        sys : control.StateSpace or any LTI system python-control can convert
            System with inputs ``w + u`` and outputs ``z + y``.
        nmeas : int
            Number of measurements (the last outputs), in ``[1, noutputs - 1]``.
        ncon : int
            Number of controls (the last inputs), in ``[1, ninputs - 1]``.

        Raises
        ------
        ModelStructureError
            If ``sys`` is not an LTI system or a count is not an integer in its range.
        """
        sys = _as_statespace(sys, "P")
        for label, val, top in (("nmeas", nmeas, sys.noutputs), ("ncon", ncon, sys.ninputs)):
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or not 0 < val < top:
                raise ModelStructureError(
                    f"{label} must be an integer in [1, {top - 1}]; got {val!r}"
                )
        ins, outs = list(sys.input_labels), list(sys.output_labels)
        nw, nz = sys.ninputs - ncon, sys.noutputs - nmeas
        return cls(sys, tuple(ins[:nw]), tuple(ins[nw:]), tuple(outs[:nz]), tuple(outs[nz:]))

    @staticmethod
    def _check_partition(kind, available, parts):
        seen = {}
        for pname, names in parts.items():
            for s in names:
                if s not in available:
                    raise ModelStructureError(
                        f"{pname}: {s!r} is not an {kind} of sys; its {kind}s are {available}"
                    )
                if s in seen:
                    raise ModelStructureError(
                        f"{kind} {s!r} is listed in both {seen[s]} and {pname}"
                    )
                seen[s] = pname
        missing = [s for s in available if s not in seen]
        if missing:
            raise ModelStructureError(
                f"{kind}s {missing} are in no partition; list each {kind} in exactly one of "
                f"{list(parts)}"
            )

    # ------------------------------------------------------------------ sizes and blocks
    @property
    def nx(self) -> int:
        """Number of states."""
        return self.sys.nstates

    @property
    def nw(self) -> int:
        """Number of exogenous inputs w."""
        return len(self.w)

    @property
    def nu(self) -> int:
        """Number of controls u."""
        return len(self.u)

    @property
    def nz(self) -> int:
        """Number of performance outputs z."""
        return len(self.z)

    @property
    def ny(self) -> int:
        """Number of measurements y."""
        return len(self.y)

    @property
    def ncon(self) -> int:
        """Number of controls u (``nu``; the name of :func:`control.hinfsyn`)."""
        return len(self.u)

    @property
    def nmeas(self) -> int:
        """Number of measurements y (``ny``; the name of :func:`control.hinfsyn`)."""
        return len(self.y)

    @property
    def dt(self):
        """Time base of ``sys`` (0 for continuous time)."""
        return self.sys.dt

    @property
    def A(self) -> np.ndarray:
        """State matrix."""
        return np.asarray(self.sys.A, dtype=float)

    @property
    def B1(self) -> np.ndarray:
        """Input matrix of w."""
        return np.asarray(self.sys.B, dtype=float)[:, : self.nw]

    @property
    def B2(self) -> np.ndarray:
        """Input matrix of u."""
        return np.asarray(self.sys.B, dtype=float)[:, self.nw :]

    @property
    def C1(self) -> np.ndarray:
        """Output matrix of z."""
        return np.asarray(self.sys.C, dtype=float)[: self.nz, :]

    @property
    def C2(self) -> np.ndarray:
        """Output matrix of y."""
        return np.asarray(self.sys.C, dtype=float)[self.nz :, :]

    @property
    def D11(self) -> np.ndarray:
        """Feedthrough from w to z."""
        return np.asarray(self.sys.D, dtype=float)[: self.nz, : self.nw]

    @property
    def D12(self) -> np.ndarray:
        """Feedthrough from u to z."""
        return np.asarray(self.sys.D, dtype=float)[: self.nz, self.nw :]

    @property
    def D21(self) -> np.ndarray:
        """Feedthrough from w to y."""
        return np.asarray(self.sys.D, dtype=float)[self.nz :, : self.nw]

    @property
    def D22(self) -> np.ndarray:
        """Feedthrough from u to y."""
        return np.asarray(self.sys.D, dtype=float)[self.nz :, self.nw :]

    def blocks(self) -> dict[str, np.ndarray]:
        """All nine blocks ``A, B1, B2, C1, C2, D11, D12, D21, D22`` as a dict of copies."""
        return {
            k: getattr(self, k).copy()
            for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21", "D22")
        }

    def with_blocks(self, **blocks) -> GeneralizedPlant:
        """A new plant with some blocks replaced (same signal names and sizes).

        Parameters
        ----------
        **blocks : array_like
            Replacement blocks by name (``A``, ``B1``, ..., ``D22``), each of the
            shape of the block it replaces.

        Raises
        ------
        ModelStructureError
            If a name is not a block or a shape does not match.
        """
        b = self.blocks()
        for k, v in blocks.items():
            if k not in b:
                raise ModelStructureError(f"unknown block {k!r}; expected one of {list(b)}")
            v = np.atleast_2d(np.asarray(v, dtype=float))
            if v.shape != b[k].shape and not (b[k].size == 0 and v.size == 0):
                raise ModelStructureError(f"block {k} must have shape {b[k].shape}; got {v.shape}")
            b[k] = v
        B = np.hstack([b["B1"], b["B2"]])
        C = np.vstack([b["C1"], b["C2"]])
        D = np.block([[b["D11"], b["D12"]], [b["D21"], b["D22"]]])
        sys = control.ss(
            b["A"],
            B,
            C,
            D,
            self.dt,
            inputs=self.w + self.u,
            outputs=self.z + self.y,
            name=self.sys.name,
        )
        return GeneralizedPlant(sys, self.w, self.u, self.z, self.y)

    def closed_loop(self, K) -> control.StateSpace:
        """The lower LFT ``F_l(P, K)`` from w to z with ``u = K y``.

        Positive feedback, as in :func:`control.hinfsyn`; the closed loop's states are
        the plant's, then the controller's.

        Parameters
        ----------
        K : control.StateSpace or any LTI system python-control can convert
            Controller from y (``ny`` inputs) to u (``nu`` outputs).

        Raises
        ------
        ModelStructureError
            If K's sizes do not match (``ny`` inputs, ``nu`` outputs) or the loop
            is ill-posed (``I - D22 Dk`` singular).
        """
        K = control.ss(K)
        if K.ninputs != self.ny or K.noutputs != self.nu:
            raise ModelStructureError(
                f"K must have {self.ny} inputs (y) and {self.nu} outputs (u); "
                f"got {K.ninputs} and {K.noutputs}"
            )
        A, B1, B2, C1, C2 = self.A, self.B1, self.B2, self.C1, self.C2
        D11, D12, D21, D22 = self.D11, self.D12, self.D21, self.D22
        Ak, Bk, Ck, Dk = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (K.A, K.B, K.C, K.D))
        nk = K.nstates
        if nk == 0:
            Ak, Bk, Ck = np.zeros((0, 0)), np.zeros((0, self.ny)), np.zeros((self.nu, 0))
        M = np.eye(self.ny) - D22 @ Dk
        if np.linalg.cond(M) > 1e12:
            raise ModelStructureError(
                f"loop is ill-posed: I - D22*Dk is singular (cond={np.linalg.cond(M):.3g})"
            )
        Mi = np.linalg.inv(M)  # y = Mi (C2 x + D21 w + D22 Ck xk)
        # u = Ck xk + Dk y
        Cy_x, Cy_k, Dy_w = Mi @ C2, Mi @ D22 @ Ck, Mi @ D21
        Cu_x, Cu_k, Du_w = Dk @ Cy_x, Ck + Dk @ Cy_k, Dk @ Dy_w
        Acl = np.block([[A + B2 @ Cu_x, B2 @ Cu_k], [Bk @ Cy_x, Ak + Bk @ Cy_k]])
        Bcl = np.vstack([B1 + B2 @ Du_w, Bk @ Dy_w])
        Ccl = np.hstack([C1 + D12 @ Cu_x, D12 @ Cu_k])
        Dcl = D11 + D12 @ Du_w
        return control.ss(
            Acl, Bcl, Ccl, Dcl, self.dt, inputs=list(self.w), outputs=list(self.z), name="F_l(P,K)"
        )

    def __repr__(self) -> str:
        return (
            f"GeneralizedPlant(nx={self.nx}, w={list(self.w)}, u={list(self.u)}, "
            f"z={list(self.z)}, y={list(self.y)}, dt={self.dt})"
        )


def as_generalized_plant(P, nmeas: int | None = None, ncon: int | None = None) -> GeneralizedPlant:
    """Return ``P`` itself if it is a :class:`GeneralizedPlant`, else partition it by counts.

    Parameters
    ----------
    P : GeneralizedPlant or control.StateSpace
        The plant; a plain system is partitioned by :meth:`GeneralizedPlant.from_counts`.
    nmeas, ncon : int, optional
        Numbers of measurements and controls: required for a plain system, and
        checked against the partitions of a GeneralizedPlant when given.

    Raises
    ------
    ModelStructureError
        If ``P`` is a plain system and the counts are missing, or if a
        GeneralizedPlant's sizes contradict counts that were given.
    """
    if isinstance(P, GeneralizedPlant):
        if (nmeas is not None and nmeas != P.ny) or (ncon is not None and ncon != P.nu):
            raise ModelStructureError(
                f"nmeas={nmeas}, ncon={ncon} contradict the GeneralizedPlant partitions "
                f"(ny={P.ny}, nu={P.nu})"
            )
        return P
    if nmeas is None or ncon is None:
        raise ModelStructureError("nmeas and ncon are required when P is not a GeneralizedPlant")
    return GeneralizedPlant.from_counts(P, nmeas=nmeas, ncon=ncon)
