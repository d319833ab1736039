"""``bdft design``: list the shipped designs or run one on the default family."""

from __future__ import annotations

import sys

from bdft.args import (
    UsageError,
    check_artifact_targets,
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
from designs.constants import CELLS_PER_AXIS

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
    p.add_argument(
        "--list",
        action="store_true",
        help="print the designs, one per line with what each is (with --json: one object)",
    )
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
    p.add_argument(
        "--cells",
        type=integer("--cells", low=1, high=8),
        default=CELLS_PER_AXIS,
        help="scheduled only: cells per identified quantity of the bank, 1 to 8 (default: "
        "%(default)s)",
    )
    p.add_argument(
        "--border-samples",
        type=integer("--border-samples", low=0, high=100_000),
        default=50,
        help="scheduled only: members (the first of the coverage members) on which designs "
        "from estimates wrong by the error bound are checked, 16 designs each, about 1 "
        "core-second per member (0: not computed; default: %(default)s)",
    )
    p.add_argument(
        "--certify-samples",
        type=integer("--certify-samples", low=0, high=10_000),
        default=None,
        help="scheduled and calibrated-force only: the first coverage members whose design's "
        "robust margin over the box its calibration bounds is certified (scheduled: about 6 "
        "core-seconds each; calibrated-force: by mu, a minute or so each) (0: not computed; "
        "default: 10 for scheduled, 3 for calibrated-force)",
    )
    p.add_argument(
        "--limit-samples",
        type=integer("--limit-samples", low=0, high=4096),
        default=64,
        help="scheduled only: Latin-hypercube members of the limit map the bank's coverage is "
        "compared with; calibrated-force: the first coverage members that also get their own "
        "limit (0: not computed; default: %(default)s)",
    )
    add_cache_argument(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


#: Designs run outside :func:`designs.registry.run_design` (their own pipeline).
SCHEDULED = "scheduled"
#: What the scheduled design is, for ``--list``.
SCHEDULED_DESCRIPTION = (
    "per-operator bank: a short calibration of the operator and the cab picks (or builds) "
    "the compensator"
)


#: The calibrated handle-force design (:mod:`designs.calibrated_force`), its own pipeline too.
CALIBRATED_FORCE = "calibrated-force"


def _listing() -> list[dict]:
    """Every design's name and one-line description, in report order."""
    from designs.calibrated_force import DESCRIPTION
    from designs.registry import DESIGNS

    rows = [{"name": d.name, "description": d.description} for d in DESIGNS.values()]
    return [
        *rows,
        {"name": SCHEDULED, "description": SCHEDULED_DESCRIPTION},
        {"name": CALIBRATED_FORCE, "description": DESCRIPTION},
    ]


def _all_names() -> list[str]:
    from designs.registry import design_names

    return [*design_names(), SCHEDULED, CALIBRATED_FORCE]


def _names() -> str:
    return ", ".join(_all_names())


def _run_scheduled(args) -> int:
    """``bdft design scheduled``: the per-operator bank (:mod:`designs.scheduled`)."""
    if args.coverage_samples < 1:
        raise UsageError(
            "--coverage-samples: expected at least 1 for the scheduled bank (its coverage is "
            f"its result); got {args.coverage_samples}"
        )
    out = check_artifact_targets("--out", args.out, [SCHEDULED])
    from backhoe import default_family
    from designs.calibration_region import REGION_RADIUS
    from designs.scheduled import scheduled_design
    from robust.jsonio import atomic_write_json

    print(
        f"[bdft design] scheduled bank, {args.cells} cells per axis, coverage on "
        f"{args.coverage_samples} members (seed {args.seed + 2}) ...",
        file=sys.stderr,
    )
    bank, obj = scheduled_design(
        default_family(),
        cells_per_axis=args.cells,
        samples=args.coverage_samples,
        seed=args.seed,
        limit_samples=args.limit_samples,
        border_samples=args.border_samples,
        certify_samples=10 if args.certify_samples is None else args.certify_samples,
        n_jobs=args.jobs,
        progress=member_progress("calibrations"),
    )
    art = dict(bank.to_json(), kind="bdft-controller-bank", name=SCHEDULED, result=obj)
    obj["artifact"] = str(atomic_write_json(out / f"{SCHEDULED}.json", art))
    if args.json:
        print_json(obj)
    else:
        cov = obj["coverage"]
        print(f"{'limit set':20s} {obj['limit_set']} (force x{obj['force_scale']:g})")
        print(
            f"{'coverage':20s} {cov['fraction']:.4f} ({cov['failures']} failures in "
            f"{cov['samples']}; P(failure) <= {cov['epsilon']:.4f} at {cov['confidence']})"
        )
        print(f"{'within error bound':20s} {cov['operator_within_error_bound']:.4f} (operator)")
        print(
            f"{'within the region':20s} {cov['estimate_within_confidence_region']:.4f} "
            f"(estimate within {REGION_RADIUS:.2f} sd of the noise-free estimate, first "
            f"{cov['confidence_region_samples']})"
        )
        for key, label in (
            ("wrong_within_bound", "wrong in the region"),
            ("wrong_within_box", "wrong in the box"),
        ):
            if obj.get(key):
                wb = obj[key]
                print(
                    f"{label:20s} stable {wb['stable']:.4f}, specification "
                    f"{wb['specification']:.4f} ({wb['designs']} designs)"
                )
        if obj["certified_over_bound"]:
            cb = obj["certified_over_bound"]
            print(
                f"{'certified on bound':20s} median margin {cb['median_lower']:.3g} (upper "
                f"{cb['median_upper']:.3g}); {cb['certified_whole_bound']} of {cb['members']} "
                "certified on the whole bound"
            )
        if obj["limit"]:
            lim = obj["limit"]
            print(f"{'limit coverage':20s} {lim['coverage']:.4f} (best: {lim['best_sets']})")
        bank = obj["bank"]
        print(
            f"{'bank':20s} {bank['cells']} cells: {bank['fraction']:.4f}, right cell "
            f"{bank['right_cell']:.4f}, wrong cell stable {bank['wrong_choice_stable']:.4f}"
        )
        for row in obj["coverage_by_cells"]:
            print(f"{'cells ' + str(row['cells']):20s} {row['fraction']:.4f}")
        print(f"{'artifact':20s} {obj['artifact']}")
    return 0


def _run_calibrated_force(args) -> int:
    """``bdft design calibrated-force``: :mod:`designs.calibrated_force`."""
    out = check_artifact_targets("--out", args.out, [CALIBRATED_FORCE])
    certify = 3 if args.certify_samples is None else args.certify_samples
    from backhoe import default_family
    from designs.calibrated_force import calibrated_force_design
    from robust.jsonio import atomic_write_json

    print(
        f"[bdft design] calibrated handle force: coverage on {args.coverage_samples} members "
        f"(seed {args.seed + 2}), own limits on the first {args.limit_samples}, "
        f"{certify} operators certified ...",
        file=sys.stderr,
    )
    obj = calibrated_force_design(
        default_family(),
        samples=args.coverage_samples,
        limit_samples=args.limit_samples,
        certify=certify,
        seed=args.seed,
        n_jobs=args.jobs,
        progress=member_progress("calibrated designs"),
    )
    art = dict(obj, kind="bdft-calibrated-design")
    obj["artifact"] = str(atomic_write_json(out / f"{CALIBRATED_FORCE}.json", art))
    if args.json:
        print_json(obj)
        return 0
    print(f"{'set':20s} {obj['set']['actuators']}/{obj['set']['sensors']}")
    print(f"{'design dampings':20s} {obj['design_dampings']} (box members {obj['box_members']})")
    if obj["coverage"]:
        c = obj["coverage"]
        cov, lim = c["coverage"], c["limit"]
        print(
            f"{'coverage':20s} {cov['fraction']:.4f} ({cov['failures']} failures in "
            f"{cov['samples']}; P(failure) <= {cov['epsilon']:.4f} at {cov['confidence']})"
        )
        print(f"{'binding':20s} {c['binding']}")
        print(
            f"{'own limits':20s} {lim['coverage']:.4f} on the first {lim['samples']}; the "
            f"calibrated design {lim['calibrated_coverage']:.4f} there (ratio {lim['ratio']:.3g})"
        )
        print(f"{'within bounds':20s} {c['operator_within_bound']:.4f} (operator)")
        print(f"{'damping asked':20s} {c['dampings']}")
    if obj["certificates"]:
        for i, m in enumerate(obj["certificates"]["members"]):
            if not m["designed"]:
                text = f"no design ({m['binding']})"
            elif "error" in m:
                text = f"not certified: {m['error']}"
            else:
                text = (
                    f"[{m['lower']:.3g}, {m['upper']:.3g}] of its calibration's box (mu, "
                    f"order {m['order']})"
                )
            print(f"{'operator ' + str(i):20s} {text}")
    print(f"{'artifact':20s} {obj['artifact']}")
    return 0


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
        (parallel processes), ``no_cache`` (compute afresh, store nothing) and ``json``.

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
        rows = _listing()
        if args.json:
            print_json({"designs": rows})
        else:
            width = max(len(r["name"]) for r in rows)
            print("\n".join(f"{r['name']:<{width}}  {r['description']}" for r in rows))
        return 0
    if not args.name:
        raise UsageError(f"NAME: expected a design name or --list; got neither ({_names()})")
    if args.name not in _all_names():
        raise UsageError(f"NAME: unknown design {args.name!r}; expected one of {_names()}")
    if args.name == SCHEDULED:
        return _run_scheduled(args)
    if args.name == CALIBRATED_FORCE:
        return _run_calibrated_force(args)
    check_artifact_targets("--out", args.out, [args.name])
    from designs.registry import run_design

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
        cache=not args.no_cache,
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
        margin = None if res.checks is None else res.checks.margin
        if margin is not None:
            print(f"{'margin, certified':20s} {margin.lower:.4g}")
            print(f"{'margin, upper':20s} {margin.upper:.4g}")
        perf = None if res.checks is None else res.checks.performance
        if perf is not None:
            print(f"{'tracking, certified':20s} {perf.lower:.4g} (robust performance margin)")
            print(f"{'tracking, upper':20s} {perf.upper:.4g}")
        if res.coverage is not None:
            print(f"{'coverage':20s} {res.coverage.describe()}")
        for note in obj["notes"]:
            print(f"note: {note}")
    return 0
