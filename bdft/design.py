"""``bdft design``: list the shipped designs or run one on the default family."""

from __future__ import annotations

import sys


def register(sub) -> None:
    p = sub.add_parser(
        "design",
        help="list the compensator designs, or run one and write its artifact",
        description="Run one compensator design on the default family: build it, validate it on a "
        "seeded sample, reduce and discretise it, and write its artifact (JSON + .mat).",
    )
    p.add_argument("name", nargs="?", help="design name (see --list)")
    p.add_argument("--list", action="store_true", help="print the design names, one per line")
    p.add_argument(
        "--samples",
        type=int,
        default=2000,
        help="family members to validate on (default: %(default)s)",
    )
    p.add_argument("--seed", type=int, default=0, help="sampling seed (default: %(default)s)")
    p.add_argument("--method", choices=["mc", "lhs", "grid", "vertices"], default="lhs")
    p.add_argument(
        "--out", default="reports/out/designs", help="artifact folder (default: %(default)s)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    from bdft import print_json
    from designs.registry import design_names, run_design
    from robust.errors import ParameterError

    if args.list:
        print("\n".join(design_names()))
        return 0
    if not args.name:
        raise ParameterError("give a design NAME or --list")
    if args.samples < 1:
        raise ParameterError(f"--samples must be a positive integer; got {args.samples}")
    print(
        f"[bdft design] running {args.name!r} on {args.samples} members (seed {args.seed}) ...",
        file=sys.stderr,
    )
    res = run_design(
        args.name, samples=args.samples, seed=args.seed, method=args.method, out_dir=args.out
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
        for note in obj["notes"]:
            print(f"note: {note}")
    return 0
