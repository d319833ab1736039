"""``bdft sweep``: parameter sweeps across a family; the page is built by :mod:`reports.sweeps`."""

from __future__ import annotations

import sys
from pathlib import Path

from bdft.args import check_report_dir, integer, real
from bdft.common import add_jobs_argument, add_scheduler_argument, print_json
from bdft.validate import add_family_arguments, build_family, check_family_arguments, progress_bar
from uncertainty.constants import DEFAULT_CHUNK

__all__ = ["MAX_POINTS", "register", "run"]

_NAMES = ("workspace", "frequency-damping", "structure-frequency")
_DEFAULT_MEMBERS = {"workspace": 2000, "frequency-damping": 200, "structure-frequency": 2000}
#: Grid points per swept axis: at least 2 (a sweep draws a line), at most this many.
MAX_POINTS = 200


def register(sub) -> None:
    """Add the ``sweep`` sub-command (``NAME`` and the family, grid and output options).

    Parameters
    ----------
    sub : argparse subparsers action
        What :meth:`argparse.ArgumentParser.add_subparsers` returned; the new parser's
        ``func`` default is :func:`run`.
    """
    p = sub.add_parser(
        "sweep",
        help="sweep workspace factor, human stiffness x damping or structure frequency "
        "across the family",
        description="Validate the same family members on a grid of one or two quantities and "
        "write one HTML page with plots and the table behind them (CSV). --samples is the "
        "number of family members at each grid point.",
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
        help="frequency-damping: the arm endpoint or the trunk on the seat (default: %(default)s)",
    )
    p.add_argument(
        "--points",
        type=integer("--points", low=2, high=MAX_POINTS),
        default=None,
        help=f"grid points per swept axis, 2 to {MAX_POINTS} (default: 19 factors, 12x12 map, "
        "13 frequencies)",
    )
    p.add_argument(
        "--workspace-factor",
        type=real("--workspace-factor", low=0.0, low_open=True),
        default=None,
        help="workspace factor of the family (K_PSF = 0.1097 / factor); default 1 for the "
        "workspace sweep (its reference) and 2 for the others (the paper's stabilised "
        "workspace, C2)",
    )
    p.add_argument(
        "--out",
        default=None,
        help="report folder: a new folder or a previous bdft report, never another folder "
        "or file (default: reports/out/sweep-<name>)",
    )
    add_jobs_argument(p, workers="parallel threads for the grid points")
    add_scheduler_argument(p)
    p.add_argument(
        "--json", action="store_true", help="print one JSON object with the table and settings"
    )
    p.set_defaults(func=run)


def _run_sweep(args, family, progress):
    import numpy as np

    from backhoe.families.sweeps import (
        frequency_damping_sweep,
        structure_frequency_sweep,
        workspace_sweep,
    )
    from backhoe.model.blocks import parameter_name

    members = args.samples or _DEFAULT_MEMBERS[args.name]
    common = dict(
        members=members,
        method=args.method,
        seed=args.seed,
        chunk=args.chunk or DEFAULT_CHUNK,
        progress=progress,
        jobs=args.jobs,
        scheduler=args.scheduler,
    )
    if args.name == "workspace":
        factors = None if args.points is None else np.linspace(1.0, 10.0, args.points)
        return workspace_sweep(family, factors=factors, **common), members * (
            19 if factors is None else len(factors)
        )
    if args.name == "frequency-damping":
        n = args.points or 12
        return frequency_damping_sweep(
            family, pair=args.pair, n_f=n, n_z=n, **common
        ), members * n * n
    n = args.points or 13
    lo = family.parameter(parameter_name("structure", "f1_hz")).low / family.struct.f1_hz
    return structure_frequency_sweep(family, scales=np.linspace(lo, 1.0, n), **common), members * n


def _total(args) -> int:
    members = args.samples or _DEFAULT_MEMBERS[args.name]
    pts = {
        "workspace": 19 if args.points is None else args.points,
        "frequency-damping": (args.points or 12) ** 2,
        "structure-frequency": args.points or 13,
    }[args.name]
    return (members + 1) * pts  # plus the nominal member at each point


def run(args) -> int:
    """Run the sweep ``args.name`` and write its page (:func:`reports.sweeps.write_sweep_report`).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``bdft sweep`` options: ``name`` (``"workspace"``,
        ``"frequency-damping"`` or ``"structure-frequency"``); the family options of
        :func:`bdft.validate.add_family_arguments` (``samples``: members per grid
        point, 0 when not given, meaning 2000, or 200 for the frequency-damping map;
        ``seed``, ``human``, ``plant_file``, ``chunk``); ``method`` (``"mc"`` or
        ``"lhs"``); ``pair`` (``"arm"`` or ``"trunk"``, for the frequency-damping map);
        ``points`` (grid points per swept axis, 2 to :data:`MAX_POINTS`, ``None`` for
        19 factors, a 12 x 12 map or 13 frequencies); ``workspace_factor`` (``None``:
        1 for the workspace sweep, 2 for the others); ``out`` (report folder, ``None`` for
        ``reports/out/sweep-<name>``; a new folder or a previous report, checked
        before the sweep runs), ``jobs`` (threads for the grid points, used above
        50,000 members in all), ``scheduler`` (a Dask scheduler's address: the grid points
        run on its workers) and ``json``.

    Returns
    -------
    int
        Exit code 0. Standard output gets the table and settings as one JSON object
        (``--json``) or the title and the CSV table; progress goes to standard error.
    """
    out = check_report_dir("--out", Path(args.out or f"reports/out/sweep-{args.name}"))
    check_family_arguments(args)
    from reports.sweeps import write_sweep_report

    factor = (
        args.workspace_factor
        if args.workspace_factor is not None
        else (1.0 if args.name == "workspace" else 2.0)
    )
    family = build_family(args).with_workspace_factor(factor)
    with progress_bar(_total(args), f"sweep {args.name}") as bar:
        res, _ = _run_sweep(args, family, bar.update)
    index = write_sweep_report(res, out)
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
