"""What every ``bdft`` sub-command shares: JSON output on standard output."""

from __future__ import annotations

import json
import sys

from bdft.args import integer
from robust.jsonio import to_jsonable
from uncertainty.margins import DEFAULT_BOXES

__all__ = ["print_json", "add_margin_boxes_argument"]


def print_json(obj) -> None:
    """Print one JSON object on stdout (numpy scalars and arrays converted).

    Parameters
    ----------
    obj : object
        A JSON-able object (dicts, lists, numbers, strings, numpy values).
    """
    sys.stdout.write(json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")
    sys.stdout.flush()


def add_margin_boxes_argument(p, subject: str) -> None:
    """Add ``--margin-boxes``: sub-boxes per scale of the certified robust margin.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The sub-command's parser.
    subject : str
        What the margin is computed for, in the help text (e.g. ``"each design"``).
    """
    p.add_argument(
        "--margin-boxes",
        type=integer("--margin-boxes", low=0, high=100_000),
        default=DEFAULT_BOXES,
        help=f"sub-boxes per scale of the certified robust margin of {subject} (0: not "
        "computed; default: %(default)s)",
    )
