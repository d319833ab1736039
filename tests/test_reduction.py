import control as ct
import numpy as np
import pytest

from robust.analysis.reduction import (
    balanced_truncation,
    hankel_singular_values,
    stable_unstable_split,
)


def sigma_max(sys, w):
    resp = np.asarray(sys(1j * w, squeeze=False))
    return max(np.linalg.svd(resp[:, :, i], compute_uv=False)[0] for i in range(len(w)))


def rand_stable(seed, n=10, p=2, m=2):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + rng.uniform(0.2, 2.0)) * np.eye(n)
    return ct.ss(A, rng.normal(size=(n, m)), rng.normal(size=(p, n)), rng.normal(size=(p, m)))


@pytest.mark.parametrize("seed", range(4))
def test_hsv_match_slycot(seed):
    sys = rand_stable(seed)
    ref = ct.hsvd(sys)  # SLICOT ab13ad
    # Hankel singular values are accurate relative to the largest one
    np.testing.assert_allclose(
        hankel_singular_values(sys.A, sys.B, sys.C), ref, rtol=1e-6, atol=1e-9 * ref[0]
    )


@pytest.mark.parametrize("seed", range(4))
def test_reduction_error_within_bound_and_matches_balred(seed):
    sys = rand_stable(seed)
    red = balanced_truncation(sys, order=5)
    w = np.logspace(-3, 3, 800)
    err = sigma_max(sys - red.sys, w)
    assert err <= red.error_bound * (1 + 1e-9)
    ref = ct.balred(sys, 5)  # SLICOT ab09ad
    err_ref = sigma_max(sys - ref, w)
    assert err == pytest.approx(err_ref, rel=1e-5)


def test_unstable_part_is_kept():
    sys = rand_stable(1, n=8)
    A = sys.A.copy()
    A += np.diag([6.0] + [0.0] * 7)
    su = ct.ss(A, sys.B, sys.C, sys.D)
    n_unst = int(np.sum(su.poles().real > 0))
    assert n_unst >= 1
    (As, Bs, Cs), (Au, Bu, Cu) = stable_unstable_split(su.A, su.B, su.C)
    s = 0.7j
    g = su.C @ np.linalg.solve(s * np.eye(8) - su.A, su.B)
    g2 = Cs @ np.linalg.solve(s * np.eye(len(As)) - As, Bs) + Cu @ np.linalg.solve(
        s * np.eye(len(Au)) - Au, Bu
    )
    np.testing.assert_allclose(g2, g, rtol=1e-8)
    red = balanced_truncation(su, order=n_unst + 2)
    assert red.n_unstable == n_unst
    assert int(np.sum(red.sys.poles().real > 0)) == n_unst


def test_tolerance_mode_picks_smallest_order():
    sys = rand_stable(2)
    red = balanced_truncation(sys, tol=0.5)
    assert red.error_bound <= 0.5
    if red.order_after > 0:
        smaller = balanced_truncation(sys, order=red.order_after - 1)
        assert smaller.error_bound > 0.5


def test_bad_order():
    from robust.errors import ParameterError

    with pytest.raises(
        ParameterError, match=r"order must be in \[0, 10\] \(unstable states are kept\); got 11"
    ):
        balanced_truncation(rand_stable(0), order=11)
