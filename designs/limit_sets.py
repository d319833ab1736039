"""The limit map's sets of actuators and sensors: their names, their order, and which set a
compensator belongs to.

:func:`split_set` reads a set's name (``actuators/sensors``), :func:`set_contains` says
whether one set knows and acts at least as much as another, :func:`design_set` gives the
smallest set containing a compensator's signals and :func:`limit_coverage_of` a set's
coverage from a map's JSON. Small, shared by the map, its report and the designs' report.
"""

from __future__ import annotations

from designs.constants import ACTUATOR_SETS, ALL_SETS
from robust.errors import ParameterError

__all__ = ["split_set", "set_contains", "design_set", "limit_coverage_of"]


def split_set(name: str) -> tuple[str, str]:
    """``"actuators/sensors"`` -> ``(actuators, sensors)``, checked.

    Parameters
    ----------
    name : str
        A set name of :data:`ALL_SETS`.

    Raises
    ------
    robust.errors.ParameterError
        If it names no set.
    """
    if not isinstance(name, str) or name not in ALL_SETS:
        raise ParameterError(f"limit map: a set must be one of {list(ALL_SETS)}; got {name!r}")
    a, s_ = name.split("/")
    return a, s_


#: Information order of the sensor sets: each knows what the earlier ones know.
_INFORMATION = ("handle", "handle+cab", "full")


def set_contains(big: str, small: str) -> bool:
    """Whether every controller of set ``small`` is a controller of set ``big``.

    Its actuators are among ``big``'s, and its sensors tell no more than ``big``'s
    (``handle`` < ``handle+cab`` < ``full``).

    Parameters
    ----------
    big, small : str
        Sets of :data:`ALL_SETS`.
    """
    (a1, s1), (a2, s2) = split_set(big), split_set(small)
    acts = set(ACTUATOR_SETS[a2]) <= set(ACTUATOR_SETS[a1])
    return acts and _INFORMATION.index(s2) <= _INFORMATION.index(s1)


def design_set(controller) -> str | None:
    """The smallest set of the map that contains a compensator's actuators and sensors.

    Outputs ``f`` / ``r_corr`` give the actuators; inputs within ``x`` give ``handle``,
    within ``x, c`` give ``handle+cab``, any other measured signal (the cylinder position
    ``y``) ``full``.

    Parameters
    ----------
    controller : control.StateSpace or None
        A compensator in the loop's convention; ``None`` (no compensator) gives ``None``.

    Returns
    -------
    str or None
        A name of :data:`ALL_SETS`.
    """
    if controller is None:
        return None
    outs = set(controller.output_labels)
    ins = set(controller.input_labels)
    acts = {("f",): "force", ("r_corr",): "reference", ("f", "r_corr"): "force+reference"}.get(
        tuple(sorted(outs & {"f", "r_corr"}))
    )
    if acts is None:
        return None
    if ins <= {"x"}:
        sens = "handle"
    elif ins <= {"x", "c"}:
        sens = "handle+cab"
    else:
        sens = "full"
    return f"{acts}/{sens}"


def limit_coverage_of(sets_json: list, name: str, force_scale: float = 1.0):
    """The map's coverage for set ``name``, or for the smallest computed set containing it.

    Parameters
    ----------
    sets_json : list of dict
        :meth:`LimitMap.sets_json` (or the ``sets`` of ``bdft limit --json``).
    name : str
        A set of :data:`ALL_SETS`.
    force_scale : float
        The force multiple.

    Returns
    -------
    (str, dict) or None
        The set used and its entry; ``None`` when no computed set contains ``name``.
    """
    entries = [e for e in sets_json if e["force_scale"] == force_scale]
    inside = [e for e in entries if set_contains(e["name"], name)]
    if not inside:
        return None
    best = min(inside, key=lambda e: e["coverage"])
    return best["name"], best
