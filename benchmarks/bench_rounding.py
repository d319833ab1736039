"""Benchmark: how far each shipped design's controller moves when its inputs move by rounding.

For each design (``--designs``, default: every registered one), the design is built twice
on the default family and its 2000-member LHS design sample (seed 0): once as it is, and
once with every uncertain parameter's nominal value and bounds, and the sample's values,
multiplied by ``1 + rel * s_i`` (``s_i = +-1`` per parameter from a seeded generator,
``--rel`` default 1e-9). Printed per design: the build's CPU time, the controller's
largest relative change of its frequency response over 0.01-1000 Hz
(``max |K_1(jw) - K_0(jw)| / max |K_0(jw)|``, 400 log-spaced points), its orders, and
how many of 200 seeded Monte Carlo members meet the specification with each controller
(:func:`designs.coverage.member_verdicts`), on how many the binding constraint changes and
the largest relative change of its utilisation. A design whose synthesis is a continuous
function of its inputs moves by about ``rel`` times a condition number; one that decides
on the edge of a ladder rung or follows a nonsmooth local search can move by a finite
amount, and its verdicts with it.

Usage::

    python benchmarks/bench_rounding.py [--designs hinf-nominal,hinf-robust] [--rel 1e-9]
        [--members 200] [--json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

from backhoe import default_family
from backhoe.model.device import DeviceLimits
from designs.coverage import member_verdicts
from designs.registry import design_names, get_design
from designs.specification import Specification
from uncertainty import sample

SEED = 0
SIGN_SEED = 123
MEMBER_SEED = 7


def perturbed(family, members, rel: float, signs: np.ndarray):
    """The family and its sample with every parameter scaled by ``1 + rel * sign``."""
    f = 1.0 + rel * signs
    params = tuple(
        dataclasses.replace(p, nominal=p.nominal * g, low=p.low * g, high=p.high * g)
        for p, g in zip(family.parameters, f)
    )
    return family.replace(parameters=params), dataclasses.replace(
        members, values=members.values * f[None, :]
    )


def response(K, w):
    """``K(jw)`` for every input-output pair, shape (outputs, inputs, len(w))."""
    return np.asarray(K(1j * w)).reshape(K.noutputs, K.ninputs, -1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", default=",".join(n for n in design_names()))
    ap.add_argument("--rel", type=float, default=1e-9)
    ap.add_argument("--members", type=int, default=200)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    fam = default_family()
    members = sample(fam.parameters, 2000, method="lhs", seed=SEED)
    signs = np.random.default_rng(SIGN_SEED).choice([-1.0, 1.0], size=len(fam.parameters))
    check = sample(fam.parameters, args.members, method="mc", seed=MEMBER_SEED)
    lim = DeviceLimits()
    spec = Specification(peak_force_n=lim.peak_force_n, continuous_force_n=lim.continuous_force_n)
    w = 2 * np.pi * np.logspace(-2, 3, 400)
    rows = []
    for name in args.designs.split(","):
        out = {"design": name, "rel": args.rel, "seed": SEED, "sign_seed": SIGN_SEED}
        Ks = []
        for rel in (0.0, args.rel):
            f, m = perturbed(fam, members, rel, signs)
            t0 = time.process_time()
            res = get_design(name).build(f, m, lim)
            out[f"cpu_s_{'perturbed' if rel else 'base'}"] = time.process_time() - t0
            Ks.append(res.controller)
        if Ks[0] is None:
            out["controller"] = "none"
        else:
            r0, r1 = response(Ks[0], w), response(Ks[1], w)
            out["relative_change"] = float(np.max(np.abs(r1 - r0)) / np.max(np.abs(r0)))
            out["orders"] = [int(Ks[0].nstates), int(Ks[1].nstates)]
            v = [member_verdicts(fam, check.values, K, spec, seed=MEMBER_SEED) for K in Ks]
            out["members_meeting_spec"] = [int(np.count_nonzero(x.holds)) for x in v]
            out["binding_changed"] = int(sum(a != b for a, b in zip(v[0].binding, v[1].binding)))
            u0, u1 = v[0].utilisation, v[1].utilisation
            fin = np.isfinite(u0) & np.isfinite(u1)
            out["utilisation_change_max"] = float(
                np.max(np.abs(u1[fin] - u0[fin]) / np.maximum(np.abs(u0[fin]), 1e-300))
                if fin.any()
                else 0.0
            )
        rows.append(out)
        if not args.json:
            print(
                f"{name:22s} cpu {out['cpu_s_base']:7.1f} s / {out['cpu_s_perturbed']:7.1f} s  "
                + (
                    "no controller"
                    if Ks[0] is None
                    else f"|dK|/|K| {out['relative_change']:.3g}  orders {out['orders']}  "
                    f"meet the specification {out['members_meeting_spec']} of {args.members}, "
                    f"binding changed on {out['binding_changed']}, utilisation moved by up to "
                    f"{out['utilisation_change_max']:.3g} (relative)"
                ),
                flush=True,
            )
    if args.json:
        print(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
