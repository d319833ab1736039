"""The ``bdft`` command line.

Each sub-command lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
taking the parsed arguments and returning the process exit code. Every command
that reports numbers has ``--json``, which prints exactly one JSON object on
standard output (progress, timings and log lines go to standard error, so the
same options and seed give the same bytes, on any x86-64 CPU with AVX2 and FMA: the
package fixes OpenBLAS's and NumPy's kernels before NumPy is imported,
:mod:`bdft.kernels`).

Options are checked before any work by one argument layer, :mod:`bdft.args`.
Building the parser and parsing need no numerical library: the options' choices and
defaults come from modules that import nothing (:mod:`backhoe.constants`,
:mod:`uncertainty.constants`, :mod:`designs.constants`), and each command module imports
the layers that do the work (NumPy, SciPy, python-control, CVXPY, Matplotlib) in the
functions that run the command, so ``bdft --help``, ``bdft COMMAND --help`` and argument
errors are answered at once (``tests/test_cli_startup.py``,
``benchmarks/bench_cli.py``).

Exit codes:

* 0: success;
* 2: bad input (an option, an input file, an output path) or a failed computation
  the workbench reports on purpose (:class:`robust.errors.BDFTError`); standard
  error gets exactly one line, ``bdft COMMAND: error: ...``, naming the option or
  file, what was expected and what was got;
* 1: an unexpected internal error (a bug); standard error gets one line saying
  where the full traceback was written (a ``bdft-COMMAND-*.log`` file in
  ``BDFT_LOG_DIR``, or the system's temporary folder);
* 130: interrupted (Ctrl-C).
"""

from __future__ import annotations

import atexit
import os
import sys
import tempfile
import threading
import traceback

# before anything imports NumPy: the same kernels on every x86-64 CPU (bdft.kernels)
from bdft.kernels import pin_numeric_kernels

pin_numeric_kernels()

from bdft import design, identify, limit, margin, report, reproduce, sweep, validate  # noqa: E402
from bdft.args import ArgumentParser, UsageError  # noqa: E402
from robust.engine import stop_workers  # noqa: E402
from robust.errors import BDFTError  # noqa: E402
from robust.version import __version__  # noqa: E402

__all__ = ["main", "program", "console", "build_parser", "COMMANDS", "LOG_DIR_ENV"]

#: Sub-command modules, in the order ``bdft --help`` lists them.
COMMANDS = (reproduce, validate, margin, sweep, identify, design, limit, report)

#: Environment variable naming the folder for tracebacks of internal errors.
LOG_DIR_ENV = "BDFT_LOG_DIR"


def build_parser() -> ArgumentParser:
    """The ``bdft`` argument parser with every sub-command registered.

    Returns
    -------
    bdft.args.ArgumentParser
        Parser of ``bdft COMMAND ...``, one sub-parser per module of :data:`COMMANDS`
        (each module's ``register``); the parsed namespace's ``func`` runs the command.
        Parse errors raise :class:`bdft.args.UsageError` instead of exiting.
    """
    parser = ArgumentParser(
        prog="bdft",
        description="Biodynamic-feedthrough robust-control workbench.",
        epilog="Exit codes: 0 success; 2 bad input or a reported error (one line on "
        "standard error); 1 internal error (the line names the traceback file).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for module in COMMANDS:
        module.register(sub)
    return parser


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _command_of(argv: list[str]) -> str:
    names = {m.__name__.rsplit(".", 1)[1] for m in COMMANDS}
    for arg in argv:
        if arg in names:
            return arg
        if not arg.startswith("-"):
            break
    return ""


def _write_traceback(command: str, argv: list[str]) -> str:
    """Write the current exception's traceback to a log file and return its path."""
    folder = os.environ.get(LOG_DIR_ENV) or tempfile.gettempdir()
    fd, path = tempfile.mkstemp(prefix=f"bdft-{command or 'main'}-", suffix=".log", dir=folder)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(f"bdft-workbench {__version__}\n")
        fh.write(f"command: bdft {' '.join(argv)}\n\n")
        fh.write(traceback.format_exc())
    return path


def main(argv: list[str] | None = None) -> int:
    """Run the ``bdft`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit code: 0 on success, 2 on bad input or a reported error, 1 on an
        unexpected internal error, 130 when interrupted (see the module notes).
        ``--help`` still exits through :class:`SystemExit` with code 0.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    command = _command_of(argv)
    prog = f"bdft {command}" if command else "bdft"
    try:
        parser = build_parser()
        args, extra = parser.parse_known_args(argv)
        command = args.command
        prog = f"bdft {command}"
        if extra:
            raise UsageError(
                f"unrecognized arguments: expected only the options of 'bdft {command} --help'; "
                f"got {' '.join(extra)}"
            )
        return int(args.func(args) or 0)
    except UsageError as exc:
        print(f"{exc.prog or prog}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except BDFTError as exc:
        print(f"{prog}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - the last resort: one line and a log file
        what = _one_line(f"{type(exc).__name__}: {exc}")[:300]
        try:
            where = f"the full traceback is in {_write_traceback(command, argv)}"
        except OSError as log_exc:
            where = f"the traceback could not be written ({_one_line(log_exc)})"
        print(f"{prog}: internal error: {what}; this is a bug, {where}", file=sys.stderr)
        return 1


def program() -> int:
    """The ``bdft`` program: :func:`main` on ``sys.argv``, then its worker processes ended.

    The local worker processes of a command's ``--jobs`` are idle once :func:`main`
    returns; ending them at once (:func:`robust.engine.stop_workers`) spares the wait for
    their interpreters' shutdown. :func:`main` itself leaves them to the next call (a
    program calling it repeatedly reuses them). The console script and ``python -m bdft``
    run :func:`console`, which also ends the process.

    Returns
    -------
    int
        :func:`main`'s exit code.
    """
    try:
        return main()
    finally:
        stop_workers()


def console() -> int:
    """The ``bdft`` console script and ``python -m bdft``: :func:`program`, then the exit.

    A command's results are written and its files closed when :func:`program` returns;
    what remains of a normal exit is the interpreter's finalisation of every module the
    numerical libraries imported (0.4-0.6 s, for nothing). So the standard streams are
    flushed, the exit handlers run (:mod:`atexit`: logging, temporary folders, the worker
    pools' trackers, Dask's clusters), the streams are flushed again and the process ends
    with :func:`os._exit`. With a thread still running that a normal exit would wait for
    (not a daemon), or a stream that cannot be flushed (a closed pipe), nothing is cut
    short: the normal exit follows.

    Returns
    -------
    int
        :func:`program`'s exit code (when the process did not end here).
    """
    code = program()
    main_thread = threading.main_thread()
    if any(t is not main_thread and not t.daemon for t in threading.enumerate()):
        return code  # (a normal exit waits for it; daemon threads end with the process)
    if not _flushed():
        return code
    atexit._run_exitfuncs()
    if not _flushed():
        return code  # (the normal exit reports what could not be written)
    os._exit(code)


def _flushed() -> bool:
    """Flush standard output and error (those the process has); whether both went out."""
    for stream in (sys.stdout, sys.stderr):
        if stream is None:
            continue
        try:
            stream.flush()
        except (OSError, ValueError):
            return False
    return True
