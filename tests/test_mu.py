"""Structured singular value bounds (uncertainty.mussv) against closed forms and SLICOT's AB13MD."""

import numpy as np
import pytest
import slycot

from robust.errors import ParameterError
from uncertainty import mussv


def _random(rng, n):
    return rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n))


def _check_delta(M, b):
    # the perturbation behind the lower bound: in the structure, size 1 / lower, singular
    n = M.shape[0]
    assert abs(np.linalg.det(np.eye(n) - M @ b.delta)) < 1e-9 * max(1.0, np.linalg.norm(M) ** n)
    assert np.linalg.norm(b.delta, 2) * b.lower == pytest.approx(1.0, rel=1e-9)
    k = 0
    for s, kind in b.blocks:
        blk = b.delta[k : k + s, k : k + s]
        off = b.delta[k : k + s].copy()
        off[:, k : k + s] = 0
        assert np.all(off == 0)
        if kind == "real":  # a repeated real scalar
            np.testing.assert_allclose(blk, blk[0, 0].real * np.eye(s), atol=1e-12)
        k += s


def test_closed_forms():
    # one full complex block: mu = sigma_max
    M = np.array([[1.0, 2.0], [0.0, 1.0]])
    b = mussv(M, [(2, "complex")])
    assert b.lower == pytest.approx(1 + np.sqrt(2), rel=1e-6)
    assert b.upper == pytest.approx(1 + np.sqrt(2), rel=1e-4) and b.upper >= b.lower
    _check_delta(M, b)
    # a repeated real scalar delta I_2 on [[0, 4], [1, 0]]: det(I - delta M) = 1 - 4 delta^2,
    # so mu = 2; with the sign of one entry flipped no real delta is singular: mu = 0
    M = np.array([[0.0, 4.0], [1.0, 0.0]])
    b = mussv(M, [(2, "real")])
    assert b.lower == pytest.approx(2.0, rel=1e-9) and 2.0 <= b.upper <= 2.0 * 1.0001
    _check_delta(M, b)
    b = mussv(np.array([[0.0, 4.0], [-1.0, 0.0]]), [(2, "real")])
    assert b.lower == 0.0 and b.upper < 1e-6
    # a real scalar on a complex number: no real delta makes 1 - (1 + j) delta vanish
    b = mussv(np.array([[1.0 + 1.0j]]), [(1, "real")])
    assert b.lower == 0.0 and b.upper < 1e-6


def test_against_ab13md_on_seeded_matrices():
    rng = np.random.default_rng(7)
    structures = [
        [(1, "complex"), (1, "complex"), (1, "complex")],
        [(2, "complex"), (1, "complex"), (1, "complex")],
        [(1, "real"), (1, "real"), (2, "complex")],
        [(1, "real"), (1, "complex"), (1, "real")],
    ]
    for blocks in structures:
        n = sum(s for s, _ in blocks)
        for _ in range(2):
            M = _random(rng, n)
            b = mussv(M, blocks)
            ref = slycot.ab13md(
                M,
                np.array([s for s, _ in blocks]),
                np.array([1 if k == "real" else 2 for _, k in blocks]),
            )[0]
            # the upper bound is the same D-G bound: never above AB13MD's by 0.1 %
            assert b.upper <= ref * 1.001
            # and certified by its own scalings: M^H D M + j (G M - M^H G) - upper^2 D <= 0
            MH = M.conj().T
            X = MH @ b.D @ M + 1j * (b.G @ M - MH @ b.G) - b.upper**2 * b.D
            assert np.linalg.eigvalsh(0.5 * (X + X.conj().T)).max() <= 1e-9 * np.abs(X).max()
            assert np.linalg.eigvalsh(b.D).min() > 0
            assert 0 < b.lower <= b.upper
            _check_delta(M, b)
            if all(k == "complex" for _, k in blocks):
                assert b.lower >= 0.95 * b.upper  # measured: within 1e-5
            else:
                # mixed: the phase search (measured 0.85-0.99 of the upper bound here;
                # sign patterns alone gave 0.05-0.9)
                assert b.lower >= 0.75 * b.upper


def test_bad_input():
    with pytest.raises(ParameterError, match="square"):
        mussv(np.ones((2, 3)), [(2, "complex")])
    with pytest.raises(ParameterError, match="finite"):
        mussv(np.array([[np.nan]]), [(1, "complex")])
    with pytest.raises(ParameterError, match="add up"):
        mussv(np.eye(3), [(2, "complex")])
    with pytest.raises(ParameterError, match=r"blocks\[1\]"):
        mussv(np.eye(3), [(2, "complex"), (1, "imaginary")])
    with pytest.raises(ParameterError, match="restarts"):
        mussv(np.eye(1), [(1, "complex")], restarts=0)
