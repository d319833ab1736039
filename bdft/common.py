"""What every ``bdft`` sub-command shares: JSON output on standard output."""

from __future__ import annotations

import json
import sys

from robust.jsonio import to_jsonable

__all__ = ["print_json"]


def print_json(obj) -> None:
    """Print one JSON object on stdout (numpy scalars and arrays converted).

    Parameters
    ----------
    obj : object
        A JSON-able object (dicts, lists, numbers, strings, numpy values).
    """
    sys.stdout.write(json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")
    sys.stdout.flush()
