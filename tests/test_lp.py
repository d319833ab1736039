"""robust.synthesis.lp.solve_lp: linprog's answers to the bit, without its per-call set-up."""

import numpy as np
import pytest
import scipy.optimize as so

from robust.synthesis import lp as lpmod
from robust.synthesis.lp import CHECK_TOL, solve_lp


def _random_lp(rng):
    m, n = int(rng.integers(1, 40)), int(rng.integers(1, 30))
    A = rng.standard_normal((m, n)) * (rng.random((m, n)) < rng.random())
    b = rng.standard_normal(m) * rng.choice([0.1, 1.0, 10.0])
    c = rng.standard_normal(n)
    kind = int(rng.integers(4))
    if kind == 0:
        bounds = [(None, None)] * n
    elif kind == 1:
        bounds = [(0.0, None)] * n
    elif kind == 2:
        bounds = [(-r, r) for r in rng.random(n) * 3]
    else:
        bounds = [(lo, lo + rng.random() * 2) for lo in rng.standard_normal(n)]
    return c, A, b, bounds


def _slp_like(rng, n=20, m=40):
    """A program shaped as slp_minimise's: steps D, distances a, level u."""
    G = rng.standard_normal((m, n))
    v = rng.standard_normal(m) * 0.1
    unit = rng.random(n) + 0.5
    ref = rng.standard_normal(n) * 0.01
    g = rng.standard_normal(n) * 1e-3
    c = np.concatenate([g, np.full(n, 1e-3 / n), [1.0]])
    A = np.vstack(
        [
            np.hstack([G, np.zeros((m, n)), -np.ones((m, 1))]),
            np.hstack([np.diag(1 / unit), -np.eye(n), np.zeros((n, 1))]),
            np.hstack([-np.diag(1 / unit), -np.eye(n), np.zeros((n, 1))]),
        ]
    )
    b = np.concatenate([-v, ref / unit, -ref / unit])
    bounds = [(-0.1 * u, 0.1 * u) for u in unit] + [(0.0, None)] * n + [(-0.05, None)]
    return c, A, b, bounds


def _same(r, s):
    assert s.status == int(r.status)
    if r.x is None:
        assert s.x is None
        return
    assert np.array_equal(s.x, r.x)
    assert s.fun == r.fun


def test_random_programs_match_linprog_bit_for_bit():
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(600):
        c, A, b, bounds = _random_lp(rng)
        r = so.linprog(c, A_ub=A, b_ub=b, bounds=bounds, method="highs")
        _same(r, solve_lp(c, A, b, bounds))
        seen.add(int(r.status))
    # optimal, infeasible and unbounded programs were all compared
    assert {0, 2, 3} <= seen


def test_tuning_shaped_programs_match_linprog_bit_for_bit():
    rng = np.random.default_rng(3)
    optimal = 0
    for _ in range(60):
        c, A, b, bounds = _slp_like(rng)
        r = so.linprog(c, A_ub=A, b_ub=b, bounds=bounds, method="highs")
        s = solve_lp(c, A, b, bounds)
        _same(r, s)
        if s.status == 0:
            optimal += 1
            # the answer is feasible within linprog's tolerance of its check
            assert np.all(A @ s.x <= b + CHECK_TOL)
    assert optimal >= 50


def test_without_scipys_module_linprog_itself_answers(monkeypatch):
    rng = np.random.default_rng(5)
    problems = [_slp_like(rng) for _ in range(5)] + [_random_lp(rng) for _ in range(20)]
    direct = [solve_lp(*p) for p in problems]
    monkeypatch.setattr(lpmod, "_highs", None)
    for p, d in zip(problems, direct):
        s = solve_lp(*p)
        assert s.status == d.status
        if d.x is not None:
            assert np.array_equal(s.x, d.x) and s.fun == d.fun


def test_known_optimum():
    # min -x - y, x + 2y <= 4, 3x + y <= 6, x, y >= 0: optimum at (1.6, 1.2)
    s = solve_lp([-1.0, -1.0], [[1.0, 2.0], [3.0, 1.0]], [4.0, 6.0], [(0, None), (0, None)])
    assert s.status == 0
    assert s.x == pytest.approx([1.6, 1.2], abs=1e-9)
    assert s.fun == pytest.approx(-2.8, abs=1e-9)


def test_infeasible_and_unbounded_codes():
    # x <= -1 with x >= 0: infeasible
    s = solve_lp([1.0], [[1.0]], [-1.0], [(0.0, None)])
    assert s.status == 2 and s.x is None
    # min -x, x free, -x <= 0 (x >= 0): unbounded
    s = solve_lp([-1.0], [[-1.0]], [0.0], [(None, None)])
    assert s.status == 3 and s.x is None


@pytest.mark.parametrize(
    "args, match",
    [
        (([1.0, 2.0], [[1.0]], [1.0], [(0, 1)] * 2), "A_ub must have shape"),
        (([[1.0]], [[1.0]], [1.0], [(0, 1)]), "c must be a non-empty vector"),
        (([], np.zeros((1, 0)), [1.0], []), "c must be a non-empty vector"),
        (([1.0], [[1.0]], [np.inf], [(0, 1)]), "b_ub must be finite"),
        (([1.0], [[1.0]], [1.0], (0, 1)), "bounds must be a sequence of 1"),
        (([1.0], [[1.0]], [1.0], [(0, 1, 2)]), "bounds must be a sequence of 1"),
        (([1.0], [[1.0]], [1.0], [("a", 1)]), "bounds must be numbers or None"),
        (([np.nan], [[1.0]], [1.0], [(0, 1)]), "c must be finite"),
        (([1.0], [[np.inf]], [1.0], [(0, 1)]), "A_ub must be finite"),
        (([1.0], [[1.0]], [np.nan], [(0, 1)]), "b_ub must be finite"),
        (([1.0], [[1.0]], [1.0], [(0, 1), (0, 1)]), "bounds must give 1"),
        (([1.0], [[1.0]], [1.0], [(np.nan, 1)]), "bounds must not hold NaN"),
    ],
)
def test_bad_arguments_are_named(args, match):
    with pytest.raises(ValueError, match=match):
        solve_lp(*args)
