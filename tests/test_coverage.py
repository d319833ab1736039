"""The design report's 'who the family covers' section: numbers from the family itself."""

import numpy as np
import pytest

from backhoe import default_family
from backhoe.model.literature import published_box
from reports.coverage import coverage_figure, family_coverage
from uncertainty import sample, validate_family


@pytest.fixture(scope="module")
def coverage():
    return family_coverage(default_family(), samples=300, seed=4)


def test_provenance_is_the_published_box(coverage):
    box = published_box(coverage.posture)
    rows = {r["parameter"]: r for r in coverage.provenance}
    assert set(rows) == {f"human.{n}" for n in box}
    for name, r in box.items():
        row = rows[f"human.{name}"]
        assert (row["low"], row["high"], row["source"]) == (r.low, r.high, r.source)
        assert r.low <= coverage.members[name].min() and coverage.members[name].max() <= r.high


def test_uncompensated_fractions_are_the_batched_validation(coverage):
    fam = default_family()
    S = sample(fam.parameters, 300, method="lhs", seed=4)
    for label, factor in (("nominal workspace", 1.0), ("doubled workspace", 2.0)):
        ref = validate_family(fam.with_workspace_factor(factor), S).fraction_stable
        assert coverage.fraction_stable[label] == ref
    # the paper's remedy helps but does not stabilise the family
    assert (
        coverage.fraction_stable["nominal workspace"]
        < coverage.fraction_stable["doubled workspace"]
        < 1.0
    )


def test_json_and_figure(coverage):
    obj = coverage.to_json()
    lo, hi = obj["sampled_span"]["zeta_arm"]
    assert lo == pytest.approx(np.min(coverage.members["zeta_arm"]))
    assert hi <= published_box()["zeta_arm"].high
    fig = coverage_figure(coverage)
    assert len(fig.axes) == 2
