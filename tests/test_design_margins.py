"""Robust margins of the shipped designs on a fixed-seed sample of the default family.

Each design is run end to end (``run_design``: build, validate, reduce, discretise)
on the same 500-member LHS sample (seed 0). The numbers asserted are those the
designs state in the comparison report; a change that loses robustness, damping or
the force accounting makes these fail.
"""

import pytest
from shipped_runs import SAMPLES, SEED
from shipped_runs import shipped_run as _run

from backhoe import default_family
from backhoe.model.device import DeviceLimits
from uncertainty import sample, validate_family
from uncertainty.search import margin_upper_bound
from uncertainty.testing import assert_robust_margin

LIM = DeviceLimits()


@pytest.fixture(scope="module")
def runs():
    return {}


def _force_flag_consistent(ev):
    within = ev.peak_force_n <= LIM.peak_force_n and ev.rms_force_n <= LIM.continuous_force_n
    assert ev.force_within_limits == within


@pytest.mark.slow
def test_hinf_robust_stabilises_the_sampled_members_and_says_when_not_all(runs):
    """What the force-only robust design holds, and what it states.

    Its multi-model tuning (BFGS with a weak Wolfe line search on a nonsmooth objective)
    ends at a controller that depends on the last bits of its data, so the tests run the
    commands' pinned kernels (tests/conftest.py). Measured on the 500 members of this sample
    (fraction stable, worst real part rad/s, held-out fraction of 4000): 0.99, +1.72,
    0.991 (with 100 BFGS iterations per round instead of 300: 1.0, -0.297, 0.997). With
    SciPy's BFGS, which stops at the first kink where its line search loses precision, the
    same code gave 0.924, +1.53, 0.928 on these kernels, while a CPU's own AVX-512 loops
    passed this test's 0.97. The 0.3 rad/s decay rate it aims at is not reached with room,
    so it is not asserted; the design's own flag must say whether it was.
    """
    r = _run(runs, "hinf-robust")
    ev = r.evaluation
    assert ev.fraction_stable >= 0.97
    # the round kept is the one with the most sampled members stable
    rounds = r.facts.design.solver["rounds"]
    kept = rounds[r.facts.design.solver["chosen_round"]]["fraction_stable"]
    assert kept == max(x["fraction_stable"] for x in rounds)
    converged = r.facts.design.solver["converged"]
    assert converged == (ev.max_real_pole < -0.3)
    notes = " ".join(r.notes)
    assert converged or "did not reach the required decay rate" in notes
    # The damping ratio is not a requirement of this design (only the decay rate is): its
    # sampled minimum sits near 0.006, so it is reported, not asserted; the certified
    # margins with the specification's damping region replace it.
    assert r.order_reduced <= 10
    _force_flag_consistent(ev)
    # the nominal member's 1 kHz sampled-data loop is stable with room (measured on the
    # five kernels: -0.30 to -0.47 rad/s, its continuous loop -0.41 to -1.08), and on the
    # worst member the 1 kHz loop is never less damped than the continuous one by more than
    # 0.1 rad/s (measured: at most 0.0002 rad/s). The tuning sees a half-sample lag at the
    # controller's output (the zero-order hold's delay); without it the tuned controller's
    # nominal 1 kHz loop was unstable (+0.53 rad/s) while its continuous loop decayed at
    # -0.35 rad/s
    chk = r.checks.sampled_data["nominal"]
    assert chk.stable_continuous and chk.stable_discrete
    assert chk.max_real_discrete < -0.25
    chk = r.checks.sampled_data["worst"]
    assert chk.max_real_discrete < chk.max_real_continuous + 0.1


def test_hinf_robust_holds_on_a_held_out_sample(runs):
    r = _run(runs, "hinf-robust")
    fam = default_family()
    v = validate_family(
        fam, sample(fam.parameters, 4000, method="lhs", seed=SEED + 1), controller=r.controller
    )
    # measured 0.991 (0.928 with SciPy's BFGS on these kernels, above)
    assert v.fraction_stable >= 0.96


def test_hinf_robust_reports_the_force_it_costs(runs):
    ev = _run(runs, "hinf-robust").evaluation
    # stabilising the stiff, lightly damped arms takes handle-position gain in the intent band:
    # the design is reported over the device limits, not hidden
    assert ev.peak_force_n > LIM.peak_force_n
    assert not ev.force_within_limits


def test_workspace_factor_stabilises_the_sample(runs):
    r = _run(runs, "workspace")
    ev = r.evaluation
    assert r.facts.stabilises_family
    assert ev.fraction_stable == 1.0
    assert ev.min_damping > 0.0
    assert ev.max_real_pole < -0.01  # the search margin
    assert 10.0 < r.facts.factor < 200.0
    assert ev.peak_force_n == 0.0 and ev.force_within_limits


def test_hinf_nominal_margins(runs):
    r = _run(runs, "hinf-nominal")
    ev = r.evaluation
    assert (
        0.2 <= ev.fraction_stable < 1.0
    )  # the nominal design is not robust: that is what the robust one buys
    assert ev.tracking_error < 0.2
    _force_flag_consistent(ev)
    chk = r.checks.sampled_data["nominal"]
    assert chk.stable_discrete and chk.max_response_deviation_db < 0.1


def test_virtual_damping_margins(runs):
    r = _run(runs, "virtual-damping")
    ev = r.evaluation
    # the chosen pair keeps the force within the device limits and stabilises more of the
    # sample than no compensation does, but not all of it
    assert r.facts.within_limits and ev.force_within_limits
    fam = default_family()
    bare = validate_family(fam, sample(fam.parameters, SAMPLES, method="lhs", seed=SEED))
    assert bare.fraction_stable < ev.fraction_stable < 1.0
    _force_flag_consistent(ev)


@pytest.mark.slow
def test_hinf_robust_with_reference_correction_trades_tracking_for_force(runs):
    r = _run(runs, "hinf-robust-corr")
    ev = r.evaluation
    assert ev.fraction_stable >= 0.99
    assert ev.tracking_error < 0.6  # the tracking budget is 0.5 on the nominal member
    assert ev.peak_force_n < 25.0  # far below the force-only robust design, still above the limit
    _force_flag_consistent(ev)
    robust = _run(runs, "hinf-robust").evaluation
    assert ev.peak_force_n < 0.2 * robust.peak_force_n
    assert ev.tracking_error < robust.tracking_error


@pytest.mark.parametrize(
    "name, floor, method",
    [("workspace", 0.35, "valueset"), ("hinf-robust", 0.2, "mu")],
    ids=["workspace", "hinf-robust"],
)
def test_certified_robust_margin_of_shipped_designs(runs, name, floor, method):
    # the certified lower bound covers every member of the scaled box (open left
    # half-plane), not samples; the floors sit below the values measured on this sample
    # (workspace 0.379 by zero exclusion on value sets, its open loop having no
    # compensator, at its workspace factor 26.1 with the valve's spread; a wider search than
    # the margin's finds an unstable member at 0.6; 0.524 at factor 11.1 before the family
    # varied the valve; 0.109 by the eigenvalue enclosures, 0.2615 by mu; hinf-robust 0.3786
    # by mu on its loop's LFT, 0.0027 by the eigenvalue enclosures with 400 sub-boxes per
    # scale; hinf-robust is tuned with a half-sample lag at its output since it went
    # unstable in the 1 kHz loop), which the box budget and the single-threaded robust
    # synthesis set the same on every thread count. The floor is certified directly (one
    # scale, as a user's test would), not by the margin's bisection: hinf-robust's by mu
    # (0.2: 10 frequencies, the bound's peak 0.954, 8.5 s; 0.08 took 6 and 4.4 s, 0.3 took 19
    # and 17.6 s), which the automatic choice takes for a family's loop with a compensator
    r = _run(runs, name)
    cert = assert_robust_margin(
        r.family, controller=r.controller, at_least=floor, max_boxes=400, method="auto"
    )
    assert cert["method"] == method
    stats = cert["certified_stats"]
    if method == "mu":
        assert stats["frequencies"] >= 1 and stats["peak_mu_upper"] < 1.0
    else:
        assert stats["cells"] >= 256
    # neither design holds the whole family's box: a member breaks each below scale 1,
    # above the certified floor
    upper, critical, _ = margin_upper_bound(
        r.family, controller=r.controller, samples=300, seed=SEED
    )
    assert floor <= upper < 1.0 and critical["violation"] > 0
