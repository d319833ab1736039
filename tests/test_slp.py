"""Sequential linear programming (:func:`robust.synthesis.tuning.slp_minimise`) on minimax
problems with known solutions.
"""

import numpy as np
import pytest

from robust.synthesis.tuning import slp_minimise


def _cb2(x):
    """Charalambous & Conn's CB2 (SIAM J. Numer. Anal. 15, 1978): max of three functions."""
    x1, x2 = x
    f = np.array([x1**2 + x2**4, (2 - x1) ** 2 + (2 - x2) ** 2, 2 * np.exp(x2 - x1)])
    G = np.array(
        [
            [2 * x1, 4 * x2**3],
            [-2 * (2 - x1), -2 * (2 - x2)],
            [-2 * np.exp(x2 - x1), 2 * np.exp(x2 - x1)],
        ]
    )
    return f, G, 0.0, np.zeros(2)


def test_cb2_minimax_value_and_point():
    # the published optimum: F* = 1.9522245 at (1.139037, 0.899559)
    res = slp_minimise(_cb2, np.array([2.0, 2.0]), np.ones(2), target=-10.0, prox=0.0, trust=0.5)
    assert res.merit == pytest.approx(1.9522245, abs=1e-6)
    np.testing.assert_allclose(res.x, [1.139037, 0.899559], atol=1e-4)
    # two functions active at the solution (f1 = f2), the third below
    f = _cb2(res.x)[0]
    assert abs(f[0] - f[1]) < 1e-6 and f[2] < f[0] - 0.05


def test_target_stops_at_the_level_and_the_distance_term_keeps_the_start():
    # with the target above the optimum, the point moves only as far as reaching it needs
    # (the steps approach the level from above, linearly: 5e-9 above it after 60)
    x0 = np.array([2.0, 2.0])
    res = slp_minimise(_cb2, x0, np.ones(2), target=2.5, prox=1e-3, trust=0.5)
    assert 2.5 - 1e-6 <= res.worst <= 2.5 + 1e-6
    far = slp_minimise(_cb2, x0, np.ones(2), target=-10.0, prox=0.0, trust=0.5)
    assert np.abs(res.x - x0).sum() < np.abs(far.x - x0).sum()


def test_penalty_enters_the_merit():
    # a linear penalty pulling x1 up moves the minimax point along the active pair
    def with_penalty(x):
        f, G, _, _ = _cb2(x)
        return f, G, 0.5 * (3 - x[0]), np.array([-0.5, 0.0])

    res = slp_minimise(with_penalty, np.array([2.0, 2.0]), np.ones(2), target=-10.0, prox=0.0)
    plain = slp_minimise(_cb2, np.array([2.0, 2.0]), np.ones(2), target=-10.0, prox=0.0)
    assert res.x[0] > plain.x[0] + 0.01
    f, _, p, _ = with_penalty(res.x)
    assert res.merit == pytest.approx(f.max() + p, rel=1e-12)


def test_same_data_same_bits():
    a = slp_minimise(_cb2, np.array([0.3, -1.0]), np.ones(2), target=-10.0, prox=1e-3)
    b = slp_minimise(_cb2, np.array([0.3, -1.0]), np.ones(2), target=-10.0, prox=1e-3)
    assert a.x.tobytes() == b.x.tobytes() and a.iterations == b.iterations
