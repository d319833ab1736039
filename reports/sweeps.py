"""Sweep pages (``bdft sweep``): the sweep's figures, settings and table on one HTML page.

The sweeps themselves are computed by :mod:`backhoe.families.sweeps`; this module draws
them (every function returns matplotlib figures) and writes the page through the
common builder of :mod:`reports.html`, with the table attached as CSV and JSON.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from backhoe.families.sweeps import SweepResult
from reports.html import HtmlPage, write_report_dir
from robust.jsonio import to_jsonable

__all__ = ["sweep_figures", "write_sweep_report"]


def sweep_figures(res: SweepResult) -> list:
    """The sweep's figures: ``[(name, matplotlib Figure, caption), ...]``.

    A line sweep (workspace factor, structure frequency) gives the fraction stable
    and worst real part, and the minimum damping in the BDFT band, against the swept
    quantity; the stiffness x damping map gives three colour maps (nominal and worst
    real part, fraction stable).

    Parameters
    ----------
    res : backhoe.SweepResult
        A computed sweep.

    Returns
    -------
    list of (str, matplotlib.figure.Figure, str)
        File stem, figure and caption of each figure.
    """
    return _FIGURES[res.name](res)


def write_sweep_report(res: SweepResult, out_dir) -> Path:
    """One HTML page for a sweep: settings, figures and the table (also as CSV and JSON).

    The folder is replaced atomically (:func:`reports.html.write_report_dir`).

    Parameters
    ----------
    res : backhoe.SweepResult
        A computed sweep.
    out_dir : path-like
        The report folder.

    Returns
    -------
    pathlib.Path
        The page's ``index.html``.
    """
    page = HtmlPage(res.title)
    page.p(res.description)
    page.h2("Settings")
    page.table(["setting", "value"], [[str(k), str(v)] for k, v in res.settings.items()])
    page.h2("Figures")
    for name, fig, caption in sweep_figures(res):
        page.figure(fig, name, caption)
    csv_name = f"{res.name}.csv"
    page.h2("Table")
    page.p(f"Also as {csv_name} and sweep.json beside this page.")
    keys = list(res.columns)
    n = len(res.columns[keys[0]])
    page.table(keys, [[float(res.columns[k][i]) for k in keys] for i in range(n)])
    page.attach(csv_name, res.csv())
    page.attach(
        "sweep.json",
        json.dumps(
            to_jsonable({"name": res.name, "settings": res.settings, "columns": res.columns}),
            indent=2,
        ),
    )
    return write_report_dir(page, out_dir)


def _figure(nrows=1, ncols=1, size=(7.0, 4.5)):
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
        f"Minimum damping of poles in {res.settings['band_hz'][0]:g}-"
        f"{res.settings['band_hz'][1]:g} Hz"
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


def _axis_label(res: SweepResult, name: str) -> str:
    units = res.settings.get("units", {}).get(name, "")
    return f"{name} [{units}]" if units and units != "-" else name


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
    a.plot(nom[kname], nom[cname], "k*", ms=12, label="nominal operator")
    a.set_xscale("log")
    a.set_xlabel(_axis_label(res, kname))
    a.set_ylabel(_axis_label(res, cname))
    a.set_title(res.title)
    a.legend(loc="upper right")
    fig.colorbar(mesh, ax=a, label="worst real part of a pole [1/s] (black: 0)")
    fig2, ax2 = _figure(1, 1, (7.0, 5.5))
    F = res.columns["fraction_stable"].reshape(nk, nc)
    m2 = ax2[0, 0].pcolormesh(K, C, F, shading="nearest", cmap="viridis", vmin=0, vmax=1)
    ax2[0, 0].set_xscale("log")
    ax2[0, 0].set_xlabel(_axis_label(res, kname))
    ax2[0, 0].set_ylabel(_axis_label(res, cname))
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
    ax3[0, 0].set_xlabel(_axis_label(res, kname))
    ax3[0, 0].set_ylabel(_axis_label(res, cname))
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
    "frequency-damping": _map_figures,
    "structure-frequency": lambda r: _line_figures(
        r, "f1_hz", "structure mode 1 frequency [Hz] (mode 2 scaled alike)"
    ),
}
