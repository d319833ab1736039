"""Benchmark: LMI H-infinity synthesis against python-control's hinfsyn (SLICOT) and dkpy.

For seeded random generalized plants (``robust.synthesis.testing.random_generalized_plant``,
4 exogenous inputs, 4 performance outputs, 2 controls, 2 measurements, 2 unstable
poles) of each order, runs in one process, side by side:

* ``robust.hinfsyn_lmi`` (this project),
* ``control.hinfsyn`` (Riccati, SLICOT sb10ad),
* ``dkpy.HinfSynLmi`` (if installed; it is not a project dependency),

and prints, per plant, wall time and the H-infinity norm each controller
*achieves* in closed loop (recomputed here with ``robust.analysis.norms.hinf_norm``;
``unstable`` if the loop is unstable), then per order: failure counts (no
controller, an exception, or an unstable loop), the ratio of our achieved norm
to SLICOT's achieved norm where SLICOT's loop is stable, and time ratios.
Peak memory: the process's peak resident set size, and with ``--tracemalloc``
the peak of Python-traced allocations per method (slower; off by default).

Usage::

    python benchmarks/bench_hinfsyn.py                 # orders 8 16 24 32, 3 seeds each
    python benchmarks/bench_hinfsyn.py --orders 8 16 --seeds 2
"""

from __future__ import annotations

import argparse
import functools
import importlib.metadata
import platform
import resource
import time
import tracemalloc
import warnings

import control
import numpy as np

import robust
from robust.analysis.norms import hinf_norm, spectral_abscissa
from robust.analysis.stability import stability_bound
from robust.synthesis.genplant import as_generalized_plant
from robust.synthesis.testing import random_generalized_plant

NMEAS, NCON = 2, 2


def _achieved(gp, K):
    cl = gp.closed_loop(K)
    if not spectral_abscissa(cl) < stability_bound():
        return np.inf
    return hinf_norm(cl)


def _run(fn, use_tracemalloc):
    if use_tracemalloc:
        tracemalloc.start()
    t0 = time.perf_counter()
    try:
        out, err = fn(), None
    except Exception as exc:  # noqa: BLE001 - a benchmark records every failure, whatever its type
        out, err = None, f"{type(exc).__name__}: {str(exc)[:80]}"
    dt = time.perf_counter() - t0
    peak = None
    if use_tracemalloc:
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return out, err, dt, peak


def _lmi(P):
    res = robust.hinfsyn_lmi(P, NMEAS, NCON)
    return res.K, res.gamma_bound


def _slicot(P):
    K, _, gam, _ = control.hinfsyn(P, NMEAS, NCON)
    return K, float(gam)


def _methods():
    ms = {"lmi": _lmi, "slicot": _slicot}
    try:
        import dkpy

        def _dk(P):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                K, _, gamma, _info = dkpy.HinfSynLmi().synthesize(P, NMEAS, NCON)
            if K is None:
                raise RuntimeError(
                    "no controller returned (dkpy default settings: Clarabel, 1e-9 tolerances)"
                )
            return K, gamma

        ms["dkpy"] = _dk
        dk_version = getattr(dkpy, "__version__", None)
        if dk_version is None:
            dk_version = importlib.metadata.version("dkpy")
    except ImportError:
        dk_version = None
    return ms, dk_version


def _fmt(x, w=9):
    if x is None:
        return "-".rjust(w)
    if isinstance(x, str):
        return x.rjust(w)
    if not np.isfinite(x):
        return "unstable".rjust(w)
    return f"{x:{w}.5g}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", type=int, nargs="+", default=[8, 16, 24, 32])
    ap.add_argument("--seeds", type=int, default=3, help="number of seeds per order (seeds 0..N-1)")
    ap.add_argument(
        "--tracemalloc", action="store_true", help="also report traced peak memory per method"
    )
    args = ap.parse_args(argv)

    methods, dk_version = _methods()
    print(
        f"python {platform.python_version()}, control {control.__version__}, "
        f"dkpy {dk_version if dk_version else 'not installed'}, machine {platform.machine()}"
    )
    print(
        "plants: robust.synthesis.testing.random_generalized_plant(n, seed=s), "
        "nw=nz=4, nu=ny=2, 2 unstable poles; "
        f"seeds 0..{args.seeds - 1}"
    )
    names = list(methods)
    header = f"{'n':>3} {'seed':>4} | " + " | ".join(
        f"{m + ' t[s]':>10} {m + ' gam':>10}" for m in names
    )
    header += f" | {'slicot rep':>10} | {'lmi/slicot':>10} | {'t lmi/slicot':>12}"
    if args.tracemalloc:
        header += " | " + " ".join(f"{m + ' MiB':>10}" for m in names)
    print(header)
    print("-" * len(header))
    summary = {}
    for n in args.orders:
        rows = []
        for seed in range(args.seeds):
            P = random_generalized_plant(n, seed=seed)
            gp = as_generalized_plant(P, NMEAS, NCON)
            rec = {}
            for m, fn in methods.items():
                out, err, dt, peak = _run(functools.partial(fn, P), args.tracemalloc)
                ach = _achieved(gp, out[0]) if out is not None else None
                rec[m] = {
                    "t": dt,
                    "gam": ach,
                    "err": err,
                    "peak": peak,
                    "rep": None if out is None else out[1],
                }
            slicot_rep = rec["slicot"]["rep"]
            ratio = None
            s_ach = rec["slicot"]["gam"]
            l_ach = rec["lmi"]["gam"]
            if s_ach is not None and np.isfinite(s_ach) and l_ach is not None:
                ratio = l_ach / s_ach
            tratio = rec["lmi"]["t"] / rec["slicot"]["t"]
            cells = []
            for m in names:
                gam = rec[m]["gam"] if rec[m]["err"] is None else "FAILED"
                cells.append(f"{rec[m]['t']:>10.3g} {_fmt(gam, 10)}")
            line = f"{n:>3} {seed:>4} | " + " | ".join(cells)
            line += f" | {_fmt(slicot_rep, 10)} | {_fmt(ratio, 10)} | {tratio:>12.3g}"
            if args.tracemalloc:
                line += " | " + " ".join(f"{rec[m]['peak']:>10.1f}" for m in names)
            print(line, flush=True)
            for m in names:
                if rec[m]["err"]:
                    print(f"      {m} error: {rec[m]['err']}")
            rows.append((rec, ratio, tratio))
        summary[n] = rows

    print()
    print("summary per order (failure = exception, no controller, or unstable closed loop)")
    head = f"{'n':>3} | " + " | ".join(f"{m + ' fail':>11}" for m in names)
    head += (
        f" | {'max lmi/slicot (slicot stable)':>30} | {'median t lmi/slicot':>19}"
        f" | {'median t dkpy/slicot':>20}"
    )
    print(head)
    print("-" * len(head))
    for n, rows in summary.items():
        fails = {
            m: sum(
                1 for rec, _, _ in rows if rec[m]["gam"] is None or not np.isfinite(rec[m]["gam"])
            )
            for m in names
        }
        ratios = [r for _, r, _ in rows if r is not None]
        tr = [t for _, _, t in rows]
        dk = (
            [rec["dkpy"]["t"] / rec["slicot"]["t"] for rec, _, _ in rows] if "dkpy" in names else []
        )
        line = f"{n:>3} | " + " | ".join(f"{fails[m]:>6}/{len(rows):<4}" for m in names)
        line += f" | {(f'{max(ratios):.4f} ({len(ratios)} plants)' if ratios else 'n/a'):>30}"
        line += f" | {np.median(tr):>19.3g} | {(f'{np.median(dk):.3g}' if dk else 'n/a'):>20}"
        print(line)
    print()
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"process peak resident memory: {peak_mib:.0f} MiB")
    if dk_version is None:
        print("dkpy not installed")


if __name__ == "__main__":
    main()
