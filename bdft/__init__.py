"""The ``bdft`` command line.

Each sub-command lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
taking the parsed arguments and returning the process exit code. Every command
that reports numbers has ``--json``, which prints exactly one JSON object on
standard output (progress and log lines go to standard error).
"""

from __future__ import annotations

import argparse
import sys

from bdft import design, identify, report, reproduce, sweep, validate
from robust.errors import BDFTError

__all__ = ["main", "build_parser", "COMMANDS"]

#: Sub-command modules, in the order ``bdft --help`` lists them.
COMMANDS = (reproduce, validate, sweep, identify, design, report)


def build_parser() -> argparse.ArgumentParser:
    """The ``bdft`` argument parser with every sub-command registered.

    Returns
    -------
    argparse.ArgumentParser
        Parser of ``bdft COMMAND ...``, one sub-parser per module of :data:`COMMANDS`
        (each module's ``register``); the parsed namespace's ``func`` runs the command.
    """
    parser = argparse.ArgumentParser(
        prog="bdft",
        description="Biodynamic-feedthrough robust-control workbench.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for module in COMMANDS:
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``bdft`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit code: 0 on success, 2 on a reported error.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except BDFTError as exc:
        print(f"bdft {args.command}: error: {exc}", file=sys.stderr)
        return 2
