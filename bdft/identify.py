"""``bdft identify``: fit a component model to measured chirp data.

Reads two channels of a CSV or ``.mat`` file, estimates H1 and coherence, fits
the requested form over a band and writes, into ``--out``:

* ``<stem>_<form>_bode.png``: measured H1 with confidence bounds and the fit
  (like the paper's Figures 6, 7 and 9);
* ``<stem>_<form>_coherence.png``;
* ``<stem>_<form>_h1.csv``: the H1/coherence table with the model's response;
* ``<stem>_<form>_fit.json``: the full fit summary.

``--save-model FILE.json`` also writes the fitted component in the format
:func:`robust.sysid.load_component_fit` reads. Everything is computed before the
first file is written, and each file is written atomically, so a failure leaves
no output behind.
"""

from __future__ import annotations

import argparse
import io
import re
import sys
from pathlib import Path

import numpy as np

from bdft.common import print_json
from robust.errors import ParameterError
from robust.jsonio import atomic_write, atomic_write_json, atomic_write_text
from robust.sysid.fit import parse_form
from robust.sysid.identify import identify_file
from robust.sysid.model_file import save_component_fit
from robust.sysid.plots import bode_figure, coherence_figure

__all__ = ["register", "run"]

DEFAULT_OUT = Path("reports") / "out" / "identify"


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
    p.add_argument("data", metavar="DATA", help="CSV (header of channel names) or .mat file")
    p.add_argument("--input", required=True, metavar="CH", help="input channel name")
    p.add_argument("--output", required=True, metavar="CH", help="output channel name")
    p.add_argument("--fs", required=True, type=float, metavar="HZ", help="sampling rate in Hz")
    p.add_argument("--form", required=True, metavar="FORM", help="valve | structure | human | M/N")
    p.add_argument(
        "--band", required=True, type=float, nargs=2, metavar=("LO", "HI"), help="fit band in Hz"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument(
        "--out",
        type=Path,
        default=DEFAULT_OUT,
        metavar="DIR",
        help=f"folder for plots and tables (default {DEFAULT_OUT})",
    )
    p.add_argument(
        "--save-model",
        type=Path,
        default=None,
        metavar="FILE.json",
        help="also write the fitted component model (fixed forms only)",
    )
    p.add_argument(
        "--nperseg",
        type=int,
        default=None,
        help="Welch segment length in samples (default: one segment per record)",
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
        type=float,
        default=0.0,
        metavar="G2",
        help="ignore frequencies with coherence below this (default 0)",
    )
    p.add_argument(
        "--significance",
        type=float,
        default=0.05,
        metavar="ALPHA",
        help="drop frequencies whose coherence is not significantly above zero at this "
        "family-wise level over the band (default 0.05; 1 keeps all)",
    )
    p.add_argument(
        "--confidence", type=float, default=0.95, help="level of the plotted bounds (default 0.95)"
    )
    p.set_defaults(func=run)
    return p


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-") or "data"


def run(args: argparse.Namespace) -> int:
    """Estimate H1 and coherence, fit the form and write the plots, table and summary.

    Everything is computed before the first file is written; each file is written
    atomically (see the module notes for the file names).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``bdft identify`` options: ``data`` (CSV or ``.mat`` path), ``input``
        and ``output`` (channel names), ``fs`` (sampling rate, Hz), ``form``
        (``"valve"``, ``"structure"``, ``"human"`` or ``"M/N"``), ``band`` (fit band
        ``(low, high)``, Hz), ``json``, ``out`` (output folder), ``save_model``
        (component-fit JSON path or ``None``; fixed forms only), ``nperseg`` (Welch
        segment length, samples), ``window``, ``detrend``, ``weighting``,
        ``min_coherence``, ``significance`` (family-wise level, positive; 1 or more
        keeps every frequency) and ``confidence`` (level of the plotted bounds, in
        (0, 1)).

    Returns
    -------
    int
        Exit code 0. Standard output gets the fit summary as one JSON object
        (``--json``) or as text.

    Raises
    ------
    robust.errors.ParameterError
        For ``--save-model`` with a rational form, a ``--significance`` that is not
        positive, or a ``--confidence`` outside (0, 1).
    """
    parsed = parse_form(args.form)
    if args.save_model is not None and isinstance(parsed, tuple):
        raise ParameterError(
            "--save-model needs a fixed form (valve, structure or human); "
            f"got the rational form {args.form!r}"
        )
    if not 0.0 < args.significance:
        raise ParameterError(
            "--significance must be in (0, 1], 1 keeping every frequency; "
            f"got {args.significance!r}"
        )
    if not 0.0 < args.confidence < 1.0:
        raise ParameterError(f"--confidence must be in (0, 1); got {args.confidence!r}")
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
    stem = f"{_slug(Path(args.data).stem)}_{_slug(args.form.replace('/', '-'))}"
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
    out = Path(args.out)
    paths = {
        "bode_png": out / f"{stem}_bode.png",
        "coherence_png": out / f"{stem}_coherence.png",
        "h1_csv": out / f"{stem}_h1.csv",
        "fit_json": out / f"{stem}_fit.json",
    }
    summary["outputs"] = {k: str(v) for k, v in paths.items()}
    if args.save_model is not None:
        summary["outputs"]["model_json"] = str(args.save_model)
    # Everything above is computed; only writes follow.
    atomic_write(paths["bode_png"], lambda tmp: bode.savefig(tmp, format="png", dpi=120))
    atomic_write(paths["coherence_png"], lambda tmp: coh.savefig(tmp, format="png", dpi=120))
    atomic_write_text(paths["h1_csv"], table_text)
    atomic_write_json(paths["fit_json"], summary)
    if args.save_model is not None:
        save_component_fit(
            args.save_model, fit, fs=result.fs, seed=result.seed, source=str(args.data)
        )
    if args.json:
        print_json(summary)
    else:
        _print_text(summary)
    return 0


def _table_csv(result, confidence: float) -> str:
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
