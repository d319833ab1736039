"""The ``bdft`` command line.

Each sub-command lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
taking the parsed arguments and returning the process exit code. Every command
that reports numbers has ``--json``, which prints exactly one JSON object on
standard output (progress and log lines go to standard error).
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys

from robust.errors import BDFTError

__all__ = ["main", "build_parser"]

#: Sub-command modules, in the order ``bdft --help`` lists them.
COMMANDS = [
    "reproduce",
    "validate",
    "sweep",
    "identify",
    "design",
    "report",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bdft",
        description="Biodynamic-feedthrough robust-control workbench.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        module = importlib.import_module(f"{__name__}.{name}")
        module.register(sub)
    return parser


def print_json(obj) -> None:
    """Print one JSON object on stdout (numpy scalars and arrays converted)."""
    from robust.jsonio import to_jsonable

    sys.stdout.write(json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")
    sys.stdout.flush()


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except BDFTError as exc:
        print(f"bdft {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
