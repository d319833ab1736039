"""``bdft validate``: closed-loop poles across a family of loops (optionally with a controller)."""

from __future__ import annotations

import sys
import time

from backhoe.constants import DAMPING_BAND_HZ, DEFAULT_POSTURE, POSTURES, RANGES
from bdft.args import (
    UsageError,
    batch,
    batch_help,
    check_input_file,
    check_json_file,
    members,
    members_help,
    real,
    seed,
)
from bdft.common import add_jobs_argument, add_scheduler_argument, print_json
from uncertainty.constants import DEFAULT_CHUNK

__all__ = [
    "add_family_arguments",
    "add_system_argument",
    "read_system",
    "controller_source",
    "build_family",
    "check_family_arguments",
    "progress_bar",
    "register",
    "run",
]

_METHODS = ("mc", "lhs", "grid", "vertices")


def add_family_arguments(p, *, samples: int, samples_help: str | None = None) -> None:
    """Add the options shared by ``validate`` and ``sweep``: family, sampling, plant files.

    The options are ``--samples``, ``--seed``, ``--human``, ``--posture``, ``--ranges``,
    ``--plant-file`` (repeatable) and ``--chunk``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The sub-command's parser.
    samples : int
        Default of ``--samples`` (number of family members; ``sweep`` and ``margin`` pass 0,
        meaning their own defaults).
    samples_help : str, optional
        The help of ``--samples`` (default: the number of members and the default).
    """
    p.add_argument(
        "--samples",
        type=members("--samples"),
        default=samples,
        help=members_help(samples_help or "number of members (default: %(default)s)"),
    )
    p.add_argument(
        "--seed",
        type=seed("--seed"),
        default=0,
        help="sampling seed, 0 to 2**63-1, written into the output (default: %(default)s)",
    )
    p.add_argument(
        "--human",
        choices=["literal", "physical"],
        default="physical",
        help="human variant of every member (default: %(default)s)",
    )
    p.add_argument(
        "--posture",
        choices=list(POSTURES),
        default=DEFAULT_POSTURE,
        help="physical human: posture whose published trunk ranges the family spans "
        "(default: %(default)s)",
    )
    p.add_argument(
        "--ranges",
        choices=list(RANGES),
        default="published",
        help="physical human: the published ranges, or the STRESS variant beyond them "
        "(default: %(default)s)",
    )
    p.add_argument(
        "--plant-file",
        action="append",
        default=[],
        metavar="FILE",
        help="component fit (kind 'bdft-component-fit') whose parameters replace that component's "
        "nominal values; may be repeated, one per component",
    )
    p.add_argument(
        "--chunk",
        type=batch("--chunk"),
        default=None,
        help=batch_help(f"members per batch (default: {DEFAULT_CHUNK})"),
    )


def register(sub) -> None:
    """Add the ``validate`` sub-command (family options, ``--method``, ``--controller``...).

    Parameters
    ----------
    sub : argparse subparsers action
        What :meth:`argparse.ArgumentParser.add_subparsers` returned; the new parser's
        ``func`` default is :func:`run`.
    """
    p = sub.add_parser(
        "validate",
        help="closed-loop poles across a family: fraction stable, worst pole, minimum damping",
        description="Sample a family of BDFT loops (human stiffness, damping and mass, "
        "structure frequencies, damping and gain), assemble every member's closed loop in "
        "batches and report the fraction stable, the largest real part of any pole, the "
        "minimum damping ratio in the BDFT band and the worst member.",
    )
    add_family_arguments(p, samples=10_000)
    add_system_argument(p)
    add_jobs_argument(p, workers="parallel threads (the compiled loops release the GIL)")
    add_scheduler_argument(p)
    p.add_argument(
        "--band",
        default=None,
        metavar="LO-HI",
        help="frequency band of the reported minimum damping ratio, Hz, HI may be inf "
        f"(default: the BDFT family's damping band, {DAMPING_BAND_HZ[0]:g}-"
        f"{DAMPING_BAND_HZ[1]:g} Hz, that of the specification and the pole region; with "
        "--system, every frequency)",
    )
    p.add_argument(
        "--method", choices=_METHODS, default="lhs", help="sampling method (default: %(default)s)"
    )
    p.add_argument(
        "--controller",
        metavar="FILE",
        default=None,
        help="controller JSON (A, B, C, D, inputs, outputs; or a bdft-controller artifact): "
        "of the BDFT loop (inputs among x, c, y; outputs among f, r_corr), or with --system "
        "of that system (in place of the file's `controller`; its signals paired with the "
        "system's by name, or by position)",
    )
    p.add_argument(
        "--workspace-factor",
        type=real("--workspace-factor", low=0.0, low_open=True),
        default=1.0,
        help="handle workspace multiple, a positive number: K_PSF = 0.1097 / factor "
        "(default: %(default)s)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object with the metrics")
    p.set_defaults(func=run)


def add_system_argument(p) -> None:
    """Add ``--system FILE.py``: a user's uncertain system instead of the BDFT family.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The sub-command's parser.
    """
    p.add_argument(
        "--system",
        metavar="FILE.py",
        default=None,
        help="a Python file that defines `system` (an uncertainty.uss) and optionally "
        "`controller` (a python-control system in its feedback path): analyse it instead "
        "of the BDFT family (the family options do not apply; the file is run as code)",
    )


def read_system(args):
    """The user's uncertain system and controller of ``--system`` (checked).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options with ``system`` (the file) and ``controller`` (a controller file,
        or None for the file's own ``controller``).

    Returns
    -------
    (uncertainty.USS, control.StateSpace or None)
        The controller of ``--controller`` when given (in place of the file's), with its
        signals paired to the system's (:func:`backhoe.families.files.match_controller`: by
        name, or by position).

    Raises
    ------
    bdft.args.UsageError
        If the file is not a readable ``.py`` file, or the controller file is not a
        readable JSON file.
    robust.errors.ParameterError
        If the controller does not fit the system (numbers of signals, names).
    """
    check_input_file(
        "--system", args.system, what="a Python file", max_bytes=1 << 20, suffixes=(".py",)
    )
    path = getattr(args, "controller", None)
    if path is not None:
        check_json_file("--controller", path)
    from backhoe.families.files import load_controller, load_system, match_controller

    system, controller = load_system(args.system)
    if path is not None:
        controller = match_controller(system, load_controller(path), where=f"--controller {path}")
    return system, controller


def controller_source(args, controller):
    """What ``controller`` of the JSON output says for a ``--system`` run."""
    if getattr(args, "controller", None) is not None:
        return args.controller
    return "defined in the file" if controller is not None else None


def check_family_arguments(args) -> None:
    """Check the family options' input files before any work (:mod:`bdft.args`).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options of :func:`add_family_arguments`: every ``plant_file`` must be
        a readable JSON object file (the loader then checks its fields).

    Raises
    ------
    bdft.args.UsageError
        Naming ``--plant-file`` and the file.
    """
    for path in args.plant_file:
        check_json_file("--plant-file", path)


def build_family(args):
    """The default family for the parsed options (plant files applied).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options of :func:`add_family_arguments`; ``human`` (``"literal"`` or
        ``"physical"``), ``posture`` and ``ranges`` (physical human) and ``plant_file``
        (component-fit JSON paths whose parameters replace that component's nominal
        values) are used.

    Returns
    -------
    backhoe.Family
        :func:`backhoe.default_family` of that human variant, at the nominal
        workspace (factor 1).
    """
    from backhoe import default_family
    from backhoe.families.files import family_nominals, load_component_fit
    from backhoe.model.physical import nominal_params

    fits = [load_component_fit(path) for path in args.plant_file]
    nominals = family_nominals(fits, human=args.human)
    if args.human == "physical":
        nominals.setdefault("physical", nominal_params(args.posture))
        return default_family(args.human, posture=args.posture, ranges=args.ranges, **nominals)
    return default_family(args.human, **nominals)


def progress_bar(total: int, desc: str):
    """A tqdm progress bar on stderr (shown on terminals for long runs only).

    Parameters
    ----------
    total : int
        Members the run will validate; below 100000 the bar is disabled, otherwise
        tqdm shows it when standard error is a terminal.
    desc : str
        Label in front of the bar.

    Returns
    -------
    tqdm.tqdm
        A context manager; ``bar.update(n)`` advances it by ``n`` members.
    """
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit="member",
        unit_scale=True,
        file=sys.stderr,
        disable=None if total >= 100_000 else True,
        leave=False,
    )


def _band(text):
    """The ``--band`` option: None (the default of what is validated) or ``(low, high)``."""
    if text is None:
        return None
    lo, sep, hi = str(text).partition("-")
    try:
        band = (float(lo), float(hi))
    except ValueError:
        band = None
    if not sep or band is None or not 0 <= band[0] < band[1]:  # (HI may be inf; not NaN)
        raise UsageError(
            f"--band: expected LO-HI in Hz with 0 <= LO < HI, HI may be inf (e.g. 2-12); "
            f"got {text!r}"
        )
    return band


def _run_system(args, band) -> int:
    """``bdft validate --system FILE.py``: members of a user's uncertain system."""
    from uncertainty import sample, validate_family

    system, controller = read_system(args)
    t0 = time.perf_counter()
    samples = sample(
        list(system.parameters.values()), args.samples, method=args.method, seed=args.seed
    )
    with progress_bar(len(samples), "validate") as bar:
        res = validate_family(
            system,
            samples,
            controller=controller,
            chunk=args.chunk or DEFAULT_CHUNK,
            band_hz=band,
            progress=bar.update,
        )
    elapsed = time.perf_counter() - t0
    print(f"[bdft validate] {res.samples} members in {elapsed:.2f} s", file=sys.stderr)
    obj = res.to_json()
    for key in ("human", "k_psf"):
        obj.pop(key)
    obj.update(
        requested_samples=samples.requested,
        system=args.system,
        controller=controller_source(args, controller),
    )
    if args.json:
        print_json(obj)
        return 0
    print(
        f"system {args.system}, controller {obj['controller'] or 'none'}: {res.samples} "
        f"members ({res.method}, seed {res.seed})"
    )
    _print_metrics(res)
    return 0


def _print_metrics(res) -> None:
    print(f"  fraction stable   {res.fraction_stable:.6f}  ({res.n_unstable} unstable)")
    print(f"  max real pole     {res.max_real_pole:.6g} 1/s")
    lo, hi = res.band_hz
    where = "at every frequency" if (lo, hi) == (0.0, float("inf")) else f"in {lo:g}-{hi:g} Hz"
    print(f"  min damping       {res.min_damping:.6g}  (poles {where})")
    print("  worst member:")
    for k, v in res.worst.items():
        print(f"    {k:18s} {v:.6g}")


def run(args) -> int:
    """Validate a sample of the family (optionally with a controller) and print the metrics.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``bdft validate`` options: the family options of
        :func:`add_family_arguments` (``samples``, ``seed``, ``human``, ``plant_file``,
        ``chunk``), ``method`` (``"mc"``, ``"lhs"``, ``"grid"`` or ``"vertices"``),
        ``controller`` (controller JSON path or ``None``), ``workspace_factor``
        (``K_PSF = 0.1097 / factor``), ``system`` (a Python file defining a ``uss``,
        validated instead of the family), ``band`` (``LO-HI`` Hz of the minimum damping),
        ``jobs`` (threads), ``scheduler`` (a Dask scheduler's address) and
        ``json``.

    Returns
    -------
    int
        Exit code 0. Standard output gets the metrics of
        :class:`uncertainty.ValidationResult` with the run's settings, as one JSON
        object (``--json``) or as text; it depends only on the options and the seed.
        The elapsed time goes to standard error.
    """
    band = _band(args.band)
    if args.system is not None:
        return _run_system(args, band)
    check_family_arguments(args)
    if args.controller is not None:
        check_json_file("--controller", args.controller)
    from backhoe.families.files import load_controller
    from uncertainty import sample, validate_family

    family = build_family(args).with_workspace_factor(args.workspace_factor)
    controller = load_controller(args.controller, bdft_loop=True) if args.controller else None
    t0 = time.perf_counter()
    samples = sample(family.parameters, args.samples, method=args.method, seed=args.seed)
    with progress_bar(len(samples), "validate") as bar:
        res = validate_family(
            family,
            samples,
            controller=controller,
            chunk=args.chunk or DEFAULT_CHUNK,
            band_hz=band,
            progress=bar.update,
            jobs=args.jobs,
            scheduler=args.scheduler,
        )
    elapsed = time.perf_counter() - t0
    print(
        f"[bdft validate] {res.samples} members in {elapsed:.2f} s "
        f"({res.samples / max(elapsed, 1e-9):,.0f} members/s)",
        file=sys.stderr,
    )
    obj = res.to_json()
    obj.update(
        requested_samples=samples.requested,
        family=family.name,
        posture=family.posture if family.human == "physical" else None,
        ranges=family.ranges if family.human == "physical" else None,
        workspace_factor=args.workspace_factor,
        controller=args.controller,
        plant_files=list(args.plant_file),
        calibration=family.describe()["calibration"],
        nominals={k: family.describe()[k] for k in ("valve", "struct", "human_nominal")},
    )
    if args.json:
        print_json(obj)
        return 0
    print(
        f"family: {family.name}"
        + (" (STRESS VARIANT: beyond the published ranges)" if family.ranges == "stress" else "")
        + f", {res.samples} members ({res.method}, seed {res.seed}), "
        f"K_PSF {res.k_psf:.5g}"
    )
    _print_metrics(res)
    return 0
