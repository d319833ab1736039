"""The design comparison page: table, verdict and figures from real design runs."""

import json
import operator

import pytest

from backhoe import default_family
from designs.limit import design_set, limit_coverage_of, limit_map
from reports.designs import run_all_designs, run_designs_with, verdict, write_design_report
from reports.limit import limit_conclusions
from robust.jsonio import to_jsonable
from uncertainty.randomized import coverage_consistent

RUNS = dict(samples=200, seed=0, names=["workspace", "hinf-nominal"], coverage_samples=60)


@pytest.fixture(scope="module")
def serial_runs():
    return run_all_designs(**RUNS, n_jobs=2)


@pytest.fixture(scope="module")
def limit():
    """One limit map for both pages: the nominal H-infinity design's set and the scheduled
    design's (LIMIT_SET, which the comparison page's map held already), on 4 members (the
    per-operator page's count; the comparison page had 8). The sets' coverages differ, the
    checks do not: they read each design's own set's entry, and the nominal design
    covers none of its 60 members (measured), so any limit coverage is consistent with it."""
    from designs.scheduled import LIMIT_SET

    lm = limit_map(
        default_family(),
        samples=4,
        seed=0,
        sets=("force/handle+cab", LIMIT_SET),
        critical=False,
        n_jobs=2,
    )
    return dict(lm.to_json(), conclusions=limit_conclusions(lm))


@pytest.mark.slow
def test_comparison_page_with_verdict(tmp_path, serial_runs, limit):
    runs = serial_runs
    index = write_design_report(runs, tmp_path / "designs", samples=200, seed=0, limit=limit)
    html = index.read_text()
    # each design beside its set's limit: the doubled workspace is another machine; the
    # nominal H-infinity design measures the handle and the cab and drives the force
    assert "limit coverage of the set" in html and "another machine" in html
    hn = runs["hinf-nominal"]
    name = design_set(hn.controller)
    assert name == "force/handle+cab"
    _, entry = limit_coverage_of(limit["sets"], name, 1.0)
    # consistency: no design covers more than its set's limit, up to its own sampling error
    # (the limit's Latin-hypercube fraction carries no tail bound)
    assert coverage_consistent(hn.coverage.fraction, 60, entry["coverage"])
    out = index.parent
    assert "Verdict" in html and "hinf-nominal" in html and "workspace" in html
    # each design's coverage of the population with its certificate (60 fresh members)
    assert "Coverage of the population" in html and "Clopper-Pearson" in html
    ws, hn = runs["workspace"].coverage, runs["hinf-nominal"].coverage
    assert ws.bound.samples == hn.bound.samples == 60 and ws.bound.seed == 2
    assert ws.fraction > hn.fraction  # the doubled workspace holds on more operators
    for fig in ("pole_clouds.png", "ratio_envelopes.png", "forces.png"):
        assert (out / fig).stat().st_size > 1000
    lines = verdict(runs)
    # workspace scaling stabilises the sample without force; the nominal H-infinity design does not
    assert (
        lines[0]
        == "Designs that stabilise every sampled member within the force limits: workspace."
    )
    assert lines[1].startswith(
        "No handle-force design (hinf-nominal) stabilises every sampled member"
    )
    assert any(
        line.startswith("workspace stabilises every sampled member") and "held-out members" in line
        for line in lines
    )
    assert any("hinf-nominal" in line and "leave members unstable" in line for line in lines)
    why = [line for line in lines if line.startswith("Why:")]
    assert len(why) == 1 and "handle-arm mode" in why[0]


def test_per_operator_design_beside_its_limit(tmp_path, limit):
    # the scheduled design's result (a few members) on the page beside its set's limit
    # coverage, with the consistency verdict computed from the design's sampling error
    from designs.scheduled import LIMIT_SET, scheduled_design

    fam = default_family()
    _, sched = scheduled_design(
        fam,
        samples=6,
        cells_sweep=(1,),
        cells_per_axis=1,
        border_samples=1,
        certify_samples=1,
        limit_samples=0,
    )
    runs, done = run_designs_with(
        samples=50, seed=0, names=["workspace"], extra_tasks=[("neg", operator.neg, 1.5)]
    )
    assert done == [-1.5]  # one process: the other tasks after the designs
    index = write_design_report(
        runs, tmp_path / "d", samples=50, seed=0, limit=limit, scheduled=sched
    )
    html = index.read_text()
    assert "The per-operator design (bdft design scheduled)" in html
    _, entry = limit_coverage_of(limit["sets"], LIMIT_SET, 1.0)
    ok = coverage_consistent(sched["coverage"]["fraction"], 6, entry["coverage"])
    assert ("within the limit" in html) and (">yes<" in html) == ok
    assert f"{100 * sched['coverage']['fraction']:.1f} % of the population" in html
    assert "continuous with the cab damper" in html
    assert "certified on the whole bound" in html
    # both checks of a wrong estimate: the calibration's joint error region and the box
    wb, wx = sched["wrong_within_bound"], sched["wrong_within_box"]
    assert "boundary of that joint error region" in html and "The harsher box" in html
    assert f"stable in {100 * wx['stable']:.1f} %" in html
    assert f"stays stable in {100 * wb['stable']:.1f} %" in html


def test_designs_in_two_processes_equal_the_serial_run(serial_runs):
    # the report runs its designs two at a time (bdft report --jobs 2); each design is the
    # one the serial run gives, numbers and order alike
    # other tasks (the report's trade-off points) share the pool and come back in order
    extra = [("neg", operator.neg, 2.5), ("abs", abs, -3), ("float", float, "7")]
    parallel, done = run_designs_with(**RUNS, n_jobs=2, design_jobs=2, extra_tasks=extra)
    assert done == [-2.5, 3, 7.0]
    assert list(parallel) == list(serial_runs) == RUNS["names"]
    for n in RUNS["names"]:
        a, b = serial_runs[n], parallel[n]
        assert type(a) is type(b)
        ja, jb = (json.dumps(to_jsonable(r.to_json()), sort_keys=True) for r in (a, b))
        assert ja == jb
