"""Uncertain state-space systems built from uncertain matrices.

``uss(A, B, C, D)`` takes matrices whose entries are numbers or uncertain expressions
(:func:`uncertainty.ureal` and arithmetic) and combines with python-control systems and
with other uncertain systems as python-control's do: ``G * H`` (series: ``H`` then ``G``),
``G + H`` (parallel), ``-G`` and ``G.feedback(H, sign=-1)``. Every evaluation comes from the
one definition: :meth:`USS.nominal` and :meth:`USS.at` give python-control systems,
:meth:`USS.matrices` the matrices of many members at once.

:meth:`USS.state_matrix` evaluates the state matrix on values of any arithmetic type
(intervals and interval gradients included), from which :func:`uncertainty.robust_margin`
builds its certified enclosures and :func:`uncertainty.validate_family` its batched members.

Not yet: named-signal interconnection and the LFT form.
"""

from __future__ import annotations

from collections.abc import Mapping

import control as ct
import numpy as np

from robust.errors import ModelStructureError, ParameterError
from uncertainty.ureal import UExpr, evaluate_matrix, merge_parameters

__all__ = ["USS", "uss"]


def _obj(M, shape=None, where="uss") -> np.ndarray:
    src = np.asarray(M, dtype=object)
    if src.size == 0 and shape is not None:
        src = np.zeros(shape, dtype=object)
    if src.ndim != 2:
        raise ParameterError(f"{where}: a matrix must be 2-D; got {src.ndim} dimensions")
    out = np.empty(src.shape, dtype=object)
    for idx, v in np.ndenumerate(src):
        out[idx] = UExpr._wrap(v, f"{where} entry {idx}")
    return out


def _params(*mats) -> dict:
    return merge_parameters(*(e.parameters for M in mats for e in M.flat))


def _dot(X, Y) -> np.ndarray:
    if X.shape[1] == 0 or X.shape[0] == 0 or Y.shape[1] == 0:
        return _obj(np.zeros((X.shape[0], Y.shape[1])))
    return np.dot(X, Y)


def _block(rows) -> np.ndarray:
    return np.block([[np.asarray(b, dtype=object) for b in r] for r in rows])


def _zeros(r, c) -> np.ndarray:
    return _obj(np.zeros((r, c)))


def _eye(n) -> np.ndarray:
    return _obj(np.eye(n))


class USS:
    """An uncertain state-space system (build with :func:`uss`).

    Parameters
    ----------
    A, B, C, D : numpy.ndarray of UExpr
        Conformal uncertain matrices (:func:`uss` checks and converts them).

    Attributes
    ----------
    A, B, C, D : numpy.ndarray of UExpr
        The uncertain matrices.
    parameters : dict
        Name -> :class:`~uncertainty.parameters.UncertainParameter` of every uncertain
        real in them.
    """

    def __init__(self, A, B, C, D):
        self.A, self.B, self.C, self.D = A, B, C, D
        self.parameters = _params(A, B, C, D)

    @property
    def nstates(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    @property
    def ninputs(self) -> int:
        """Number of inputs."""
        return self.B.shape[1]

    @property
    def noutputs(self) -> int:
        """Number of outputs."""
        return self.C.shape[0]

    def __repr__(self) -> str:
        return (
            f"USS({self.nstates} states, {self.ninputs} inputs, {self.noutputs} outputs; "
            f"parameters {list(self.parameters)})"
        )

    # -- evaluation ---------------------------------------------------------------
    def matrices(self, values: Mapping) -> tuple:
        """``A, B, C, D`` at ``values`` (name -> number or array of ``n`` members).

        Parameters not given are at their nominal. With arrays, each matrix has the shape
        ``(n,) + its shape``.
        """
        unknown = [k for k in values if k not in self.parameters]
        if unknown:
            raise ParameterError(
                f"USS.matrices: {unknown} are not parameters of this system "
                f"({list(self.parameters)})"
            )
        vals = {k: np.asarray(v, float) for k, v in values.items()}
        shape = np.broadcast_shapes(*(v.shape for v in vals.values())) if vals else ()
        full = {k: vals.get(k, np.full(shape, p.nominal)) for k, p in self.parameters.items()}
        return tuple(
            evaluate_matrix(M, full) if M.size else np.zeros(shape + M.shape)
            for M in (self.A, self.B, self.C, self.D)
        )

    def state_matrix(self, values: Mapping) -> list:
        """The state matrix with every uncertain real replaced by ``values[name]``.

        One evaluation of the matrix's expressions (shared sub-expressions once) for
        values of any arithmetic type: numbers, arrays of members, intervals or interval
        gradients (:mod:`robust.analysis.intervals`), which is how the batched members
        and the certified enclosures come from the one definition.

        Parameters
        ----------
        values : mapping
            Name -> value for every parameter of the system.

        Returns
        -------
        list of lists
            The entries, row by row (numbers for entries without uncertain reals).
        """
        missing = [n for n in self.parameters if n not in values]
        if missing:
            raise ParameterError(
                f"USS.state_matrix: values must give every parameter; missing {missing}"
            )
        memo: dict = {}
        return [[e._eval(values, memo) for e in row] for row in self.A]

    def state_matrices(self, rows) -> np.ndarray:
        """State matrices of many members at once.

        Parameters
        ----------
        rows : array_like, shape (N, d)
            Parameter values, columns in the order of :attr:`parameters`.

        Returns
        -------
        numpy.ndarray, shape (N, n, n)
        """
        rows = np.atleast_2d(np.asarray(rows, float))
        if rows.ndim != 2 or rows.shape[1] != len(self.parameters):
            raise ParameterError(
                f"USS.state_matrices: rows must have {len(self.parameters)} columns "
                f"({list(self.parameters)}); got shape {rows.shape}"
            )
        vals = {n: rows[:, j] for j, n in enumerate(self.parameters)}
        n = self.nstates
        out = np.empty((rows.shape[0], n, n))
        with np.errstate(divide="ignore", invalid="ignore"):  # a divisor at 0: inf, reported
            entries = self.state_matrix(vals)
        for i, row in enumerate(entries):
            for j, v in enumerate(row):
                out[:, i, j] = v
        return out

    def at(self, values: Mapping) -> ct.StateSpace:
        """The member at ``values`` (name -> number; others nominal), a python-control system."""
        for k, v in values.items():
            if np.ndim(v) != 0:
                raise ParameterError(
                    f"USS.at: values[{k!r}] must be a number; got shape {np.shape(v)}"
                )
        return ct.ss(*self.matrices(values))

    def nominal(self) -> ct.StateSpace:
        """The nominal member, a python-control system."""
        return self.at({})

    # -- combination --------------------------------------------------------------
    @staticmethod
    def _as_uss(other, where: str) -> USS:
        if isinstance(other, USS):
            return other
        if isinstance(other, ct.StateSpace):
            if not other.isctime():
                raise ModelStructureError(
                    f"{where}: only continuous-time systems combine with a uss; got dt={other.dt}"
                )
            return uss(other.A, other.B, other.C, other.D)
        if isinstance(other, ct.TransferFunction):
            return USS._as_uss(ct.ss(other), where)
        try:
            return uss([], [], [], [[other]]) if np.ndim(other) == 0 else uss([], [], [], other)
        except ParameterError:
            raise ParameterError(
                f"{where}: expected a uss, a python-control system, a number or a matrix; "
                f"got {type(other).__name__}"
            ) from None

    def __mul__(self, other) -> USS:
        """``self * other``: ``other``'s output drives ``self`` (series, as python-control)."""
        g, h = self, self._as_uss(other, "uss *")
        if h.noutputs != g.ninputs:
            raise ModelStructureError(
                f"uss *: {h.noutputs} outputs cannot drive {g.ninputs} inputs"
            )
        A = _block([[g.A, _dot(g.B, h.C)], [_zeros(h.nstates, g.nstates), h.A]])
        B = _block([[_dot(g.B, h.D)], [h.B]])
        C = _block([[g.C, _dot(g.D, h.C)]])
        return USS(_obj(A), _obj(B), _obj(C), _obj(_dot(g.D, h.D)))

    def __rmul__(self, other) -> USS:
        return self._as_uss(other, "uss *") * self

    def __add__(self, other) -> USS:
        """``self + other``: parallel, the outputs added."""
        g, h = self, self._as_uss(other, "uss +")
        if (g.ninputs, g.noutputs) != (h.ninputs, h.noutputs):
            raise ModelStructureError(
                f"uss +: sizes differ ({g.ninputs} -> {g.noutputs} and {h.ninputs} -> {h.noutputs})"
            )
        A = _block([[g.A, _zeros(g.nstates, h.nstates)], [_zeros(h.nstates, g.nstates), h.A]])
        return USS(_obj(A), _obj(_block([[g.B], [h.B]])), _obj(_block([[g.C, h.C]])), g.D + h.D)

    __radd__ = __add__

    def __neg__(self) -> USS:
        return USS(self.A, self.B, -self.C, -self.D)

    def __sub__(self, other) -> USS:
        return self + (-self._as_uss(other, "uss -"))

    def __rsub__(self, other) -> USS:
        return self._as_uss(other, "uss -") + (-self)

    def feedback(self, other=1, sign: int = -1) -> USS:
        """The loop ``u = r + sign * other(y)`` closed around ``self`` (python-control's).

        Parameters
        ----------
        other : USS, control.StateSpace or number
            In the feedback path (default 1: unit feedback).
        sign : int
            -1 (negative feedback) or +1.

        Raises
        ------
        robust.errors.ModelStructureError
            If the sizes do not close a loop, or the direct feed-through around it
            (``D_self D_other``) depends on an uncertain real (an uncertain algebraic loop,
            not supported yet).
        """
        if sign not in (-1, 1):
            raise ParameterError(f"USS.feedback: sign must be -1 or +1; got {sign!r}")
        g, h = self, self._as_uss(other, "USS.feedback")
        if (h.ninputs, h.noutputs) != (g.noutputs, g.ninputs):
            raise ModelStructureError(
                f"USS.feedback: the feedback system must map {g.noutputs} outputs to "
                f"{g.ninputs} inputs; got {h.ninputs} -> {h.noutputs}"
            )
        DD = _dot(g.D, h.D)
        if any(e.parameters for e in DD.flat):
            raise ModelStructureError(
                "USS.feedback: the loop's direct feed-through D1 D2 depends on uncertain "
                "reals (an uncertain algebraic loop); not supported yet"
            )
        num = np.array([[e.nominal() for e in row] for row in DD]).reshape(DD.shape)
        M = np.eye(g.noutputs) - sign * num
        try:
            E = _obj(np.linalg.inv(M))
        except np.linalg.LinAlgError:
            raise ModelStructureError("USS.feedback: the loop is algebraically singular") from None
        s = float(sign)
        # y1 = E (C1 x1 + s D1 C2 x2 + D1 r); u1 = r + s (C2 x2 + D2 y1)
        Cy = _block([[_dot(E, g.C), s * _dot(E, _dot(g.D, h.C))]])
        Dy = _dot(E, g.D)
        Cu = _block([[_zeros(g.ninputs, g.nstates), s * h.C]]) + s * _dot(h.D, Cy)
        Du = _eye(g.ninputs) + s * _dot(h.D, Dy)
        A = _block([[g.A, _zeros(g.nstates, h.nstates)], [_zeros(h.nstates, g.nstates), h.A]])
        A = A + _block([[_dot(g.B, Cu)], [_dot(h.B, Cy)]])
        B = _block([[_dot(g.B, Du)], [_dot(h.B, Dy)]])
        return USS(_obj(A), _obj(B), _obj(Cy), _obj(Dy))


def uss(A, B, C, D) -> USS:
    """An uncertain state-space system from uncertain (or plain) matrices.

    Parameters
    ----------
    A, B, C, D : array_like
        Matrices of numbers and uncertain expressions (:func:`uncertainty.ureal`);
        ``A`` square (or empty for a static gain), the shapes conformal.

    Returns
    -------
    USS

    Examples
    --------
    A mass on a spring with an uncertain stiffness, closed by a python-control
    controller:

    >>> import control as ct
    >>> from uncertainty import ureal, uss
    >>> k = ureal("k", 4.0, 2.0, 6.0)
    >>> G = uss([[0, 1], [-k, -0.2]], [[0], [1]], [[1, 0]], [[0]])
    >>> loop = G.feedback(ct.ss([], [], [], [[2.0]]))
    >>> [float(p) for p in abs(loop.at({"k": 2.0}).poles()).round(3)]
    [2.0, 2.0]
    """
    D = _obj(D, where="uss D")
    A = _obj(A, shape=(0, 0), where="uss A")
    n = A.shape[0]
    B = _obj(B, shape=(n, D.shape[1]), where="uss B")
    C = _obj(C, shape=(D.shape[0], n), where="uss C")
    if A.shape != (n, n) or B.shape != (n, D.shape[1]) or C.shape != (D.shape[0], n):
        raise ModelStructureError(
            f"uss: matrices not conformal: A {A.shape}, B {B.shape}, C {C.shape}, D {D.shape}"
        )
    return USS(A, B, C, D)
