"""The family's loop as the robust margin sees it, and interval enclosures of its
closed-loop state matrix over a box.

:func:`closed_loop_enclosure` encloses the state matrix of every member of a box of a
family's parameters in an interval matrix, by interval arithmetic through the blocks and the
interconnection of the Figure 5 junction table (midpoint-radius interval arithmetic, Rump
1999; with ``derivatives``, interval forward differentiation, Moore, Kearfott &
Cloud, *Introduction to Interval Analysis*, SIAM 2009: :mod:`robust.analysis.intervals`).

:class:`_FamilyLoop` is what :func:`uncertainty.margin_loop` gives for a
:class:`~backhoe.families.family.Family` (registered here): the family's loop through the
interface of :mod:`uncertainty.enclosure` (``matrices``, ``enclosure``, ``recheck``), with
the value-set route of :mod:`backhoe.families.valueset` besides. The package's
``__init__`` imports this module, so the registration is in place whenever a family is.
The objects are sent to worker processes and stay importable at module level.
"""

from __future__ import annotations

import control as ct
import numpy as np

from backhoe.analysis.loops import loop_poles
from backhoe.constants import DAMPING_BAND_HZ
from backhoe.families.batched import closed_loop_matrices
from backhoe.families.family import Family
from backhoe.families.loop import INTERVALS, LoopAssembly, family_uss, fixed_parameters
from backhoe.families.valueset import ValueSetLoop, certify_scale_valueset
from robust.analysis.intervals import Gradient, Interval
from robust.errors import BDFTError
from uncertainty.enclosure import box_variables, margin_loop
from uncertainty.uss import USS

__all__ = ["closed_loop_enclosure"]


def _param_intervals(
    family: Family, lo: np.ndarray, hi: np.ndarray, derivatives: bool, fixed: dict | None = None
) -> dict:
    """Every model parameter over the box: the varied ones as :func:`box_variables`, the
    others fixed (``fixed``: their point intervals, when the caller keeps them)."""
    if fixed is None:
        fixed = {n: Interval.point(v) for n, v in fixed_parameters(family).items()}
    out = dict(fixed)
    out.update(box_variables(family.parameters, lo, hi, derivatives))
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

    Interval arithmetic through the blocks of :func:`backhoe.families.batched.loop_blocks`
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
        # ``method="auto"`` takes mu for the loop closed by a compensator (the tighter there)
        self.prefers_mu = controller is not None
        self.parameters = tuple(family.parameters)
        self.names = tuple(family.names)
        self._asm = None
        self._system = None
        self._valueset = None

    @property
    def system(self) -> USS:
        """The loop as an uncertain system (:func:`backhoe.families.loop.family_uss`: the same
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

    def valueset_why_not(self, region) -> str:
        """Why zero exclusion on value sets does not apply ('' where it does): it needs the
        open loop (no compensator) of a family with the physical human, and certifies the
        open left half-plane only."""
        if self.controller is not None:
            return "needs a family without a compensator"
        return ValueSetLoop.why_not(self.family) or (
            "certifies the open left half-plane only"
            if region.decay_rate > 0 or region.min_damping > 0
            else ""
        )

    def certify_valueset(self, lo_t, hi_t, w_max: float, max_cells: int, probe=None):
        """:func:`backhoe.families.valueset.certify_scale_valueset` over the box ``lo_t ..
        hi_t`` (family coordinates) and ``[0, w_max]``, the open loop's factors built once."""
        if self._valueset is None:
            self._valueset = ValueSetLoop(self.family)
        return certify_scale_valueset(self._valueset, lo_t, hi_t, w_max, max_cells, probe)


@margin_loop.register
def _(family: Family, controller=None):
    # the BDFT family's loop, for uncertainty.robust_margin and its relatives
    return _FamilyLoop(family, controller)
