"""Seeded members whose operators and structures are those the tests measured before the
family varied the valve, each with a valve of its own."""

from __future__ import annotations

import numpy as np

from uncertainty import sample

#: Seed offset of the valves' own draw.
VALVE_SEED_OFFSET = 1000


def rows_with_valves(family, n: int, *, method: str, seed: int) -> np.ndarray:
    """``n`` member rows of ``family``: its other parameters drawn as a family without the
    valve's spread draws them (the same stream: ``sample`` of those columns, ``seed``), its
    ``valve.*`` parameters drawn apart (seed ``seed + VALVE_SEED_OFFSET``).

    Parameters
    ----------
    family : backhoe.Family
    n : int
        Members.
    method : str
        Sampling method of :func:`uncertainty.sample`.
    seed : int
        Seed of the other parameters' draw.

    Returns
    -------
    numpy.ndarray, shape (n, d)
        Columns in ``family.names`` order.
    """
    valves = [p for p in family.parameters if p.name.startswith("valve.")]
    others = [p for p in family.parameters if not p.name.startswith("valve.")]
    a = sample(others, n, method=method, seed=seed)
    b = sample(valves, n, method=method, seed=seed + VALVE_SEED_OFFSET)
    return np.column_stack([(b if q.startswith("valve.") else a).column(q) for q in family.names])
