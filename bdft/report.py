"""``bdft report``: run every design on the default family and write the comparison page."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from bdft.args import (
    check_artifact_targets,
    check_report_dir,
    factor_list,
    integer,
    members,
    members_help,
    seed,
)
from bdft.common import (
    add_cache_argument,
    add_coverage_arguments,
    add_margin_boxes_argument,
    member_progress,
    print_json,
)
from bdft.design import SCHEDULED

__all__ = ["register", "run"]

_LIMIT = "achievable-limit map"
_SCHEDULED = "per-operator design"


def _limit_task(task) -> dict:
    """The report's achievable-limit map (a task of the designs' pool): ``(samples, seed)``."""
    from backhoe import default_family
    from designs.limit import limit_map
    from reports.limit import limit_conclusions

    samples, seed = task
    lm = limit_map(default_family(), samples=samples, seed=seed)
    return dict(lm.to_json(), conclusions=limit_conclusions(lm))


def _scheduled_task(task):
    """The report's per-operator design (a task of the designs' pool): ``(samples, seed)``;
    its bank of controllers and its result."""
    from backhoe import default_family
    from designs.scheduled import scheduled_design

    samples, seed = task
    return scheduled_design(default_family(), samples=samples, seed=seed, limit_samples=0)


def register(sub) -> None:
    """Add the ``report`` sub-command (options ``--samples``, ``--seed``, ``--out``, ``--json``).

    Parameters
    ----------
    sub : argparse subparsers action
        What :meth:`argparse.ArgumentParser.add_subparsers` returned; the new parser's
        ``func`` default is :func:`run`.
    """
    p = sub.add_parser(
        "report",
        help="run every design on the default family and write the comparison report",
        description="Run every shipped design on the same seeded sample of the default family, "
        "write their artifacts and one HTML page comparing them.",
    )
    p.add_argument(
        "--samples",
        type=members("--samples"),
        default=2000,
        help=members_help("family members (default: %(default)s)"),
    )
    p.add_argument(
        "--seed",
        type=seed("--seed"),
        default=0,
        help="sampling seed, 0 to 2**63-1 (default: %(default)s)",
    )
    p.add_argument(
        "--out",
        default="reports/out/designs",
        help="report folder: a new folder or a previous bdft report, never another folder or "
        "file; the artifacts go to <out>-artifacts (default: %(default)s)",
    )
    add_margin_boxes_argument(p, "each design")
    add_coverage_arguments(p, "each design")
    p.add_argument(
        "--limit-samples",
        type=integer("--limit-samples", low=0, high=100_000),
        default=64,
        help="members of the achievable-limit map shown beside the designs' coverage "
        "(bdft limit's computation, default sets; 0: not computed; default: %(default)s, "
        "about a second per member per core)",
    )
    p.add_argument(
        "--scheduled-samples",
        type=integer("--scheduled-samples", low=0, high=100_000),
        default=2000,
        help="fresh members, each with its own simulated calibration, of the per-operator "
        "design's coverage (bdft design scheduled; 0: not computed; default: %(default)s, "
        "about half a core-second per member)",
    )
    p.add_argument(
        "--tradeoff",
        type=factor_list("--tradeoff"),
        default=(0.5, 1.0, 2.0, 4.0),
        help="multiples of the Omni's force limits at which the robust handle-force LMI design "
        "is rerun for the force-budget trade-off (Pareto curve), comma-separated, or 'none' "
        "(default: 0.5,1,2,4; one to three minutes each, run with the designs over --jobs)",
    )
    add_cache_argument(p)
    p.add_argument(
        "--json", action="store_true", help="print one JSON object with every design's summary"
    )
    p.set_defaults(func=run)


def run(args) -> int:
    """Run every design on the same sample and write the comparison page.

    The page goes to ``args.out``, the designs' artifacts to the sibling folder
    ``<out>-artifacts``; a design that raises a workbench error
    (:class:`robust.errors.BDFTError`) is listed with its error instead of its numbers.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``bdft report`` options: ``samples`` (family members every design is
        validated on), ``seed`` (sampling seed), ``out`` (report folder: a new folder or
        a previous report; it and the artifacts' folder are checked before any work),
        ``margin_boxes`` (sub-boxes per scale of each design's certified robust margin,
        0 skips it), ``tradeoff`` (force-limit multiples of the Pareto sweep, empty skips
        it), ``coverage_samples`` (each design's coverage certificate), ``jobs`` (local
        processes: the designs run that many at once, each with its coverage checks in
        its own process, and beside them the trade-off's points, the map and the
        per-operator design, the longest first),
        ``limit_samples`` (members of the achievable-limit map shown beside the designs'
        coverage, 0 skips it), ``scheduled_samples`` (members of the per-operator design's
        coverage, :func:`designs.scheduled.scheduled_design`, 0 skips it) and ``json``.

    Returns
    -------
    int
        Exit code 0. Standard output gets one JSON object (``--json``: the report path
        and every design's summary or error) or one line per design; progress goes to
        standard error.
    """
    from backhoe import default_family
    from designs.registry import report_design_names
    from designs.robust_lmi_tradeoff import tradeoff_point, tradeoff_tasks
    from reports.coverage import family_coverage
    from reports.designs import run_designs_with, write_design_report
    from robust.cache import lookup, store
    from robust.jsonio import atomic_write_json

    designs = set(report_design_names())

    def progress(msg):
        name = msg[: -len(" done")] if msg.endswith(" done") else msg
        what = "design " if name in designs else ""
        print(f"[bdft report] {what}{msg} ...", file=sys.stderr, flush=True)

    use_cache = not args.no_cache
    out = check_report_dir("--out", args.out)
    art_dir = Path(args.out).with_name(out.name + "-artifacts")
    check_artifact_targets("--out", art_dir, [*report_design_names(), SCHEDULED])
    # the trade-off's points (each a robust LMI design), the achievable-limit map and the
    # per-operator design share the designs' pool of processes (what the cache holds is not
    # run again)
    extra = []

    def look(kind, inputs):
        return lookup(kind, inputs) if use_cache else (False, None)

    scheduled_inputs = {"samples": args.scheduled_samples, "seed": args.seed}
    scheduled_pair = None
    if args.scheduled_samples:
        found, scheduled_pair = look("scheduled-design", scheduled_inputs)
        if not found:
            extra.insert(0, (_SCHEDULED, _scheduled_task, (args.scheduled_samples, args.seed)))
    trade_inputs = {"factors": list(args.tradeoff or [])}
    tradeoff = None
    if args.tradeoff:
        found, tradeoff = look("force-tradeoff", trade_inputs)
        if not found:
            tasks = tradeoff_tasks(default_family(), args.tradeoff, cache=use_cache)
            extra += [
                (f"force-budget trade-off, force x{f:g}", tradeoff_point, t)
                for f, t in zip(args.tradeoff, tasks)
            ]
    limit_inputs = {"samples": args.limit_samples, "seed": args.seed}
    limit = None
    if args.limit_samples:
        found, limit = look("limit-map", limit_inputs)
        if not found:
            extra.append((_LIMIT, _limit_task, (args.limit_samples, args.seed)))
    runs, answers = run_designs_with(
        samples=args.samples,
        seed=args.seed,
        out_dir=art_dir,
        progress=progress,
        margin_boxes=args.margin_boxes,
        coverage_samples=args.coverage_samples,
        n_jobs=args.jobs,
        member_progress=member_progress("coverage"),
        cache=use_cache,
        design_jobs=args.jobs,
        extra_tasks=extra,
    )
    points = []
    for (label, _, _), answer in zip(extra, answers):
        if label == _LIMIT:
            limit = answer
            if use_cache:
                store("limit-map", limit_inputs, limit)
        elif label == _SCHEDULED:
            scheduled_pair = answer
            if use_cache:
                store("scheduled-design", scheduled_inputs, scheduled_pair)
        else:
            points.append(answer)
    if points:
        tradeoff = points
        if use_cache:
            store("force-tradeoff", trade_inputs, tradeoff)
    for f, pt in zip(args.tradeoff or [], tradeoff or []):
        print(
            f"[bdft report] force x{f:g}: scale {pt.scale:.3g} reached, certified margin "
            f"{pt.certified_scale:.3g}",
            file=sys.stderr,
            flush=True,
        )
    scheduled = None
    if scheduled_pair is not None:
        bank, scheduled = scheduled_pair
        scheduled = dict(scheduled)
        art = dict(bank.to_json(), kind="bdft-controller-bank", name=SCHEDULED, result=scheduled)
        scheduled["artifact"] = str(atomic_write_json(art_dir / f"{SCHEDULED}.json", art))
    coverage = family_coverage(default_family(), samples=args.samples, seed=args.seed)
    path = write_design_report(
        runs,
        out,
        samples=args.samples,
        seed=args.seed,
        coverage=coverage,
        tradeoff=tradeoff,
        limit=limit,
        scheduled=scheduled,
    )
    print(f"[bdft report] written to {path}", file=sys.stderr)
    if args.json:
        print_json(
            {
                "report": str(path),
                "family": coverage.to_json(),
                "limit": limit,
                "scheduled": scheduled,
                "tradeoff": [dataclasses.asdict(p) for p in tradeoff or []],
                "designs": {
                    k: (str(r) if isinstance(r, Exception) else r.to_json())
                    for k, r in runs.items()
                },
            }
        )
    else:
        for k, r in runs.items():
            if isinstance(r, Exception):
                print(f"{k:16s} FAILED: {str(r)[:400]}")
            else:
                e = r.evaluation
                ho = float("nan") if r.checks is None else r.checks.held_out.fraction_stable
                print(
                    f"{k:16s} stable {e.fraction_stable:.4f} (held-out {ho:.4f})  "
                    f"worst Re {e.max_real_pole:+.3f}  "
                    f"peak force {e.peak_force_n:.3g} N  rms {e.rms_force_n:.3g} N  "
                    f"order {r.order_reduced}"
                )
        print(f"report: {path}")
    return 0
