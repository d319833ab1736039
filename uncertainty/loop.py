"""The BDFT loop of a family written once over any arithmetic: intervals or uncertain reals.

The family's varied blocks (the structure's two sections, the human) and the Figure 5
interconnection are written here once, in terms of an *algebra*: how to make a matrix from
rows, a block diagonal, a vertical stack, a constant matrix, a square and a reciprocal.
Two algebras use the definition:

* :data:`INTERVALS`: midpoint-radius intervals and interval gradients
  (:mod:`robust.analysis.intervals`), the certified enclosures of
  :func:`uncertainty.margins.robust_margin`;
* :data:`UNCERTAIN`: uncertain expressions (:func:`uncertainty.ureal`), from which
  :func:`family_uss` builds the family's closed loop as an uncertain system
  (:func:`uncertainty.uss`), the form every generic analysis takes.

The batched evaluation of many members (:func:`uncertainty.batched.closed_loop_matrices`)
is the third evaluation; the tests check that the three agree on seeded members.

The closed loop is ``A_cl = A + B M (C + D M C + (D M)^2 C + ...)`` with the blocks'
matrices ``A, B, C, D`` stacked block-diagonally and ``M`` the constant interconnection
(block inputs from block outputs, :func:`uncertainty.batched.interconnection`); the
series is finite because the direct feedthroughs form no algebraic cycle.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import control as ct
import numpy as np

from robust.analysis.intervals import Gradient, Interval, iblockdiag, imatrix, ivstack
from robust.errors import ParameterError
from uncertainty.batched import interconnection, loop_blocks
from uncertainty.family import Family
from uncertainty.ureal import UExpr, umatrix
from uncertainty.uss import USS, nonzero_pattern

__all__ = ["Algebra", "INTERVALS", "UNCERTAIN", "LoopAssembly", "fixed_parameters", "family_uss"]


@dataclasses.dataclass(frozen=True)
class Algebra:
    """How the loop's matrices are made in one kind of arithmetic.

    Parameters
    ----------
    matrix : callable
        Rows of entries (numbers and the algebra's scalars) to a matrix.
    blockdiag : callable
        A list of matrices to their block diagonal.
    vstack : callable
        A list of matrices stacked vertically.
    constant : callable
        A numeric array to a constant matrix.
    square : callable
        ``x**2`` of a scalar (tight for intervals).
    reciprocal : callable
        ``1 / x`` of a scalar.
    nonzero : callable
        The structural pattern of a matrix (bool array: entries that may be nonzero).
    """

    matrix: Callable
    blockdiag: Callable
    vstack: Callable
    constant: Callable
    square: Callable
    reciprocal: Callable
    nonzero: Callable


def _interval_pattern(X) -> np.ndarray:
    v = X.val if isinstance(X, Gradient) else X
    return (np.abs(v.mid) + v.rad) > 0


def _object_blockdiag(mats) -> np.ndarray:
    rows = sum(m.shape[0] for m in mats)
    cols = sum(m.shape[1] for m in mats)
    out = umatrix(np.zeros((rows, cols)))
    r = c = 0
    for m in mats:
        out[r : r + m.shape[0], c : c + m.shape[1]] = m
        r, c = r + m.shape[0], c + m.shape[1]
    return out


#: Intervals and interval gradients: the certified enclosures.
INTERVALS = Algebra(
    matrix=imatrix,
    blockdiag=iblockdiag,
    vstack=ivstack,
    constant=Interval.point,
    square=lambda x: x.square(),
    reciprocal=lambda x: x.reciprocal(),
    nonzero=_interval_pattern,
)

#: Uncertain expressions: the family as an uncertain system.
UNCERTAIN = Algebra(
    matrix=umatrix,
    blockdiag=_object_blockdiag,
    vstack=lambda mats: umatrix(np.vstack(mats)),
    constant=umatrix,
    square=lambda x: x**2 if isinstance(x, UExpr) else x * x,
    reciprocal=lambda x: 1.0 / x,
    nonzero=nonzero_pattern,
)


def _section(z, w, alg: Algebra):
    w2, zw2 = alg.square(w), 2.0 * z * w
    A = alg.matrix([[0.0, 1.0], [-w2, -zw2]])
    C = alg.matrix([[w2, zw2]])
    return A, C


def structure_block(p: dict, alg: Algebra) -> tuple:
    """The structure's two cascaded sections (``y -> v, c``): ``A, B, C, D``.

    Parameters
    ----------
    p : dict
        Every ``struct.*`` parameter, in the algebra's scalars (or numbers).
    alg : Algebra
        The arithmetic.
    """
    tau = 2 * math.pi
    z1, w1 = p["struct.zeta1"], tau * p["struct.f1_hz"]
    z2, w2 = p["struct.zeta2"], tau * p["struct.f2_hz"]
    A1, _ = _section(z1, w1, alg)
    A2, C2 = _section(z2, w2, alg)
    w1s, zw1 = alg.square(w1), 2.0 * z1 * w1
    # cascade: section 1 driven by y, section 2 driven by section 1's output C1 x1
    A = alg.blockdiag([A1, A2]) + alg.matrix(
        [[0.0] * 4, [0.0] * 4, [0.0] * 4, [w1s, zw1, 0.0, 0.0]]
    )
    B = alg.constant(np.array([[0.0], [1.0], [0.0], [0.0]]))
    Cv = alg.matrix([[0.0, 0.0, p["struct.k_s"] * C2[0, 0], p["struct.k_s"] * C2[0, 1]]])
    CA = Cv @ A
    C = alg.vstack([Cv, CA @ A])
    D = alg.vstack([alg.constant(np.zeros((1, 1))), CA @ B])
    return A, B, C, D


def physical_human_block(p: dict, family: Family, alg: Algebra) -> tuple:
    """The physical (two-mass) human (``c, f -> h``): ``A, B, C, D``.

    Parameters
    ----------
    p : dict
        Every ``human.*`` parameter, in the algebra's scalars (or numbers).
    family : Family
        The family (the trunk's share of the body mass).
    alg : Algebra
        The arithmetic.
    """
    tau = 2 * math.pi
    m_t = (family.physical.m_trunk / family.body_mass) * p["human.body_mass"]
    m_a = p["human.m_arm"]
    r = m_a * alg.reciprocal(m_t)
    wt, wa = tau * p["human.f_trunk_hz"], tau * p["human.f_arm_hz"]
    wt2, wa2 = alg.square(wt), alg.square(wa)
    st = 2.0 * p["human.zeta_trunk"] * wt
    sa = 2.0 * p["human.zeta_arm"] * wa
    one_r = 1.0 + r
    A = alg.matrix(
        [
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [-(one_r * wt2) - r * wa2, r * wa2, -(one_r * st) - r * sa, r * sa],
            [wa2, -wa2, sa, -sa],
        ]
    )
    cu, g = p["human.c_unit"], p["human.h_gain"]
    B = alg.matrix([[0.0, 0.0], [0.0, 0.0], [-cu, 0.0], [-cu, alg.reciprocal(m_a)]])
    C = alg.matrix([[0.0, g, 0.0, 0.0]])
    D = alg.constant(np.zeros((1, 2)))
    return A, B, C, D


def literal_human_block(p: dict, alg: Algebra) -> tuple:
    """The literal Eqn 5 human (``v -> h``): ``A, B, C, D``.

    Parameters
    ----------
    p : dict
        Every ``human.*`` parameter of the literal human, in the algebra's scalars.
    alg : Algebra
        The arithmetic.
    """
    k, z1, p1 = p["human.k_h"], p["human.z1"], p["human.p1"]
    A = alg.matrix([[0.0, 1.0], [-alg.square(p1), -2.0 * p1]])
    B = alg.constant(np.array([[0.0], [1.0]]))
    C = alg.matrix([[k * (alg.square(z1) - alg.square(p1)), k * (2.0 * (z1 - p1))]])
    D = alg.matrix([[k]])
    return A, B, C, D


def fixed_parameters(family: Family) -> dict:
    """Every model parameter of the family's varied blocks at its fixed (nominal) value.

    Parameters
    ----------
    family : Family
        The family.
    """
    fixed = {
        f"struct.{f.name}": getattr(family.struct, f.name)
        for f in dataclasses.fields(family.struct)
    }
    if family.human == "literal":
        fixed.update(
            {
                f"human.{f.name}": getattr(family.literal, f.name)
                for f in dataclasses.fields(family.literal)
            }
        )
    else:
        names = ("m_arm", "f_arm_hz", "zeta_arm", "f_trunk_hz", "zeta_trunk", "h_gain", "c_unit")
        fixed.update({f"human.{n}": getattr(family.physical, n) for n in names})
        fixed["human.body_mass"] = family.body_mass
    return fixed


#: Varied blocks kept per :class:`LoopAssembly` (the boxes of a few waves of a subdivision).
_RECENT_BLOCKS = 64


def _interval_key(prefix: str, p: dict):
    """The bytes of every ``prefix`` parameter's interval (or gradient), or None if one is
    of another kind."""
    parts: list = [prefix]
    for name, v in p.items():
        if not name.startswith(prefix):
            continue
        if isinstance(v, Gradient):
            arrays, tag = (v.val.mid, v.val.rad, v.der.mid, v.der.rad), b"G"
        elif isinstance(v, Interval):
            arrays, tag = (v.mid, v.rad), b"I"
        else:
            return None
        parts.append((name, tag, *(np.ascontiguousarray(a).tobytes() for a in arrays)))
    return tuple(parts)


def _freeze(block) -> None:
    for m in block:
        for iv in (m.val, m.der) if isinstance(m, Gradient) else (m,):
            iv.mid.setflags(write=False)
            iv.rad.setflags(write=False)


class LoopAssembly:
    """The family's closed loop over an algebra: the fixed blocks and the interconnection
    built once, the varied blocks from the parameters' values.

    Parameters
    ----------
    family : Family
        The family.
    controller : control.StateSpace or None
        Compensator in the loop's convention (fixed).
    algebra : Algebra
        The arithmetic of :meth:`state_matrix`.
    """

    def __init__(self, family: Family, controller, algebra: Algebra):
        self.family, self.controller, self.algebra = family, controller, algebra
        nominal = np.array([p.nominal for p in family.parameters], float)
        blocks = loop_blocks(family, nominal[None], controller=controller, check_bounds=False)
        self.names = [b.name for b in blocks]
        self.fixed = {
            b.name: tuple(algebra.constant(x[0]) for x in (b.A, b.B, b.C, b.D))
            for b in blocks
            if b.name not in ("structure", "human")
        }
        self.M = interconnection(family, blocks, controller)
        # the varied blocks of recent boxes, keyed by their parameters' intervals (interval
        # algebra only): a sub-box halved in a human parameter has its parent's structure
        # block, and the other way round
        self._recent: dict | None = {} if algebra is INTERVALS else None

    def _varied(self, prefix: str, p: dict, build: Callable):
        """The block of the ``prefix`` parameters, built or (intervals) recalled: the same
        arrays for the same intervals, bit for bit, as the arithmetic depends on nothing
        else; kept read-only."""
        if self._recent is None:
            return build()
        key = _interval_key(prefix, p)
        if key is None:
            return build()
        block = self._recent.pop(key, None)
        if block is None:
            block = build()
            _freeze(block)
        self._recent[key] = block  # (the most recent last)
        if len(self._recent) > _RECENT_BLOCKS:
            del self._recent[next(iter(self._recent))]
        return block

    def state_matrix(self, p: dict):
        """The closed-loop state matrix with every model parameter at ``p[name]``.

        Parameters
        ----------
        p : dict
            Every parameter of :func:`fixed_parameters`' names, as the algebra's scalars
            or numbers.
        """
        alg, family = self.algebra, self.family
        mats = []
        for name in self.names:
            if name == "structure":
                mats.append(self._varied("struct.", p, lambda: structure_block(p, alg)))
            elif name == "human":
                mats.append(
                    self._varied(
                        "human.",
                        p,
                        lambda: (
                            literal_human_block(p, alg)
                            if family.human == "literal"
                            else physical_human_block(p, family, alg)
                        ),
                    )
                )
            else:
                mats.append(self.fixed[name])
        A, B, C, D = (alg.blockdiag([m[i] for m in mats]) for i in range(4))
        DM = D @ self.M
        # length of the finite series from the sparsity pattern of D M (nilpotent: no cycle)
        pattern = (alg.nonzero(D).astype(int) @ (self.M != 0).astype(int)) > 0
        power, terms = pattern.copy(), 0
        while power.any():
            terms += 1
            if terms > pattern.shape[0]:
                raise ParameterError(
                    "the controller's feedthrough closes an algebraic loop; give a strictly "
                    "proper controller"
                )
            power = (power.astype(int) @ pattern.astype(int)) > 0
        Z, term = C, C
        for _ in range(terms):
            term = DM @ term
            Z = Z + term
        return A + (B @ self.M) @ Z


def family_uss(family: Family, controller: ct.StateSpace | None = None) -> USS:
    """The family's closed loop (with ``controller``) as an uncertain system.

    Its uncertain reals are the family's parameters (same names, ranges and
    distributions); the other model parameters are at their fixed values. Only the state
    matrix is the loop's (inputs and outputs are not wired: ``B``, ``C``, ``D`` are empty),
    which is what stability, margins and validation take.

    Parameters
    ----------
    family : Family
        The family.
    controller : control.StateSpace, optional
        Compensator in the loop's convention.

    Returns
    -------
    USS
        Its ``parameters`` in the family's order.

    Examples
    --------
    >>> from uncertainty import default_family, family_uss
    >>> fam = default_family("literal")
    >>> loop = family_uss(fam)
    >>> loop.nstates, list(loop.parameters) == list(fam.names)
    (11, True)
    """
    p = dict(fixed_parameters(family))
    for q in family.parameters:
        p[q.name] = UExpr("param", (q,), {q.name: q})
    A = LoopAssembly(family, controller, UNCERTAIN).state_matrix(p)
    n = A.shape[0]
    sys = USS(
        umatrix(A), umatrix(np.zeros((n, 0))), umatrix(np.zeros((0, n))), umatrix(np.zeros((0, 0)))
    )
    # the family's order (an uncertain real that cancels out still belongs to the family)
    sys.parameters = {q.name: q for q in family.parameters}
    return sys
