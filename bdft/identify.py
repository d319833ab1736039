"""``bdft identify``: fit a component model to measured chirp data.

Reads two channels of a CSV or ``.mat`` file, estimates H1 and coherence, fits
the requested form over a band and writes, into ``--out``:

* ``<stem>_<form>_bode.png``: measured H1 with confidence bounds and the fit
  (like the paper's Figures 6, 7 and 9);
* ``<stem>_<form>_coherence.png``;
* ``<stem>_<form>_h1.csv``: the H1/coherence table with the model's response;
* ``<stem>_<form>_fit.json``: the full fit summary.

``--save-model FILE.json`` also writes the fitted component in the format
:func:`backhoe.sysid.load_component_fit` reads. Every option, the data file and both
output paths are checked before any work (:mod:`bdft.args`); everything is computed
before the first file is written, and the files are written as one group
(:func:`robust.jsonio.atomic_write_group`: all of them or none), so a failure leaves
no output behind. An existing ``--save-model`` file is replaced only when it is a
component fit, and the files in ``--out`` only when they are previous outputs of
``bdft identify``.
"""

from __future__ import annotations

import argparse
import io
import json
import re
import sys
from pathlib import Path

from bdft.args import (
    UsageError,
    check_input_file,
    check_output_dir,
    check_output_file,
    integer,
    memory_budget,
    real,
)
from bdft.common import print_json
from robust.errors import ParameterError

__all__ = ["MAX_RATIONAL_ORDER", "register", "run"]

DEFAULT_OUT = Path("reports") / "out" / "identify"
#: Highest denominator order of a rational form ``M/N``.
MAX_RATIONAL_ORDER = 20
#: The data file may use at most this fraction of the memory budget (text and arrays).
_DATA_BUDGET_FRACTION = 8
#: Kind of the files ``--save-model`` writes (:mod:`backhoe.sysid.model_file`).
_COMPONENT_FIT_KIND = "bdft-component-fit"
_DATA_SUFFIXES = (".csv", ".txt", ".mat")


def register(subparsers) -> argparse.ArgumentParser:
    """Add the ``identify`` sub-command to ``subparsers``.

    Parameters
    ----------
    subparsers : argparse subparsers action
        What :meth:`argparse.ArgumentParser.add_subparsers` returned; the new parser's
        ``func`` default is :func:`run`.

    Returns
    -------
    argparse.ArgumentParser
        The ``identify`` parser.
    """
    p = subparsers.add_parser(
        "identify",
        help="fit a valve/structure/human or rational model to measured chirp data",
        description=(
            "Estimate H1 and coherence from input/output records (Welch, averaged over records) "
            "and fit a fixed form (the paper's Eqn 3 'valve', Eqn 4 'structure', Eqn 5 'human') "
            "or a rational model 'M/N' (numerator order M, denominator order N, e.g. 2/4) over a "
            "band."
        ),
    )
    p.add_argument(
        "data",
        metavar="DATA",
        help="CSV (header of channel names) or .mat file, at most 1/8 of the memory budget "
        f"({memory_budget() // _DATA_BUDGET_FRACTION:,} bytes)",
    )
    p.add_argument("--input", required=True, metavar="CH", help="input channel name")
    p.add_argument("--output", required=True, metavar="CH", help="output channel name")
    p.add_argument(
        "--fs",
        required=True,
        type=real("--fs", low=0.0, low_open=True, unit="Hz"),
        metavar="HZ",
        help="sampling rate in Hz, positive",
    )
    p.add_argument(
        "--form",
        required=True,
        metavar="FORM",
        help=f"valve | structure | human | M/N (0 <= M <= N <= {MAX_RATIONAL_ORDER})",
    )
    p.add_argument(
        "--band",
        required=True,
        type=real("--band", low=0.0, low_open=True, unit="Hz"),
        nargs=2,
        metavar=("LO", "HI"),
        help="fit band in Hz, 0 < LO < HI <= fs/2",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument(
        "--out",
        type=Path,
        default=DEFAULT_OUT,
        metavar="DIR",
        help=f"folder for plots and tables (default {DEFAULT_OUT}); files there are replaced "
        "only when they are previous outputs of bdft identify",
    )
    p.add_argument(
        "--save-model",
        type=Path,
        default=None,
        metavar="FILE.json",
        help="also write the fitted component model (fixed forms only); an existing file is "
        "replaced only when it is a component fit",
    )
    p.add_argument(
        "--nperseg",
        type=integer("--nperseg", low=2),
        default=None,
        help="Welch segment length in samples, at least 2 (default: one segment per record)",
    )
    p.add_argument(
        "--window",
        default=None,
        help="scipy.signal window (default: boxcar for whole records, else hann)",
    )
    p.add_argument("--detrend", default="constant", choices=("none", "constant", "linear"))
    p.add_argument("--weighting", default="coherence", choices=("coherence", "none"))
    p.add_argument(
        "--min-coherence",
        type=real("--min-coherence", low=0.0, high=1.0),
        default=0.0,
        metavar="G2",
        help="ignore frequencies with coherence below this, in [0, 1] (default 0)",
    )
    p.add_argument(
        "--significance",
        type=real("--significance", low=0.0, high=1.0, low_open=True),
        default=0.05,
        metavar="ALPHA",
        help="drop frequencies whose coherence is not significantly above zero at this "
        "family-wise level over the band, in (0, 1] (default 0.05; 1 keeps all)",
    )
    p.add_argument(
        "--confidence",
        type=real("--confidence", low=0.0, high=1.0, low_open=True, high_open=True),
        default=0.95,
        help="level of the plotted bounds, in (0, 1) (default 0.95)",
    )
    p.set_defaults(func=run)
    return p


def _check(args: argparse.Namespace) -> None:
    """Every check that needs no computation: options, the data file, the output paths."""
    check_input_file(
        "DATA",
        args.data,
        what="a .csv, .txt or .mat data file",
        max_bytes=memory_budget() // _DATA_BUDGET_FRACTION,
        suffixes=_DATA_SUFFIXES,
    )
    for option, name in (("--input", args.input), ("--output", args.output)):
        if not name.strip():
            raise UsageError(f"{option}: expected a channel name; got an empty string")
    if args.input == args.output:
        raise UsageError(
            f"--input, --output: expected two different channels; got {args.input!r} for both"
        )
    from backhoe.sysid.fit import parse_form

    try:
        parsed = parse_form(args.form)
    except ParameterError as exc:
        raise UsageError(f"--form: {exc}") from None
    if isinstance(parsed, tuple) and parsed[1] > MAX_RATIONAL_ORDER:
        raise UsageError(
            f"--form: expected a denominator order N <= {MAX_RATIONAL_ORDER}; got {args.form!r}"
        )
    if args.save_model is not None and isinstance(parsed, tuple):
        raise UsageError(
            "--save-model needs a fixed form (valve, structure or human); "
            f"got the rational form {args.form!r}"
        )
    lo, hi = args.band
    if not lo < hi:
        raise UsageError(f"--band: expected LO < HI; got LO={lo:g} Hz, HI={hi:g} Hz")
    if hi > args.fs / 2.0:
        raise UsageError(
            f"--band: expected HI <= fs/2 = {args.fs / 2.0:g} Hz; got HI={hi:g} Hz, beyond the "
            "Nyquist frequency"
        )
    if args.window is not None:
        import scipy.signal

        try:
            scipy.signal.get_window(args.window, 16)
        except (ValueError, TypeError) as exc:
            raise UsageError(
                f"--window: expected a scipy.signal window name (hann, boxcar, ...); "
                f"got {args.window!r} ({exc})"
            ) from None
    check_output_dir("--out", args.out)
    paths = _output_paths(args)
    _check_previous_outputs(paths)
    if args.save_model is not None:
        check_output_file("--save-model", args.save_model, kind=_COMPONENT_FIT_KIND)
        if any(Path(args.save_model).absolute() == q.absolute() for q in paths.values()):
            raise UsageError(
                f"--save-model: expected a file apart from the outputs in --out; got "
                f"{str(args.save_model)!r}, one of them"
            )


def _output_paths(args: argparse.Namespace) -> dict:
    """The files written into ``--out``, named after the data file and the form."""
    stem = f"{_slug(Path(args.data).stem)}_{_slug(args.form.replace('/', '-'))}"
    out = Path(args.out)
    return {
        "bode_png": out / f"{stem}_bode.png",
        "coherence_png": out / f"{stem}_coherence.png",
        "h1_csv": out / f"{stem}_h1.csv",
        "fit_json": out / f"{stem}_fit.json",
    }


def _ours(path: Path, key: str) -> bool:
    """Whether an existing output file was written by ``bdft identify`` (by content)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(64)
        if key.endswith("_png"):
            return head.startswith(b"\x89PNG\r\n\x1a\n")
        if key == "h1_csv":
            return head.startswith(b"# bdft identify:")
        obj = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(obj, dict) and {"params_class", "outputs", "spectral"} <= set(obj)


def _check_previous_outputs(paths: dict) -> None:
    for key, path in paths.items():
        if path.is_dir() or ((path.exists() or path.is_symlink()) and not _ours(path, key)):
            raise UsageError(
                f"--out: expected no file at {str(path)!r} or a previous output of bdft identify; "
                "found another file or folder there (not replaced)"
            )


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-") or "data"


def run(args: argparse.Namespace) -> int:
    """Estimate H1 and coherence, fit the form and write the plots, table and summary.

    Every option and path is checked first; everything is computed before the first
    file is written, and the files are written as one group, all or none (see the
    module notes for the file names).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``bdft identify`` options: ``data`` (CSV or ``.mat`` path), ``input``
        and ``output`` (channel names), ``fs`` (sampling rate, Hz), ``form``
        (``"valve"``, ``"structure"``, ``"human"`` or ``"M/N"``), ``band`` (fit band
        ``(low, high)``, Hz), ``json``, ``out`` (output folder), ``save_model``
        (component-fit JSON path or ``None``; fixed forms only), ``nperseg`` (Welch
        segment length, samples), ``window``, ``detrend``, ``weighting``,
        ``min_coherence``, ``significance`` (family-wise level in (0, 1]; 1 keeps
        every frequency) and ``confidence`` (level of the plotted bounds, in
        (0, 1)).

    Returns
    -------
    int
        Exit code 0. Standard output gets the fit summary as one JSON object
        (``--json``) or as text.

    Raises
    ------
    bdft.args.UsageError
        Before any work, for a missing or unreadable data file, equal channel names,
        an unknown form, ``--save-model`` with a rational form, a band that is not
        ``0 < LO < HI <= fs/2``, an unknown window, or an output path that cannot be
        written or would replace a file of the user's.
    """
    _check(args)
    from backhoe.sysid.identify import identify_file
    from backhoe.sysid.model_file import save_component_fit
    from backhoe.sysid.plots import bode_figure, coherence_figure
    from robust.jsonio import atomic_write_group, to_jsonable

    band = (float(args.band[0]), float(args.band[1]))
    result = identify_file(
        args.data,
        args.input,
        args.output,
        args.fs,
        args.form,
        band,
        nperseg=args.nperseg,
        window=args.window,
        detrend=args.detrend,
        weighting=args.weighting,
        min_coherence=args.min_coherence,
        significance=None if args.significance >= 1.0 else args.significance,
    )
    est, fit = result.estimate, result.fit
    label = f"{args.input} -> {args.output}"
    f_range = (max(est.f_hz[1], band[0] / 10.0), min(est.fs / 2.0, band[1] * 5.0))
    bode = bode_figure(
        est,
        fit,
        band_hz=band,
        f_range_hz=f_range,
        confidence=args.confidence,
        title=f"{Path(args.data).name}: {label}, {args.form} fit",
    )
    coh = coherence_figure(
        est,
        band_hz=band,
        f_range_hz=f_range,
        threshold=fit.coherence_threshold,
        title=f"{Path(args.data).name}: coherence {label} ({est.n_records} records)",
    )
    table_text = _table_csv(result, args.confidence)
    summary = result.to_dict()
    paths = _output_paths(args)
    summary["outputs"] = {k: str(v) for k, v in paths.items()}
    if args.save_model is not None:
        summary["outputs"]["model_json"] = str(args.save_model)
    # Everything above is computed; only writes follow, all of them or none.
    fit_text = json.dumps(to_jsonable(summary), indent=2, allow_nan=False) + "\n"
    items = [
        (paths["bode_png"], lambda tmp: bode.savefig(tmp, format="png", dpi=120)),
        (paths["coherence_png"], lambda tmp: coh.savefig(tmp, format="png", dpi=120)),
        (paths["h1_csv"], lambda tmp: Path(tmp).write_text(table_text, encoding="utf-8")),
        (paths["fit_json"], lambda tmp: Path(tmp).write_text(fit_text, encoding="utf-8")),
    ]
    if args.save_model is not None:
        items.append(
            (
                args.save_model,
                lambda tmp: save_component_fit(
                    tmp, fit, fs=result.fs, seed=result.seed, source=str(args.data)
                ),
            )
        )
    atomic_write_group(items)
    if args.json:
        print_json(summary)
    else:
        _print_text(summary)
    return 0


def _table_csv(result, confidence: float) -> str:
    import numpy as np

    est, fit = result.estimate, result.fit
    cols = est.table(confidence)
    h = fit.frequency_response(est.f_hz[1:])
    model = np.concatenate([[np.nan + 0j], h])
    with np.errstate(divide="ignore", invalid="ignore"):
        cols["model_mag_db"] = 20.0 * np.log10(np.abs(model))
        cols["model_phase_deg"] = np.degrees(np.angle(model))
    cols["in_band"] = ((est.f_hz >= fit.band_hz[0]) & (est.f_hz <= fit.band_hz[1])).astype(float)
    buf = io.StringIO()
    buf.write(
        f"# bdft identify: source={result.source} input={result.input_name} "
        f"output={result.output_name} fs={result.fs:g} "
        f"seed={'none' if result.seed is None else result.seed} form={fit.form} "
        f"nperseg={est.nperseg} window={est.window} detrend={est.detrend} "
        f"records={est.n_records}\n"
    )
    buf.write(",".join(cols) + "\n")
    np.savetxt(buf, np.column_stack(list(cols.values())), delimiter=",", fmt="%.10g")
    return buf.getvalue()


def _print_text(summary: dict) -> None:
    w = sys.stdout.write
    lo, hi = summary["band"]
    w(
        f"form {summary['form']} ({summary['params_class']}), band {lo:g}-{hi:g} Hz, "
        f"{summary['n_points']} frequencies, {summary['spectral']['n_records']} records\n"
    )
    for name, val in summary["params"].items():
        sd = summary["std_errors"].get(name)
        w(f"  {name:>8s} = {val:.6g}" + (f"  (+- {sd:.2g})" if sd is not None else "") + "\n")
    w(
        f"fit error: {summary['fit_error_db']:.3f} dB, "
        f"{summary['fit_error_deg']:.2f} deg (weighted RMS)\n"
    )
    for b in summary["band_errors"]:
        a, c = b["band_hz"]
        w(
            f"  {a:8.3g}-{c:<8.3g} Hz: {b['rms_db']:.3f} dB, {b['rms_deg']:.2f} deg, "
            f"mean coherence {b['mean_coherence']:.3f}\n"
        )
    for note in summary["notes"]:
        w(f"note: {note}\n")
    w(f"seed: {summary['seed']}\n")
    for v in summary["outputs"].values():
        w(f"wrote {v}\n")
