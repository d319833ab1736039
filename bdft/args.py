"""The one argument layer of the ``bdft`` command line: every option is checked before work.

Every sub-command builds its parser from :class:`ArgumentParser` and the option types
below, and checks its files and output paths with the ``check_*`` functions at the
start of its ``run``, before any computation. A bad option never reaches the
computation: it raises :class:`UsageError` (a :class:`robust.errors.ParameterError`),
which :func:`bdft.main` prints as exactly one line::

    bdft COMMAND: error: --OPTION: expected WHAT; got VALUE

and exits with code 2 (argparse's own errors, such as an unknown choice, are
printed in the same form).

Sizes are checked against a memory budget, :func:`memory_budget` (4 GiB, or
``BDFT_MEMORY_BUDGET_GIB`` from the environment): a family member costs
:data:`BYTES_PER_MEMBER` bytes while a sample is drawn and validated (its parameter
values, the sampling's working copies and its metrics), and a member of a batch
:data:`BYTES_PER_BATCH_MEMBER` (its closed-loop matrices and poles), so
``--samples`` is at most :func:`max_members` and ``--chunk`` at most
:func:`max_batch`; the help of each option states its limit.

Output paths are checked for a writable parent, and are never a file or folder of
the user's: a report folder may replace only a previous report of ours
(:func:`reports.html.check_report_target`), an artifact only a previous artifact
(:func:`robust.export.check_artifact_target`), a component-fit file only a previous
component fit.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

from robust.errors import ParameterError

__all__ = [
    "ArgumentParser",
    "UsageError",
    "MEMORY_BUDGET_ENV",
    "DEFAULT_MEMORY_BUDGET_GIB",
    "MAX_FAMILY_PARAMETERS",
    "BYTES_PER_MEMBER",
    "MAX_LOOP_STATES",
    "BYTES_PER_BATCH_MEMBER",
    "MAX_SEED",
    "MAX_JSON_BYTES",
    "memory_budget",
    "max_members",
    "max_batch",
    "integer",
    "real",
    "members",
    "batch",
    "seed",
    "members_help",
    "batch_help",
    "check_output_dir",
    "check_report_dir",
    "check_output_file",
    "check_artifact_targets",
    "check_input_file",
    "check_json_file",
]

#: Environment variable that sets the memory budget, in GiB.
MEMORY_BUDGET_ENV = "BDFT_MEMORY_BUDGET_GIB"
#: Memory budget without :data:`MEMORY_BUDGET_ENV`, GiB.
DEFAULT_MEMORY_BUDGET_GIB = 4.0
#: Uncertain parameters of the largest shipped family (the physical human's: four of the
#: valve/cylinder, five of the structure, six of the operator); tests check that no family
#: has more.
MAX_FAMILY_PARAMETERS = 15
#: Bytes one family member costs while a sample is drawn and validated: its parameter
#: values, the sampling's unit and quantile copies (three float64 rows of
#: :data:`MAX_FAMILY_PARAMETERS`) and its metrics (largest real part, damping, stability
#: flag, three float64). Measured: about 265 bytes per member for a million members.
BYTES_PER_MEMBER = 8 * (3 * MAX_FAMILY_PARAMETERS + 3)
#: Closed-loop states a batch is sized for (the loop's 13-15 and a controller's).
MAX_LOOP_STATES = 32
#: Bytes one member of a batch costs: closed-loop ``A`` and the eigenvalue work space,
#: about ``40 n^2`` bytes for ``n`` states (:func:`uncertainty.validate_family`).
BYTES_PER_BATCH_MEMBER = 40 * MAX_LOOP_STATES**2
#: Largest sampling seed (a signed 64-bit integer, as JSON and MATLAB readers keep it).
MAX_SEED = 2**63 - 1
#: Largest JSON input file (controller, component fit) the command line reads.
MAX_JSON_BYTES = 64 * 2**20


class UsageError(ParameterError):
    """A command-line option or argument is wrong; printed as one line, exit code 2.

    Parameters
    ----------
    message : str
        What is wrong: the option, what was expected, what was got.
    prog : str, optional
        The program the message is about (``"bdft validate"``); :func:`bdft.main`
        uses the running sub-command's when empty.
    """

    def __init__(self, message: str, prog: str = ""):
        super().__init__(message)
        self.prog = prog


_JSON_TYPES = {
    list: "array",
    str: "string",
    int: "number",
    float: "number",
    bool: "boolean",
    type(None): "null",
}
_ARGUMENT_PREFIX = re.compile(r"^argument ([^:]+): ")
_INVALID_CHOICE = re.compile(r"invalid choice: (.+) \(choose from (.+)\)$")
_REQUIRED = re.compile(r"^the following arguments are required: (.+)$")


def _consistent(message: str) -> str:
    """argparse's messages in the form of the others: ``OPTION: expected ...; got ...``."""
    message = _ARGUMENT_PREFIX.sub(r"\1: ", message)
    message = _INVALID_CHOICE.sub(r"expected one of \2; got \1 (invalid choice)", message)
    return _REQUIRED.sub(r"\1: expected a value (required); got none", message)


class ArgumentParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose errors raise :class:`UsageError`.

    Instead of printing the usage and exiting, a parsing error (a missing or
    malformed option, an unknown choice) raises :class:`UsageError` with the
    parser's ``prog`` and the message ``--option: ...`` (argparse's
    ``argument --option: ...`` shortened), so :func:`bdft.main` prints it as one line.
    Sub-parsers made by :meth:`add_subparsers` are of this class too.

    Parameters
    ----------
    *args, **kwargs
        As for :class:`argparse.ArgumentParser`.
    """

    def error(self, message: str):
        """Raise :class:`UsageError` for ``message`` (argparse calls this on a parse error).

        Parameters
        ----------
        message : str
            argparse's message.
        """
        raise UsageError(_consistent(message), prog=self.prog)


def memory_budget() -> int:
    """The memory budget in bytes: ``BDFT_MEMORY_BUDGET_GIB`` GiB, or 4 GiB when unset.

    Returns
    -------
    int
        Bytes a command may plan to hold for its sample and batches.

    Raises
    ------
    UsageError
        If the environment variable is set to anything but a positive finite number.
    """
    text = os.environ.get(MEMORY_BUDGET_ENV)
    if text is None or not text.strip():
        return int(DEFAULT_MEMORY_BUDGET_GIB * 2**30)
    try:
        gib = float(text)
    except ValueError:
        gib = math.nan
    if not math.isfinite(gib) or gib <= 0:
        raise UsageError(f"{MEMORY_BUDGET_ENV}: expected a positive number of GiB; got {text!r}")
    return int(gib * 2**30)


def _gib(nbytes: int) -> str:
    return f"{nbytes / 2**30:g} GiB"


def max_members() -> int:
    """Largest ``--samples``: the memory budget over :data:`BYTES_PER_MEMBER`.

    Returns
    -------
    int
        Members a sample may hold (about 14.9 million with the default 4 GiB).
    """
    return memory_budget() // BYTES_PER_MEMBER


def max_batch() -> int:
    """Largest ``--chunk``: the memory budget over :data:`BYTES_PER_BATCH_MEMBER`.

    Returns
    -------
    int
        Members a batch may hold (about 105 thousand with the default 4 GiB).
    """
    return memory_budget() // BYTES_PER_BATCH_MEMBER


def _parse_int(option: str, text: str, expected: str) -> int:
    try:
        return int(text)
    except ValueError:
        pass
    try:
        x = float(text)  # "1e6" is a fine way to write a million
    except ValueError:
        x = math.nan
    if math.isfinite(x) and x.is_integer():
        return int(x)
    raise argparse.ArgumentTypeError(f"expected {expected}; got {text!r}")


def integer(
    option: str,
    *,
    low: int | None = None,
    high: int | None = None,
    why: str = "",
    expected: str = "",
) -> Callable[[str], int]:
    """An argparse ``type``: an integer in ``[low, high]``.

    Integers may be written in float notation when they are whole (``1e6``).

    Parameters
    ----------
    option : str
        The option's name (for the function's name; argparse names the option in the
        message).
    low, high : int, optional
        Bounds, inclusive; None for unbounded.
    why : str, optional
        Why ``high`` is the limit, appended to the message when it is exceeded (e.g.
        the memory budget).
    expected : str, optional
        What is expected, in words, instead of the bounds (``"an integer in
        [0, 2**63)"``).

    Returns
    -------
    callable
        ``parse(text) -> int``; raises :class:`argparse.ArgumentTypeError` with
        ``expected ...; got ...``.
    """
    if expected:
        pass
    elif low is not None and high is not None:
        expected = f"an integer from {low:,} to {high:,}"
    elif low is not None:
        expected = {0: "a non-negative integer", 1: "a positive integer"}.get(
            low, f"an integer >= {low:,}"
        )
    elif high is not None:
        expected = f"an integer <= {high:,}"
    else:
        expected = "an integer"

    def parse(text: str) -> int:
        n = _parse_int(option, text, expected)
        if (low is not None and n < low) or (high is not None and n > high):
            extra = f" ({why})" if why and high is not None and n > high else ""
            raise argparse.ArgumentTypeError(f"expected {expected}{extra}; got {text}")
        return n

    parse.__name__ = f"integer for {option}"
    return parse


def real(
    option: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    unit: str = "",
) -> Callable[[str], float]:
    """An argparse ``type``: a finite real number within bounds.

    Parameters
    ----------
    option : str
        The option's name (for the function's name).
    low, high : float, optional
        Bounds; None for unbounded.
    low_open, high_open : bool, optional
        Whether the bound itself is excluded.
    unit : str, optional
        Unit named in the message (``"Hz"``).

    Returns
    -------
    callable
        ``parse(text) -> float``; NaN and infinities are refused.
    """
    lo = "(" if low_open or low is None else "["
    hi = ")" if high_open or high is None else "]"
    a = "-inf" if low is None else f"{low:g}"
    b = "inf" if high is None else f"{high:g}"
    if low is None and high is None:
        expected = "a finite number"
    elif low == 0 and low_open and high is None:
        expected = "a positive finite number"
    else:
        expected = f"a finite number in {lo}{a}, {b}{hi}"
    if unit:
        expected += f" ({unit})"

    def parse(text: str) -> float:
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}; got {text!r}") from None
        bad = not math.isfinite(x)
        if low is not None:
            bad |= x <= low if low_open else x < low
        if high is not None:
            bad |= x >= high if high_open else x > high
        if bad:
            raise argparse.ArgumentTypeError(f"expected {expected}; got {text}")
        return x

    parse.__name__ = f"number for {option}"
    return parse


def factor_list(option: str) -> Callable[[str], tuple]:
    """An argparse ``type``: comma-separated positive factors (at most 8), or ``none``.

    Parameters
    ----------
    option : str
        The option's name (for the function's name).

    Returns
    -------
    callable
        ``parse(text) -> tuple of float`` (empty for ``none``).
    """
    one = real(option, low=0.0, low_open=True, high=100.0)

    def parse(text: str) -> tuple:
        if text.strip().lower() == "none":
            return ()
        parts = [t for t in text.split(",") if t.strip()]
        if not parts or len(parts) > 8:
            raise argparse.ArgumentTypeError(
                f"expected 1 to 8 comma-separated factors in (0, 100] or 'none'; got {text!r}"
            )
        return tuple(one(t.strip()) for t in parts)

    parse.__name__ = f"factors for {option}"
    return parse


def members(option: str = "--samples") -> Callable[[str], int]:
    """An argparse ``type`` for a number of family members: 1 to :func:`max_members`.

    Parameters
    ----------
    option : str, optional
        The option's name.

    Returns
    -------
    callable
        ``parse(text) -> int``; the message of a value over the limit states the
        memory budget and the bytes per member.
    """
    budget = memory_budget()
    return integer(
        option,
        low=1,
        high=budget // BYTES_PER_MEMBER,
        why=f"the {_gib(budget)} memory budget at {BYTES_PER_MEMBER} bytes per member; "
        f"set {MEMORY_BUDGET_ENV} to change it",
    )


def batch(option: str = "--chunk") -> Callable[[str], int]:
    """An argparse ``type`` for members per batch: 1 to :func:`max_batch`.

    Parameters
    ----------
    option : str, optional
        The option's name.

    Returns
    -------
    callable
        ``parse(text) -> int``.
    """
    budget = memory_budget()
    return integer(
        option,
        low=1,
        high=budget // BYTES_PER_BATCH_MEMBER,
        why=f"the {_gib(budget)} memory budget at {BYTES_PER_BATCH_MEMBER} bytes per batch "
        f"member; set {MEMORY_BUDGET_ENV} to change it",
    )


def seed(option: str = "--seed") -> Callable[[str], int]:
    """An argparse ``type`` for a sampling seed: 0 to :data:`MAX_SEED`.

    Parameters
    ----------
    option : str, optional
        The option's name.

    Returns
    -------
    callable
        ``parse(text) -> int``.
    """
    return integer(
        option,
        low=0,
        high=MAX_SEED,
        expected="an integer from 0 to 2**63-1",
        why="a signed 64-bit integer",
    )


def members_help(text: str) -> str:
    """Help text of a members option, with its limit appended.

    Parameters
    ----------
    text : str
        What the option is (argparse's ``%(default)s`` may be used).

    Returns
    -------
    str
        ``text`` and ``at most N (the memory budget at B bytes per member)``.
    """
    budget = memory_budget()
    return (
        f"{text}; at most {budget // BYTES_PER_MEMBER:,} ({_gib(budget)} memory budget at "
        f"{BYTES_PER_MEMBER} bytes per member; {MEMORY_BUDGET_ENV} changes it)"
    )


def batch_help(text: str) -> str:
    """Help text of a batch-size option, with its limit appended.

    Parameters
    ----------
    text : str
        What the option is.

    Returns
    -------
    str
        ``text`` and its limit.
    """
    budget = memory_budget()
    return (
        f"{text}; at most {budget // BYTES_PER_BATCH_MEMBER:,} ({_gib(budget)} memory budget "
        f"at {BYTES_PER_BATCH_MEMBER} bytes per batch member)"
    )


def _existing_ancestor(path: Path) -> Path:
    ancestor = path.absolute()
    while not (ancestor.exists() or ancestor.is_symlink()):
        ancestor = ancestor.parent
    return ancestor


def _can_create_in(folder: Path) -> str | None:
    """None if a file can be created in ``folder`` (tried, not guessed); else the reason."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return exc.strerror or str(exc)
    return None


def _check_creatable(option: str, path: Path, what: str) -> None:
    """The nearest existing folder at or above ``path``'s place must be one bdft can write in.

    Checked by creating (and at once removing) an unnamed file there: permission
    bits do not tell for root, read-only mounts or virtual file systems.
    """
    ancestor = _existing_ancestor(path if path.is_dir() else path.parent)
    if not ancestor.is_dir():
        raise UsageError(f"{option}: expected {what}; got {str(path)!r}, but {ancestor} is a file")
    why = _can_create_in(ancestor)
    if why is not None:
        raise UsageError(
            f"{option}: expected {what} in a folder bdft can write; got {str(path)!r}, "
            f"but files cannot be created in {ancestor} ({why})"
        )


def check_output_dir(option: str, path: str | os.PathLike) -> Path:
    """Check an output folder (artifacts, plots): a writable folder, or one bdft can create.

    Parameters
    ----------
    option : str
        The option that gave it (``"--out"``).
    path : str or os.PathLike
        The folder.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    UsageError
        If ``path`` is empty, an existing file, or not creatable or writable.
    """
    if str(path) == "":
        raise UsageError(f"{option}: expected a folder path; got an empty string")
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise UsageError(
            f"{option}: expected a folder; got {str(p)!r}, an existing file (not replaced)"
        )
    _check_creatable(option, p, "a folder")
    return p


def check_report_dir(option: str, path: str | os.PathLike) -> Path:
    """Check a report folder: new, or a previous report of ours, in a writable folder.

    Parameters
    ----------
    option : str
        The option that gave it (``"--out"``).
    path : str or os.PathLike
        The report folder.

    Returns
    -------
    pathlib.Path
        The absolute folder path.

    Raises
    ------
    UsageError
        If :func:`reports.html.check_report_target` refuses it (an existing file, a
        folder of the user's, an unwritable place).
    """
    from reports.html import check_report_target  # (Matplotlib: not for --help)

    try:
        return check_report_target(path, option=option)
    except ParameterError as exc:
        raise UsageError(str(exc)) from None


def check_output_file(
    option: str,
    path: str | os.PathLike,
    *,
    kind: str,
    suffix: str = ".json",
) -> Path:
    """Check an output JSON file: a writable place, and no file of the user's replaced.

    Parameters
    ----------
    option : str
        The option that gave it (``"--save-model"``).
    path : str or os.PathLike
        The file.
    kind : str
        The ``kind`` field of the files bdft writes there; an existing file is
        replaced only when it is a JSON object of that kind.
    suffix : str, optional
        Required file-name ending.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    UsageError
        If ``path`` is empty, lacks ``suffix``, is a folder, is an existing file of
        another kind, or is not creatable or writable.
    """
    if str(path) == "":
        raise UsageError(f"{option}: expected a {suffix} file path; got an empty string")
    p = Path(path)
    if p.is_dir():
        raise UsageError(f"{option}: expected a {suffix} file; got {str(p)!r}, a folder")
    if p.suffix.lower() != suffix:
        raise UsageError(f"{option}: expected a file name ending in {suffix}; got {str(p)!r}")
    if p.exists() or p.is_symlink():
        if _json_kind(p) != kind:
            raise UsageError(
                f"{option}: expected a new file or a previous {kind!r} file; got {str(p)!r}, "
                "an existing file of another kind (not replaced)"
            )
    _check_creatable(option, p, f"a {suffix} file")
    return p


def _json_kind(path: Path) -> str | None:
    try:
        if not path.is_file() or path.stat().st_size > MAX_JSON_BYTES:
            return None
        obj = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    kind = obj.get("kind") if isinstance(obj, dict) else None
    return kind if isinstance(kind, str) else None


def check_artifact_targets(option: str, folder: str | os.PathLike, names: Sequence[str]) -> Path:
    """Check an artifact folder and the artifacts ``<name>.json`` / ``.mat`` it will receive.

    Parameters
    ----------
    option : str
        The option that gave the folder (``"--out"``).
    folder : str or os.PathLike
        The folder.
    names : sequence of str
        Design names whose artifacts are written there.

    Returns
    -------
    pathlib.Path
        ``folder``.

    Raises
    ------
    UsageError
        If the folder is not usable (:func:`check_output_dir`) or an existing file
        there is not a previous artifact (:func:`robust.export.check_artifact_target`).
    """
    from robust.export import check_artifact_target  # (NumPy, python-control: not for --help)

    p = check_output_dir(option, folder)
    for name in names:
        try:
            check_artifact_target(p / f"{name}.json")
        except ParameterError as exc:
            raise UsageError(f"{option}: {exc}") from None
    return p


def check_input_file(
    option: str,
    path: str | os.PathLike,
    *,
    what: str,
    max_bytes: int,
    suffixes: Sequence[str] | None = None,
) -> Path:
    """Check an input file: it exists, is a readable regular file, and is not too big.

    Parameters
    ----------
    option : str
        The option or argument that gave it (``"--controller"``, ``"DATA"``).
    path : str or os.PathLike
        The file.
    what : str
        What the file should be, for messages (``"a JSON file"``).
    max_bytes : int
        Largest accepted size.
    suffixes : sequence of str, optional
        Accepted file-name endings (lower case), any when None.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    UsageError
        Naming ``option``, what was expected and what was found.
    """
    p = Path(path)
    if str(path) == "":
        raise UsageError(f"{option}: expected {what}; got an empty path")
    if not p.exists():
        raise UsageError(f"{option}: expected {what}; got {str(p)!r}, which does not exist")
    if p.is_dir():
        raise UsageError(f"{option}: expected {what}; got {str(p)!r}, a folder")
    if not p.is_file():
        raise UsageError(f"{option}: expected {what}; got {str(p)!r}, not a regular file")
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise UsageError(
            f"{option}: expected {what} (name ending in {' or '.join(suffixes)}); got {str(p)!r}"
        )
    if not os.access(p, os.R_OK):
        raise UsageError(f"{option}: expected {what} bdft can read; got {str(p)!r}, not readable")
    size = p.stat().st_size
    if size > max_bytes:
        raise UsageError(
            f"{option}: expected {what} of at most {max_bytes:,} bytes; "
            f"got {str(p)!r} with {size:,} bytes"
        )
    return p


def _huge_integer(obj) -> int | None:
    """The first integer in a parsed JSON value too large for a float64, or None."""
    stack = [obj]
    while stack:
        v = stack.pop()
        if isinstance(v, dict):
            stack.extend(v.values())
        elif isinstance(v, list):
            stack.extend(v)
        elif isinstance(v, int) and not isinstance(v, bool) and abs(v) > sys.float_info.max:
            return v
    return None


def check_json_file(option: str, path: str | os.PathLike) -> Path:
    """Check a JSON input file: readable, at most :data:`MAX_JSON_BYTES`, one JSON object.

    The loaders check the fields; this makes sure that what they are given parses.

    Parameters
    ----------
    option : str
        The option that gave it (``"--controller"``, ``"--plant-file"``).
    path : str or os.PathLike
        The file.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    UsageError
        If the file is missing, a folder, unreadable, too big, not UTF-8, not JSON,
        nested too deeply, holds an integer no float can hold, or is not a JSON object.
    """
    what = "a JSON file"
    p = check_input_file(option, path, what=what, max_bytes=MAX_JSON_BYTES)
    raw = p.read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UsageError(
            f"{option}: expected {what}; got {str(p)!r}, which is not UTF-8 text "
            f"(byte {raw[exc.start]:#04x} at offset {exc.start})"
        ) from None
    try:
        obj = json.loads(text)
    except RecursionError:
        raise UsageError(
            f"{option}: expected {what}; got {str(p)!r}, which is nested too deeply to read"
        ) from None
    except ValueError as exc:
        raise UsageError(
            f"{option}: expected {what}; got {str(p)!r}, which is not valid JSON ({exc})"
        ) from None
    big = _huge_integer(obj)
    if big is not None:
        raise UsageError(
            f"{option}: expected {what} of numbers a 64-bit float can hold; got {str(p)!r}, "
            f"holding an integer of {len(str(abs(big)))} digits"
        )
    if not isinstance(obj, dict):
        raise UsageError(
            f"{option}: expected {what} holding one JSON object; got {str(p)!r}, "
            f"holding a JSON {_JSON_TYPES.get(type(obj), type(obj).__name__)}"
        )
    return p
