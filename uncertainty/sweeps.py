"""Parameter sweeps across a family: workspace factor, human stiffness x damping, structure frequency.

Each sweep fixes one or two quantities on a grid and, at every grid point,
validates the same base sample of the family's other parameters (common random
numbers, so differences between grid points are not sampling noise). It returns
a :class:`SweepResult`: the table behind the plots (one row per grid point) and
functions that draw the figures. Library code returns matplotlib figures; the
``bdft sweep`` command saves them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from robust.errors import ParameterError
from uncertainty.batched import BDFT_BAND_HZ, DEFAULT_CHUNK, STABILITY_THRESHOLD, member_metrics
from uncertainty.family import Family
from uncertainty.sampling import sample

__all__ = [
    "SWEEPS",
    "SweepResult",
    "workspace_sweep",
    "stiffness_damping_sweep",
    "structure_frequency_sweep",
]

#: Sweep names of ``bdft sweep``.
SWEEPS = ("workspace", "stiffness-damping", "structure-frequency")


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

    def figures(self) -> list:
        """``[(name, matplotlib Figure, caption), ...]`` for the sweep."""
        return _FIGURES[self.name](self)


def _metrics_on_grid(
    family: Family,
    grid_values: list[dict],
    members: int,
    *,
    method: str,
    seed: int,
    chunk: int,
    progress: Callable[[int], None] | None,
    band_hz=BDFT_BAND_HZ,
):
    """Validate the base sample at every grid point; per-point fraction stable, worst real part, min damping."""
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
    for g in grid_values:
        fam = g.get("__family__", family)
        vals = np.empty((M + 1, len(names)))
        for j, name in enumerate(names):
            vals[:M, j] = g[name] if name in g else S.column(name)
            vals[M, j] = g.get(name, nominal[name])  # the other parameters at their nominal values
        mr_all, md_all, _ = member_metrics(
            fam, vals, chunk=chunk, band_hz=band_hz, progress=progress
        )
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


def _check_members(members):
    if isinstance(members, bool) or not isinstance(members, (int, np.integer)) or members < 1:
        raise ParameterError(f"members must be a positive integer; got {members!r}")


def workspace_sweep(
    family: Family,
    *,
    factors=None,
    members: int = 2000,
    method: str = "lhs",
    seed: int = 0,
    chunk: int = DEFAULT_CHUNK,
    progress=None,
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
        Sampling of the members.
    chunk : int
        Members per batch.
    progress : callable, optional
        Called with the number of members finished.
    """
    _check_members(members)
    f = np.asarray(np.arange(1.0, 10.01, 0.5) if factors is None else factors, float)
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ParameterError(
            f"factors must be a non-empty 1-D array of positive numbers; got {factors!r}"
        )
    grid = [{"__family__": family.with_workspace_factor(x)} for x in f]
    rows, settings = _metrics_on_grid(
        family, grid, members, method=method, seed=seed, chunk=chunk, progress=progress
    )
    cols = {"workspace_factor": f, "k_psf": family.k_psf / f, **rows}
    return SweepResult(
        name="workspace",
        title=f"Workspace factor sweep ({family.human} human)",
        description=(
            "Handle workspace multiplied by each factor (K_PSF divided by it), the same family members at "
            "every factor. The paper's study (C2, C3) is factors 2 to 10 for the nominal loop."
        ),
        columns=cols,
        settings=settings,
        grid_shape=(len(f),),
    )


def stiffness_damping_sweep(
    family: Family,
    *,
    pair: str = "arm",
    n_k: int = 12,
    n_c: int = 12,
    members: int = 200,
    method: str = "lhs",
    seed: int = 0,
    chunk: int = DEFAULT_CHUNK,
    progress=None,
) -> SweepResult:
    """Map of the worst real part over a grid of one human stiffness x damping.

    Parameters
    ----------
    family : Family
        A physical-human family containing ``human.k_<pair>`` and ``human.c_<pair>``.
    pair : {"arm", "trunk"}
        Which spring-damper of the chain to sweep.
    n_k, n_c : int
        Grid points (log-spaced over the parameters' ranges).
    members : int
        Members (the other parameters) validated at each grid point.
    """
    _check_members(members)
    if family.human != "physical":
        raise ParameterError(
            f"the stiffness x damping sweep needs the physical human; the family uses {family.human!r}"
        )
    if pair not in ("arm", "trunk"):
        raise ParameterError(f"pair must be 'arm' or 'trunk'; got {pair!r}")
    for n in (n_k, n_c):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
            raise ParameterError(f"n_k and n_c must be integers >= 2; got {n!r}")
    pk, pc = family.parameter(f"human.k_{pair}"), family.parameter(f"human.c_{pair}")
    ks = np.geomspace(pk.low, pk.high, n_k)
    cs = np.geomspace(pc.low, pc.high, n_c)
    K, C = np.meshgrid(ks, cs, indexing="ij")
    grid = [{pk.name: k, pc.name: c} for k, c in zip(K.ravel(), C.ravel())]
    rows, settings = _metrics_on_grid(
        family, grid, members, method=method, seed=seed, chunk=chunk, progress=progress
    )
    settings["pair"] = pair
    settings["nominal"] = {pk.name: pk.nominal, pc.name: pc.nominal}
    cols = {pk.name: K.ravel(), pc.name: C.ravel(), **rows}
    return SweepResult(
        name="stiffness-damping",
        title=f"Human {pair} stiffness x damping ({family.human} human)",
        description=(
            f"Worst (largest) real part of the closed-loop poles over {settings['members_per_point']} members of "
            f"the family's other parameters, at each {pk.name} x {pc.name} grid point (log-spaced over the "
            "family's order-of-magnitude ranges)."
        ),
        columns=cols,
        settings=settings,
        grid_shape=(n_k, n_c),
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
) -> SweepResult:
    """Fraction stable, worst real part and minimum damping versus the structure's natural frequencies.

    Both modes are scaled together, ``f_i = scale * f_i(nominal)``, from the
    family's lowest ``struct.f1_hz`` (a machine on its tyres) to the stilts values.
    """
    _check_members(members)
    f1n, f2n = family.struct.f1_hz, family.struct.f2_hz
    if scales is None:
        lo = family.parameter("struct.f1_hz").low / f1n if "struct.f1_hz" in family.names else 0.4
        scales = np.linspace(lo, 1.0, 13)
    s = np.asarray(scales, float)
    if s.ndim != 1 or s.size == 0 or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ParameterError(
            f"scales must be a non-empty 1-D array of positive numbers; got {scales!r}"
        )
    fixed = [n for n in ("struct.f1_hz", "struct.f2_hz") if n in family.names]
    if len(fixed) != 2:
        raise ParameterError(
            "the structure-frequency sweep needs struct.f1_hz and struct.f2_hz in the family"
        )
    grid = [{"struct.f1_hz": x * f1n, "struct.f2_hz": x * f2n} for x in s]
    rows, settings = _metrics_on_grid(
        family, grid, members, method=method, seed=seed, chunk=chunk, progress=progress
    )
    cols = {"scale": s, "f1_hz": s * f1n, "f2_hz": s * f2n, **rows}
    return SweepResult(
        name="structure-frequency",
        title=f"Structure natural frequency sweep ({family.human} human)",
        description=(
            "Both structure modes scaled together from a machine on its tyres up to the paper's stilts values "
            "(6.3 and 6.5 Hz); the same members of the family's other parameters at each frequency."
        ),
        columns=cols,
        settings=settings,
        grid_shape=(len(s),),
    )


# -- figures ----------------------------------------------------------------------------------
def _figure(nrows=1, ncols=1, size=(7.0, 4.5)):
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, constrained_layout=True)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def _line_figures(res: SweepResult, xkey: str, xlabel: str):
    x = res.columns[xkey]
    fig, ax = _figure(2, 1, (7.0, 6.0))
    a, b = ax[0, 0], ax[1, 0]
    a.plot(x, res.columns["fraction_stable"], "o-")
    a.set_ylabel("fraction stable")
    a.set_ylim(-0.02, 1.02)
    a.grid(True, alpha=0.3)
    a.set_title(res.title)
    b.plot(x, res.columns["max_real_pole"], "o-", color="C3")
    b.axhline(0.0, color="k", lw=0.8)
    b.set_ylabel("worst real part of a pole [1/s]")
    b.set_xlabel(xlabel)
    b.grid(True, alpha=0.3)
    fig2, ax2 = _figure(1, 1, (7.0, 3.5))
    md = np.where(np.isfinite(res.columns["min_damping"]), res.columns["min_damping"], np.nan)
    ax2[0, 0].plot(x, md, "o-", color="C2")
    ax2[0, 0].axhline(0.0, color="k", lw=0.8)
    ax2[0, 0].set_xlabel(xlabel)
    ax2[0, 0].set_ylabel("minimum damping ratio")
    ax2[0, 0].set_title(
        f"Minimum damping of poles in {res.settings['band_hz'][0]:g}-{res.settings['band_hz'][1]:g} Hz"
    )
    ax2[0, 0].grid(True, alpha=0.3)
    n = res.settings["members_per_point"]
    return [
        (
            "stability",
            fig,
            f"Fraction of the {n} members stable and the worst real part, versus {xlabel}.",
        ),
        (
            "damping",
            fig2,
            f"Minimum damping ratio of the poles in the BDFT band over the {n} members.",
        ),
    ]


def _map_figures(res: SweepResult):
    kname, cname = list(res.columns)[:2]
    nk, nc = res.grid_shape
    K = res.columns[kname].reshape(nk, nc)
    C = res.columns[cname].reshape(nk, nc)
    Z = res.columns["max_real_pole"].reshape(nk, nc)
    fig, ax = _figure(1, 1, (7.0, 5.5))
    a = ax[0, 0]
    lim = float(np.max(np.abs(Z))) or 1.0
    mesh = a.pcolormesh(K, C, Z, shading="nearest", cmap="RdBu_r", vmin=-lim, vmax=lim)
    if Z.min() < 0.0 < Z.max():
        a.contour(K, C, Z, levels=[0.0], colors="k", linewidths=1.2)
    nom = res.settings["nominal"]
    a.plot(nom[kname], nom[cname], "k*", ms=12, label="nominal (fit to Eqn 5)")
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlabel(f"{kname} [N/m]")
    a.set_ylabel(f"{cname} [N s/m]")
    a.set_title(res.title)
    a.legend(loc="upper right")
    fig.colorbar(mesh, ax=a, label="worst real part of a pole [1/s] (black: 0)")
    fig2, ax2 = _figure(1, 1, (7.0, 5.5))
    F = res.columns["fraction_stable"].reshape(nk, nc)
    m2 = ax2[0, 0].pcolormesh(K, C, F, shading="nearest", cmap="viridis", vmin=0, vmax=1)
    ax2[0, 0].set_xscale("log")
    ax2[0, 0].set_yscale("log")
    ax2[0, 0].set_xlabel(f"{kname} [N/m]")
    ax2[0, 0].set_ylabel(f"{cname} [N s/m]")
    ax2[0, 0].set_title("Fraction of members stable")
    fig2.colorbar(m2, ax=ax2[0, 0], label="fraction stable")
    fig3, ax3 = _figure(1, 1, (7.0, 5.5))
    Zn = res.columns["nominal_max_real"].reshape(nk, nc)
    lim3 = float(np.max(np.abs(Zn))) or 1.0
    m3 = ax3[0, 0].pcolormesh(K, C, Zn, shading="nearest", cmap="RdBu_r", vmin=-lim3, vmax=lim3)
    if Zn.min() < 0.0 < Zn.max():
        ax3[0, 0].contour(K, C, Zn, levels=[0.0], colors="k", linewidths=1.2)
    ax3[0, 0].plot(nom[kname], nom[cname], "k*", ms=12)
    ax3[0, 0].set_xscale("log")
    ax3[0, 0].set_yscale("log")
    ax3[0, 0].set_xlabel(f"{kname} [N/m]")
    ax3[0, 0].set_ylabel(f"{cname} [N s/m]")
    ax3[0, 0].set_title("Largest real part, other parameters nominal")
    fig3.colorbar(m3, ax=ax3[0, 0], label="largest real part of a pole [1/s] (black: 0)")
    n = res.settings["members_per_point"]
    return [
        (
            "nominal_real_part",
            fig3,
            "Largest real part of the poles with every other parameter at its nominal value; "
            "black line: stability boundary.",
        ),
        (
            "worst_real_part",
            fig,
            f"Worst real part over {n} members at each grid point; black line: 0 (stability "
            "boundary of the worst member).",
        ),
        ("fraction_stable", fig2, f"Fraction of the {n} members stable at each grid point."),
    ]


_FIGURES = {
    "workspace": lambda r: _line_figures(
        r, "workspace_factor", "workspace factor (K_PSF = 0.1097 / factor)"
    ),
    "stiffness-damping": _map_figures,
    "structure-frequency": lambda r: _line_figures(
        r, "f1_hz", "structure mode 1 frequency [Hz] (mode 2 scaled alike)"
    ),
}
