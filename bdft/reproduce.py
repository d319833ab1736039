"""``bdft reproduce``: check the paper's claims C1-C5 and write the reproduction report."""

from __future__ import annotations

import sys

from backhoe.constants import HUMAN_VARIANT_NAMES
from bdft.args import check_report_dir
from bdft.common import print_json

__all__ = ["register", "run"]


def register(sub) -> None:
    """Add the ``reproduce`` sub-command (options ``--out``, ``--human``, ``--json``).

    Parameters
    ----------
    sub : argparse subparsers action
        What :meth:`argparse.ArgumentParser.add_subparsers` returned; the new parser's
        ``func`` default is :func:`run`.
    """
    p = sub.add_parser(
        "reproduce",
        help="check the paper's claims C1-C5 and write the reproduction report (HTML)",
        description="Build the paper's loop, run the calibration search, check claims C1-C5 for "
        "each human variant and write one HTML page with its figures.",
    )
    p.add_argument(
        "--out",
        default="reports/out/reproduce",
        help="report folder: a new folder or a previous bdft report, never another folder or "
        "file (default: %(default)s)",
    )
    p.add_argument(
        "--human",
        choices=[*HUMAN_VARIANT_NAMES, "all"],
        default="all",
        help="human variant(s) to evaluate (default: %(default)s)",
    )
    p.add_argument(
        "--json", action="store_true", help="print one JSON object with the claims and calibration"
    )
    p.set_defaults(func=run)


def run(args) -> int:
    """Check claims C1-C5 (:func:`reports.reproduce.reproduce`) and write the report.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``bdft reproduce`` options: ``out`` (report folder: a new folder or a
        previous report, checked before any work), ``human``
        (a name of :data:`backhoe.model.human.HUMAN_VARIANT_NAMES` or ``"all"``) and ``json``.

    Returns
    -------
    int
        Exit code 0. Standard output gets the claims and calibration as one JSON object
        (``--json``, with the report path under ``"report"``) or one line per claim and
        variant; progress goes to standard error.
    """
    from reports.reproduce import reproduce, result_to_json, write_reproduction_report

    out = check_report_dir("--out", args.out)
    variants = HUMAN_VARIANT_NAMES if args.human == "all" else (args.human,)

    def progress(msg: str) -> None:
        print(f"[bdft reproduce] {msg} ...", file=sys.stderr, flush=True)

    res = reproduce(variants=variants, progress=progress)
    path = write_reproduction_report(res, out)
    progress(f"report written to {path}")
    if args.json:
        obj = result_to_json(res)
        obj["report"] = str(path)
        print_json(obj)
    else:
        for v in res.variants:
            print(v.label)
            for key, c in v.claims.items():
                print(f"  {key}: {c.status:12s} {c.detail}")
        for name, why in res.unavailable.items():
            print(f"{name}: not evaluated ({why})")
        print(f"report: {path}")
    return 0
