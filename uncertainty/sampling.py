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
import math
from collections.abc import Iterable, Mapping

import numpy as np
from scipy.stats import qmc

from robust.errors import ParameterError
from uncertainty.parameters import UncertainParameter

__all__ = ["METHODS", "SampleSet", "sample", "MAX_VERTEX_DIM", "MAX_SAMPLE_BYTES", "max_members"]

#: Sampling methods.
METHODS = ("mc", "lhs", "grid", "vertices")
#: Largest dimension for which all box vertices are enumerated (2**20 vertices).
MAX_VERTEX_DIM = 20
#: Largest sample :func:`sample` draws, in bytes of member values (``members * d * 8``):
#: 2 GiB, about 24 million members of the 11-parameter physical family (drawing needs
#: about four times this at its peak). A larger request is refused before anything is
#: allocated (a hard backstop: ``bdft`` applies its own, smaller memory budget first);
#: validate a larger family in several samples with different seeds.
MAX_SAMPLE_BYTES = 2**31


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


def max_members(d: int) -> int:
    """Most members of ``d`` parameters one :func:`sample` call draws (:data:`MAX_SAMPLE_BYTES`).

    Parameters
    ----------
    d : int
        Number of uncertain parameters, >= 1.
    """
    return MAX_SAMPLE_BYTES // (8 * max(1, int(d)))


def _grid_points(n: int, d: int) -> int:
    return max(2, int(math.floor(n ** (1.0 / d) + 1e-9)))


def _members_drawn(method: str, n: int, d: int) -> int:
    """How many members ``method`` gives for a request of ``n`` (before drawing anything)."""
    if method == "grid":
        return _grid_points(n, d) ** d
    if method == "vertices":
        return n if d > MAX_VERTEX_DIM else min(n, 2**d)
    return n


def _unit_samples(method: str, n: int, d: int, rng: np.random.Generator) -> np.ndarray:
    if method == "mc":
        return rng.random((n, d))
    if method == "lhs":
        return qmc.LatinHypercube(d=d, seed=rng).random(n)
    if method == "grid":
        k = _grid_points(n, d)
        axes = [np.linspace(0.0, 1.0, k)] * d
        mesh = np.meshgrid(*axes, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=1)
    # vertices
    if d > MAX_VERTEX_DIM:
        raise ParameterError(
            f"vertices: dimension d={d} gives 2**{d} vertices; at most d={MAX_VERTEX_DIM} supported"
        )
    # the rows of itertools.product((0, 1), repeat=d), built without Python tuples: bit
    # d-1-j of the row index is coordinate j
    idx = np.arange(2**d, dtype=np.int64)
    corners = ((idx[:, None] >> np.arange(d - 1, -1, -1)) & 1).astype(float)
    if n < len(corners):
        corners = corners[np.sort(rng.choice(len(corners), size=n, replace=False))]
    return corners


def sample(
    parameters: Iterable[UncertainParameter], n: int, *, method: str = "lhs", seed: int | None = 0
) -> SampleSet:
    """Draw ``n`` members of the box spanned by ``parameters``.

    Parameters
    ----------
    parameters : sequence of UncertainParameter, uss or Family
        The uncertain parameters (names must be unique): a sequence or any iterable of them
        (``dict.values()`` too), or an uncertain system (:func:`uncertainty.uss`) or a
        family, whose parameters are taken in their order.
    n : int
        Number of members, >= 1. A request whose sample would exceed
        :data:`MAX_SAMPLE_BYTES` (``members * d * 8`` bytes; see :func:`max_members`) is
        refused before anything is allocated.
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

    Raises
    ------
    ParameterError
        If ``parameters`` are not unique :class:`UncertainParameter`, ``n`` is not a
        positive integer or asks for more than :data:`MAX_SAMPLE_BYTES` of members,
        ``method`` is unknown or ``seed`` is not a non-negative integer or None.
    """
    # an uncertain system or a family gives its own parameters; a mapping its values
    source = getattr(parameters, "parameters", parameters)
    if isinstance(source, Mapping):
        source = source.values()
    if isinstance(source, (str, bytes, UncertainParameter)) or not isinstance(source, Iterable):
        raise ParameterError(
            "sample: parameters must be a sequence of UncertainParameter (or any iterable of "
            f"them, a uss or a family); got {type(parameters).__name__}"
        )
    params = list(source)
    if not params:
        raise ParameterError("sample: need at least one uncertain parameter; got none")
    for p in params:
        if not isinstance(p, UncertainParameter):
            raise ParameterError(
                f"sample: parameters must be UncertainParameter; got {type(p).__name__}"
            )
    names = [p.name for p in params]
    if len(set(names)) != len(names):
        raise ParameterError(f"sample: parameter names must be unique; got {names}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"sample: n must be a positive integer; got {n!r}")
    if method not in METHODS:
        raise ParameterError(f"sample: method must be one of {METHODS}; got {method!r}")
    d = len(params)
    count = _members_drawn(method, int(n), d)
    if count > max_members(d):
        what = (
            f"{count} members ({_grid_points(int(n), d)}**{d} grid points)"
            if (method == "grid")
            else f"{count} members"
        )
        raise ParameterError(
            f"sample: n={n!r} asks for {what} of {d} parameters, {count * d * 8 / 2**20:.4g} "
            f"MiB; at most {max_members(d)} members ({MAX_SAMPLE_BYTES // 2**20} MiB, "
            "MAX_SAMPLE_BYTES) are drawn at once; validate in several samples with different "
            "seeds"
        )
    seed = _resolve_seed(seed)
    rng = np.random.default_rng(seed)
    # one parameter's quantiles contiguous in memory (its column of u is strided)
    u = np.ascontiguousarray(_unit_samples(method, int(n), d, rng).T)
    values = np.empty((u.shape[1], d))
    for j, p in enumerate(params):
        values[:, j] = p.ppf(u[j])
    return SampleSet(names=tuple(names), values=values, method=method, seed=seed, requested=int(n))
