"""``bdft limit``: the achievable-limit map of the default family (:mod:`designs.limit`)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bdft.args import UsageError, check_report_dir, factor_list, integer, seed
from bdft.common import add_jobs_argument, add_scheduler_argument, member_progress, print_json
from designs.constants import ALL_SETS, DEFAULT_SETS, FORCE_SCALES, LIMIT_SAMPLES

__all__ = ["register", "run"]


def _sets(text: str) -> tuple:
    if text.strip() == "all":
        return ALL_SETS
    parts = tuple(t.strip() for t in text.split(",") if t.strip())
    bad = [p for p in parts if p not in ALL_SETS]
    if not parts or bad:
        raise argparse.ArgumentTypeError(
            f"expected 'all' or comma-separated sets among {', '.join(ALL_SETS)}; got {text!r}"
        )
    return tuple(dict.fromkeys(parts))


def register(sub) -> None:
    """Add the ``limit`` sub-command.

    Parameters
    ----------
    sub : argparse subparsers action
        What :meth:`argparse.ArgumentParser.add_subparsers` returned; the new parser's
        ``func`` default is :func:`run`.
    """
    p = sub.add_parser(
        "limit",
        help="the achievable-limit map: per member and actuator set, the best "
        "full-information compensator",
        description="For a Latin hypercube of the default family (and its critical members), "
        "find per member and actuator set the full-information compensator that meets the "
        "specification with the least handle force, verify it in numpy, and report the "
        "coverage at multiples of the Omni's force limits; one HTML page with the maps.",
    )
    p.add_argument(
        "--samples",
        type=integer("--samples", low=1, high=100_000),
        default=LIMIT_SAMPLES,
        help="Latin-hypercube members, 1 to 100000 (default: %(default)s; about 4 s each per core)",
    )
    p.add_argument(
        "--seed", type=seed("--seed"), default=0, help="sampling seed (default: %(default)s)"
    )
    p.add_argument(
        "--sets",
        type=_sets,
        default=DEFAULT_SETS,
        help="sets ACTUATORS/SENSORS, comma-separated, or 'all' "
        f"({', '.join(ALL_SETS)}; default: {','.join(DEFAULT_SETS)})",
    )
    p.add_argument(
        "--force-scales",
        type=factor_list("--force-scales"),
        default=FORCE_SCALES,
        help="multiples of the Omni's force limits reported, comma-separated (default: 1,2,4)",
    )
    p.add_argument(
        "--basis-check",
        type=integer("--basis-check", low=0, high=1000),
        default=8,
        help="members re-run with a basis of twice as many poles to measure convergence "
        "(0: skipped; default: %(default)s)",
    )
    add_jobs_argument(p)
    add_scheduler_argument(p)
    p.add_argument(
        "--out",
        default="reports/out/limit",
        help="report folder: a new folder or a previous bdft report (default: %(default)s)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    """Compute the limit map, write its page and print the coverage table.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``bdft limit`` options: ``samples``, ``seed``, ``sets``, ``force_scales``
        (empty is refused), ``basis_check`` (members of the convergence check, 0 skips
        it), ``jobs``, ``scheduler`` (a Dask scheduler's address), ``out`` (report folder,
        checked before any work) and ``json``.

    Returns
    -------
    int
        Exit code 0. Standard output gets one JSON object (``--json``: ``sets`` with
        ``name``, ``force_scale``, ``coverage``, ``samples``, ``seed``, ``binding``, and the
        rest of the map) or the table; progress and timings go to standard error.
    """
    if not args.force_scales:
        raise UsageError("--force-scales: expected at least one multiple; got none")
    out = check_report_dir("--out", Path(args.out))
    from backhoe import default_family
    from designs.limit import basis_check, limit_map
    from reports.limit import best_set, limit_conclusions, write_limit_report

    family = default_family()
    t0 = time.perf_counter()
    lm = limit_map(
        family,
        samples=args.samples,
        seed=args.seed,
        sets=args.sets,
        force_scales=args.force_scales,
        n_jobs=args.jobs,
        progress=member_progress("limit map"),
        scheduler=args.scheduler,
    )
    t1 = time.perf_counter()
    basis = None
    if args.basis_check:
        basis = basis_check(
            family, lm, members=args.basis_check, n_jobs=args.jobs, scheduler=args.scheduler
        )
    t2 = time.perf_counter()
    index = write_limit_report(lm, out, basis=basis)
    print(
        f"[bdft limit] map {t1 - t0:.1f} s, basis check {t2 - t1:.1f} s; page {index}",
        file=sys.stderr,
    )
    if args.json:
        obj = lm.to_json()
        obj["basis_check"] = basis
        obj["conclusions"] = limit_conclusions(lm)
        obj["best_set"] = best_set(lm)
        obj["report"] = str(index)
        print_json(obj)
    else:
        for e in lm.sets_json():
            binding = ", ".join(f"{k} {v}" for k, v in sorted(e["binding"].items())) or "-"
            print(
                f"{e['name']:26s} x{e['force_scale']:<4g} coverage {100 * e['coverage']:5.1f} % "
                f"({e['covered']}/{e['samples']})  uncovered: {binding}"
            )
        for line in limit_conclusions(lm):
            print(line)
        print(f"report: {index}")
    return 0
