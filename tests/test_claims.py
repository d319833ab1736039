"""The paper's claims C1-C3 (pole counts), checked two independent ways."""

import numpy as np
import paper_formulas as pf
import pytest

from backhoe import (
    DEFAULT_CALIBRATION,
    K_PSF_NOMINAL,
    K_PSF_STABLE,
    BDFTLoop,
    LiteralHuman,
    bdft_ratio,
    calibrate,
    critical_k_psf,
    evaluate_claims,
    loop_poles,
)
from robust import InfeasibleError
from robust.analysis.stability import unstable_mask

CAL = DEFAULT_CALIBRATION


def char_roots(k_psf):
    return pf.characteristic_roots(k_psf, CAL.kp, CAL.ki, CAL.loop_scale, CAL.handle_sign)


@pytest.mark.parametrize(
    "k_psf,n_unstable",
    [(K_PSF_NOMINAL, 2), (K_PSF_STABLE, 0)] + [(K_PSF_NOMINAL / f, 0) for f in range(2, 11)],
    ids=["C1-nominal", "C2-0.055"] + [f"C3-x{f}" for f in range(2, 11)],
)
def test_pole_counts_c1_c3(k_psf, n_unstable):
    ps = loop_poles(BDFTLoop(k_psf=k_psf))
    assert ps.n_unstable == n_unstable
    # independent: roots of the characteristic polynomial built from the printed formulas
    roots = char_roots(k_psf)
    assert np.count_nonzero(unstable_mask(roots)) == n_unstable
    np.testing.assert_allclose(
        np.sort_complex(ps.poles), np.sort_complex(roots), rtol=1e-6, atol=1e-8
    )


def test_nominal_unstable_pair_is_complex():
    ps = loop_poles(BDFTLoop())
    up = ps.unstable_poles
    assert up.size == 2 and np.all(np.abs(up.imag) > 1.0) and np.isclose(up[0], np.conj(up[1]))


def test_critical_k_psf_is_between_the_claims():
    kc = critical_k_psf(BDFTLoop())
    assert K_PSF_STABLE < kc < K_PSF_NOMINAL
    # just below and just above the crossing
    assert loop_poles(BDFTLoop(k_psf=kc * 0.999)).stable
    assert loop_poles(BDFTLoop(k_psf=kc * 1.001)).n_unstable == 2


def test_calibration_search_reproduces_the_defaults():
    res = calibrate(LiteralHuman())
    cal = res.calibration
    assert (cal.kp, cal.ki, cal.handle_sign) == (CAL.kp, CAL.ki, CAL.handle_sign)
    assert cal.loop_scale == pytest.approx(CAL.loop_scale, rel=1e-12)
    assert res.chosen.reproduces_c1_c3
    assert res.chosen.gain_margin_db >= 6.0 and res.chosen.phase_margin_deg >= 45.0


def test_calibration_with_positive_sign_only_cannot_reproduce_c1():
    # positive feedback at the handle loses stability through a real pole: never "two
    # unstable poles"
    with pytest.raises(InfeasibleError, match="no PI gains x junction sign .* reproduce C1-C3"):
        calibrate(
            LiteralHuman(), signs=(1,), kp_grid=(0.1, 0.3), ki_ratio_grid=(0.0, 1.0), g_points=60
        )


def test_claims_literal_variant():
    claims = evaluate_claims(BDFTLoop())
    assert claims["C1"].holds and claims["C2"].holds and claims["C3"].holds
    # the literal Eqn 5 puts the feedthrough at low frequency (BRIEF section 4): C4 fails
    assert claims["C4"].status == "fails"
    assert claims["C4"].numbers["low_band_dev_db"][2] > 10.0
    assert claims["C5"].status == "not testable"
    peaks = list(claims["C3"].numbers["peak_dev_db"].values())
    assert peaks == sorted(peaks, reverse=True)


def test_bdft_ratio_matches_formula():
    f = np.array([0.2, 1.0, 6.3])
    loop = BDFTLoop(k_psf=K_PSF_STABLE)
    s = 2j * np.pi * f
    want = pf.loop_u_to_y(
        s, K_PSF_STABLE, CAL.kp, CAL.ki, CAL.loop_scale, CAL.handle_sign
    ) / pf.loop_u_to_y(s, K_PSF_STABLE, CAL.kp, CAL.ki, CAL.loop_scale, CAL.handle_sign, bdft=False)
    np.testing.assert_allclose(bdft_ratio(loop, f), want, rtol=1e-7)


def test_bdft_loop_gain_matches_formula():
    from backhoe import bdft_loop_gain

    f = np.array([0.5, 1.0, 6.4])
    s = 2j * np.pi * f
    L = pf.pi(s, CAL.kp, CAL.ki) * pf.valve(s)
    want = CAL.handle_sign * CAL.loop_scale * 0.055 * pf.human(s) * pf.structure(s) * L / (1 + L)
    got = bdft_loop_gain(BDFTLoop(k_psf=0.055), f)["loop"]
    np.testing.assert_allclose(got, want, rtol=1e-8)
