"""Levenberg-Marquardt least squares: minima, stopping tests, determinism, bad input."""

import numpy as np
import pytest
import scipy.optimize as sopt

from robust.errors import ParameterError
from robust.sysid.levenberg import levenberg_marquardt


def _damped_cosine(seed=0, n=150, noise=0.05):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 10.0, n)
    y = 3.0 * np.exp(-0.4 * t) * np.cos(1.3 * t + 0.2) + noise * rng.standard_normal(n)

    def fun(p):
        return p[0] * np.exp(-p[1] * t) * np.cos(p[2] * t + p[3]) - y

    def jac(p):
        e, c, s = np.exp(-p[1] * t), np.cos(p[2] * t + p[3]), np.sin(p[2] * t + p[3])
        return np.stack([e * c, -t * p[0] * e * c, -t * p[0] * e * s, -p[0] * e * s], axis=1)

    return fun, jac


def test_it_reaches_the_minimum_that_scipy_finds():
    fun, jac = _damped_cosine()
    x0 = np.array([1.0, 0.1, 1.2, 0.0])
    got = levenberg_marquardt(fun, jac, x0)
    ref = sopt.least_squares(fun, x0, jac=jac, method="trf", x_scale="jac", xtol=1e-12)
    assert got.converged and got.status in (1, 2, 3)
    np.testing.assert_allclose(got.x, ref.x, rtol=1e-6)
    assert got.cost == pytest.approx(ref.cost, rel=1e-10)
    # the returned residual and Jacobian are those at the returned point
    np.testing.assert_array_equal(got.fun, fun(got.x))
    np.testing.assert_array_equal(got.jac, jac(got.x))
    # at a minimum the gradient J'f vanishes (relative to the scales of J and f)
    g = got.jac.T @ got.fun
    assert np.max(np.abs(g) / (np.linalg.norm(got.jac, axis=0) * np.linalg.norm(got.fun))) < 1e-5


def test_rosenbrock_from_the_classical_start():
    def fun(p):
        return np.array([10.0 * (p[1] - p[0] ** 2), 1.0 - p[0]])

    def jac(p):
        return np.array([[-20.0 * p[0], 10.0], [-1.0, 0.0]])

    got = levenberg_marquardt(fun, jac, [-1.2, 1.0])
    assert got.converged
    np.testing.assert_allclose(got.x, [1.0, 1.0], atol=1e-8)
    assert got.cost < 1e-20


def test_an_exact_fit_stops_on_a_zero_residual_or_a_vanishing_step():
    A = np.array([[1.0, 2.0], [3.0, -1.0], [0.5, 0.5]])
    b = A @ np.array([0.7, -0.2])
    got = levenberg_marquardt(lambda p: A @ p - b, lambda p: A, [5.0, 5.0])
    assert got.converged
    np.testing.assert_allclose(got.x, [0.7, -0.2], rtol=1e-10)
    assert got.cost < 1e-25


def test_the_same_answer_whatever_was_allocated_before():
    # the answer depends on the data alone (scipy's MINPACK did not, on the calibration
    # fits: module notes)
    fun, jac = _damped_cosine(seed=3, noise=0.3)
    rng = np.random.default_rng(0)
    keep, answers = [], set()
    for _ in range(20):
        keep.append(np.empty(int(rng.integers(1, 500))))
        r = levenberg_marquardt(fun, jac, [1.0, 0.05, 1.0, 0.5])
        answers.add(r.x.tobytes() + r.fun.tobytes())
    assert len(answers) == 1


def test_the_budget_and_the_evaluation_counts():
    fun, jac = _damped_cosine()
    calls = {"f": 0, "j": 0}

    def f(p):
        calls["f"] += 1
        return fun(p)

    def j(p):
        calls["j"] += 1
        return jac(p)

    short = levenberg_marquardt(f, j, [1.0, 0.1, 1.2, 0.0], max_nfev=3)
    assert short.status == 0 and not short.converged
    assert short.nfev == 3 == calls["f"] and short.njev == calls["j"]
    assert "budget" in short.message
    # the last accepted point, with its own residual
    np.testing.assert_array_equal(short.fun, fun(short.x))


def test_a_trial_point_with_a_non_finite_residual_is_a_failed_step():
    # log(p) is undefined for p <= 0: the full Gauss-Newton step from 0.1 lands below 0
    y = np.array([np.log(2.0), np.log(2.0)])

    def fun(p):
        with np.errstate(invalid="ignore"):
            return np.log(np.array([p[0], p[0]])) - y

    def jac(p):
        return np.array([[1.0 / p[0]], [1.0 / p[0]]])

    got = levenberg_marquardt(fun, jac, [0.05])
    assert got.converged
    assert got.x[0] == pytest.approx(2.0, rel=1e-8)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(x0=[np.nan, 1.0]), "x0"),
        (dict(x0=[]), "x0"),
        (dict(x0=[1.0, 1.0], ftol=0.0), "ftol"),
        (dict(x0=[1.0, 1.0], gtol=1.5), "gtol"),
        (dict(x0=[1.0, 1.0], max_nfev=0), "max_nfev"),
    ],
)
def test_bad_arguments_are_named(kwargs, match):
    fun, jac = (lambda p: np.array([p[0], p[1], 1.0])), (lambda p: np.eye(3)[:, :2])
    with pytest.raises(ParameterError, match=match):
        levenberg_marquardt(fun, jac, **kwargs)


def test_bad_evaluations_are_named():
    with pytest.raises(ParameterError, match="at least 2 residuals"):
        levenberg_marquardt(lambda p: np.array([p[0]]), lambda p: np.ones((1, 2)), [1.0, 2.0])
    with pytest.raises(ParameterError, match=r"jac\(x0\) must have shape \(3, 2\)"):
        levenberg_marquardt(lambda p: np.ones(3), lambda p: np.ones((2, 3)), [1.0, 2.0])
    with pytest.raises(ParameterError, match="not finite"):
        levenberg_marquardt(lambda p: np.array([np.inf, 1.0]), lambda p: np.eye(2), [1.0, 2.0])
