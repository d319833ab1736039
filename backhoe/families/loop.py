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

The batched evaluation of many members (:func:`backhoe.families.batched.closed_loop_matrices`)
is the third evaluation; the tests check that the three agree on seeded members.

The closed loop is ``A_cl = A + B M (C + D M C + (D M)^2 C + ...)`` with the blocks'
matrices ``A, B, C, D`` stacked block-diagonally and ``M`` the constant interconnection
(block inputs from block outputs, :func:`backhoe.families.batched.interconnection`); the
series is finite because the direct feedthroughs form no algebraic cycle.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import control as ct
import numpy as np

from backhoe.families.batched import interconnection, loop_blocks, loop_junctions
from backhoe.families.family import Family
from backhoe.model.blocks import (
    Algebra,
    block_values,
    human_entries_modal,
    literal_human_block,
    physical_human_block,
    structure_block,
    valve_block,
)
from backhoe.model.wiring import EXOGENOUS, expand
from robust.analysis.intervals import Gradient, Interval, iblockdiag, imatrix, ivstack
from robust.errors import ParameterError
from uncertainty.ureal import UExpr, umatrix
from uncertainty.uss import USS, nonzero_pattern

__all__ = [
    "Algebra",
    "INTERVALS",
    "UNCERTAIN",
    "LoopAssembly",
    "fixed_parameters",
    "family_uss",
    "port_matrices",
]


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
        self.nominal = nominal = np.array([p.nominal for p in family.parameters], float)
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

    def _stacked(self, p: dict):
        """The blocks' matrices ``A, B, C, D`` stacked block-diagonally, at ``p``."""
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
        return tuple(alg.blockdiag([m[i] for m in mats]) for i in range(4))

    def _series(self, D):
        """``X -> (I - D M)^-1 X`` as the finite series ``sum_k (D M)^k X``."""
        DM = D @ self.M
        # length of the finite series from the sparsity pattern of D M (nilpotent: no cycle)
        pattern = (self.algebra.nonzero(D).astype(int) @ (self.M != 0).astype(int)) > 0
        power, terms = pattern.copy(), 0
        while power.any():
            terms += 1
            if terms > pattern.shape[0]:
                raise ParameterError(
                    "the controller's feedthrough closes an algebraic loop; give a strictly "
                    "proper controller"
                )
            power = (power.astype(int) @ pattern.astype(int)) > 0

        def apply(X):
            Z, term = X, X
            for _ in range(terms):
                term = DM @ term
                Z = Z + term
            return Z

        return apply

    def state_matrix(self, p: dict):
        """The closed-loop state matrix with every model parameter at ``p[name]``.

        Parameters
        ----------
        p : dict
            Every parameter of :func:`fixed_parameters`' names, as the algebra's scalars
            or numbers.
        """
        A, B, C, D = self._stacked(p)
        return A + (B @ self.M) @ self._series(D)(C)

    def state_space(self, p: dict, E, F_y, F_w):
        """The closed loop's ``A, B, C, D`` from exogenous inputs ``w`` to outputs ``z``.

        The block inputs are ``M y_b + E w`` and the outputs ``z = F_y y_b + F_w w``
        (:func:`port_matrices`); with ``N = (I - D M)^-1`` (a finite series):
        ``A + B M N C``, ``B (M N D E + E)``, ``F_y N C`` and ``F_y N D E + F_w``.

        Parameters
        ----------
        p : dict
            As :meth:`state_matrix`.
        E, F_y, F_w : numpy.ndarray
            Constant port matrices.
        """
        A, B, C, D = self._stacked(p)
        series = self._series(D)
        Z, W = series(C), series(D @ E)
        return A + (B @ self.M) @ Z, B @ (self.M @ W + E), F_y @ Z, F_y @ W + F_w


def port_matrices(junctions, block_inputs, block_outputs, inputs, outputs):
    """Constant matrices that give a loop exogenous inputs and named outputs.

    ``E`` (block inputs from the loop's inputs ``w``), ``F_y`` and ``F_w`` (the outputs
    ``z = F_y y_b + F_w w`` from the block outputs and the inputs), every signal expanded
    through the junction table (:func:`backhoe.model.wiring.expand`) with the exogenous
    signals not among ``inputs`` at zero.

    Parameters
    ----------
    junctions : iterable of backhoe.model.wiring.Junction
        The loop's junction table (:func:`backhoe.families.batched.loop_junctions`).
    block_inputs, block_outputs : sequence of str
        The blocks' inputs and outputs, stacked in block order.
    inputs : sequence of str
        Exogenous inputs (of :data:`backhoe.model.wiring.EXOGENOUS`).
    outputs : sequence of str
        Block outputs or junction signals.

    Returns
    -------
    E, F_y, F_w : numpy.ndarray
        Shapes ``(m, n_w)``, ``(n_z, p)`` and ``(n_z, n_w)``.

    Raises
    ------
    ParameterError
        If an input is not exogenous or reaches no block, or an output is not a signal of
        the loop.
    """
    table = tuple(junctions)
    ins, outs = list(inputs), list(outputs)
    for w in ins:
        if w not in EXOGENOUS:
            raise ParameterError(
                f"inputs: {w!r} is not an exogenous input of the loop; expected one of "
                f"{list(EXOGENOUS)}"
            )
    if len(set(ins)) != len(ins) or len(set(outs)) != len(outs):
        raise ParameterError(f"inputs and outputs must not repeat; got {ins} and {outs}")
    zero = [s for s in EXOGENOUS if s not in ins]
    col_w = {s: j for j, s in enumerate(ins)}
    col_y = {s: j for j, s in enumerate(block_outputs)}
    E = np.zeros((len(block_inputs), len(ins)))
    for i, s in enumerate(block_inputs):
        for src, coef in expand(s, table, zero=zero).items():
            if src in col_w:
                E[i, col_w[src]] += coef
    for j, w in enumerate(ins):
        if not E[:, j].any():
            raise ParameterError(
                f"inputs: {w!r} reaches no block of this loop (a literal human takes no "
                "external force)"
            )
    signals = set(block_outputs) | {j.output for j in table}
    F_y, F_w = np.zeros((len(outs), len(block_outputs))), np.zeros((len(outs), len(ins)))
    for i, z in enumerate(outs):
        if z not in signals:
            raise ParameterError(
                f"outputs: {z!r} is not a signal of the loop; expected one of {sorted(signals)}"
            )
        for src, coef in expand(z, table, zero=zero).items():
            if src in col_w:
                F_w[i, col_w[src]] += coef
            else:
                F_y[i, col_y[src]] += coef
    return E, F_y, F_w


def family_uss(
    family: Family,
    controller: ct.StateSpace | None = None,
    *,
    inputs: str | Sequence[str] = (),
    outputs: str | Sequence[str] = (),
) -> USS:
    """The family's closed loop (with ``controller``) as an uncertain system.

    Its uncertain reals are the family's parameters (same names, ranges and
    distributions); the other model parameters are at their fixed values. Without
    ``inputs`` and ``outputs`` only the state matrix is the loop's (``B``, ``C``, ``D``
    empty), which is what stability, margins and validation take; with them, the loop's
    map from the exogenous inputs (the intended motion ``"u"``, and with the physical human
    an external hand force ``"f_ext"``) to any of its signals: a block output (``"y"``
    the cylinder position, ``"c"`` the cab, ``"h"`` the human's, ``"e"`` the valve
    command, the controller's ``"r_corr"``, or its force alone ``"f_ctrl"``) or a junction
    (``"x"`` the handle position, ``"r"`` the cylinder reference, ``"err"`` its error,
    ``"f"`` the force on the hand: the controller's plus ``"f_ext"``), as the member's own
    loop names them (:meth:`backhoe.model.loop.BDFTLoop.system`); what robust performance
    (:func:`uncertainty.robust_performance`) takes.

    Parameters
    ----------
    family : Family
        The family.
    controller : control.StateSpace, optional
        Compensator in the loop's convention.
    inputs, outputs : str or sequence of str, optional
        The loop's exogenous inputs and the signals it outputs (signal names).

    Returns
    -------
    USS
        Its ``parameters`` in the family's order, its inputs and outputs named as asked.

    Raises
    ------
    ParameterError
        If an input is not exogenous or reaches no block, or an output is not a signal of
        the loop.

    Examples
    --------
    >>> from backhoe import default_family, family_uss
    >>> fam = default_family("literal")
    >>> loop = family_uss(fam)
    >>> loop.nstates, list(loop.parameters) == list(fam.names)
    (11, True)
    >>> G = family_uss(fam, inputs="u", outputs=["y", "x"])
    >>> G.inputs, G.outputs, G.nstates
    (['u'], ['y', 'x'], 11)
    """
    p = dict(fixed_parameters(family))
    for q in family.parameters:
        p[q.name] = UExpr("param", (q,), {q.name: q})
    ins = [inputs] if isinstance(inputs, str) else list(inputs)
    outs = [outputs] if isinstance(outputs, str) else list(outputs)
    assembly = LoopAssembly(family, controller, UNCERTAIN)
    if ins or outs:
        blocks = loop_blocks(
            family, assembly.nominal[None], controller=controller, check_bounds=False
        )
        E, F_y, F_w = port_matrices(
            loop_junctions(family, controller),
            [s for b in blocks for s in b.inputs],
            [s for b in blocks for s in b.outputs],
            ins,
            outs,
        )
        A, B, C, D = assembly.state_space(p, E, F_y, F_w)
        sys = USS(umatrix(A), umatrix(B), umatrix(C), umatrix(D), inputs=ins, outputs=outs)
    else:
        A = assembly.state_matrix(p)
        n = A.shape[0]
        sys = USS(
            umatrix(A),
            umatrix(np.zeros((n, 0))),
            umatrix(np.zeros((0, n))),
            umatrix(np.zeros((0, 0))),
        )
    # the family's order (an uncertain real that cancels out still belongs to the family)
    sys.parameters = {q.name: q for q in family.parameters}
    return sys
