"""``bdft sweep``: parameter sweeps across a family, one HTML page per sweep with plots and CSV."""

from __future__ import annotations

import html
import io
import sys
from pathlib import Path

from bdft.validate import add_family_arguments, build_family, progress_bar

_NAMES = ("workspace", "stiffness-damping", "structure-frequency")
_DEFAULT_MEMBERS = {"workspace": 2000, "stiffness-damping": 200, "structure-frequency": 2000}


def register(sub) -> None:
    p = sub.add_parser(
        "sweep",
        help="sweep workspace factor, human stiffness x damping or structure frequency across the family",
        description="Validate the same family members on a grid of one or two quantities and write one HTML "
        "page with plots and the table behind them (CSV). --samples is the number of family members at each "
        "grid point.",
    )
    p.add_argument("name", choices=_NAMES, help="which sweep")
    add_family_arguments(p, samples=0)
    p.add_argument(
        "--method",
        choices=("mc", "lhs"),
        default="lhs",
        help="sampling of the members (default: lhs)",
    )
    p.add_argument(
        "--pair",
        choices=("arm", "trunk"),
        default="arm",
        help="stiffness-damping: which spring-damper of the human chain (default: %(default)s)",
    )
    p.add_argument(
        "--points",
        type=int,
        default=None,
        help="grid points per swept axis (default: 19 factors, 12x12 map, 13 frequencies)",
    )
    p.add_argument(
        "--workspace-factor",
        type=float,
        default=None,
        help="workspace factor of the family (K_PSF = 0.1097 / factor); default 1 for the workspace "
        "sweep (its reference) and 2 for the others (the paper's stabilised workspace, C2)",
    )
    p.add_argument("--out", default=None, help="output folder (default: reports/out/sweep-<name>)")
    p.add_argument(
        "--json", action="store_true", help="print one JSON object with the table and settings"
    )
    p.set_defaults(func=run)


def _run_sweep(args, family, progress):
    import numpy as np

    from uncertainty import DEFAULT_CHUNK
    from uncertainty.sweeps import (
        stiffness_damping_sweep,
        structure_frequency_sweep,
        workspace_sweep,
    )

    members = args.samples or _DEFAULT_MEMBERS[args.name]
    common = dict(
        members=members,
        method=args.method,
        seed=args.seed,
        chunk=args.chunk or DEFAULT_CHUNK,
        progress=progress,
    )
    if args.name == "workspace":
        factors = None if args.points is None else np.linspace(1.0, 10.0, args.points)
        return workspace_sweep(family, factors=factors, **common), members * (
            19 if factors is None else len(factors)
        )
    if args.name == "stiffness-damping":
        n = args.points or 12
        return stiffness_damping_sweep(
            family, pair=args.pair, n_k=n, n_c=n, **common
        ), members * n * n
    n = args.points or 13
    lo = family.parameter("struct.f1_hz").low / family.struct.f1_hz
    return structure_frequency_sweep(family, scales=np.linspace(lo, 1.0, n), **common), members * n


def _total(args) -> int:
    members = args.samples or _DEFAULT_MEMBERS[args.name]
    pts = {
        "workspace": 19 if args.points is None else args.points,
        "stiffness-damping": (args.points or 12) ** 2,
        "structure-frequency": args.points or 13,
    }[args.name]
    return (members + 1) * pts  # plus the nominal member at each point


def _page(res, figures, csv_name: str) -> str:
    def esc(x):
        return html.escape(str(x))

    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>{esc(res.title)}</title>",
        "<style>body{font-family:sans-serif;max-width:60em;margin:2em auto}table{border-collapse:collapse}"
        "td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}img{max-width:100%}</style>",
        "</head><body>",
        f"<h1>{esc(res.title)}</h1>",
        f"<p>{esc(res.description)}</p>",
        "<h2>Settings</h2><table>",
    ]
    for k, v in res.settings.items():
        parts.append(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>")
    parts.append("</table><h2>Figures</h2>")
    for name, _, caption in figures:
        parts.append(
            f"<figure><img src='{esc(name)}.png' alt='{esc(name)}'><figcaption>{esc(caption)}</figcaption>"
            "</figure>"
        )
    parts.append(
        f"<h2>Table</h2><p>Also as <a href='{esc(csv_name)}'>{esc(csv_name)}</a>.</p><table><tr>"
    )
    keys = list(res.columns)
    parts.extend(f"<th>{esc(k)}</th>" for k in keys)
    parts.append("</tr>")
    n = len(res.columns[keys[0]])
    for i in range(n):
        parts.append("<tr>" + "".join(f"<td>{res.columns[k][i]:.6g}</td>" for k in keys) + "</tr>")
    parts.append("</table></body></html>\n")
    return "\n".join(parts)


def write_sweep(res, out_dir) -> Path:
    """Write ``index.html``, one PNG per figure and ``<name>.csv`` into ``out_dir``, each atomically."""
    import matplotlib

    matplotlib.use("Agg")
    from robust.jsonio import atomic_write_bytes, atomic_write_json, atomic_write_text

    out = Path(out_dir)
    figures = res.figures()
    for name, fig, _ in figures:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110)
        atomic_write_bytes(out / f"{name}.png", buf.getvalue())
    csv_name = f"{res.name}.csv"
    atomic_write_text(out / csv_name, res.csv())
    atomic_write_json(
        out / "sweep.json", {"name": res.name, "settings": res.settings, "columns": res.columns}
    )
    return atomic_write_text(out / "index.html", _page(res, figures, csv_name))


def run(args) -> int:
    from bdft import print_json

    factor = (
        args.workspace_factor
        if args.workspace_factor is not None
        else (1.0 if args.name == "workspace" else 2.0)
    )
    family = build_family(args).with_workspace_factor(factor)
    with progress_bar(_total(args), f"sweep {args.name}") as bar:
        res, _ = _run_sweep(args, family, bar.update)
    out = Path(args.out or f"reports/out/sweep-{args.name}")
    index = write_sweep(res, out)
    print(f"[bdft sweep] report written to {index}", file=sys.stderr)
    if args.json:
        print_json(
            {
                "name": res.name,
                "report": str(index),
                "settings": res.settings,
                "columns": res.columns,
            }
        )
    else:
        print(res.title)
        print(res.csv(), end="")
        print(f"report: {index}")
    return 0
