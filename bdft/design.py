"""``bdft design``: list the shipped designs or run one on the default family."""

from __future__ import annotations

import sys

from bdft.args import (
    UsageError,
    check_artifact_targets,
    members,
    members_help,
    seed,
)
from bdft.common import (
    add_coverage_arguments,
    add_margin_boxes_argument,
    member_progress,
    print_json,
)
from designs.registry import design_names, run_design

__all__ = ["register", "run"]


def register(sub) -> None:
    """Add the ``design`` sub-command (options ``NAME``, ``--list``, ``--samples``...).

    Parameters
    ----------
    sub : argparse subparsers action
        What :meth:`argparse.ArgumentParser.add_subparsers` returned; the new parser's
        ``func`` default is :func:`run`.
    """
    p = sub.add_parser(
        "design",
        help="list the compensator designs, or run one and write its artifact",
        description="Run one compensator design on the default family: build it, validate it "
        "on a seeded sample, reduce and discretise it, and write its artifact (JSON + .mat).",
    )
    p.add_argument("name", nargs="?", help="design name (see --list)")
    p.add_argument("--list", action="store_true", help="print the design names, one per line")
    p.add_argument(
        "--samples",
        type=members("--samples"),
        default=2000,
        help=members_help("family members to validate on (default: %(default)s)"),
    )
    p.add_argument(
        "--seed",
        type=seed("--seed"),
        default=0,
        help="sampling seed, 0 to 2**63-1 (default: %(default)s)",
    )
    p.add_argument(
        "--method",
        choices=["mc", "lhs", "grid", "vertices"],
        default="lhs",
        help="sampling method (default: %(default)s)",
    )
    p.add_argument(
        "--out",
        default="reports/out/designs",
        help="artifact folder; NAME.json and NAME.mat there are replaced only when they are "
        "previous artifacts (default: %(default)s)",
    )
    add_margin_boxes_argument(p, "the design")
    add_coverage_arguments(p, "the design")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def _names() -> str:
    return ", ".join(design_names())


def run(args) -> int:
    """List the designs, or run one through :func:`designs.registry.run_design` and print it.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``bdft design`` options: ``name`` (a design name, or ``None`` with
        ``list``), ``list``, ``samples`` (family members to validate on), ``seed``,
        ``method`` (sampling method), ``out`` (artifact folder), ``margin_boxes``
        (sub-boxes per scale of the certified robust margin, 0 skips it),
        ``coverage_samples`` (members of the coverage certificate, 0 skips it), ``jobs``
        (parallel processes) and ``json``.

    Returns
    -------
    int
        Exit code 0. The summary goes to standard output (one JSON object with
        ``--json``, otherwise one line per key), progress to standard error.

    Raises
    ------
    bdft.args.UsageError
        Without a design name and without ``--list``, for an unknown design name, or
        an ``--out`` where the artifact cannot be written (checked before the design
        is computed).
    """
    if args.list:
        print("\n".join(design_names()))
        return 0
    if not args.name:
        raise UsageError(f"NAME: expected a design name or --list; got neither ({_names()})")
    if args.name not in design_names():
        raise UsageError(f"NAME: unknown design {args.name!r}; expected one of {_names()}")
    check_artifact_targets("--out", args.out, [args.name])
    print(
        f"[bdft design] running {args.name!r} on {args.samples} members (seed {args.seed}) ...",
        file=sys.stderr,
    )
    res = run_design(
        args.name,
        samples=args.samples,
        seed=args.seed,
        method=args.method,
        out_dir=args.out,
        margin_boxes=args.margin_boxes,
        coverage_samples=args.coverage_samples,
        n_jobs=args.jobs,
        progress=member_progress("coverage"),
    )
    obj = res.to_json()
    if args.json:
        print_json(obj)
    else:
        for key in (
            "name",
            "fraction_stable",
            "max_real_pole",
            "min_damping",
            "suppression_db",
            "tracking_error",
            "peak_force_N",
            "rms_force_N",
            "force_within_limits",
            "order",
            "artifact",
        ):
            print(f"{key:20s} {obj[key]}")
        margin = res.details.get("robust_margin")
        if margin:
            print(f"{'margin, certified':20s} {margin['lower']:.4g}")
            print(f"{'margin, upper':20s} {margin['upper']:.4g}")
        if res.coverage is not None:
            print(f"{'coverage':20s} {res.coverage.describe()}")
        for note in obj["notes"]:
            print(f"note: {note}")
    return 0
