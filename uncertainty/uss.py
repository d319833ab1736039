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

:func:`interconnect` joins systems by signal names, as python-control's
``interconnect`` does implicitly (an input is driven by the output of the same name).

:func:`uncertainty.lft_form` gives the LFT form (:mod:`uncertainty.lft`).
"""

from __future__ import annotations

from collections.abc import Mapping

import control as ct
import numpy as np

from robust.errors import ModelStructureError, ParameterError
from uncertainty.ureal import UExpr, evaluate_matrix, merge_parameters

__all__ = ["USS", "uss", "interconnect", "nonzero_pattern"]


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


def _labels(names, n: int, prefix: str) -> list:
    if names is None:
        return [f"{prefix}[{i}]" for i in range(n)]
    names = [names] if isinstance(names, str) else [str(x) for x in names]
    if len(names) != n:
        raise ParameterError(f"uss: {n} {prefix} signal names expected; got {names}")
    return names


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

    inputs, outputs : list of str, optional
        Signal names (default ``u[i]``, ``y[i]``), used by :func:`interconnect`.

    Attributes
    ----------
    A, B, C, D : numpy.ndarray of UExpr
        The uncertain matrices.
    parameters : dict
        Name -> :class:`~uncertainty.parameters.UncertainParameter` of every uncertain
        real in them.
    inputs, outputs : list of str
        Signal names.
    """

    #: numpy defers its operators to this class (``np.float64(2) * G`` is a uss), and so do
    #: uncertain expressions (``k * G``)
    __array_ufunc__ = None

    def __init__(self, A, B, C, D, inputs=None, outputs=None):
        self.A, self.B, self.C, self.D = A, B, C, D
        self.parameters = _params(A, B, C, D)
        self.inputs = _labels(inputs, B.shape[1] if B.ndim == 2 else D.shape[1], "u")
        self.outputs = _labels(outputs, D.shape[0], "y")

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
        """The member at ``values`` (name -> number; others nominal), a python-control system.

        Its signal names are the system's (python-control's defaults where names repeat).
        """
        for k, v in values.items():
            if np.ndim(v) != 0:
                raise ParameterError(
                    f"USS.at: values[{k!r}] must be a number; got shape {np.shape(v)}"
                )
        names = {}
        if len(set(self.inputs)) == len(self.inputs):
            names["inputs"] = list(self.inputs)
        if len(set(self.outputs)) == len(self.outputs):
            names["outputs"] = list(self.outputs)
        return ct.ss(*self.matrices(values), **names)

    def nominal(self) -> ct.StateSpace:
        """The nominal member, a python-control system."""
        return self.at({})

    # -- combination --------------------------------------------------------------
    @staticmethod
    def _as_uss(other, where: str) -> USS:
        if isinstance(other, USS):
            return other
        if hasattr(other, "to_uss"):  # an uncertain transfer function (uncertainty.tf)
            return other.to_uss()
        if isinstance(other, ct.StateSpace):
            if not other.isctime():
                raise ModelStructureError(
                    f"{where}: only continuous-time systems combine with a uss; got dt={other.dt}"
                )
            return uss(
                other.A,
                other.B,
                other.C,
                other.D,
                inputs=list(other.input_labels),
                outputs=list(other.output_labels),
            )
        if isinstance(other, ct.TransferFunction):
            return USS._as_uss(ct.ss(other), where)
        try:
            return uss([], [], [], [[other]]) if np.ndim(other) == 0 else uss([], [], [], other)
        except ParameterError:
            raise ParameterError(
                f"{where}: expected a uss, an uncertain transfer function, a python-control "
                f"system, a number, an uncertain expression or a matrix; "
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
        return USS(_obj(A), _obj(B), _obj(C), _obj(_dot(g.D, h.D)), h.inputs, g.outputs)

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
        return USS(
            _obj(A),
            _obj(_block([[g.B], [h.B]])),
            _obj(_block([[g.C, h.C]])),
            g.D + h.D,
            g.inputs,
            g.outputs,
        )

    __radd__ = __add__

    def __neg__(self) -> USS:
        return USS(self.A, self.B, -self.C, -self.D, self.inputs, self.outputs)

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
        return USS(_obj(A), _obj(B), _obj(Cy), _obj(Dy), g.inputs, g.outputs)


def uss(A, B=None, C=None, D=None, *, inputs=None, outputs=None) -> USS:
    """An uncertain state-space system from uncertain (or plain) matrices, or from a system.

    Parameters
    ----------
    A, B, C, D : array_like
        Matrices of numbers and uncertain expressions (:func:`uncertainty.ureal`);
        ``A`` square (or empty for a static gain), the shapes conformal.
        With ``A`` alone: a system to convert, a python-control ``StateSpace`` or
        ``TransferFunction`` (continuous time; its signal names kept), an uncertain
        transfer function (:func:`uncertainty.tf`, realised by
        :meth:`~uncertainty.UTF.to_uss`), a ``uss`` (returned as it is, renamed if names
        are given) or a number or uncertain expression (a static gain).
    inputs, outputs : str or list of str, optional
        Signal names (default ``u[i]``, ``y[i]``, or the system's own), for
        :func:`interconnect`.

    Returns
    -------
    USS

    Raises
    ------
    robust.errors.ParameterError
        If only some of ``B, C, D`` are given, an entry is neither a number nor an
        uncertain expression, or a name list has the wrong length.
    robust.errors.ModelStructureError
        If the matrices are not conformal, a system is discrete-time or an uncertain
        transfer function is improper.

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

    A python-control system becomes a ``uss`` with its signal names:

    >>> P = uss(ct.tf([1.0], [1.0, 1.0], inputs="u", outputs="y"))
    >>> P.nstates, P.inputs, P.outputs
    (1, ['u'], ['y'])
    """
    given = [M is not None for M in (B, C, D)]
    if not any(given):
        if isinstance(A, (list, tuple, np.ndarray)):
            raise ParameterError(
                "uss: a matrix alone is not a system; expected the four matrices A, B, C, D "
                "or one system (python-control, uncertain transfer function); "
                f"got {type(A).__name__}"
            )
        sys = USS._as_uss(A, "uss")
        if inputs is None and outputs is None:
            return sys
        return USS(
            sys.A,
            sys.B,
            sys.C,
            sys.D,
            sys.inputs if inputs is None else inputs,
            sys.outputs if outputs is None else outputs,
        )
    if not all(given):
        raise ParameterError(
            "uss: expected the four matrices A, B, C, D or one system; "
            f"got {', '.join(n for n, g in zip('BCD', given) if g)} besides A"
        )
    D = _obj(D, where="uss D")
    A = _obj(A, shape=(0, 0), where="uss A")
    n = A.shape[0]
    B = _obj(B, shape=(n, D.shape[1]), where="uss B")
    C = _obj(C, shape=(D.shape[0], n), where="uss C")
    if A.shape != (n, n) or B.shape != (n, D.shape[1]) or C.shape != (D.shape[0], n):
        raise ModelStructureError(
            f"uss: matrices not conformal: A {A.shape}, B {B.shape}, C {C.shape}, D {D.shape}"
        )
    return USS(A, B, C, D, inputs, outputs)


def nonzero_pattern(M) -> np.ndarray:
    """The entries of an uncertain matrix that are not the constant 0 (bool array).

    Parameters
    ----------
    M : numpy.ndarray of UExpr
        The matrix.
    """
    return np.vectorize(lambda e: not (e._op == "const" and e._args[0] == 0.0), otypes=[bool])(M)


def interconnect(systems, inputs, outputs) -> USS:
    """Systems joined by signal names: every input is driven by the output of its name.

    As python-control's ``interconnect`` with implicit connections: a system input named
    ``s`` is driven by the output named ``s`` of another system, or by the external input
    ``s`` (listed in ``inputs``); the result's outputs are the signals named in
    ``outputs``. Signs and sums go through the systems themselves (a static gain of -1,
    a summing system ``uss([], [], [], [[1, -1]], inputs=["r", "y"], outputs=["e"])``).

    Parameters
    ----------
    systems : sequence of USS, control.StateSpace or control.TransferFunction
        The blocks, with signal names (python-control's labels are kept).
    inputs : str or list of str
        External inputs: the names of block inputs they drive.
    outputs : str or list of str
        Signals to expose: names of block outputs.

    Returns
    -------
    USS
        States in the order of ``systems``.

    Raises
    ------
    robust.errors.ModelStructureError
        If an output name is given twice, a block input is driven by nothing, a listed
        signal does not exist, or the direct feed-throughs close an algebraic loop that
        depends on an uncertain real (a constant one is solved).

    Examples
    --------
    A unit-feedback loop around an uncertain plant, by names:

    >>> from uncertainty import interconnect, ureal, uss
    >>> a = ureal("a", 1.0, 0.5, 2.0)
    >>> P = uss([[-a]], [[1]], [[1]], [[0]], inputs="u", outputs="y")
    >>> E = uss([], [], [], [[1, -1]], inputs=["r", "y"], outputs="u")
    >>> T = interconnect([P, E], inputs="r", outputs="y")
    >>> float(T.at({"a": 2.0}).poles()[0].real)
    -3.0
    """
    syss = [USS._as_uss(s, "interconnect") for s in systems]
    ext = [inputs] if isinstance(inputs, str) else list(inputs)
    outs = [outputs] if isinstance(outputs, str) else list(outputs)
    u_all = [n for s in syss for n in s.inputs]
    y_all = [n for s in syss for n in s.outputs]
    dup = sorted({n for n in y_all if y_all.count(n) > 1})
    if dup:
        raise ModelStructureError(f"interconnect: output names must be unique; {dup} repeat")
    for n in u_all:
        if n not in y_all and n not in ext:
            raise ModelStructureError(
                f"interconnect: input {n!r} is driven by no output and is not an external input"
            )
    for n in ext:
        if n not in u_all:
            raise ModelStructureError(f"interconnect: external input {n!r} drives no block")
    for n in outs:
        if n not in y_all:
            raise ModelStructureError(f"interconnect: output {n!r} is no block's output")
    nx = [s.nstates for s in syss]
    n, m, p = sum(nx), len(u_all), len(y_all)
    A, B, C, D = _zeros(n, n), _zeros(n, m), _zeros(p, n), _zeros(p, m)
    x = u = y = 0
    for s in syss:
        A[x : x + s.nstates, x : x + s.nstates] = s.A
        B[x : x + s.nstates, u : u + s.ninputs] = s.B
        C[y : y + s.noutputs, x : x + s.nstates] = s.C
        D[y : y + s.noutputs, u : u + s.ninputs] = s.D
        x, u, y = x + s.nstates, u + s.ninputs, y + s.noutputs
    M = np.array([[1.0 if ui == yk else 0.0 for yk in y_all] for ui in u_all]).reshape(m, p)
    E = np.array([[1.0 if ui == w else 0.0 for w in ext] for ui in u_all]).reshape(m, len(ext))
    # y = C x + D (M y + E w): y = (I - D M)^-1 (C x + D E w)
    DM = _dot(D, _obj(M))
    rhs_x, rhs_w = C, _dot(D, _obj(E))
    pattern = nonzero_pattern(DM) if DM.size else np.zeros((p, p), bool)
    power, terms = pattern.copy(), 0
    while power.any() and terms <= p:
        terms += 1
        power = (power.astype(int) @ pattern.astype(int)) > 0
    if terms <= p:  # nilpotent: a finite series
        Yx, Yw, tx, tw = rhs_x, rhs_w, rhs_x, rhs_w
        for _ in range(terms):
            tx, tw = _dot(DM, tx), _dot(DM, tw)
            Yx, Yw = Yx + tx, Yw + tw
    elif not any(e.parameters for e in DM.flat):
        num = np.array([[e.nominal() for e in row] for row in DM]).reshape(p, p)
        try:
            inv = _obj(np.linalg.inv(np.eye(p) - num))
        except np.linalg.LinAlgError:
            raise ModelStructureError("interconnect: the algebraic loop is singular") from None
        Yx, Yw = _dot(inv, rhs_x), _dot(inv, rhs_w)
    else:
        raise ModelStructureError(
            "interconnect: the direct feed-throughs close an algebraic loop that depends on "
            "uncertain reals; not supported"
        )
    BM = _dot(B, _obj(M))
    Anew = A + _dot(BM, Yx)
    Bnew = _dot(B, _obj(E)) + _dot(BM, Yw)
    S = np.array([[1.0 if yk == o else 0.0 for yk in y_all] for o in outs]).reshape(len(outs), p)
    Cnew, Dnew = _dot(_obj(S), Yx), _dot(_obj(S), Yw)
    return USS(_obj(Anew), _obj(Bnew), _obj(Cnew), _obj(Dnew), ext, outs)
