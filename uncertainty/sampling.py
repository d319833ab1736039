"""Samples of a parameter box: grid, Monte Carlo, Latin hypercube and box vertices.

Every sampler works in the unit hypercube and maps to values through each
parameter's inverse distribution function, so the distribution (uniform,
log-uniform, truncated normal) is honoured by all of them. Every
:class:`SampleSet` records the method and the seed; a seed of ``None`` is
replaced by fresh entropy, which is then recorded, so every sample set can be
re-drawn exactly.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence

import numpy as np
from scipy.stats import qmc

from robust.errors import ParameterError
from uncertainty.parameters import UncertainParameter

__all__ = ["METHODS", "SampleSet", "sample", "MAX_VERTEX_DIM"]

#: Sampling methods.
METHODS = ("mc", "lhs", "grid", "vertices")
#: Largest dimension for which all box vertices are enumerated (2**20 vertices).
MAX_VERTEX_DIM = 20


@dataclasses.dataclass(frozen=True)
class SampleSet:
    """Parameter values of the members of a family.

    Attributes
    ----------
    names : tuple of str
        Parameter names, one per column.
    values : ndarray, shape (N, d)
        One member per row (read-only).
    method : str
        One of :data:`METHODS`.
    seed : int
        Seed of the random generator (also recorded for ``grid``, which does not use it).
    requested : int
        Number of members asked for (``grid`` and ``vertices`` may give fewer; see :func:`sample`).
    """

    names: tuple[str, ...]
    values: np.ndarray
    method: str
    seed: int
    requested: int

    def __post_init__(self):
        v = np.array(self.values, dtype=float)
        if v.ndim != 2 or v.shape[1] != len(self.names):
            raise ParameterError(
                f"SampleSet.values must have shape (N, {len(self.names)}); got {v.shape}"
            )
        v.setflags(write=False)
        object.__setattr__(self, "values", v)
        object.__setattr__(self, "names", tuple(self.names))

    def __len__(self) -> int:
        return self.values.shape[0]

    def column(self, name: str) -> np.ndarray:
        """Values of parameter ``name``, shape (N,)."""
        try:
            return self.values[:, self.names.index(name)]
        except ValueError:
            raise ParameterError(
                f"no parameter {name!r} in the sample set; have {list(self.names)}"
            ) from None

    def row(self, i: int) -> dict[str, float]:
        """Parameters of member ``i`` as ``{name: value}``."""
        return {n: float(x) for n, x in zip(self.names, self.values[i])}

    def slice(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start:stop`` (a view), shape (stop - start, d)."""
        return self.values[start:stop]


def _resolve_seed(seed) -> int:
    if seed is None:
        return int(np.random.SeedSequence().entropy % (2**63))
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"seed must be a non-negative integer or None; got {seed!r}")
    return int(seed)


def _unit_samples(method: str, n: int, d: int, rng: np.random.Generator) -> np.ndarray:
    if method == "mc":
        return rng.random((n, d))
    if method == "lhs":
        return qmc.LatinHypercube(d=d, seed=rng).random(n)
    if method == "grid":
        k = max(2, int(math.floor(n ** (1.0 / d) + 1e-9)))
        axes = [np.linspace(0.0, 1.0, k)] * d
        mesh = np.meshgrid(*axes, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=1)
    # vertices
    if d > MAX_VERTEX_DIM:
        raise ParameterError(
            f"vertices: dimension d={d} gives 2**{d} vertices; at most d={MAX_VERTEX_DIM} supported"
        )
    corners = np.array(list(itertools.product((0.0, 1.0), repeat=d)))
    if n < len(corners):
        corners = corners[np.sort(rng.choice(len(corners), size=n, replace=False))]
    return corners


def sample(
    parameters: Sequence[UncertainParameter], n: int, *, method: str = "lhs", seed: int | None = 0
) -> SampleSet:
    """Draw ``n`` members of the box spanned by ``parameters``.

    Parameters
    ----------
    parameters : sequence of UncertainParameter
        The uncertain parameters (names must be unique).
    n : int
        Number of members, >= 1.
    method : {"mc", "lhs", "grid", "vertices"}
        ``mc``: independent draws. ``lhs``: Latin hypercube
        (:class:`scipy.stats.qmc.LatinHypercube`). ``grid``: ``k`` evenly spaced
        quantiles per parameter, bounds included, with ``k = max(2, floor(n**(1/d)))``,
        so ``k**d`` members (fewer than ``n`` unless ``n`` is a perfect power; at
        least ``2**d``). ``vertices``: the ``2**d`` corners of the box, or a random
        subset of ``n`` of them when ``n < 2**d``.
    seed : int or None
        Seed of :func:`numpy.random.default_rng`; ``None`` draws fresh entropy and
        records it.

    Returns
    -------
    SampleSet
    """
    params = list(parameters)
    if not params:
        raise ParameterError("sample: need at least one uncertain parameter; got none")
    names = [p.name for p in params]
    if len(set(names)) != len(names):
        raise ParameterError(f"sample: parameter names must be unique; got {names}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"sample: n must be a positive integer; got {n!r}")
    if method not in METHODS:
        raise ParameterError(f"sample: method must be one of {METHODS}; got {method!r}")
    seed = _resolve_seed(seed)
    rng = np.random.default_rng(seed)
    u = _unit_samples(method, int(n), len(params), rng)
    values = np.column_stack([p.ppf(u[:, j]) for j, p in enumerate(params)])
    return SampleSet(names=tuple(names), values=values, method=method, seed=seed, requested=int(n))
