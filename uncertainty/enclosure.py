"""The loops the robust margin analyses, and the interval variables of a box.

The margin sees an uncertain system (:mod:`uncertainty.uss`, closed with a controller) or
a parametric family of a machine through one small interface, the *margin loop*:

* ``parameters`` and ``names``: the uncertain parameters
  (:class:`~uncertainty.parameters.UncertainParameter`) and their names, in the columns'
  order;
* ``matrices(rows)``: the closed-loop state matrices of members (rows of values), batched;
* ``enclosure(lo, hi, derivatives)``: an interval (or interval-gradient) matrix holding
  the state matrix of every member of a box, raising ``_Unbounded`` where a divisor's
  range holds 0;
* ``recheck(row)``: the poles of one member by an independent evaluation (or None);
* ``default_band_hz``: the damping band a region leaves to the default;

and where a route needs them: ``system``, the loop as an uncertain system, whose LFT the
mu route takes; ``prefers_mu``, whether ``method="auto"`` takes mu (a decay rate, damping
of every pole; False when absent); ``valueset_why_not(region)``, why the value-set route
does not apply ("" where it does; absent: it does not), and ``certify_valueset(...)``
where it does. ``tests/test_plugin_family.py`` registers a family of its own.

:func:`margin_loop` builds it, by single dispatch on the analysed object's type:
``_SystemLoop`` here evaluates an uncertain system's one state matrix; a machine's family
registers its own loop type (the BDFT family's is
:class:`backhoe.families.enclosure._FamilyLoop`, registered by that module), so this layer
knows no machine.

One concern apart from the search (:mod:`uncertainty.search`) and the certificates
(:mod:`uncertainty.boxcert`), which both take their loops from here; the loop objects are
sent to worker processes and stay importable at module level.
"""

from __future__ import annotations

import functools
from typing import Protocol

import control as ct
import numpy as np

from robust.analysis.intervals import Gradient, Interval, imatrix
from robust.errors import ModelStructureError, ParameterError
from uncertainty.region import EVERY_FREQUENCY_HZ, Region
from uncertainty.uss import USS

__all__ = ["MarginFamily", "margin_loop"]


class MarginFamily(Protocol):
    """A parametric family the margin functions take besides an uncertain system: a type
    registered with :func:`margin_loop`, whose loop has the interface of the module notes
    (the BDFT family, :class:`backhoe.Family`, is one)."""

    parameters: tuple


def box_variables(parameters, lo, hi, derivatives: bool) -> dict:
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
    #: ``method="auto"`` takes mu for an uncertain system's loop
    prefers_mu = True

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
        vals = box_variables(self.parameters, lo, hi, derivatives)
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

    def valueset_why_not(self, region) -> str:
        """Why the value-set route does not apply: it needs a family's open loop."""
        return "needs a family without a compensator"


@functools.singledispatch
def margin_loop(system, controller=None):
    """The loop a margin function analyses for ``system`` closed by ``controller``.

    A single-dispatch function (:func:`functools.singledispatch`): this layer registers
    the uncertain system (:class:`~uncertainty.uss.USS`, evaluated from its one state
    matrix); a machine's family registers its own loop type with
    ``margin_loop.register(FamilyType)`` (the BDFT family's is registered by
    :mod:`backhoe.families.enclosure`), so :func:`uncertainty.robust_margin` and its
    relatives take it without this layer knowing the machine. An object that already is a
    margin loop (``matrices`` and ``enclosure``) is returned as it is.

    Parameters
    ----------
    system : USS or a registered family
        What to analyse.
    controller : control.StateSpace, optional
        Compensator (the system's feedback path, or the family's loop convention).

    Raises
    ------
    ParameterError
        If nothing is registered for ``system``'s type.
    """
    if hasattr(system, "matrices") and hasattr(system, "enclosure"):
        return system
    raise ParameterError(
        "robust margin: expected an uncertain system (uncertainty.uss) or a family whose "
        f"type is registered with uncertainty.margin_loop; got {type(system).__name__}"
    )


@margin_loop.register
def _(system: USS, controller=None):
    return _SystemLoop(system, controller)


def loop_region(loop, region: Region | None) -> Region:
    """``region`` (default: the open left half-plane) with the loop's default damping band
    where it leaves the band to the default: the loop's own (0.5-10 Hz for the BDFT family's
    loop, every frequency for an uncertain system)."""
    return (region or Region()).with_default_band(loop.default_band_hz)
