"""``bdft margin``: how much of the family a loop provably holds, and the member that breaks it."""

from __future__ import annotations

import argparse
import math
import sys

from bdft.args import UsageError, check_json_file, integer, real, seed
from bdft.common import add_jobs_argument, add_scheduler_argument, print_json
from bdft.validate import (
    add_family_arguments,
    add_system_argument,
    build_family,
    controller_source,
    read_system,
)
from uncertainty.constants import DEFAULT_BOXES, LOWER_METHODS

__all__ = ["register", "run"]

#: Default members per scale of the upper bounds' searches: the stability margin's (an
#: eigenvalue problem per member) and the robust performance's (an H-infinity norm each)
MARGIN_SAMPLES, PERFORMANCE_SAMPLES = 1000, 64


def register(sub) -> None:
    """Add the ``margin`` sub-command (family options, ``--controller``, ``--region``...).

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The sub-parsers of the ``bdft`` parser.
    """
    p = sub.add_parser(
        "margin",
        help="robust margin of the family: certified lower bound, upper bound, critical member",
        description="Scale the family's box about its nominal (each parameter in its own "
        "coordinates) and find the largest scale at which every member's poles lie in the "
        "region: an upper bound with the member that breaks it (worst-case search), and a "
        "lower bound with a certificate that covers the whole box (verified enclosures of "
        "every eigenvalue of every member over sub-boxes, or a quadratic Lyapunov LMI per "
        "sub-box). A margin >= 1 means the whole family meets the region.",
    )
    add_family_arguments(
        p,
        samples=0,
        samples_help="members per scale of the upper bound's worst-case search (default: "
        f"{MARGIN_SAMPLES}; with --gamma {PERFORMANCE_SAMPLES})",
    )
    add_system_argument(p)
    add_jobs_argument(p)
    add_scheduler_argument(p)
    p.add_argument(
        "--controller",
        default=None,
        help="controller JSON (A, B, C, D, inputs, outputs; or a bdft-controller artifact): of "
        "the BDFT loop, or with --system of that system (in place of the file's `controller`; "
        "paired with its signals by name, or by position)",
    )
    p.add_argument(
        "--region",
        default="lhp",
        help="required pole region: 'lhp', 'decay:A' (real parts below -A rad/s), "
        "'damping:Z[@LO-HI]' (damping ratio >= Z for poles in LO-HI Hz), comma-joined "
        "(default: %(default)s); the eigenvalue method certifies all of it, the Lyapunov "
        "method the decay-rate part",
    )
    p.add_argument(
        "--workspace-factor",
        type=real("--workspace-factor", low=0.0, low_open=True),
        default=1.0,
        help="workspace factor of the family (K_PSF = 0.1097 / factor; default 1)",
    )
    p.add_argument(
        "--time-limit",
        type=real("--time-limit", low=1.0, high=36000.0, unit="s"),
        default=600.0,
        help="wall-clock safety limit of the certified lower bound, s (the result is set by "
        "--max-boxes; default: %(default)s)",
    )
    p.add_argument(
        "--max-boxes",
        type=integer("--max-boxes", low=1, high=100_000),
        default=DEFAULT_BOXES,
        help="sub-boxes tried per scale by the lower bound; the value-set route takes 500 cells "
        "per sub-box (default: %(default)s)",
    )
    p.add_argument(
        "--method",
        choices=LOWER_METHODS,
        default="auto",
        help="lower-bound certificate: 'auto' (default: mu for a --system or a --controller, "
        "zero exclusion on value sets for the family's open loop and the region 'lhp', else "
        "mu), 'eigenvalues' (verified eigenvalue enclosures), 'lyapunov' (a quadratic "
        "Lyapunov LMI per sub-box), 'valueset', or 'mu' (the loop's state matrix as an LFT, "
        "the family's or a --system's, mixed mu below 1 on every edge of the region: the "
        "decay line, the damping cone's edges, and for damping in a band the band's edges; "
        "--max-boxes caps its frequencies)",
    )
    p.add_argument(
        "--search-seed",
        type=seed("--search-seed"),
        default=None,
        help="seed of the upper bound's search (default: --seed)",
    )
    p.add_argument(
        "--gamma",
        type=real("--gamma", low=0.0, low_open=True),
        default=None,
        help="robust performance instead of stability: the largest scale at which every "
        "member is stable with ||T||_inf < GAMMA, T the closed loop from --inputs to "
        "--outputs (certified lower bound by mu with a performance block, upper bound with "
        "the worst member's exact norm)",
    )
    p.add_argument(
        "--inputs",
        default=None,
        help="with --gamma: the loop's inputs, comma-joined (the family's: u, and with the "
        "physical human f_ext; default u; a --system's names, default all)",
    )
    p.add_argument(
        "--outputs",
        default=None,
        help="with --gamma: the loop's outputs, comma-joined (the family's: y, c, h, x, e, r, "
        "err, f, r_corr, f_ctrl; default y; a --system's names, default all)",
    )
    p.add_argument(
        "--band",
        type=_band,
        default=None,
        help="with --gamma: the bound over a band only, LOW,HIGH in Hz (HIGH may be inf; a "
        "single-input single-output T); the box's stability is still certified over every "
        "frequency (default: every frequency)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def _band(text: str) -> tuple[float, float]:
    """An argparse ``type``: ``LOW,HIGH`` in Hz, ``0 <= LOW < HIGH``, ``HIGH`` may be ``inf``."""
    parts = str(text).split(",")
    try:
        lo, hi = (float(x) for x in parts) if len(parts) == 2 else (math.nan, math.nan)
    except ValueError:
        lo = hi = math.nan
    if not (math.isfinite(lo) and 0.0 <= lo < hi) or math.isnan(hi):
        raise argparse.ArgumentTypeError(
            f"expected LOW,HIGH in Hz with 0 <= LOW < HIGH (HIGH may be inf); got {text!r}"
        )
    return lo, hi


_band.__name__ = "band for --band"


def _names(option: str, text):
    if text is None:
        return None
    names = [t.strip() for t in str(text).split(",")]
    if not all(names):
        raise UsageError(f"{option}: expected signal names, comma-joined (e.g. u); got {text!r}")
    return names


def _check_performance_options(args) -> None:
    if args.gamma is None:
        for opt, val in (
            ("--inputs", args.inputs),
            ("--outputs", args.outputs),
            ("--band", args.band),
        ):
            if val is not None:
                raise UsageError(f"{opt} is for robust performance: give --gamma as well")
        return
    if args.region != "lhp":
        raise UsageError(
            f"--region: robust performance (--gamma) asks for stability only (lhp); got "
            f"{args.region!r}"
        )
    if args.method != "auto":
        raise UsageError(
            f"--method: robust performance (--gamma) is certified by mu; got {args.method!r}"
        )


def _parameters_json(system) -> list:
    return [
        {
            "name": n,
            "nominal": p.nominal,
            "low": p.low,
            "high": p.high,
            "distribution": p.distribution,
        }
        for n, p in system.parameters.items()
    ]


def _loop(args):
    """The ``--system``'s uncertain system or the family, and the controller, checked."""
    from backhoe.families.files import load_controller

    if args.system is not None:
        return read_system(args)
    if args.controller is not None:
        check_json_file("--controller", args.controller)
    family = build_family(args).with_workspace_factor(args.workspace_factor)
    controller = load_controller(args.controller, bdft_loop=True) if args.controller else None
    return family, controller


def _search_seed(args) -> int:
    return args.seed if args.search_seed is None else args.search_seed


def _with_progress(desc: str, call):
    """``call(progress)`` under a progress bar on standard error."""
    from tqdm import tqdm

    with tqdm(desc=desc, unit="step", file=sys.stderr, disable=None) as bar:

        def progress(msg: str) -> None:
            bar.set_postfix_str(msg[:60])
            bar.update(1)

        return call(progress)


def _result_json(args, res, source, controller) -> dict:
    """The result's JSON with what was analysed; each bound's time goes to standard error."""
    for k, v in res.timings_s.items():
        print(f"[bdft margin] {k} bound: {v:.1f} s", file=sys.stderr)
    obj = res.to_json()
    obj.pop("timings_s")
    if args.system is not None:
        obj.update(
            system=args.system,
            parameters=_parameters_json(source),
            controller=controller_source(args, controller),
        )
    else:
        obj.update(
            family=source.name,
            ranges=source.ranges,
            workspace_factor=args.workspace_factor,
            controller=args.controller,
        )
    return obj


def _heading(args, source, obj) -> str:
    """The summary's first line: what was analysed, with which controller."""
    if args.system is not None:
        return f"system {args.system}, controller {obj['controller'] or 'none'}"
    label = " (STRESS VARIANT)" if source.ranges == "stress" else ""
    return f"family {source.name}{label}, controller {args.controller or 'none'}"


def run(args) -> int:
    """Compute both bounds of the robust margin and print them.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options: the family options of :func:`bdft.validate.add_family_arguments`
        (``--samples`` is the upper bound's search size per scale), ``system`` (a
        Python file defining a ``uss``, instead of the family), ``controller``,
        ``region``, ``workspace_factor``, ``time_limit``, ``max_boxes``, ``method``,
        ``search_seed``, ``jobs`` and ``scheduler`` (where the lower bound's sub-boxes are
        certified: local processes or a Dask cluster; the same result on every engine) and
        ``json``.

    Returns
    -------
    int
        Exit code 0. Standard output gets one JSON object (``--json``) or a summary;
        progress goes to standard error.
    """
    from uncertainty.margins import robust_margin
    from uncertainty.region import Region

    _check_performance_options(args)
    region = Region.parse(args.region)
    if args.gamma is not None:
        return _run_performance(args)
    family, controller = _loop(args)
    res = _with_progress(
        "margin",
        lambda progress: robust_margin(
            family,
            controller=controller,
            region=region,
            samples=args.samples or MARGIN_SAMPLES,
            seed=_search_seed(args),
            max_boxes=args.max_boxes,
            time_limit_s=args.time_limit,
            method=args.method,
            progress=progress,
            jobs=args.jobs,
            scheduler=args.scheduler,
        ),
    )
    obj = _result_json(args, res, family, controller)
    if args.json:
        print_json(obj)
        return 0
    print(_heading(args, family, obj))
    print(f"region: {region.describe()}")
    print(f"  certified lower bound  {res.lower:.4g}")
    print(f"  upper bound            {res.upper:.4g}")
    used = res.certificate.get("method", args.method)
    print(f"  lower bound by         {used} ({res.method['lower_region']})")
    if res.critical:
        print(f"  critical member (violation {res.critical['violation']:.4g} rad/s):")
        for k, v in res.critical["parameters"].items():
            print(f"    {k:18s} {v:.6g}")
    return 0


def _run_performance(args) -> int:
    """``bdft margin --gamma``: both bounds of the robust performance margin."""
    from backhoe.families.loop import family_uss
    from uncertainty.performance import robust_performance

    inputs, outputs = _names("--inputs", args.inputs), _names("--outputs", args.outputs)
    source, controller = _loop(args)
    if args.system is None:
        # the family's loop is closed here, through its ports
        inputs, outputs = inputs or ["u"], outputs or ["y"]
        system = family_uss(source, controller, inputs=inputs, outputs=outputs)
    else:
        system = source
    res = _with_progress(
        "performance",
        lambda progress: robust_performance(
            system,
            controller=controller if args.system is not None else None,
            inputs=inputs,
            outputs=outputs,
            gamma=args.gamma,
            band_hz=args.band,
            samples=args.samples or PERFORMANCE_SAMPLES,
            seed=_search_seed(args),
            time_limit_s=args.time_limit,
            progress=progress,
        ),
    )
    obj = _result_json(args, res, source, controller)
    obj.update(gamma=args.gamma, inputs=inputs, outputs=outputs, band_hz=args.band)
    if args.json:
        print_json(obj)
        return 0
    print(_heading(args, source, obj))
    chans = f"{','.join(inputs or ['all'])} -> {','.join(outputs or ['all'])}"
    over = "" if args.band is None else f" over {args.band[0]:g}-{args.band[1]:g} Hz"
    print(f"robust performance: ||T||_inf < {args.gamma:.6g}{over} and stable, T: {chans}")
    print(f"  nominal ||T||_inf / gamma  {res.nominal_norm:.4g}")
    print(f"  certified lower bound    {res.lower:.4g}")
    print(f"  upper bound              {res.upper:.4g}")
    if res.worst:
        w = res.worst
        print(f"  worst member (||T||_inf / gamma {w['norm']:.4g} at {w['frequency_hz']:.4g} Hz):")
        for k, v in w["parameters"].items():
            print(f"    {k:18s} {v:.6g}")
    return 0
