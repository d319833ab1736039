"""Run one design as a script: ``python -m designs NAME [--samples N] [--seed S] [--out DIR]``.

The design runs through the common pipeline on the default family and its
summary is printed as one JSON object (the same object as ``bdft design NAME --json``).
"""

from __future__ import annotations

import argparse
import json
import sys

from designs.registry import design_names, run_design
from robust.jsonio import to_jsonable

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Run the design named in ``argv`` and print its JSON summary.

    Parameters
    ----------
    argv : list of str, optional
        ``NAME [--samples N] [--seed S] [--out DIR] [--coverage-samples N]``
        (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Process exit code (0).
    """
    parser = argparse.ArgumentParser(
        prog="python -m designs",
        description="Run one design on the default family and print its summary as JSON.",
    )
    parser.add_argument("name", choices=design_names(), help="design name")
    parser.add_argument("--samples", type=int, default=2000, help="family members (default 2000)")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (default 0)")
    parser.add_argument("--out", default=None, help="artifact folder (default: none written)")
    parser.add_argument(
        "--coverage-samples",
        type=int,
        default=2000,
        help="independent members of the coverage certificate, 0 to skip (default 2000)",
    )
    args = parser.parse_args(argv)
    res = run_design(
        args.name,
        samples=args.samples,
        seed=args.seed,
        out_dir=args.out,
        coverage_samples=args.coverage_samples,
    )
    sys.stdout.write(json.dumps(to_jsonable(res.to_json()), indent=2, allow_nan=False) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
