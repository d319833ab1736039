"""Assumption checks of H-infinity synthesis (robust.synthesis.assumptions), called directly.

The failures seen through hinfsyn_lmi are in test_hinfsyn.py; here: which modes the
PBH tests look at (everything not stable by robust.analysis.stability), modes
reported in rad/s whatever the time scale, and the separate checks.
"""

import control
import numpy as np
import pytest

from robust.errors import AssumptionError, ParameterError
from robust.synthesis.assumptions import (
    check_detectable,
    check_hinf_assumptions,
    check_regularity,
    check_stabilisable,
    pbh_failures,
)
from robust.synthesis.genplant import GeneralizedPlant
from robust.synthesis.lmi import PlantBlocks


def _blocks(a_free, *, scale=1.0, D12=None, D21=None):
    """Two states: state 0 (pole ``a_free``) neither driven by u nor seen by y;
    state 1 (pole -1) controllable and observable.  ``scale`` multiplies A (rad/s)."""
    A = scale * np.diag([a_free, -1.0])
    return PlantBlocks(
        A=A,
        B1=np.array([[1.0], [1.0]]),
        B2=np.array([[0.0], [1.0]]),
        C1=np.array([[1.0, 1.0], [0.0, 0.0]]),
        C2=np.array([[0.0, 1.0]]),
        D11=np.zeros((2, 1)),
        D12=np.array([[0.0], [1.0]]) if D12 is None else D12,
        D21=np.array([[1.0]]) if D21 is None else D21,
    )


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e4])
def test_unstable_hidden_mode_is_named_in_rad_per_s(scale):
    b = _blocks(2.0, scale=scale)
    with pytest.raises(AssumptionError, match=r"\(A, B2\) is not stabilisable") as err:
        check_stabilisable(b)
    mode = float(str(err.value).split("[")[1].split("]")[0])
    assert mode == pytest.approx(2.0 * scale, rel=1e-6)
    with pytest.raises(AssumptionError, match=r"\(C2, A\) is not detectable"):
        check_detectable(b)


def test_marginal_modes_must_be_controllable_and_stable_ones_need_not():
    # a pole on the imaginary axis is not stable (robust.analysis.stability): refused
    with pytest.raises(AssumptionError, match=r"not stabilisable: the mode\(s\) \[0\.0\]"):
        check_stabilisable(_blocks(0.0))
    # a slow but stable hidden mode is fine
    check_stabilisable(_blocks(-1e-3))
    check_detectable(_blocks(-1e-3))


def test_pbh_failures_scales_modes_by_w0():
    A = np.diag([0.5, -1.0])
    B = np.array([[0.0], [1.0]])
    assert pbh_failures(A, B, side="right", w0=10.0) == [pytest.approx(5.0)]
    assert pbh_failures(A, B.T, side="left", w0=10.0) == [pytest.approx(5.0)]
    assert pbh_failures(np.zeros((0, 0)), np.zeros((0, 1)), side="right") == []
    with pytest.raises(ParameterError, match="side must be 'right' or 'left'; got 'up'"):
        pbh_failures(A, B, side="up")


def test_regularity():
    check_regularity(_blocks(-1.0))
    with pytest.raises(AssumptionError, match="D12 must have full column rank 1.*got rank 0"):
        check_regularity(_blocks(-1.0, D12=np.zeros((2, 1))))
    with pytest.raises(AssumptionError, match="D21 must have full row rank 1.*got rank 0"):
        check_regularity(_blocks(-1.0, D21=np.zeros((1, 1))))


def test_check_hinf_assumptions_require_regular():
    b = _blocks(-1.0, D12=np.zeros((2, 1)))
    sys = control.ss(
        b.A,
        np.hstack([b.B1, b.B2]),
        np.vstack([b.C1, b.C2]),
        np.block([[b.D11, b.D12], [b.D21, np.zeros((1, 1))]]),
    )
    gp = GeneralizedPlant.from_counts(sys, nmeas=1, ncon=1)
    check_hinf_assumptions(gp, require_regular=False)
    with pytest.raises(AssumptionError, match="D12 must have full column rank"):
        check_hinf_assumptions(gp)
