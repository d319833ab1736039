"""Physical human model: structure, force port, fit to Eqn 5 and its stored result."""

import dataclasses
import itertools

import control as ct
import numpy as np
import pytest

from backhoe.model._human_fit_data import FIT_RESULT
from backhoe.model.human import HumanModel, human_variant
from backhoe.model.human_fit import (
    BOX_FIT_NAMES,
    FIT_BAND_HZ,
    chain_response,
    eqn5_response,
    fit_chain,
    fit_frequencies,
    fit_in_box,
)
from backhoe.model.literature import DEFAULT_POSTURE, published_box
from backhoe.model.physical import (
    EQN5_FIT,
    PhysicalHuman,
    PhysicalHumanParams,
    fit_summary,
    nominal_params,
    segment_masses,
)
from robust.errors import ParameterError


def test_variant_is_a_human_model_with_force_port():
    h = human_variant("physical")
    assert isinstance(h, PhysicalHuman)
    assert isinstance(h, HumanModel)
    assert h.has_force_port and h.variant == "physical"
    sys = h.system()
    assert sys.input_labels == ["c", "f"] and sys.output_labels == ["h"]
    assert np.all(np.real(ct.poles(sys)) < 0)


def test_response_matches_independent_chain_solution():
    p = PhysicalHumanParams()
    f = np.geomspace(0.1, 30, 50)
    sys = PhysicalHuman(p).system()
    resp = sys(2j * np.pi * f)  # (1, 2, F)
    ref = (
        p.h_gain
        * p.c_unit
        * chain_response(f, [p.m_trunk, p.m_arm], [p.k_trunk, p.k_arm], [p.c_trunk, p.c_arm])
    )
    np.testing.assert_allclose(resp[0, 0], ref, rtol=1e-10)


def test_low_frequency_motion_is_bounded_and_force_port_is_the_static_compliance():
    p = PhysicalHumanParams()
    dc = PhysicalHuman(p).system().dcgain()
    m_tot = p.m_trunk + p.m_arm
    # seat acceleration: the chain sags by the inertial load on each spring
    np.testing.assert_allclose(
        dc[0, 0], -p.h_gain * p.c_unit * (m_tot / p.k_trunk + p.m_arm / p.k_arm), rtol=1e-10
    )
    # handle force: the two springs in series
    np.testing.assert_allclose(dc[0, 1], p.h_gain * (1 / p.k_trunk + 1 / p.k_arm), rtol=1e-10)


def _errors_against_eqn5(params):
    f = fit_frequencies()
    model = PhysicalHuman(params).system()(2j * np.pi * f)[0, 0]
    ratio = model / eqn5_response(f)
    err_db = 20 * np.log10(np.abs(ratio))
    err_deg = np.degrees(np.angle(ratio))
    return err_db, err_deg


def test_fit_summary_errors_are_the_models_errors_against_eqn5():
    s = fit_summary()
    err_db, err_deg = _errors_against_eqn5(PhysicalHumanParams())
    assert s["fit error, magnitude [dB]"]["max"] == pytest.approx(np.max(np.abs(err_db)), rel=1e-9)
    assert s["fit error, magnitude [dB]"]["rms"] == pytest.approx(
        np.sqrt(np.mean(err_db**2)), rel=1e-9
    )
    assert s["fit error, phase [deg]"]["rms"] == pytest.approx(
        np.sqrt(np.mean(err_deg**2)), rel=1e-9
    )
    assert f"{FIT_BAND_HZ[0]:g}-{FIT_BAND_HZ[1]:g} Hz" in s["nominal"]
    assert (
        s["unit-conversion gain h_gain [paper h units per m, for c in m/s^2]"]
        == PhysicalHumanParams().h_gain
    )


def test_nominal_lies_in_the_published_box_and_beats_its_corners():
    # the nominal is a member of the published ranges; no corner of the box (the arm and
    # trunk parameters the fit moves) matches Eqn 5 better on the same error measure
    box = published_box(DEFAULT_POSTURE)
    p = PhysicalHumanParams()
    for name in BOX_FIT_NAMES:
        assert box[name].contains(getattr(p, name)), name

    def cost(params):
        err_db, err_deg = _errors_against_eqn5(params)
        mag = err_db / (20 / np.log(10))
        mag = mag - mag.mean()  # the unit gain is free
        return np.sum(mag**2) + np.sum(np.radians(err_deg) ** 2)

    best = cost(p)
    for corner in itertools.product(*[(box[n].low, box[n].high) for n in BOX_FIT_NAMES]):
        values = dict(zip(BOX_FIT_NAMES, corner))
        for sign in (1.0, -1.0):
            q = PhysicalHumanParams.from_modes(m_trunk=p.m_trunk, h_gain=sign * p.h_gain, **values)
            assert cost(q) >= best * (1 - 1e-9)


def test_modal_parameters_round_trip_and_define_the_uncoupled_modes():
    p = PhysicalHumanParams.from_modes(
        m_trunk=40.0, m_arm=1.5, f_trunk_hz=3.0, zeta_trunk=0.3, f_arm_hz=2.0, zeta_arm=0.25
    )
    assert (p.f_trunk_hz, p.zeta_trunk, p.f_arm_hz, p.zeta_arm) == pytest.approx(
        (3.0, 0.3, 2.0, 0.25), rel=1e-12
    )
    # arm with the trunk held: m_arm s^2 + c_arm s + k_arm
    lam = np.roots([p.m_arm, p.c_arm, p.k_arm])
    assert np.abs(lam[0]) / (2 * np.pi) == pytest.approx(2.0, rel=1e-12)
    assert -lam[0].real / np.abs(lam[0]) == pytest.approx(0.25, rel=1e-12)
    # upper body rigid with the arm on the seat spring
    lam = np.roots([p.m_trunk + p.m_arm, p.c_trunk, p.k_trunk])
    assert np.abs(lam[0]) / (2 * np.pi) == pytest.approx(3.0, rel=1e-12)
    with pytest.raises(ParameterError, match="zeta_arm"):
        PhysicalHumanParams.from_modes(
            m_trunk=40.0, m_arm=1.5, f_trunk_hz=3.0, zeta_trunk=0.3, f_arm_hz=2.0, zeta_arm=-0.1
        )


def test_variants_are_the_nominal_the_other_posture_and_the_eqn5_fit():
    assert human_variant("physical").params == PhysicalHumanParams()
    nb = human_variant("physical-no-backrest")
    assert nb.params == nominal_params("no-backrest") and nb.variant == "physical-no-backrest"
    lo, hi = (
        published_box("no-backrest")["f_trunk_hz"].low,
        published_box("no-backrest")["f_trunk_hz"].high,
    )
    assert lo <= nb.params.f_trunk_hz <= hi
    e5 = human_variant("eqn5-fit")
    assert e5.params == EQN5_FIT
    # the unconstrained fit's arm is the lightly damped artefact, outside the published box
    assert e5.params.zeta_arm < published_box()["zeta_arm"].low
    assert e5.params.m_arm > published_box()["m_arm"].high


def test_upper_body_mass_follows_anthropometry():
    seg = segment_masses(75.0)
    p = PhysicalHumanParams()
    assert p.m_trunk == pytest.approx(seg["trunk"])
    h = PhysicalHuman.for_body_mass(100.0)
    assert h.params.m_trunk == pytest.approx(seg["trunk"] * 100.0 / 75.0)


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("k_trunk", -1.0, "PhysicalHumanParams.k_trunk"),
        ("c_arm", float("nan"), "PhysicalHumanParams.c_arm"),
        ("m_arm", 0.0, "PhysicalHumanParams.m_arm"),
        ("h_gain", 0.0, "h_gain must be nonzero"),
    ],
    ids=["negative-stiffness", "nan-damping", "zero-mass", "zero-gain"],
)
def test_invalid_parameters_raise(field, value, match):
    with pytest.raises(ParameterError, match=match):
        dataclasses.replace(PhysicalHumanParams(), **{field: value})


@pytest.mark.slow
def test_fit_reproduces_stored_result():
    stored = FIT_RESULT["two_dof"]
    fresh = fit_chain(stored["masses"])
    for key in ("stiffnesses", "dampings"):
        np.testing.assert_allclose(fresh[key], stored[key], rtol=1e-4, err_msg=key)
    assert fresh["gain"] == pytest.approx(stored["gain"], rel=1e-4)
    assert fresh["err_db_max"] == pytest.approx(stored["err_db_max"], rel=1e-4)
    assert fresh["at_bounds"] == []


@pytest.mark.slow
@pytest.mark.parametrize("posture", ["backrest", "no-backrest"])
def test_box_fit_reproduces_stored_result(posture):
    stored = FIT_RESULT["literature"][posture]
    fresh = fit_in_box(published_box(posture))
    # the fit's errors and gain reproduce to 1e-6; the parameters to 1e-3, since the fit is
    # flat along some of them: with the backrest, m_arm lands 6.6e-5 (relative) apart on two
    # CPUs' BLAS kernels while the rms errors agree to 1e-7
    for key in ("h_gain", "err_db_rms", "err_deg_rms"):
        assert fresh[key] == pytest.approx(stored[key], rel=1e-6), key
    for key in BOX_FIT_NAMES:
        assert fresh[key] == pytest.approx(stored[key], rel=1e-3), key
    assert fresh["at_bounds"] == stored["at_bounds"]


def test_handle_offset_scales_only_the_arm_by_the_arm_geometry():
    from backhoe.model.arm import ArmGeometry

    h = PhysicalHuman()
    g = ArmGeometry()
    fwd = h.with_handle_offset(0.1016)
    s = g.stiffness_scale(0.1016)
    assert fwd.params.k_arm == pytest.approx(h.params.k_arm * s)
    assert fwd.params.c_arm == pytest.approx(h.params.c_arm * s)
    assert fwd.params.k_trunk == h.params.k_trunk and fwd.handle_offset_m == pytest.approx(0.1016)
    back = fwd.with_handle_offset(-0.1016)  # offsets compose
    assert back.params.k_arm == pytest.approx(h.params.k_arm, rel=1e-12)
    # independent check of the compliance: the Jacobian from finite differences of the kinematics
    L1, L2 = g.lengths
    q = np.array(g.joint_angles(0.05))

    def hand(q):
        return np.array(
            [
                L1 * np.cos(q[0]) + L2 * np.cos(q[0] + q[1]),
                L1 * np.sin(q[0]) + L2 * np.sin(q[0] + q[1]),
            ]
        )

    J = np.column_stack(
        [(hand(q + e) - hand(q - e)) / 2e-7 for e in (np.array([1e-7, 0]), np.array([0, 1e-7]))]
    )
    np.testing.assert_allclose(hand(q), [g.hand_x + 0.05, g.hand_y], atol=1e-12)
    assert g.fore_aft_compliance(0.05) == pytest.approx((J @ J.T)[0, 0], rel=1e-6)
    with pytest.raises(ParameterError, match="out of the arm's reach"):
        h.with_handle_offset(1.0)


def test_phase_weighted_fit_needs_a_sign():
    with pytest.raises(ValueError, match="needs sign"):
        fit_chain([47.1, 3.75], phase_weight=1.0)
