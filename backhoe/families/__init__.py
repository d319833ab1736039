"""Parametric families of the backhoe and its operator.

:mod:`.family` (the :class:`~backhoe.families.family.Family` and its members),
:mod:`.family_ranges` (the default ranges and their sources), :mod:`.batched` (many
members' matrices at once, from the blocks), :mod:`.loop` (the loop over any arithmetic:
the uncertain system :func:`~backhoe.families.loop.family_uss`, interval enclosures),
:mod:`.enclosure` (the family's loop as the robust margin sees it), :mod:`.valueset`
(zero exclusion on the open loop's value sets), :mod:`.validation` (batched validation),
:mod:`.sweeps` and :mod:`.files` (controllers, fitted components and user systems from
files). Import the public names from :mod:`backhoe`.
"""

# the family's margin loop and validation are registered with uncertainty.margin_loop and
# uncertainty.validate_family by these modules, imported whenever any family module is
from backhoe.families.enclosure import closed_loop_enclosure
from backhoe.families.validation import member_metrics

__all__ = ["closed_loop_enclosure", "member_metrics"]
