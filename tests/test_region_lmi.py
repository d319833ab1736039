"""LMI pole regions (Chilali & Gahinet 1996): certificates against eigenvalues."""

import math

import numpy as np
import pytest

from robust.analysis.region import EVERY_FREQUENCY_HZ, Region
from robust.errors import InfeasibleError, ModelStructureError, ParameterError, VerificationError
from robust.synthesis.region import (
    certify_region,
    check_region_certificate,
    recentring,
    region_lmis,
)


def _modal(poles, seed=0):
    """A real matrix with the given (conjugate-closed) poles, in random coordinates."""
    blocks = []
    for p in poles:
        if p.imag > 0:
            blocks.append(np.array([[p.real, p.imag], [-p.imag, p.real]]))
        elif p.imag == 0:
            blocks.append(np.array([[p.real]]))
    n = sum(b.shape[0] for b in blocks)
    A = np.zeros((n, n))
    i = 0
    for b in blocks:
        k = b.shape[0]
        A[i : i + k, i : i + k] = b
        i += k
    T = np.random.default_rng(seed).normal(size=(n, n)) + 3 * np.eye(n)
    return T @ A @ np.linalg.inv(T)


def _pair(zeta, wn):
    return complex(-zeta * wn, wn * math.sqrt(1 - zeta**2))


@pytest.mark.parametrize(
    "zeta, inside",
    [(0.12, True), (0.3, True), (0.08, False), (0.0999, False)],
    ids=["z0.12", "z0.3", "z0.08", "z0.0999"],
)
def test_cone_certificate_iff_damping(zeta, inside):
    # a lightly damped 6 Hz mode (the structure), a slow real pole and a fast one
    poles = [_pair(zeta, 2 * math.pi * 6), -0.5, -300.0]
    A = _modal(poles)
    region = Region(decay_rate=0.1, min_damping=0.1, band_hz=EVERY_FREQUENCY_HZ)
    v = region.worst_violation(np.linalg.eigvals(A))
    if inside:
        cert = certify_region(A, region)
        assert cert.violation == pytest.approx(v, rel=1e-6) and v < 0
        assert cert.lmi_max_eig["decay"] < 0 and cert.lmi_max_eig["cone"] < 0
        assert cert.lmi_max_eig["X_min"] > 0
        # an independent rebuild of the LMIs from X
        checks = check_region_certificate(A, cert.X, region)
        assert max(checks["decay"], checks["cone"]) < 0
    else:
        assert v > 0
        with pytest.raises(InfeasibleError, match="outside the region"):
            certify_region(A, region)


def test_decay_rate_only():
    A = _modal([-0.15, _pair(0.05, 10.0)])
    ok = certify_region(A, Region(decay_rate=0.1))
    assert set(ok.lmi_max_eig) == {"decay", "X_min"}
    with pytest.raises(InfeasibleError, match="violation"):
        certify_region(A, Region(decay_rate=0.2))


def test_region_lmis_match_the_eigenvalues_for_a_normal_matrix():
    # for a normal matrix X = I works exactly when every eigenvalue is in the region
    lam = _pair(0.2, 5.0)
    A = np.array([[lam.real, lam.imag], [-lam.imag, lam.real]])
    for zeta, expect in ((0.19, True), (0.21, False)):
        mats = region_lmis(A, np.eye(2), Region(0.0, zeta))
        assert bool(np.linalg.eigvalsh(mats["cone"]).max() < 0) == expect


def test_violations_and_scaling():
    r = Region(0.1, 0.1, EVERY_FREQUENCY_HZ)
    p = np.array([-1.0 + 20j, -0.05, -3.0])
    v = r.violations(p)
    assert v[0] == pytest.approx(max(-1.0 + 0.1, -1.0 + 0.1 * abs(p[0])))
    assert v[1] == pytest.approx(0.05)
    assert r.worst_violation([]) == -math.inf
    s = r.scaled(20.0)
    assert s.decay_rate == pytest.approx(0.005) and s.min_damping == 0.1
    assert s.band_hz == EVERY_FREQUENCY_HZ
    assert "damping ratio >= 0.1" in r.describe()


def test_violations_in_a_band_and_everywhere():
    # a pole at 20/(2 pi) = 3.2 Hz is damped 0.05: outside a 1-10 Hz band's cone, inside
    # a 5-10 Hz band's (only the decay counts there); everywhere() asks every pole's damping
    p = np.array([-1.0 + 20j, -3.0])
    inside, outside = Region(0.1, 0.1, (1.0, 10.0)), Region(0.1, 0.1, (5.0, 10.0))
    assert inside.violations(p)[0] == pytest.approx(-1.0 + 0.1 * abs(p[0]))
    assert outside.violations(p)[0] == pytest.approx(-1.0 + 0.1)
    np.testing.assert_array_equal(
        outside.everywhere().violations(p), Region(0.1, 0.1, EVERY_FREQUENCY_HZ).violations(p)
    )
    assert outside.scaled(2.0).band_hz == (2.5, 5.0)
    assert Region(0.1, 0.1).scaled(2.0).band_hz is None
    with pytest.raises(ParameterError, match="band"):
        Region(0.1, 0.1).violations(p)
    # the member-wise measure keeps the decay line STABILITY_TOL left of the axis
    assert outside.violation(p[None])[0] >= outside.worst_violation(p)


def test_a_band_limited_region_is_certified_at_every_frequency():
    # a lightly damped 0.4 Hz mode below the band: the region in its band holds, but the
    # LMI cone holds for every pole, so no certificate exists (synthesis is conservative)
    A = _modal([_pair(0.05, 2 * math.pi * 0.4), -2.0])
    region = Region(0.1, 0.1, (0.5, 10.0))
    assert region.violation(np.linalg.eigvals(A)[None])[0] < 0
    with pytest.raises(InfeasibleError, match="every frequency"):
        certify_region(A, region)
    assert certify_region(A, Region(0.1, 0.01)).violation < 0


def test_recentring():
    P = np.diag([1e-4, 1.0, 1e6])
    T = recentring(P)
    assert np.allclose(T.T @ P @ T, np.eye(3), atol=1e-9)


@pytest.mark.parametrize(
    "kwargs, match",
    [({"decay_rate": -0.1}, "decay_rate"), ({"min_damping": 1.0}, "min_damping")],
    ids=["negative-decay", "damping-one"],
)
def test_bad_region(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        Region(**kwargs)


def test_bad_matrix():
    with pytest.raises(ModelStructureError, match="square"):
        certify_region(np.ones((2, 3)), Region())
    with pytest.raises(ModelStructureError, match="finite"):
        certify_region(np.array([[np.nan]]), Region())
    with pytest.raises(ModelStructureError, match="Region"):
        certify_region(np.eye(2) * -1, (0.1, 0.1))


def test_recentring_floors_a_singular_matrix():
    T = recentring(np.diag([0.0, 1.0]))
    assert np.all(np.isfinite(T)) and abs(np.linalg.det(T)) > 0
    with pytest.raises(VerificationError, match="positive definite"):
        recentring(-np.eye(2))


def test_modal_certificate_for_a_diagonalisable_matrix():
    # well-conditioned eigenvectors: X = (V V^H)^-1 from them, no SDP; for a normal
    # matrix that is a multiple of the identity
    poles = [_pair(0.2, 2 * math.pi * 6), _pair(0.5, 3.0), -0.5, -300.0]
    A = _modal(poles, seed=3)
    region = Region(decay_rate=0.1, min_damping=0.15)
    cert = certify_region(A, region)
    assert cert.method == "modal" and cert.to_json()["method"] == "modal"
    checks = check_region_certificate(A, cert.X, region)
    assert checks["decay"] < 0 and checks["cone"] < 0 and checks["X_min"] > 0
    lam = _pair(0.2, 5.0)
    N = np.array([[lam.real, lam.imag], [-lam.imag, lam.real]])
    Xn = certify_region(N, Region(0.0, 0.15)).X
    assert np.allclose(Xn / Xn[0, 0], np.eye(2), atol=1e-12)


def test_nearly_defective_matrix_falls_back_to_the_sdp():
    # two copies of a damped pair 1e-9 apart, coupled strongly: the eigenvectors are nearly
    # parallel, the modal certificate's margin is below rounding, the SDP certifies
    lam = _pair(0.3, 4.0)
    R = np.array([[lam.real, lam.imag], [-lam.imag, lam.real]])
    A = np.block([[R, 50.0 * np.eye(2)], [np.zeros((2, 2)), R * (1 + 1e-9)]])
    assert np.linalg.cond(np.linalg.eig(A)[1]) > 1e6
    region = Region(decay_rate=0.5, min_damping=0.2)
    cert = certify_region(A, region)
    assert cert.method == "sdp"
    checks = check_region_certificate(A, cert.X, region)
    assert checks["decay"] < 0 and checks["cone"] < 0 and checks["X_min"] > 0
