"""Sampling: reproducibility by seed, methods, bounds and recorded provenance."""

import numpy as np
import pytest

from backhoe.families.family_ranges import default_family
from robust.errors import ParameterError
from uncertainty.sampling import METHODS, sample

PARAMS = default_family("physical").parameters


@pytest.mark.parametrize("method", METHODS)
def test_same_seed_same_samples_and_seed_recorded(method):
    a = sample(PARAMS, 500, method=method, seed=11)
    b = sample(PARAMS, 500, method=method, seed=11)
    np.testing.assert_array_equal(a.values, b.values)
    assert a.seed == 11 and a.method == method and a.requested == 500
    assert a.names == tuple(p.name for p in PARAMS)


@pytest.mark.parametrize("method", ["mc", "lhs"])
def test_different_seed_different_samples(method):
    a = sample(PARAMS, 200, method=method, seed=1)
    b = sample(PARAMS, 200, method=method, seed=2)
    assert not np.array_equal(a.values, b.values)


def test_none_seed_is_replaced_by_recorded_entropy():
    a = sample(PARAMS, 50, method="mc", seed=None)
    b = sample(PARAMS, 50, method="mc", seed=a.seed)
    np.testing.assert_array_equal(a.values, b.values)


@pytest.mark.parametrize("method", METHODS)
def test_samples_lie_within_bounds(method):
    s = sample(PARAMS, 2000, method=method, seed=3)
    lo = np.array([p.low for p in PARAMS])
    hi = np.array([p.high for p in PARAMS])
    assert np.all(s.values >= lo) and np.all(s.values <= hi)
    assert not s.values.flags.writeable


def test_latin_hypercube_has_one_sample_per_stratum():
    s = sample(PARAMS, 100, method="lhs", seed=5)
    for j, p in enumerate(PARAMS):
        if p.distribution == "uniform":
            u = (s.values[:, j] - p.low) / (p.high - p.low)
        else:
            u = np.log(s.values[:, j] / p.low) / np.log(p.high / p.low)
        np.testing.assert_array_equal(np.sort(np.floor(u * 100).astype(int)), np.arange(100))


def test_vertices_and_grid():
    d = len(PARAMS)
    v = sample(PARAMS, 10**6, method="vertices", seed=0)
    assert len(v) == 2**d
    lo = np.array([p.low for p in PARAMS])
    hi = np.array([p.high for p in PARAMS])
    assert np.all((np.isclose(v.values, lo)) | (np.isclose(v.values, hi)))
    sub = sample(PARAMS, 10, method="vertices", seed=0)
    assert len(sub) == 10 and len(np.unique(sub.values, axis=0)) == 10
    g = sample(PARAMS[:2], 25, method="grid", seed=0)
    assert len(g) == 25 and len(np.unique(g.values[:, 0])) == 5


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(n=0), "n must be a positive integer"),
        (dict(method="sobol"), "method must be one of"),
        (dict(seed=-1), "seed must be a non-negative integer"),
    ],
    ids=["zero-n", "bad-method", "negative-seed"],
)
def test_bad_requests_raise(kw, match):
    args = dict(n=10, method="mc", seed=0)
    args.update(kw)
    with pytest.raises(ParameterError, match=match):
        sample(PARAMS, args.pop("n"), **args)


def test_sample_takes_a_uss_a_family_or_any_iterable_of_parameters():
    from backhoe import default_family
    from uncertainty import ureal, uss

    k = ureal("k", 1.0, 0.5, 2.0)
    m = ureal("m", 1.0, 0.8, 1.5)
    G = uss([[-k / m]], [[1.0]], [[1.0]], [[0.0]])
    ref = sample(list(G.parameters.values()), 7, seed=3)
    for source in (G, G.parameters.values(), iter(G.parameters.values()), G.parameters):
        got = sample(source, 7, seed=3)
        assert got.names == ("k", "m") and np.array_equal(got.values, ref.values)
    fam = default_family()
    assert sample(fam, 4, seed=1).names == tuple(p.name for p in fam.parameters)
