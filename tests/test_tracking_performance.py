"""designs.tracking_performance: the specification's tracking bound over the family's box.

The margin is computed on the family's loop built from the blocks over uncertain reals
(``family_uss``); every number is checked here on the python-control members
(``Family.member``, the paper's transfer functions) by the specification's own exact check
(``designs.response.deviation_checks``): the nominal peak, the worst member, and members of
the certified box.
"""

from __future__ import annotations

import control as ct
import numpy as np
import pytest

from backhoe import default_family
from designs.response import deviation_checks
from designs.spec import Specification
from designs.tracking_performance import (
    deviation_system,
    performance_summary,
    tracking_performance,
)
from robust.analysis.bounds import bound_ratio
from uncertainty import scaled_bounds

SPEC = Specification()
#: A workspace 22 times the paper's: the uncompensated loop tracks within the bound on its
#: nominal member (peak 0.23 of the bound) and on a part of the box.
K_PSF = 0.005


@pytest.fixture(scope="module")
def wide():
    fam = default_family().replace(k_psf=K_PSF)
    res = tracking_performance(fam, None, SPEC, fractions=(0.7, 0.5, 0.3), bisections=0)
    return fam, res


def _tracking(fam, values: dict, controller=None):
    loop = fam.member(np.array([values[n] for n in fam.names]))
    if np.linalg.eigvals(loop.system(bdft=True, controller=controller).A).real.max() >= 0:
        return np.inf
    return deviation_checks(loop, SPEC, controller)[0].value


def test_the_nominal_peak_is_the_python_control_members_tracking_check(wide):
    fam, res = wide
    nominal = dict(zip(fam.names, fam.nominal_values()))
    assert res.nominal_norm == pytest.approx(_tracking(fam, nominal), rel=1e-6)
    assert 0.1 < res.nominal_norm < 0.5


def test_the_margin_is_bracketed_and_the_worst_member_breaks_the_bound(wide):
    fam, res = wide
    assert 0.1 < res.lower <= res.upper < 1.0
    assert res.certificate["certified"] and res.certificate["stability"]["certified"]
    w = res.worst
    assert w["norm"] >= 1.0 and w["scale"] == res.upper
    # the member's own tracking check, on its python-control realisation
    assert _tracking(fam, w["parameters"]) >= 1.0 - 1e-6
    assert 0.0 <= w["frequency_hz"] <= SPEC.split_hz


def test_members_of_the_certified_box_meet_the_tracking_bound(wide):
    fam, res = wide
    R = deviation_system(fam)
    lo, hi = scaled_bounds(R, res.lower)
    rng = np.random.default_rng(3)
    rows = np.vstack([lo, hi, lo + rng.random((10, lo.size)) * (hi - lo)])
    names = list(R.parameters)
    worst = max(_tracking(fam, dict(zip(names, r))) for r in rows)
    assert worst < 1.0


def test_the_summary_keeps_both_bounds_and_the_scales_tried(wide):
    _, res = wide
    s = performance_summary(res)
    assert (s["lower"], s["upper"]) == (res.lower, res.upper)
    assert s["certificate"]["certified"] and s["certificate"]["frequencies_used"] > 0
    assert [h["scale"] for h in s["certificate"]["history"]][0] == pytest.approx(0.7 * res.upper)
    assert "timings_s" not in s


def test_a_reference_correction_enters_the_deviation_divided_by_k_psf():
    # a static correction from the cylinder position (the cylinder loop's gain lowered by a
    # fifth): R = (x - u) + r_corr / K_PSF on the uncertain loop against the python-control
    # member's exact tracking check
    fam = default_family().replace(k_psf=K_PSF)
    K = ct.ss([], [], [], [[0.2]], inputs="y", outputs="r_corr")
    R = deviation_system(fam, K)
    num, den = SPEC.tracking_weight
    peak = bound_ratio(
        R.nominal(), [ct.ss(ct.tf(list(num), list(den)))], band_hz=(0, SPEC.split_hz)
    )
    nominal = dict(zip(fam.names, fam.nominal_values()))
    assert peak.value == pytest.approx(_tracking(fam, nominal, K), rel=1e-6)
    without = deviation_system(fam)
    assert (
        abs(
            peak.value
            - bound_ratio(
                without.nominal(), [ct.ss(ct.tf(list(num), list(den)))], band_hz=(0, SPEC.split_hz)
            ).value
        )
        > 1e-3
    )
