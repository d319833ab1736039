"""The design comparison page: table, verdict and figures from real design runs."""

from reports.designs import run_all_designs, verdict, write_design_report


def test_comparison_page_with_verdict(tmp_path):
    runs = run_all_designs(
        samples=200, seed=0, names=["workspace", "hinf-nominal"], coverage_samples=60, n_jobs=2
    )
    index = write_design_report(runs, tmp_path / "designs", samples=200, seed=0)
    html = index.read_text()
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
