"""H-infinity norm: the Bruinsma-Steinbuch iteration against a frequency grid and SLICOT ab13dd."""

import control
import numpy as np
import pytest
import scipy.linalg as sla

from robust.analysis.lyapunov import lyapunov, lyapunov_solver
from robust.analysis.norms import h2_norm, hinf_norm, is_stable, sigma_max, spectral_abscissa
from robust.errors import ModelStructureError, ParameterError


def _fr(sys, w):
    """Frequency response array, shape (outputs, inputs, len(w))."""
    return np.stack([np.atleast_2d(sys(1j * x)) for x in np.atleast_1d(w)], axis=-1)


def _stable_rss(n, p, m, seed):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + rng.uniform(0.05, 1.0)) * np.eye(n)
    return control.ss(
        A, rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((p, m))
    )


#: seeded random stable systems: states, outputs, inputs, seed
RANDOM_SYSTEMS = pytest.mark.parametrize(
    "n,p,m,seed",
    [(1, 1, 1, 0), (3, 2, 2, 1), (8, 3, 1, 2), (20, 2, 4, 3), (40, 4, 4, 4)],
    ids=["n1", "n3", "n8", "n20", "n40"],
)


@RANDOM_SYSTEMS
def test_bb_matches_grid_and_slicot(n, p, m, seed):
    sys = _stable_rss(n, p, m, seed)
    bb = hinf_norm(sys)
    grid = hinf_norm(sys, method="grid")
    ref = hinf_norm(sys, method="slicot")
    # bb is an upper bound up to the rounding of Hamiltonian eigenvalues near a flat peak
    # (about 1e-8 relative); grid is a lower bound
    assert grid <= bb * (1 + 1e-7)
    assert bb == pytest.approx(ref, rel=1e-6)
    assert grid == pytest.approx(ref, rel=1e-6)


@pytest.mark.parametrize("zeta", [1e-1, 1e-3, 1e-5], ids=["zeta1e-1", "zeta1e-3", "zeta1e-5"])
def test_lightly_damped_resonance_peak(zeta):
    # |G(jw)| of wn^2/(s^2 + 2 zeta wn s + wn^2) peaks at 1/(2 zeta sqrt(1 - zeta^2))
    wn = 37.7  # rad/s, the structure's 6 Hz mode
    sys = control.ss(control.tf([wn**2], [1, 2 * zeta * wn, wn**2]))
    exact = 1.0 / (2 * zeta * np.sqrt(1 - zeta**2))
    val, w = hinf_norm(sys, return_frequency=True)
    assert val == pytest.approx(exact, rel=1e-7)
    assert w == pytest.approx(wn * np.sqrt(1 - 2 * zeta**2), rel=1e-4)


def test_feedthrough_dominates_at_infinite_frequency():
    sys = control.ss(
        [[-1.0]], [[1.0]], [[1.0]], [[-2.0]]
    )  # G = -2 + 1/(s+1): |G| rises to 2 as w -> inf
    val, w = hinf_norm(sys, return_frequency=True)
    assert val == pytest.approx(2.0, rel=1e-8)
    assert w == np.inf


def test_unstable_is_inf_and_stability_check():
    sys = control.ss([[0.5, 1.0], [0.0, -1.0]], [[1.0], [1.0]], [[1.0, 0.0]], [[0.0]])
    assert not is_stable(sys)
    assert spectral_abscissa(sys) == pytest.approx(0.5)
    for method in ("bb", "grid", "slicot"):
        assert hinf_norm(sys, method=method) == np.inf


@RANDOM_SYSTEMS
def test_h2_norm_matches_slicot_and_the_observability_gramian(n, p, m, seed):
    rss = _stable_rss(n, p, m, seed)
    sys = control.ss(rss.A, rss.B, rss.C, np.zeros((p, m)))
    h2 = h2_norm(sys)
    # python-control's norm(p=2) calls SLICOT ab13bd (slycot)
    assert h2 == pytest.approx(control.norm(sys, p=2), rel=1e-9)
    # the dual Gramian: trace(B' Wo B), A' Wo + Wo A + C' C = 0
    Wo = sla.solve_continuous_lyapunov(rss.A.T, -rss.C.T @ rss.C)
    assert h2 == pytest.approx(np.sqrt(np.trace(rss.B.T @ Wo @ rss.B)), rel=1e-9)
    # the matrices' form gives the same bits as the system's
    assert h2_norm(sys.A, sys.B, sys.C) == h2
    assert h2_norm(sys.A, sys.B, sys.C, np.zeros((p, m))) == h2


def test_h2_norm_of_a_first_order_lag_feedthrough_and_unstable():
    # 1/(s + a): ||G||_2^2 = 1/(2 a)
    a = 3.0
    assert h2_norm(control.ss([[-a]], [[1.0]], [[1.0]], [[0.0]])) == pytest.approx(
        np.sqrt(1 / (2 * a)), rel=1e-14
    )
    # white noise straight through has infinite power; so has an unstable system
    assert h2_norm(control.ss([[-a]], [[1.0]], [[1.0]], [[0.5]])) == np.inf
    assert h2_norm(control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]])) == np.inf
    assert h2_norm(control.ss([], [], [], [[0.0]])) == 0.0
    with pytest.raises(ModelStructureError, match="continuous-time"):
        h2_norm(control.c2d(control.ss([[-a]], [[1.0]], [[1.0]], [[0.0]]), 0.01))
    with pytest.raises(ModelStructureError, match="matrices A, B and C"):
        h2_norm(np.eye(2), np.ones((2, 1)))


def test_static_gain():
    sys = control.ss([], [], [], [[3.0, 4.0]])
    assert hinf_norm(sys) == pytest.approx(5.0)


def test_sigma_max_matches_freqresp():
    sys = _stable_rss(5, 2, 3, 7)
    w = np.array([0.0, 0.3, 2.0, 11.0])
    resp = _fr(sys, w)
    ref = [np.linalg.norm(resp[:, :, k], 2) for k in range(len(w))]
    np.testing.assert_allclose(sigma_max(sys, w), ref, rtol=1e-10)


def test_sigma_max_stacked_is_one_frequency_at_a_time_to_the_bit():
    """The frequencies go through LAPACK in stacks (more than one stack here); each
    matrix of a stack is solved and decomposed as it would be alone."""
    import scipy.linalg as sla

    rng = np.random.default_rng(11)
    w = np.concatenate([[0.0], np.geomspace(1e-3, 1e3, 600)])
    for n, m, p in ((1, 1, 1), (7, 1, 1), (12, 2, 3), (23, 3, 1)):
        A = rng.normal(size=(n, n)) - 2.0 * np.eye(n)
        B, C, D = rng.normal(size=(n, m)), rng.normal(size=(p, n)), rng.normal(size=(p, m))
        sys = control.ss(A, B, C, D)
        H, Q = sla.hessenberg(A, calc_q=True)
        Bq, Cq = Q.T @ B, C @ Q
        one = [np.linalg.norm(D + Cq @ np.linalg.solve(1j * x * np.eye(n) - H, Bq), 2) for x in w]
        np.testing.assert_array_equal(sigma_max(sys, w), one)


def test_bad_inputs():
    sys = _stable_rss(2, 1, 1, 0)
    with pytest.raises(ParameterError, match="method must be"):
        hinf_norm(sys, method="fast")
    with pytest.raises(ParameterError, match="rtol"):
        hinf_norm(sys, rtol=0.0)
    with pytest.raises(ModelStructureError, match="continuous-time"):
        hinf_norm(control.c2d(sys, 0.01))
    with pytest.raises(ModelStructureError, match="control.StateSpace"):
        hinf_norm(np.eye(2))


def test_badly_scaled_realization_gives_the_same_norm():
    # The closed loop of the force-feedback plant with an LMI H-infinity controller: an
    # interconnection whose states span many decades.  The transfer function, hence the norm,
    # does not depend on the realization; the Hamiltonian test must not lose the
    # imaginary-axis crossings (it used to return a value below the grid's lower bound).
    from backhoe import BDFTLoop, human_variant
    from backhoe.synthesis.forcefb import force_feedback_plant
    from robust.synthesis.nominal import hinfsyn_lmi

    gp = force_feedback_plant(BDFTLoop(human=human_variant("physical")))
    cl = gp.closed_loop(hinfsyn_lmi(gp).K)
    assert np.linalg.norm(cl.A) > 1e7  # badly scaled indeed
    bb = hinf_norm(cl)
    grid = hinf_norm(cl, method="grid")
    assert grid <= bb * (1 + 1e-9)  # grid is a lower bound, bb an upper bound
    assert bb == pytest.approx(grid, rel=1e-6)
    assert bb == pytest.approx(hinf_norm(cl, method="slicot"), rel=1e-5)
    # and in diagonally rescaled coordinates (scales 1e-3 .. 1e3) the same value
    d = 10.0 ** np.random.default_rng(1).uniform(-3.0, 3.0, cl.nstates)
    cl2 = control.ss(cl.A / d[:, None] * d[None, :], cl.B / d[:, None], cl.C * d[None, :], cl.D)
    assert hinf_norm(cl2) == pytest.approx(bb, rel=1e-6)


def test_lyapunov_returns_scipys_bits_and_solves_the_equation():
    # the synthesis' lean Bartels-Stewart: the same LAPACK calls as scipy, so the same bits
    # (a transposed view as A too, as the tuning passes it), and the equation's residual
    # small on its own; anything else is scipy's to check
    rng = np.random.default_rng(11)
    for n in (1, 4, 18, 31):
        A = rng.normal(size=(n, n))
        A -= (np.abs(np.linalg.eigvals(A).real).max() + 0.5) * np.eye(n)
        B, C = rng.normal(size=(n, 2)), rng.normal(size=(3, n))
        for a, q in ((A, -B @ B.T), (A.T, -C.T @ C)):
            X = lyapunov(a, q)
            np.testing.assert_array_equal(X, sla.solve_continuous_lyapunov(a, q))
            res = a @ X + X @ a.T - q
            assert np.abs(res).max() <= 1e-10 * (np.abs(a).max() * np.abs(X).max() + 1.0)
    with pytest.raises(ValueError):
        lyapunov(np.array([[np.nan]]), np.eye(1))


def test_one_schur_form_gives_the_equation_and_the_eigenvalues():
    # the equation with lyapunov's bits, the eigenvalues LAPACK's to rounding
    rng = np.random.default_rng(12)
    for n in (1, 4, 18, 31):
        A = rng.normal(size=(n, n)) * 10.0 ** rng.uniform(-2, 2, size=(n, 1))
        A -= (np.abs(np.linalg.eigvals(A).real).max() + 0.5) * np.eye(n)
        B = rng.normal(size=(n, 2))
        gram = lyapunov_solver(A)
        np.testing.assert_array_equal(gram.solve(-B @ B.T), lyapunov(A, -B @ B.T))
        lam = np.sort_complex(gram.eigenvalues)
        np.testing.assert_allclose(lam, np.sort_complex(np.linalg.eigvals(A)), rtol=1e-9)
    # an unstable A: the eigenvalues say so before anything is solved
    assert lyapunov_solver(np.array([[1.0, 2.0], [0.0, -3.0]])).eigenvalues.real.max() == 1.0
    # anything but a finite float64 square matrix: numpy's and scipy's own errors
    with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
        lyapunov_solver(np.array([[np.nan]]))
    with pytest.raises(np.linalg.LinAlgError):
        lyapunov_solver(np.ones((2, 3)))
    ints = lyapunov_solver(np.array([[-1, 0], [0, -2]]))
    np.testing.assert_allclose(ints.solve(-np.eye(2)), np.diag([0.5, 0.25]))


def _osborne_reference(A, B, C, max_sweeps=50):
    """The state balancing as numpy norms compute it (the compiled sweeps' reference)."""
    n = A.shape[0]
    A, B, C = A.copy(), B.copy(), C.copy()
    for _ in range(max_sweeps):
        changed = False
        for i in range(n):
            c = np.hypot(np.linalg.norm(np.delete(A[:, i], i)), np.linalg.norm(C[:, i]))
            r = np.hypot(np.linalg.norm(np.delete(A[i, :], i)), np.linalg.norm(B[i, :]))
            if c == 0.0 or r == 0.0:
                continue
            e = int(np.round(0.5 * np.log2(r / c)))
            if e == 0:
                continue
            A[:, i] *= 2.0**e
            C[:, i] *= 2.0**e
            A[i, :] /= 2.0**e
            B[i, :] /= 2.0**e
            changed = True
        if not changed:
            break
    return A, B, C


@pytest.mark.parametrize("seed", range(6))
def test_state_balancing_matches_the_numpy_sweeps_exactly(seed):
    from robust.analysis.norms import _balance_states

    rng = np.random.default_rng(seed)
    n, m, p = int(rng.integers(1, 25)), int(rng.integers(1, 4)), int(rng.integers(1, 4))
    # states scaled over twelve decades, some entries zero (a state without a path is kept)
    s = 10.0 ** rng.uniform(-6.0, 6.0, n)
    A = rng.standard_normal((n, n)) * (rng.random((n, n)) < 0.6)
    A = A * s[:, None] / s[None, :]
    B = rng.standard_normal((n, m)) * s[:, None]
    C = rng.standard_normal((p, n)) / s[None, :]
    if n > 2:
        B[0], C[:, 1] = 0.0, 0.0
    got = _balance_states(A, B, C)
    ref = _osborne_reference(A, B, C)
    for g, r in zip(got, ref):
        np.testing.assert_array_equal(g, r)
    # a similarity by powers of 2: the same transfer function (no rounding at all)
    d = np.diag(got[0]) - np.diag(A)
    assert not d.any()
    assert np.linalg.norm(got[0]) < np.linalg.norm(A)
