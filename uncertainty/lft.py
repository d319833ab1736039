"""The linear fractional (LFT) form of an uncertain system.

Every uncertain real ``p`` with range ``[low, high]`` is written ``p = c + h delta`` with
``c`` the range's centre, ``h`` its half-width and ``|delta| <= 1``. Each entry of the
system's matrices is a rational expression of the ``p``, so it is an LFT of the
``delta`` (Zhou, Doyle & Glover, *Robust and Optimal Control*, 1996, ch. 10): built node by
node from the expression, with the rules

* a parameter: ``c + h delta`` (one channel);
* a sum: the two LFTs side by side; a product: their series connection;
* a reciprocal ``1 / e``: the inverse of ``e``'s LFT (its constant part must not be 0);
* an integer power: repeated products.

The entries are then stacked into ``S(delta) = [[A, B], [C, D]] = S0 + L Delta (I - F
Delta)^-1 R`` with ``Delta`` block diagonal, each parameter's channels together
(``delta_i I_{r_i}``), and the system becomes the constant system ``M`` (a python-control
state space) with ``[w; u] -> [z; y]`` closed by ``w = Delta z``: the form a mu analysis
takes (:func:`uncertainty.mussv` on ``M(jw)`` with ``(r_i, "real")`` blocks).

Built node by node, a parameter has as many channels as it has occurrences in the
expressions (a canonical form's ``1 / m`` in every entry of a row, for example). These are
then reduced to a controllable and observable structured realization by the n-D Kalman
decomposition (Beck & D'Andrea, "Minimality, controllability and observability for
uncertain systems", ACC 1997; D'Andrea & Khatri, ACC 1997): the smallest subspace
``V = V_1 x ... x V_k`` (one part per parameter's channels) that holds the range of ``R``
and is invariant under ``F`` carries every signal of the loop, because ``Delta`` maps each
such subspace into itself; restricted to an orthonormal basis ``T`` of it,
``S(delta) = S0 + (L T) Delta' (I - T' F T Delta')^-1 (T' R)`` exactly, and the same on the
transposed realization with the range of ``L'``. The ``r_i`` are then the dimensions left.
Each step is exact up to rounding; the tests close both forms at seeded members and compare.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from robust.errors import ModelStructureError, ParameterError
from uncertainty.ureal import UExpr
from uncertainty.uss import USS

__all__ = ["LFTForm", "lft_form"]


@dataclasses.dataclass(frozen=True)
class _Scalar:
    """``d + c Delta (I - a Delta)^-1 b`` with ``Delta = diag(delta of names[k])``."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: float
    names: tuple

    @staticmethod
    def const(v: float) -> _Scalar:
        return _Scalar(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), float(v), ())

    def __add__(self, o: _Scalar) -> _Scalar:
        r1, r2 = len(self.names), len(o.names)
        a = np.block([[self.a, np.zeros((r1, r2))], [np.zeros((r2, r1)), o.a]])
        return _Scalar(
            a,
            np.vstack([self.b, o.b]),
            np.hstack([self.c, o.c]),
            self.d + o.d,
            self.names + o.names,
        )

    def __neg__(self) -> _Scalar:
        return _Scalar(self.a, self.b, -self.c, -self.d, self.names)

    def __mul__(self, o: _Scalar) -> _Scalar:
        # series: o first, then self (scalars commute; the channel order is self's, o's)
        r1, r2 = len(self.names), len(o.names)
        a = np.block([[self.a, self.b @ o.c], [np.zeros((r2, r1)), o.a]])
        b = np.vstack([self.b * o.d, o.b])
        c = np.hstack([self.c, self.d * o.c])
        return _Scalar(a, b, c, self.d * o.d, self.names + o.names)

    def reciprocal(self) -> _Scalar:
        if self.d == 0.0:
            raise ParameterError(
                "lft_form: a divisor is 0 at the centre of its parameters' ranges; its "
                "reciprocal has no LFT about that centre"
            )
        di = 1.0 / self.d
        return _Scalar(self.a - di * (self.b @ self.c), di * self.b, -di * self.c, di, self.names)


def _scalar(e: UExpr, centre: dict, half: dict, memo: dict) -> _Scalar:
    key = id(e)
    if key in memo:
        return memo[key]
    op, args = e._op, e._args
    if op == "const":
        out = _Scalar.const(args[0])
    elif op == "param":
        name = args[0].name
        out = _Scalar(
            np.zeros((1, 1)), np.ones((1, 1)), np.full((1, 1), half[name]), centre[name], (name,)
        )
    elif op == "neg":
        out = -_scalar(args[0], centre, half, memo)
    elif op == "pow":
        base, k = _scalar(args[0], centre, half, memo), args[1]
        out = _Scalar.const(1.0)
        for _ in range(abs(k)):
            out = out * base
        if k < 0:
            out = out.reciprocal()
    else:
        x, y = _scalar(args[0], centre, half, memo), _scalar(args[1], centre, half, memo)
        if op == "+":
            out = x + y
        elif op == "-":
            out = x + (-y)
        elif op == "*":
            out = x * y
        else:
            out = x * y.reciprocal()
    memo[key] = out
    return out


@dataclasses.dataclass(frozen=True)
class LFTForm:
    """An uncertain system as a constant system closed by a structured ``Delta``.

    Parameters
    ----------
    M : control.StateSpace
        Inputs ``w[0..R-1]`` then the system's inputs; outputs ``z[0..R-1]`` then the
        system's outputs; the system's states.
    blocks : list of (str, int)
        Per uncertain real, in the order of the channels: its name and repetition ``r_i``
        (``Delta = diag(delta_1 I_{r_1}, ...)``, ``|delta_i| <= 1``).
    centre, half_width : dict
        Per uncertain real, ``p = centre + half_width * delta``.
    """

    M: ct.StateSpace
    blocks: list
    centre: dict
    half_width: dict

    @property
    def mu_blocks(self) -> list:
        """The block structure as :func:`uncertainty.mussv` takes it."""
        return [(r, "real") for _, r in self.blocks]

    def close(self, deltas) -> ct.StateSpace:
        """The member at normalised values ``deltas`` (name -> delta in [-1, 1]).

        Parameters
        ----------
        deltas : mapping
            Name -> delta; parameters not given are at the centre of their range.
        """
        d = np.concatenate([np.full(r, float(deltas.get(n, 0.0))) for n, r in self.blocks])
        R = d.size
        A, B, C, D = (np.asarray(x, float) for x in (self.M.A, self.M.B, self.M.C, self.M.D))
        Dl = np.diag(d)
        F = D[:R, :R]
        K = np.linalg.solve(np.eye(R) - Dl @ F, Dl)  # w = K z0, z0 = C_z x + D_zu u
        Ac = A + B[:, :R] @ K @ C[:R]
        Bc = B[:, R:] + B[:, :R] @ K @ D[:R, R:]
        Cc = C[R:] + D[R:, :R] @ K @ C[:R]
        Dc = D[R:, R:] + D[R:, :R] @ K @ D[:R, R:]
        return ct.ss(Ac, Bc, Cc, Dc)


#: Relative singular-value threshold of the reduction's bases (relative to the largest entry
#: of the LFT written in the parameters' own deviations, ``p - centre``, not the normalised
#: ``delta``: see :func:`_reduce`).
REDUCE_RTOL = 1e-10


def _orth(X: np.ndarray, tol: float) -> np.ndarray:
    if X.shape[1] == 0:
        return np.zeros((X.shape[0], 0))
    U, sv, _ = np.linalg.svd(X, full_matrices=False)
    return U[:, sv > tol]


def _reachable(F: np.ndarray, R: np.ndarray, sizes: list, tol: float) -> list:
    """Orthonormal bases ``Q_i`` (one per block of ``sizes``) of the smallest block-structured
    subspace that holds ``range(R)`` and is invariant under ``F``."""
    edges = np.cumsum([0, *sizes])
    blocks = [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]
    Q = [_orth(R[b], tol) for b in blocks]
    while True:
        T = _blockdiag(Q, sizes)
        image = F @ T
        grown = False
        for i, b in enumerate(blocks):
            new = _orth(np.hstack([Q[i], image[b]]), tol)
            if new.shape[1] > Q[i].shape[1]:
                Q[i], grown = new, True
        if not grown:
            return Q


def _blockdiag(Q: list, sizes: list) -> np.ndarray:
    T = np.zeros((sum(sizes), sum(q.shape[1] for q in Q)))
    r = c = 0
    for q, size in zip(Q, sizes):
        T[r : r + size, c : c + q.shape[1]] = q
        r, c = r + size, c + q.shape[1]
    return T


def _reduce(F, L, Rm, sizes, half):
    """The controllable, then observable, part of ``S0 + L Delta (I - F Delta)^-1 Rm``
    (module notes): ``(F, L, Rm, sizes)`` of the reduced realization.

    ``half`` holds each channel's half-width: the columns of ``F`` and ``L`` carry it
    (``F = F_u H``, ``L = L_u H``, ``H`` one scalar per block), and the subspaces are found on
    ``F_u`` and ``L_u``, the LFT in the parameters' own deviations. A block-structured
    subspace is the same for both (``H`` maps it onto itself), but the rank decisions are
    not: with the normalised matrices, a box scaled small (1e-4 about a loop with controller
    gains of 1e7) left a block's channels below the threshold set by another's, and they
    were dropped as if they were rounding. On ``F_u`` and ``L_u`` they do not depend on the
    box's size."""
    h = np.where(np.asarray(half, float) > 0, np.asarray(half, float), 1.0)
    Fu, Lu = F / h[None, :], L / h[None, :]
    scale = max(1.0, *(float(np.abs(X).max(initial=0.0)) for X in (Fu, Lu, Rm)))
    tol = REDUCE_RTOL * scale
    Q = _reachable(Fu, Rm, sizes, tol)
    T = _blockdiag(Q, sizes)
    F, L, Rm, Fu, Lu = T.T @ F @ T, L @ T, T.T @ Rm, T.T @ Fu @ T, Lu @ T
    sizes = [q.shape[1] for q in Q]
    Q = _reachable(Fu.T, Lu.T, sizes, tol)
    U = _blockdiag(Q, sizes)
    return U.T @ F @ U, L @ U, U.T @ Rm, [q.shape[1] for q in Q]


def lft_form(system, *, bounds=None, reduce: bool = True) -> LFTForm:
    """The LFT form of an uncertain system (see the module notes).

    Parameters
    ----------
    system : USS
        The uncertain system.
    bounds : mapping, optional
        Name -> ``(low, high)``: the box the ``delta`` are normalised to, in place of the
        parameters' own ranges (for example a box scaled about the nominal); parameters not
        given keep their ranges.
    reduce : bool
        Reduce the channels to a controllable and observable structured realization
        (module notes); False keeps one channel per occurrence of a parameter.

    Returns
    -------
    LFTForm

    Raises
    ------
    ParameterError
        If a divisor is 0 at the centre of the box (no LFT about that centre).

    Examples
    --------
    >>> from uncertainty import ureal, uss
    >>> from uncertainty.lft import lft_form
    >>> k = ureal("k", 4.0, 2.0, 6.0)
    >>> m = ureal("m", 1.0, 0.5, 1.5)
    >>> G = uss([[0, 1], [-k / m, -0.1]], [[0], [1]], [[1, 0]], [[0]])
    >>> F = lft_form(G)
    >>> F.blocks, F.mu_blocks
    ([('k', 1), ('m', 1)], [(1, 'real'), (1, 'real')])
    >>> float(F.close({"k": 1.0, "m": -1.0}).A[1, 0])  # -6 / 0.5
    -12.0
    """
    if not isinstance(system, USS):
        raise ModelStructureError(f"lft_form: expected a uss; got {type(system).__name__}")
    params = system.parameters
    box = {n: (p.low, p.high) for n, p in params.items()}
    for n, b in dict(bounds or {}).items():
        if n not in box:
            raise ParameterError(f"lft_form: bounds name an unknown parameter {n!r}")
        low, high = (float(x) for x in b)
        if not (math.isfinite(low) and math.isfinite(high) and low <= high):
            raise ParameterError(
                f"lft_form: bounds[{n!r}] must be finite (low, high) with low <= high; got {b!r}"
            )
        box[n] = (low, high)
    centre = {n: 0.5 * (lo + hi) for n, (lo, hi) in box.items()}
    half = {n: 0.5 * (hi - lo) for n, (lo, hi) in box.items()}
    n, m, q = system.nstates, system.ninputs, system.noutputs
    S = np.block([[system.A, system.B], [system.C, system.D]]) if n else system.D
    S = np.asarray(S, dtype=object).reshape(n + q, n + m)
    entries = {}
    for idx, e in np.ndenumerate(S):
        entries[idx] = _scalar(e, centre, half, {})
    # channels: grouped by parameter (in the system's parameter order)
    chans = [(idx, k, name) for idx, s in entries.items() for k, name in enumerate(s.names)]
    order = sorted(range(len(chans)), key=lambda i: (list(params).index(chans[i][2]), i))
    pos = {(chans[i][0], chans[i][1]): j for j, i in enumerate(order)}
    R = len(chans)
    F = np.zeros((R, R))
    L = np.zeros((n + q, R))
    Rm = np.zeros((R, n + m))
    S0 = np.zeros((n + q, n + m))
    for (i, j), s in entries.items():
        S0[i, j] = s.d
        cols = [pos[((i, j), k)] for k in range(len(s.names))]
        if cols:
            F[np.ix_(cols, cols)] = s.a
            L[i, cols] = s.c[0]
            Rm[cols, j] = s.b[:, 0]
    counts = [chans[i][2] for i in order]
    names = [name for name in params if name in counts]
    sizes = [counts.count(name) for name in names]
    if reduce and R:
        F, L, Rm, sizes = _reduce(F, L, Rm, sizes, [half[name] for name in counts])
        R = sum(sizes)
    M = ct.ss(
        S0[:n, :n],
        np.hstack([L[:n], S0[:n, n:]]),
        np.vstack([Rm[:, :n], S0[n:, :n]]),
        np.block([[F, Rm[:, n:]], [L[n:], S0[n:, n:]]]),
        inputs=[f"w[{k}]" for k in range(R)] + list(system.inputs),
        outputs=[f"z[{k}]" for k in range(R)] + list(system.outputs),
    )
    blocks = [(name, r) for name, r in zip(names, sizes) if r > 0]
    return LFTForm(M=M, blocks=blocks, centre=centre, half_width=half)
