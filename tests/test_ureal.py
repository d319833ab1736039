"""Named uncertain reals: arithmetic, evaluation from one definition, enclosures, matrices."""

import numpy as np
import pytest

from robust.analysis.intervals import Gradient
from robust.errors import ParameterError
from uncertainty import UExpr, evaluate_matrix, umatrix, ureal


def _exprs():
    k = ureal("k", 10.0, 8.0, 12.0, unit="N/m", source="test")
    m = ureal("m", 2.0, 1.5, 2.5, distribution="loguniform", unit="kg")
    c = ureal("c", 0.3, -0.5, 0.5)
    e = (2 * k + 3) / (m - 1) ** 2 - k / m + np.float64(0.5) * c**3 - (-c) ** -2 + 1 / m
    return k, m, c, e


def _formula(k, m, c):
    return (2 * k + 3) / (m - 1) ** 2 - k / m + 0.5 * c**3 - (-c) ** -2 + 1 / m


def test_arithmetic_nominal_at_and_batched():
    k, m, c, e = _exprs()
    assert isinstance(e, UExpr) and list(e.parameters) == ["k", "m", "c"]
    assert e.parameters["k"].units == "N/m" and e.parameters["m"].distribution == "loguniform"
    assert e.nominal() == pytest.approx(_formula(10.0, 2.0, 0.3), rel=1e-14)
    assert e.at({"k": 11.0, "c": -0.2}) == pytest.approx(_formula(11.0, 2.0, -0.2), rel=1e-14)
    rng = np.random.default_rng(3)
    K, M, C = rng.uniform(8, 12, 500), rng.uniform(1.5, 2.5, 500), rng.uniform(0.1, 0.5, 500)
    np.testing.assert_allclose(e.evaluate({"k": K, "m": M, "c": C}), _formula(K, M, C), rtol=1e-13)
    # numpy scalars on either side, unary minus, zeroth power
    assert (np.float64(3.0) - k).nominal() == -7.0 and (k * np.int64(2)).nominal() == 20.0
    assert (-k + +k).nominal() == 0.0 and (k**0).nominal() == 1.0
    assert "k" in repr(e)


def test_interval_encloses_every_member_and_is_exact_for_monotone_terms():
    k, m, c, e = _exprs()
    box = {"c": (0.2, 0.4)}  # c away from 0 (the expression divides by c^2)
    lo, hi = e.interval(box)
    rng = np.random.default_rng(5)
    K, M, C = rng.uniform(8, 12, 4000), rng.uniform(1.5, 2.5, 4000), rng.uniform(0.2, 0.4, 4000)
    v = _formula(K, M, C)
    assert lo <= v.min() and v.max() <= hi
    # a sum of single-use parameters is enclosed exactly: k - 2 m ranges over [3, 9]
    lo, hi = (k - 2 * m).interval()
    assert lo == pytest.approx(3.0, abs=1e-12) and hi == pytest.approx(9.0, abs=1e-12)
    # an even power of an interval containing 0 starts at 0 (up to the outward rounding),
    # where c * c would give [-0.25, 0.25]
    lo, hi = (c**2).interval()
    assert -1e-12 <= lo <= 0.0 and hi == pytest.approx(0.25)
    assert (c * c).interval()[0] == pytest.approx(-0.25)
    with pytest.raises(ParameterError, match="contains 0"):
        (1 / c).interval()


def test_mean_value_form_through_the_same_definition():
    # on Gradient numbers (what the margin certifier uses): an enclosure of the value over
    # k in [9.9, 10.1] and of its derivative in k, exactly 2 / (m - 1)^2 - 1 / m = 1.5 here
    k, m, c, e = _exprs()
    g = e.evaluate({"k": Gradient.variable(9.9, 10.1, 0, 1), "m": 2.0, "c": 0.3})
    assert float(g.val.lo) <= e.at({"k": 9.9}) <= e.at({"k": 10.1}) <= float(g.val.hi)
    assert float(g.der.lo[0]) <= 1.5 <= float(g.der.hi[0])
    assert float(g.der.hi[0]) - float(g.der.lo[0]) < 1e-9


def test_matrices():
    k, m, c, _ = _exprs()
    A = umatrix([[0, 1], [-k / m, -c / m]])
    assert A.shape == (2, 2) and A.dtype == object
    np.testing.assert_allclose(
        evaluate_matrix(A, {"k": 10.0, "m": 2.0, "c": 0.3}), [[0, 1], [-5.0, -0.15]]
    )
    batch = evaluate_matrix(A, {"k": [8.0, 12.0], "m": [2.0, 2.0], "c": [0.3, 0.3]})
    assert batch.shape == (2, 2, 2) and batch[1, 1, 0] == -6.0


def test_bad_input():
    k = ureal("k", 10.0, 8.0, 12.0)
    with pytest.raises(ParameterError, match="nominal"):
        ureal("k", 20.0, 8.0, 12.0)
    with pytest.raises(ParameterError, match="named 'k'"):
        k + ureal("k", 9.0, 8.0, 12.0)
    with pytest.raises(ParameterError, match="integer"):
        k**0.5
    with pytest.raises(ParameterError, match="operand"):
        k + "1"
    with pytest.raises(ParameterError, match="finite"):
        k * float("nan")
    with pytest.raises(ParameterError, match="missing"):
        (k * ureal("m", 1.0, 0.5, 2.0)).evaluate({"k": 1.0})
    with pytest.raises(ParameterError, match="not parameters"):
        k.at({"z": 1.0})
    with pytest.raises(ParameterError, match="truth value"):
        bool(k)
    with pytest.raises(ParameterError, match="2-D"):
        umatrix([k, 1.0])
