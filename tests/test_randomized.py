"""The probabilistic coverage certificate: its arithmetic against closed forms and the binomial."""

import math

import numpy as np
import pytest
from scipy import stats

from robust.errors import ParameterError
from uncertainty.randomized import CoverageBound, failure_bound, samples_needed


@pytest.mark.parametrize("n", [1, 10, 200, 2000, 100_000])
@pytest.mark.parametrize("conf", [0.9, 0.99, 0.999, 1 - 1e-6])
def test_no_failures_closed_form(n, conf):
    # k = 0: (1 - eps)^N = beta, so eps = 1 - beta^(1/N)
    eps = failure_bound(n, 0, conf)
    assert eps == pytest.approx(1 - (1 - conf) ** (1 / n), rel=1e-12)
    assert (1 - eps) ** n == pytest.approx(1 - conf, rel=1e-9)


@pytest.mark.parametrize(("n", "k"), [(20, 1), (200, 3), (2000, 17), (2000, 1000), (50, 49)])
@pytest.mark.parametrize("conf", [0.95, 0.999])
def test_binomial_tail_equals_beta_at_the_bound(n, k, conf):
    # the defining property: P(Binomial(N, eps) <= k) = beta, computed by a different route
    eps = failure_bound(n, k, conf)
    assert stats.binom.cdf(k, n, eps) == pytest.approx(1 - conf, rel=1e-7)

    # and the tail sum written out term by term
    def log_term(i):
        log_comb = math.lgamma(n + 1) - math.lgamma(i + 1) - math.lgamma(n - i + 1)
        return log_comb + i * math.log(eps) + (n - i) * math.log1p(-eps)

    tail = math.fsum(math.exp(log_term(i)) for i in range(k + 1))
    assert tail == pytest.approx(1 - conf, rel=1e-7)
    # more failures never give a smaller bound; more samples with the same count do
    assert failure_bound(n, k - 1, conf) < eps
    assert failure_bound(2 * n, k, conf) < eps


def test_all_failed_and_observed_rate():
    assert failure_bound(10, 10) == 1.0
    # the bound lies above the observed failure rate
    for n, k in [(100, 5), (2000, 40), (2000, 0)]:
        assert failure_bound(n, k) > k / n


def test_sample_complexity():
    # ln(1/beta) / ln(1/(1 - eps)): 1375 samples for eps = 1 %, beta = 1e-6 (Tempo et al.)
    assert samples_needed(0.01, 1 - 1e-6) == 1375
    assert samples_needed(0.05, 0.95) == 59
    for eps, conf in [(0.01, 0.999), (0.001, 0.99), (0.2, 0.5)]:
        n = samples_needed(eps, conf)
        assert failure_bound(n, 0, conf) <= eps < failure_bound(n - 1, 0, conf)


def test_coverage_bound_object():
    c = CoverageBound(2000, 17, 0.999, seed=4)
    j = c.to_json()
    assert j["fraction"] == pytest.approx(1 - 17 / 2000)
    assert j["epsilon"] == pytest.approx(failure_bound(2000, 17, 0.999))
    assert j["lower"] == pytest.approx(1 - j["epsilon"])
    assert j["samples"] == 2000 and j["failures"] == 17 and j["seed"] == 4
    assert "17 failures in 2000" in c.describe()


def test_simulated_coverage_of_the_bound():
    # with a known failure probability the bound holds in about `confidence` of trials
    rng = np.random.default_rng(11)
    p, n, conf = 0.03, 300, 0.9
    k = rng.binomial(n, p, size=4000)
    held = np.mean([failure_bound(n, int(x), conf) >= p for x in k])
    assert 0.88 <= held <= 0.96


@pytest.mark.parametrize(
    ("args", "text"),
    [
        ((0, 0), "samples"),
        ((10, 11), "failures must be at most samples"),
        ((10, -1), "failures"),
        ((10, 1, 1.0), "confidence"),
        ((10, 1, float("nan")), "confidence"),
    ],
)
def test_bad_input(args, text):
    with pytest.raises(ParameterError, match=text):
        failure_bound(*args)


def test_bad_input_other():
    with pytest.raises(ParameterError, match="epsilon"):
        samples_needed(0.0)
    with pytest.raises(ParameterError, match="independent draws"):
        CoverageBound(100, 0, method="lhs")


def test_hoeffding_and_consistency():
    from uncertainty.randomized import coverage_consistent, hoeffding_halfwidth

    # sqrt(ln(2 / beta) / (2 N)): beta = 1e-3, N = 2000 -> 0.0436
    assert hoeffding_halfwidth(2000, 0.999) == pytest.approx(math.sqrt(math.log(2000) / 4000))
    # the bound holds empirically for a fair coin
    rng = np.random.default_rng(3)
    frac = rng.binomial(400, 0.5, size=20000) / 400
    assert np.mean(np.abs(frac - 0.5) > hoeffding_halfwidth(400, 0.99)) < 0.01
    # the design's Clopper-Pearson lower bound against the limit's fraction as it is: 620 of
    # 2000 covered has the lower bound 0.277 at confidence 0.999 (scipy's beta quantile)
    lower = 1 - stats.beta.ppf(0.999, 1381, 620)
    assert 0.27 < lower < 0.29
    assert coverage_consistent(0.31, 2000, lower + 1e-3)
    assert not coverage_consistent(0.31, 2000, lower - 1e-3)
    assert not coverage_consistent(0.60, 2000, 0.30)
    # few members: 6 of 6 covered proves only 0.316 (1 - 0.001^(1/6))
    assert coverage_consistent(1.0, 6, 0.32) and not coverage_consistent(1.0, 6, 0.31)
