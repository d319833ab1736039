"""What every ``bdft`` sub-command shares: JSON output on standard output."""

from __future__ import annotations

import json
import os
import sys

from bdft.args import integer
from uncertainty.constants import DEFAULT_BOXES

__all__ = [
    "print_json",
    "add_margin_boxes_argument",
    "add_coverage_arguments",
    "add_jobs_argument",
    "member_progress",
]


def print_json(obj) -> None:
    """Print one JSON object on stdout (numpy scalars and arrays converted).

    Floats are printed to :data:`robust.jsonio.JSON_DIGITS` significant digits
    (:func:`robust.jsonio.round_significant`), so the same run prints the same bytes on
    any CPU and BLAS thread count.

    Parameters
    ----------
    obj : object
        A JSON-able object (dicts, lists, numbers, strings, numpy values).
    """
    from robust.jsonio import round_significant, to_jsonable

    out = round_significant(to_jsonable(obj))
    sys.stdout.write(json.dumps(out, indent=2, allow_nan=False) + "\n")
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


def add_coverage_arguments(p, subject: str) -> None:
    """Add ``--coverage-samples`` and ``--jobs``: the coverage certificate of ``subject``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The sub-command's parser.
    subject : str
        What the coverage is computed for, in the help text.
    """
    p.add_argument(
        "--coverage-samples",
        type=integer("--coverage-samples", low=0, high=1_000_000),
        default=2000,
        help=f"independent members (Monte Carlo, seed SEED+2) on which the specification is "
        f"checked for the coverage certificate of {subject} (0: not computed; "
        "default: %(default)s)",
    )
    add_jobs_argument(p)


def add_jobs_argument(p, *, workers: str = "parallel processes") -> None:
    """Add ``--jobs``: parallel workers, 1 to 256 (default: the number of cores).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The sub-command's parser.
    workers : str
        What the jobs are, for the help text (default ``"parallel processes"``).
    """
    p.add_argument(
        "--jobs",
        type=integer("--jobs", low=1, high=256),
        default=max(1, os.cpu_count() or 1),
        help=f"{workers} (default: the number of cores, %(default)s)",
    )


def add_cache_argument(p) -> None:
    """Add ``--no-cache``: compute everything, neither reading nor writing the result cache.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The sub-command's parser.
    """
    p.add_argument(
        "--no-cache",
        action="store_true",
        help="compute every result afresh and store nothing (default: results are kept in "
        "$BDFT_CACHE_DIR or ~/.cache/bdft under a hash of their inputs and of the code, so a "
        "rerun with nothing changed is fast)",
    )


def add_scheduler_argument(p) -> None:
    """Add ``--scheduler ADDRESS``: run the work's tasks on a Dask distributed cluster.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The sub-command's parser.
    """
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="address of a Dask scheduler (tcp://host:8786) whose workers run the tasks, or "
        "local:N for a local Dask cluster of N workers (default: $DASK_SCHEDULER_ADDRESS if "
        "set, else local processes, --jobs); the same results as a local run; needs pip "
        'install ".[distributed]"',
    )


def member_progress(desc: str):
    """A ``progress(done, total)`` callback drawing a tqdm bar on standard error.

    The bar appears on terminals only (tqdm's ``disable=None``) and closes itself when
    ``done`` reaches ``total``.

    Parameters
    ----------
    desc : str
        Label in front of the bar.
    """
    state = {}

    def progress(done: int, total: int) -> None:
        bar = state.get("bar")
        if bar is None:
            from tqdm import tqdm

            bar = state["bar"] = tqdm(
                total=total, desc=desc, unit="member", file=sys.stderr, disable=None, leave=False
            )
        bar.update(done - bar.n)
        if done >= total:
            bar.close()
            state.pop("bar")

    return progress
