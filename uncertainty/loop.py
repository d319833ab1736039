"""The BDFT loop of a family written once over any arithmetic: intervals or uncertain reals.

The family's varied blocks (the valve/cylinder, the structure's two sections, the human)
and the Figure 5 interconnection are written here once, in terms of an *algebra*: how to
make a matrix from rows, a block diagonal, a vertical stack, a constant matrix, a square and
a reciprocal.
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

from collections.abc import Callable

import control as ct
import numpy as np

from robust.analysis.intervals import Gradient, Interval, iblockdiag, imatrix, ivstack
from robust.errors import ParameterError
from robust.model.blocks import (
    Algebra,
    block_values,
    human_entries_modal,
    literal_human_block,
    physical_human_block,
    structure_block,
    valve_block,
)
from uncertainty.batched import interconnection, loop_blocks
from uncertainty.family import Family
from uncertainty.ureal import UExpr, umatrix
from uncertainty.uss import USS, nonzero_pattern

__all__ = ["Algebra", "INTERVALS", "UNCERTAIN", "LoopAssembly", "fixed_parameters", "family_uss"]


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


def fixed_parameters(family: Family) -> dict:
    """Every model parameter of the family's varied blocks at its fixed (nominal) value.

    Parameters
    ----------
    family : Family
        The family.
    """
    return family.fixed_model_values()


#: Varied blocks kept per :class:`LoopAssembly` (the boxes of a few waves of a subdivision).
_RECENT_BLOCKS = 64


def _interval_key(block: str, p: dict):
    """The bytes of every ``block`` parameter's interval (or gradient), or None if one is
    of another kind."""
    parts: list = [block]
    for name, v in block_values(p, block).items():
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
            if b.name not in ("valve", "structure", "human")
        }
        self.M = interconnection(family, blocks, controller)
        # the varied blocks of recent boxes, keyed by their parameters' intervals (interval
        # algebra only): a sub-box halved in a human parameter has its parent's structure
        # block, and the other way round
        self._recent: dict | None = {} if algebra is INTERVALS else None

    def _varied(self, block: str, p: dict, build: Callable):
        """The ``block``'s matrices from its parameters, built or (intervals) recalled: the same
        arrays for the same intervals, bit for bit, as the arithmetic depends on nothing
        else; kept read-only."""
        if self._recent is None:
            return build()
        key = _interval_key(block, p)
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
            if name == "valve":
                mats.append(self._varied("valve", p, lambda: valve_block(p, alg)))
            elif name == "structure":
                mats.append(self._varied("structure", p, lambda: structure_block(p, alg)))
            elif name == "human":
                mats.append(
                    self._varied(
                        "human",
                        p,
                        lambda: (
                            literal_human_block(p, alg)
                            if family.human == "literal"
                            else physical_human_block(
                                human_entries_modal(p, family.trunk_share, alg), alg
                            )
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
