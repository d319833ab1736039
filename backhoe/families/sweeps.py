"""Parameter sweeps across a family: workspace factor, human stiffness x damping, structure mode.

Each sweep fixes one or two quantities on a grid and, at every grid point,
validates the same base sample of the family's other parameters (common random
numbers, so differences between grid points are not sampling noise). It returns
a :class:`SweepResult`: the table behind the plots (one row per grid point) and
how it was made. The figures and the page are drawn by :mod:`reports.sweeps`;
the ``bdft sweep`` command writes them.

Every table has the columns ``fraction_stable``, ``max_real_pole`` (worst real part
over the members, 1/s), ``min_damping`` (smallest damping ratio in the BDFT band),
``n_unstable`` and ``nominal_max_real`` (largest real part with every other
parameter nominal, 1/s), after the swept quantities.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

import numpy as np

from backhoe.constants import DAMPING_BAND_HZ
from backhoe.families.batched import TASK_MEMBERS
from backhoe.families.family import Family
from backhoe.families.validation import member_metrics
from backhoe.model.blocks import parameter_name
from robust.checks import check_callable, check_int
from robust.engine import map_tasks, scheduler_address
from robust.errors import ParameterError
from uncertainty.sampling import sample
from uncertainty.validation import DEFAULT_CHUNK, STABILITY_THRESHOLD

__all__ = [
    "SWEEPS",
    "SweepResult",
    "workspace_sweep",
    "frequency_damping_sweep",
    "structure_frequency_sweep",
]

#: Sweep names of ``bdft sweep``.
SWEEPS = ("workspace", "frequency-damping", "structure-frequency")


@dataclasses.dataclass(frozen=True)
class SweepResult:
    """The table of a sweep and how it was made.

    Attributes
    ----------
    name : str
        One of :data:`SWEEPS`.
    title, description : str
        For the report page.
    columns : dict of str -> ndarray
        The table: equal-length columns, one row per grid point.
    settings : dict
        Family name, human variant, members per grid point, sampling method and
        seed, stability threshold, BDFT band.
    grid_shape : tuple of int
        Shape of the grid (a map has two axes).
    """

    name: str
    title: str
    description: str
    columns: dict
    settings: dict
    grid_shape: tuple

    def csv(self) -> str:
        """The table as CSV text (header row, ``%.10g`` numbers)."""
        keys = list(self.columns)
        lines = [",".join(keys)]
        n = len(next(iter(self.columns.values())))
        for i in range(n):
            lines.append(",".join(f"{self.columns[k][i]:.10g}" for k in keys))
        return "\n".join(lines) + "\n"


def _metrics_on_grid(
    family: Family,
    grid_values: list[dict],
    members: int,
    *,
    method: str,
    seed: int,
    chunk: int,
    progress: Callable[[int], None] | None,
    band_hz=DAMPING_BAND_HZ,
    check_bounds: bool = True,
    jobs: int = 1,
    scheduler: str | None = None,
):
    """Validate the base sample at every grid point.

    Returns the per-point fraction stable, worst real part and minimum damping, and
    the settings. With ``check_bounds=False`` the grid values may leave the family's
    bounds (they must stay physical). The grid points are independent tasks: on a Dask
    scheduler, or in ``jobs`` threads of this process when the sweep holds more than
    :data:`~backhoe.families.batched.TASK_MEMBERS` members (below that, the grid points are
    too small to gain); every engine gives the same bits.
    """
    jobs = check_int("sweep: jobs", jobs, low=1)
    fixed = set().union(*(g.keys() for g in grid_values))
    base_params = [p for p in family.parameters if p.name not in fixed]
    S = sample(base_params, members, method=method, seed=seed)
    names = family.names
    M = len(S)
    rows = {
        "fraction_stable": [],
        "max_real_pole": [],
        "min_damping": [],
        "n_unstable": [],
        "nominal_max_real": [],
    }
    nominal = dict(zip(names, family.nominal_values()))
    tasks = []
    for g in grid_values:
        vals = np.empty((M + 1, len(names)))
        for j, name in enumerate(names):
            vals[:M, j] = g[name] if name in g else S.column(name)
            vals[M, j] = g.get(name, nominal[name])  # the other parameters at their nominal values
        tasks.append((g.get("__family__", family), vals))
    point = functools.partial(_point_metrics, chunk, band_hz, check_bounds)
    if scheduler_address(scheduler) is None and (jobs == 1 or len(tasks) * (M + 1) <= TASK_MEMBERS):
        results = [point(t, progress) for t in tasks]
    else:
        done = (lambda i: progress(M + 1)) if progress is not None else None
        results = map_tasks(
            point, tasks, jobs=jobs, scheduler=scheduler, progress=done, threads=True
        )
    for mr_all, md_all in results:
        mr, md = mr_all[:M], md_all[:M]
        rows["nominal_max_real"].append(float(mr_all[M]))
        stable = mr < STABILITY_THRESHOLD
        rows["fraction_stable"].append(float(np.mean(stable)))
        rows["max_real_pole"].append(float(mr.max()))
        rows["min_damping"].append(float(md.min()))
        rows["n_unstable"].append(int(M - stable.sum()))
    settings = {
        "family": family.name,
        "human": family.human,
        "members_per_point": M,
        "method": S.method,
        "seed": S.seed,
        "varied_at_each_point": list(S.names),
        "stability_threshold": STABILITY_THRESHOLD,
        "band_hz": list(band_hz),
        "k_psf": family.k_psf,
    }
    return {k: np.asarray(v) for k, v in rows.items()}, settings


def _point_metrics(chunk, band_hz, check_bounds, task, progress=None):
    """Per-member largest real part and smallest in-band damping at one grid point."""
    fam, vals = task
    mr, md, _ = member_metrics(
        fam, vals, chunk=chunk, band_hz=band_hz, progress=progress, check_bounds=check_bounds
    )
    return mr, md


def _check_members(members, family=None, progress=None):
    if isinstance(members, bool) or not isinstance(members, (int, np.integer)) or members < 1:
        raise ParameterError(f"members must be a positive integer; got {members!r}")
    if not isinstance(family, Family):
        raise ParameterError(f"family must be a backhoe.Family; got {type(family).__name__}")
    check_callable("progress", progress)


def workspace_sweep(
    family: Family,
    *,
    factors=None,
    members: int = 2000,
    method: str = "lhs",
    seed: int = 0,
    chunk: int = DEFAULT_CHUNK,
    progress=None,
    jobs: int = 1,
    scheduler: str | None = None,
) -> SweepResult:
    """Fraction stable and worst real part versus workspace factor (``K_PSF = K_PSF0 / factor``).

    Parameters
    ----------
    family : Family
        Family at the reference ``K_PSF`` (factor 1).
    factors : array_like, optional
        Workspace factors (default 1 to 10 in steps of 0.5; the paper's study is 2-10).
    members : int
        Family members validated at each factor (the same members at every factor).
    method, seed : str, int
        Sampling of the members: method of :func:`uncertainty.sample` and seed.
    chunk : int
        Members per batch.
    progress : callable, optional
        Called with the number of members finished.
    jobs : int
        Threads of this process for the grid points (used above
        :data:`~backhoe.families.batched.TASK_MEMBERS` members in all; the compiled loops release
        the GIL).
    scheduler : str, optional
        A Dask scheduler's address (or ``$DASK_SCHEDULER_ADDRESS``): the grid points run on
        its workers (:func:`robust.engine.map_tasks`); the same result on every engine.

    Returns
    -------
    SweepResult
        Named ``"workspace"``; columns ``workspace_factor`` and ``k_psf``, then the
        metrics.
    """
    _check_members(members, family, progress)
    f = np.asarray(np.arange(1.0, 10.01, 0.5) if factors is None else factors, float)
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ParameterError(
            f"factors must be a non-empty 1-D array of positive numbers; got {factors!r}"
        )
    grid = [{"__family__": family.with_workspace_factor(x)} for x in f]
    rows, settings = _metrics_on_grid(
        family,
        grid,
        members,
        method=method,
        seed=seed,
        chunk=chunk,
        progress=progress,
        jobs=jobs,
        scheduler=scheduler,
    )
    cols = {"workspace_factor": f, "k_psf": family.k_psf / f, **rows}
    return SweepResult(
        name="workspace",
        title=f"Workspace factor sweep ({family.human} human)",
        description=(
            "Handle workspace multiplied by each factor (K_PSF divided by it), the same family "
            "members at every factor. The paper's study (C2, C3) is factors 2 to 10 for the "
            "nominal loop."
        ),
        columns=cols,
        settings=settings,
        grid_shape=(len(f),),
    )


def frequency_damping_sweep(
    family: Family,
    *,
    pair: str = "arm",
    n_f: int = 12,
    n_z: int = 12,
    members: int = 200,
    method: str = "lhs",
    seed: int = 0,
    chunk: int = DEFAULT_CHUNK,
    progress=None,
    jobs: int = 1,
    scheduler: str | None = None,
) -> SweepResult:
    """Map of the worst real part over a grid of one human natural frequency x damping ratio.

    Parameters
    ----------
    family : Family
        A physical-human family varying the pair's natural frequency and damping ratio.
    pair : {"arm", "trunk"}
        Which part of the operator to sweep: the arm endpoint or the trunk on the seat.
    n_f, n_z : int
        Grid points over the parameters' ranges (frequency log-spaced, damping ratio
        linear), at least 2 each.
    members : int
        Members (the other parameters) validated at each grid point.
    method, seed : str, int
        Sampling of the members: method of :func:`uncertainty.sample` and seed.
    chunk : int
        Members per batch.
    progress : callable, optional
        Called with the number of members finished.
    jobs : int
        Threads of this process for the grid points (used above
        :data:`~backhoe.families.batched.TASK_MEMBERS` members in all; the compiled loops release
        the GIL).
    scheduler : str, optional
        A Dask scheduler's address (or ``$DASK_SCHEDULER_ADDRESS``): the grid points run on
        its workers (:func:`robust.engine.map_tasks`); the same result on every engine.

    Returns
    -------
    SweepResult
        Named ``"frequency-damping"``, grid shape ``(n_f, n_z)``; columns
        the pair's natural frequency (Hz) and damping ratio (their parameter names), then the
        metrics;
        ``settings["nominal"]`` holds the two nominal values and ``settings["units"]``
        their units.
    """
    _check_members(members, family, progress)
    if family.human != "physical":
        raise ParameterError(
            "the frequency x damping sweep needs the physical human; "
            f"the family uses {family.human!r}"
        )
    if pair not in ("arm", "trunk"):
        raise ParameterError(f"pair must be 'arm' or 'trunk'; got {pair!r}")
    for n in (n_f, n_z):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
            raise ParameterError(f"n_f and n_z must be integers >= 2; got {n!r}")
    pf, pz = (
        family.parameter(parameter_name("human", f"f_{pair}_hz")),
        family.parameter(parameter_name("human", f"zeta_{pair}")),
    )
    fs = np.geomspace(pf.low, pf.high, n_f)
    zs = np.linspace(pz.low, pz.high, n_z)
    F, Z = np.meshgrid(fs, zs, indexing="ij")
    grid = [{pf.name: f, pz.name: z} for f, z in zip(F.ravel(), Z.ravel())]
    rows, settings = _metrics_on_grid(
        family,
        grid,
        members,
        method=method,
        seed=seed,
        chunk=chunk,
        progress=progress,
        jobs=jobs,
        scheduler=scheduler,
    )
    settings["pair"] = pair
    settings["nominal"] = {pf.name: pf.nominal, pz.name: pz.nominal}
    settings["units"] = {pf.name: pf.units, pz.name: pz.units}
    cols = {pf.name: F.ravel(), pz.name: Z.ravel(), **rows}
    return SweepResult(
        name="frequency-damping",
        title=f"Human {pair} natural frequency x damping ratio ({family.human} human)",
        description=(
            "Worst (largest) real part of the closed-loop poles over "
            f"{settings['members_per_point']} members of the family's other parameters, at each "
            f"{pf.name} x {pz.name} grid point (over the family's published ranges)."
        ),
        columns=cols,
        settings=settings,
        grid_shape=(n_f, n_z),
    )


def structure_frequency_sweep(
    family: Family,
    *,
    scales=None,
    members: int = 2000,
    method: str = "lhs",
    seed: int = 0,
    chunk: int = DEFAULT_CHUNK,
    progress=None,
    jobs: int = 1,
    scheduler: str | None = None,
) -> SweepResult:
    """Fraction stable, worst real part and minimum damping versus the structure's frequencies.

    Both modes are scaled together, ``f_i = scale * f_i(nominal)``, from the
    family's lowest first structure frequency (a machine on its tyres) to the stilts values.

    Parameters
    ----------
    family : Family
        A family varying both structure frequencies.
    scales : array_like, optional
        Scale factors of both natural frequencies (default: 13 points from the
        family's lowest first structure frequency over the nominal, to 1). Scales may take the
        frequencies beyond the family's bounds (the sweep asks for them explicitly);
        they must be positive.
    members : int
        Members (the other parameters) validated at each frequency.
    method, seed : str, int
        Sampling of the members: method of :func:`uncertainty.sample` and seed.
    chunk : int
        Members per batch.
    progress : callable, optional
        Called with the number of members finished.
    jobs : int
        Threads of this process for the grid points (used above
        :data:`~backhoe.families.batched.TASK_MEMBERS` members in all; the compiled loops release
        the GIL).
    scheduler : str, optional
        A Dask scheduler's address (or ``$DASK_SCHEDULER_ADDRESS``): the grid points run on
        its workers (:func:`robust.engine.map_tasks`); the same result on every engine.

    Returns
    -------
    SweepResult
        Named ``"structure-frequency"``; columns ``scale``, ``f1_hz`` and ``f2_hz``
        (Hz), then the metrics.
    """
    _check_members(members, family, progress)
    f1n, f2n = family.struct.f1_hz, family.struct.f2_hz
    if scales is None:
        lo = (
            family.parameter(parameter_name("structure", "f1_hz")).low / f1n
            if parameter_name("structure", "f1_hz") in family.names
            else 0.4
        )
        scales = np.linspace(lo, 1.0, 13)
    s = np.asarray(scales, float)
    if s.ndim != 1 or s.size == 0 or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ParameterError(
            f"scales must be a non-empty 1-D array of positive numbers; got {scales!r}"
        )
    fixed = [
        n
        for n in (parameter_name("structure", "f1_hz"), parameter_name("structure", "f2_hz"))
        if n in family.names
    ]
    if len(fixed) != 2:
        raise ParameterError(
            f"the structure-frequency sweep needs {parameter_name('structure', 'f1_hz')} and "
            f"{parameter_name('structure', 'f2_hz')} in the family"
        )
    grid = [
        {
            parameter_name("structure", "f1_hz"): x * f1n,
            parameter_name("structure", "f2_hz"): x * f2n,
        }
        for x in s
    ]
    rows, settings = _metrics_on_grid(
        family,
        grid,
        members,
        method=method,
        seed=seed,
        chunk=chunk,
        progress=progress,
        check_bounds=False,
        jobs=jobs,
        scheduler=scheduler,
    )
    cols = {"scale": s, "f1_hz": s * f1n, "f2_hz": s * f2n, **rows}
    return SweepResult(
        name="structure-frequency",
        title=f"Structure natural frequency sweep ({family.human} human)",
        description=(
            "Both structure modes scaled together from a machine on its tyres up to the paper's "
            "stilts values (6.3 and 6.5 Hz); the same members of the family's other parameters at "
            "each frequency."
        ),
        columns=cols,
        settings=settings,
        grid_shape=(len(s),),
    )
