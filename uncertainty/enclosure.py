"""Interval enclosures of the closed-loop state matrix over a box, and the loops the margin
analyses.

:func:`closed_loop_enclosure` encloses the state matrix of every member of a box of a
family's parameters in an interval matrix, by interval arithmetic through the blocks and the
interconnection of the Figure 5 junction table (midpoint-radius interval arithmetic, Rump
1999; with ``derivatives``, interval forward differentiation, Moore, Kearfott &
Cloud, *Introduction to Interval Analysis*, SIAM 2009: :mod:`robust.analysis.intervals`).

The margin sees a family (with a fixed controller) or an uncertain system (:mod:`uncertainty.uss`,
closed with a controller) through one small interface, built by ``_loop``: ``matrices``
(batched members), ``enclosure`` (intervals or interval gradients over a box) and
``recheck`` (python-control poles of one member). ``_FamilyLoop`` evaluates the family's
loop (:mod:`uncertainty.batched`, :mod:`uncertainty.loop`), ``_SystemLoop`` the system's
one uncertain state matrix; a box whose matrix is unbounded (a divisor's range holding 0)
raises ``_Unbounded``.

One concern apart from the search (:mod:`uncertainty.search`) and the certificates
(:mod:`uncertainty.boxcert`), which both take their loops from here; the loop objects are
sent to worker processes and stay importable at module level.
"""

from __future__ import annotations

import control as ct
import numpy as np

from robust.analysis.intervals import Gradient, Interval, imatrix
from robust.analysis.loops import loop_poles
from robust.analysis.stability import DAMPING_BAND_HZ
from robust.errors import BDFTError, ModelStructureError, ParameterError
from uncertainty.batched import closed_loop_matrices
from uncertainty.family import Family
from uncertainty.loop import INTERVALS, LoopAssembly, family_uss, fixed_parameters
from uncertainty.region import EVERY_FREQUENCY_HZ, Region
from uncertainty.uss import USS

__all__ = ["closed_loop_enclosure"]


def _box_variables(parameters, lo, hi, derivatives: bool) -> dict:
    """The varied parameters over the box ``lo .. hi``: intervals, or :class:`Gradient`
    variables in the parameters' coordinates (log for log-uniform: d value / d t is the
    value itself, 1 for linear)."""
    d = len(parameters)
    out = {}
    for j, (p, a, b) in enumerate(zip(parameters, lo, hi)):
        if not derivatives:
            out[p.name] = Interval.hull(a, b)
        else:
            dv = Interval.hull(a, b) if p.distribution == "loguniform" else None
            out[p.name] = Gradient.variable(a, b, j, d, dvalue=dv)
    return out


def _param_intervals(
    family: Family, lo: np.ndarray, hi: np.ndarray, derivatives: bool, fixed: dict | None = None
) -> dict:
    """Every model parameter over the box: the varied ones as :func:`_box_variables`, the
    others fixed (``fixed``: their point intervals, when the caller keeps them)."""
    if fixed is None:
        fixed = {n: Interval.point(v) for n, v in fixed_parameters(family).items()}
    out = dict(fixed)
    out.update(_box_variables(family.parameters, lo, hi, derivatives))
    return out


def closed_loop_enclosure(
    family: Family,
    lo,
    hi,
    *,
    controller: ct.StateSpace | None = None,
    derivatives: bool = False,
) -> Interval | Gradient:
    """An interval matrix containing the closed-loop state matrix of every member in a box.

    Interval arithmetic through the blocks of :func:`uncertainty.batched.loop_blocks`
    (same block and state order) and the interconnection of the Figure 5 junction
    table, ``A_cl = A + B M (C + D M C + (D M)^2 C + ...)`` (the series is finite: the
    direct feedthroughs form no algebraic cycle).

    Parameters
    ----------
    family : Family
        The family.
    lo, hi : array_like, shape (d,)
        The box: bounds of every uncertain parameter (values, family order).
    controller : control.StateSpace, optional
        Compensator in the loop's convention (fixed).
    derivatives : bool
        Also enclose the partial derivatives of the matrix over the box with respect to
        each parameter in the family's coordinates (log of the value for log-uniform
        parameters): a :class:`~robust.analysis.intervals.Gradient` is returned.

    Raises
    ------
    ParameterError
        If the controller's feedthrough closes an algebraic loop (no finite series).
    """
    return _Assembly(family, controller).matrix(lo, hi, derivatives)


class _Assembly(LoopAssembly):
    """The family's loop evaluated on intervals (or interval gradients) over a box."""

    def __init__(self, family: Family, controller):
        super().__init__(family, controller, INTERVALS)
        # the fixed parameters' point intervals, the same for every box (read-only)
        self._fixed = {n: Interval.point(v) for n, v in fixed_parameters(family).items()}
        for iv in self._fixed.values():
            iv.mid.setflags(write=False)
            iv.rad.setflags(write=False)

    def matrix(self, lo, hi, derivatives: bool):
        """The enclosure of the closed-loop state matrix over the box ``lo .. hi``."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        return self.state_matrix(_param_intervals(self.family, lo, hi, derivatives, self._fixed))


class _FamilyLoop:
    """The BDFT loop of a family with a fixed controller: what the margin needs of it."""

    #: the damping band of a region that leaves it to the default: the BDFT band
    default_band_hz = DAMPING_BAND_HZ

    def __init__(self, family: Family, controller):
        self.family, self.controller = family, controller
        self.parameters = tuple(family.parameters)
        self.names = tuple(family.names)
        self._asm = None
        self._system = None

    @property
    def system(self) -> USS:
        """The loop as an uncertain system (:func:`uncertainty.loop.family_uss`: the same
        blocks over uncertain reals), built on first use; the mu route takes its LFT."""
        if self._system is None:
            self._system = family_uss(self.family, self.controller)
        return self._system

    def matrices(self, rows) -> np.ndarray:
        """Closed-loop state matrices of members (rows of values), batched."""
        return closed_loop_matrices(
            self.family, rows, controller=self.controller, check_bounds=False
        )

    def enclosure(self, lo, hi, derivatives: bool):
        """Interval (or :class:`Gradient`) enclosure of the matrix over a box of values."""
        if self._asm is None:
            self._asm = _Assembly(self.family, self.controller)
        return self._asm.matrix(lo, hi, derivatives)

    def recheck(self, row):
        """Poles of the member's Figure 5 loop by python-control, or None outside the model."""
        try:
            member = self.family.member(row, check_bounds=False)
        except BDFTError:  # e.g. a scaled structure damping ratio >= 1, outside the loop model
            return None
        return (
            loop_poles(member, controller=self.controller).poles,
            "python-control poles of the member's Figure 5 loop",
        )


class _Unbounded(ParameterError):
    """A box holds members whose matrix is unbounded (a divisor's range contains 0)."""


class _SystemLoop:
    """An uncertain system (closed with a controller if one is given) seen by the margin.

    Every evaluation comes from the system's one uncertain state matrix: numbers (batched
    members), intervals and interval gradients (the certificate's enclosures) run through
    the same expressions, shared sub-expressions evaluated once.
    """

    #: the damping band of a region that leaves it to the default: every frequency (a
    #: user's own system has no band of its own)
    default_band_hz = EVERY_FREQUENCY_HZ

    def __init__(self, system: USS, controller):
        closed = system if controller is None else system.feedback(controller, sign=-1)
        if not closed.parameters:
            raise ParameterError(
                "robust margin: the system has no uncertain real (build it with uncertainty.ureal)"
            )
        if closed.nstates == 0:
            raise ModelStructureError("robust margin: the system has no state (a static gain)")
        self.system = closed
        self.parameters = tuple(closed.parameters.values())
        self.names = tuple(closed.parameters)

    def matrices(self, rows) -> np.ndarray:
        """State matrices of members (rows of values, columns in :attr:`names` order)."""
        return self.system.state_matrices(rows)

    def enclosure(self, lo, hi, derivatives: bool):
        """Interval (or :class:`Gradient`) enclosure of the state matrix over a box."""
        vals = _box_variables(self.parameters, lo, hi, derivatives)
        try:
            return imatrix(self.system.state_matrix(vals))
        except ParameterError as exc:
            box = ", ".join(f"{n} in [{a:.6g}, {b:.6g}]" for n, a, b in zip(self.names, lo, hi))
            raise _Unbounded(
                "robust margin: an entry of the system's matrix divides by an expression "
                f"whose range contains 0 on the box {box} "
                f"(the system is unbounded there): {exc}"
            ) from None

    def recheck(self, row):
        """Poles of the member's python-control system."""
        member = self.system.at(dict(zip(self.names, (float(x) for x in row))))
        return ct.poles(member), "python-control poles of the member system"


def _loop(system, controller):
    """The loop a margin function analyses: a family's or an uncertain system's."""
    if isinstance(system, (_FamilyLoop, _SystemLoop)):
        return system
    if isinstance(system, Family):
        return _FamilyLoop(system, controller)
    if isinstance(system, USS):
        return _SystemLoop(system, controller)
    raise ParameterError(
        f"robust margin: expected a Family or an uncertain system (uncertainty.uss); "
        f"got {type(system).__name__}"
    )


def loop_region(loop, region: Region | None) -> Region:
    """``region`` (default: the open left half-plane) with the loop's default damping band
    where it leaves the band to the default: 0.5-10 Hz for the BDFT family's loop, every
    frequency for a user's own system."""
    return (region or Region()).with_default_band(loop.default_band_hz)
