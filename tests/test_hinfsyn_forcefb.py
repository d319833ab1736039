"""LMI H-infinity synthesis on the workbench's force-feedback generalized plant.

The plant (:func:`backhoe.synthesis.forcefb.force_feedback_plant`, 22 states) interconnects
companion-form blocks whose state scales span many decades and has performance
and measurement channels of very different sizes; with the ``eqn5-fit`` human it is
open-loop unstable.  References are what python-control's Riccati ``hinfsyn`` (SLICOT
``sb10ad``) *achieves* in closed loop, recomputed with
:func:`robust.analysis.norms.hinf_norm`; on this plant SLICOT's gamma iteration stops far
above the optimum, so the LMI design must be at least as good.
"""

import control
import numpy as np
import pytest

from backhoe import BDFTLoop, human_variant
from backhoe.synthesis.forcefb import force_feedback_plant
from robust.analysis.norms import hinf_norm
from robust.analysis.stability import poles_stable, unstable_mask
from robust.errors import AssumptionError
from robust.synthesis.assumptions import check_hinf_assumptions
from robust.synthesis.genplant import GeneralizedPlant
from robust.synthesis.nominal import hinfsyn_lmi


def _plant(human="physical", **loop_kw):
    return force_feedback_plant(BDFTLoop(human=human_variant(human), **loop_kw))


def _slicot_achieved(gp):
    pytest.importorskip("slycot")
    K_ref = control.hinfsyn(gp.sys, gp.ny, gp.nu)[0]
    return hinf_norm(gp.closed_loop(K_ref))


def _check(gp, res):
    cl = gp.closed_loop(res.K)
    poles = control.poles(cl)
    assert poles_stable(poles), f"closed loop unstable: max Re = {poles.real.max()}"
    assert res.gamma <= res.gamma_bound * (1 + 1e-6)
    # independent norms of the same closed loop: SLICOT ab13dd and the frequency grid
    assert hinf_norm(cl, method="slicot") == pytest.approx(res.gamma, rel=1e-5)
    assert hinf_norm(cl, method="grid") <= res.gamma_bound * (1 + 1e-6)
    # the LMI optimum bounds every controller's norm from below (up to the strictness margin)
    assert res.gamma_opt <= res.gamma * (1 + 1e-5)


@pytest.mark.parametrize("loop_kw", [{}, {"k_psf": 0.055}], ids=["default", "k_psf-0.055"])
def test_force_feedback_plant_against_slicot(loop_kw):
    gp = _plant(**loop_kw)
    res = hinfsyn_lmi(gp)
    _check(gp, res)
    achieved_ref = _slicot_achieved(gp)
    assert res.gamma <= 1.01 * achieved_ref
    assert res.gamma_opt <= achieved_ref * (1 + 1e-4)


def _unbalanced(gp, seed=0):
    """The same plant in state coordinates scaled by factors spanning 1e-4 .. 1e4."""
    d = 10.0 ** np.random.default_rng(seed).permutation(np.linspace(-4.0, 4.0, gp.nx))
    s = gp.sys
    sys = control.ss(
        s.A / d[:, None] * d[None, :],
        s.B / d[:, None],
        s.C * d[None, :],
        s.D,
        inputs=s.input_labels,
        outputs=s.output_labels,
    )
    return GeneralizedPlant.from_system(sys, w=gp.w, u=gp.u, z=gp.z, y=gp.y)


def test_pbh_checks_are_independent_of_state_scaling():
    # With the eqn5-fit human the unstable pair (+0.345 +- 8.2j rad/s) is controllable from f
    # and observable from [x_m, c_m]; an absolute rank threshold in badly scaled coordinates
    # called it uncontrollable and unobservable.
    gp = _plant("eqn5-fit")
    assert unstable_mask(np.linalg.eigvals(gp.A)).any()
    gu = _unbalanced(gp)
    assert np.allclose(
        np.sort_complex(np.linalg.eigvals(gu.A)), np.sort_complex(np.linalg.eigvals(gp.A))
    )
    check_hinf_assumptions(gp)
    check_hinf_assumptions(gu)


def test_pbh_still_detects_uncontrollable_unstable_mode_when_badly_scaled():
    # state 1 (pole +1) is driven by w but never by u; the states are scaled over 8 decades
    d = np.array([1e-4, 1.0, 1e4])
    A = np.array([[1.0, 0.0, 0.0], [0.0, -2.0, 0.5], [0.3, 0.0, -3.0]])
    B1, B2 = np.array([[1.0], [1.0], [1.0]]), np.array([[0.0], [0.0], [1.0]])
    C1, C2 = np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]), np.array([[1.0, 1.0, 1.0]])
    sys = control.ss(
        A / d[:, None] * d[None, :],
        np.hstack([B1, B2]) / d[:, None],
        np.vstack([C1, C2]) * d[None, :],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]],
    )
    gp = GeneralizedPlant.from_counts(sys, nmeas=1, ncon=1)
    with pytest.raises(
        AssumptionError, match=r"\(A, B2\) is not stabilisable: the mode\(s\) \[1\.0\]"
    ):
        check_hinf_assumptions(gp)


def test_force_feedback_plant_in_unbalanced_coordinates():
    gp = _plant()
    gu = _unbalanced(gp)
    res = hinfsyn_lmi(gu)
    _check(gu, res)
    # the controller is a property of the transfer functions: it serves both realizations
    assert hinf_norm(gp.closed_loop(res.K)) == pytest.approx(res.gamma, rel=1e-5)
