"""Frequency responses through one Hessenberg form (robust.analysis.resolvent): against LAPACK's
solve per frequency, against SLICOT's evaluation, a frequency on an eigenvalue, bad input."""

import hashlib

import control as ct
import mpmath as mp
import numpy as np
import pytest
from numba_builds import outputs_here_and_generic, register

from backhoe import default_family
from robust.analysis.loops import frequency_response, resolvent_times
from robust.analysis.resolvent import resolvent_solve, siso_responses


def _lapack(A, b, c, Bb, Cb, w):
    """The three products from numpy's LU solve of every ``j w I - A``."""
    n = A.shape[0]
    M = 1j * w[:, None, None] * np.eye(n) - A
    Rb = np.linalg.solve(M, np.broadcast_to(b[:, None], (w.size, n, 1)))[:, :, 0]
    RBb = np.linalg.solve(M, np.broadcast_to(Bb, (w.size, n, Bb.shape[1])))
    return Rb @ c, np.einsum("i,fij->fj", c, RBb), Rb @ Cb.T


def _system(rng, n, m=3, p=4):
    A = rng.normal(size=(n, n)) - 2.0 * np.eye(n)
    return (
        A,
        rng.normal(size=n),
        rng.normal(size=n),
        rng.normal(size=(n, m)),
        rng.normal(size=(p, n)),
    )


@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 12, 19, 26])
def test_against_lapack_solves(n):
    rng = np.random.default_rng(100 + n)
    A, b, c, Bb, Cb = _system(rng, n)
    w = np.concatenate([[0.0], np.geomspace(1e-3, 1e3, 40), [-2.5]])
    got = siso_responses(A, b, c, Bb, Cb, w)
    want = _lapack(A, b, c, Bb, Cb, w)
    for g, r in zip(got, want, strict=True):
        assert g.shape == r.shape
        np.testing.assert_allclose(g, r, rtol=0, atol=1e-12 * np.abs(r).max())
        # and entrywise where the entry is not tiny
        big = np.abs(r) > 1e-6 * np.abs(r).max()
        np.testing.assert_allclose(g[big], r[big], rtol=1e-10)


def test_against_slicot_through_python_control():
    """A lightly damped chain (modes over two decades), as the synthesis loops are."""
    modes = [(0.5, 0.02), (6.0, 0.05), (40.0, 0.1)]
    blocks = [
        np.array([[0.0, 1.0], [-((2 * np.pi * f) ** 2), -2 * z * 2 * np.pi * f]]) for f, z in modes
    ]
    n = 2 * len(modes)
    A = np.zeros((n, n))
    for k, a in enumerate(blocks):
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = a
        if k:
            A[2 * k + 1, 2 * k - 2] = 3.0  # the previous mode drives this one
    rng = np.random.default_rng(7)
    b, c = rng.normal(size=n), rng.normal(size=n)
    Bb, Cb = rng.normal(size=(n, 2)), rng.normal(size=(3, n))
    w = 2 * np.pi * np.geomspace(0.05, 200.0, 300)
    crb, cRBb, CbRb = siso_responses(A, b, c, Bb, Cb, w)
    sys = ct.ss(A, np.column_stack([b, Bb]), np.vstack([c, Cb]), 0.0)
    G = sys(1j * w)  # (outputs, inputs, n_w), SLICOT's TB05AD
    np.testing.assert_allclose(crb, G[0, 0], rtol=1e-9)
    np.testing.assert_allclose(cRBb, G[0, 1:].T, rtol=1e-9)
    np.testing.assert_allclose(CbRb, G[1:, 0].T, rtol=1e-9)


def _exact(A, b, c, w):
    """``c (j w I - A)^-1 b`` in 40 digits (mpmath's LU)."""
    n = A.shape[0]
    with mp.workdps(40):
        M = mp.matrix(n, n)
        for i in range(n):
            for j in range(n):
                M[i, j] = -mp.mpf(float(A[i, j]))
            M[i, i] += mp.mpc(0, float(w))
        x = mp.lu_solve(M, mp.matrix([mp.mpf(float(v)) for v in b]))
        return complex(sum(mp.mpf(float(c[i])) * x[i] for i in range(n)))


def test_states_spanning_decades_keep_their_digits():
    """States scaled over twelve decades (a loop in physical units): the balancing keeps the
    answer to a few units in the last place, where the orthogonal reduction alone lost
    three digits."""
    rng = np.random.default_rng(5)
    n = 10
    A0 = rng.normal(size=(n, n)) - 3.0 * np.eye(n)
    s = 10.0 ** rng.uniform(-6, 6, n)
    A = A0 * s[:, None] / s[None, :]
    b, c = rng.normal(size=n) * s, rng.normal(size=n) / s
    w = np.array([0.0, 0.3, 2.0, 11.0])
    crb, _, _ = siso_responses(A, b, c, np.zeros((n, 0)), np.zeros((0, n)), w)
    for k, wk in enumerate(w):
        ex = _exact(A, b, c, wk)
        assert abs(crb[k] - ex) <= 1e-13 * abs(ex)


def test_the_loops_response_against_40_digits():
    """The default family's nominal loop (13 states): the tracking and feedthrough bands."""
    fam = default_family()
    sys = fam.member(fam.nominal_values()).system(bdft=True, outputs=["y"])
    f = np.array([0.05, 0.5, 2.0, 5.0, 6.2, 7.5])
    got = frequency_response(sys, f, inp=sys.input_labels[0], out="y")
    A, B, C = (np.asarray(m, float) for m in (sys.A, sys.B, sys.C))
    d = float(np.asarray(sys.D)[0, 0])
    for k, fk in enumerate(f):
        ex = _exact(A, B[:, 0], C[0], 2 * np.pi * fk) + d
        assert abs(got[k] - ex) <= 2e-14 * abs(ex)


def test_matrices_already_reduced():
    """Upper triangular and diagonal matrices (columns with nothing to reduce)."""
    rng = np.random.default_rng(3)
    for A in (np.triu(rng.normal(size=(6, 6))) - 3 * np.eye(6), np.diag(-np.arange(1.0, 6.0))):
        n = A.shape[0]
        b, c = rng.normal(size=n), rng.normal(size=n)
        Bb, Cb = rng.normal(size=(n, 2)), rng.normal(size=(2, n))
        w = np.linspace(0.0, 10.0, 7)
        for g, r in zip(siso_responses(A, b, c, Bb, Cb, w), _lapack(A, b, c, Bb, Cb, w)):
            np.testing.assert_allclose(g, r, rtol=1e-12)


def test_a_frequency_on_an_eigenvalue_is_refused():
    A = np.array([[0.0, 1.0], [-4.0, 0.0]])  # eigenvalues +-2j
    one = np.ones(2)
    with pytest.raises(np.linalg.LinAlgError, match=r"singular at w = 2\.0"):
        siso_responses(A, one, one, np.eye(2), np.eye(2), [1.0, 2.0])
    # beside it, the answer is finite and right
    got = siso_responses(A, one, one, np.eye(2), np.eye(2), [1.0, 2.5])
    for g, r in zip(got, _lapack(A, one, one, np.eye(2), np.eye(2), np.array([1.0, 2.5]))):
        np.testing.assert_allclose(g, r, rtol=1e-13)


def test_bad_input_names_what_is_wrong():
    A, one = -np.eye(3), np.ones(3)
    with pytest.raises(ValueError, match="A must be square"):
        siso_responses(np.ones((3, 2)), one, one, np.eye(3), np.eye(3), [1.0])
    with pytest.raises(ValueError, match="b and c of its size"):
        siso_responses(A, np.ones(2), one, np.eye(3), np.eye(3), [1.0])
    with pytest.raises(ValueError, match="Bb must have 3 rows"):
        siso_responses(A, one, one, np.eye(2), np.eye(3), [1.0])
    bad = A.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="A has an entry that is not finite"):
        siso_responses(bad, one, one, np.eye(3), np.eye(3), [1.0])
    with pytest.raises(ValueError, match="w has an entry"):
        siso_responses(A, one, one, np.eye(3), np.eye(3), [np.inf])


def test_no_states():
    z = np.zeros((0, 0))
    crb, cRBb, CbRb = siso_responses(z, [], [], np.zeros((0, 2)), np.zeros((3, 0)), [1.0, 2.0])
    assert crb.shape == (2,) and cRBb.shape == (2, 2) and CbRb.shape == (2, 3)
    assert not np.any(crb) and not np.any(cRBb) and not np.any(CbRb)


_HASH_SCRIPT = """
import hashlib
import numpy as np
from robust.analysis.resolvent import resolvent_solve, siso_responses
rng = np.random.default_rng(11)
h = hashlib.sha256()
for n in (3, 9, 19):
    A = rng.normal(size=(n, n)) - 2.0 * np.eye(n)
    out = siso_responses(A, rng.normal(size=n), rng.normal(size=n), rng.normal(size=(n, 5)),
                         rng.normal(size=(6, n)), np.geomspace(0.01, 100.0, 30))
    for a in out:
        h.update(a.tobytes())
    h.update(resolvent_solve(A, np.geomspace(0.01, 100.0, 30), rng.normal(size=(n, 3))).tobytes())
print(h.hexdigest())
"""
register("resolvent", _HASH_SCRIPT)


def test_same_bits_for_a_generic_cpu_build(tmp_path):
    """The compiled loop gives the same bits built for a generic x86-64 (no AVX, no FMA)."""
    here, generic = outputs_here_and_generic("resolvent", tmp_path)
    assert len(here) == 64 and here == generic
    rng = np.random.default_rng(11)
    h = hashlib.sha256()
    for n in (3, 9, 19):
        A = rng.normal(size=(n, n)) - 2.0 * np.eye(n)
        out = siso_responses(
            A,
            rng.normal(size=n),
            rng.normal(size=n),
            rng.normal(size=(n, 5)),
            rng.normal(size=(6, n)),
            np.geomspace(0.01, 100.0, 30),
        )
        for a in out:
            h.update(a.tobytes())
        X = resolvent_solve(A, np.geomspace(0.01, 100.0, 30), rng.normal(size=(n, 3)))
        h.update(X.tobytes())
    assert h.hexdigest() == here


@pytest.mark.parametrize("n", [1, 2, 5, 13, 26])
def test_a_block_of_right_hand_sides_against_lapack(n):
    rng = np.random.default_rng(200 + n)
    A = rng.normal(size=(n, n)) - 2.0 * np.eye(n)
    B = rng.normal(size=(n, 4))
    w = np.concatenate([[0.0], np.geomspace(1e-3, 1e3, 30), [-2.5]])
    M = 1j * w[:, None, None] * np.eye(n) - A
    want = np.linalg.solve(M, np.broadcast_to(B, (w.size, n, 4)))
    got = resolvent_solve(A, w, B)
    assert got.shape == (w.size, n, 4)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    # the loops' entry point takes this way for real data and keeps LU for complex data
    np.testing.assert_array_equal(resolvent_times(A, w, B), got)
    Bc = B + 1j * rng.normal(size=B.shape)
    np.testing.assert_allclose(resolvent_times(A, w, Bc), np.linalg.solve(M, Bc), rtol=1e-12)


def test_a_block_of_right_hand_sides_keeps_its_digits_over_decades():
    """States scaled over twelve decades: each entry of ``R B`` to a few units in the last
    place of 40-digit arithmetic."""
    rng = np.random.default_rng(6)
    n = 8
    s = 10.0 ** rng.uniform(-6, 6, n)
    A = (rng.normal(size=(n, n)) - 3.0 * np.eye(n)) * s[:, None] / s[None, :]
    B = rng.normal(size=(n, 2)) * s[:, None]
    w = np.array([0.0, 0.7, 9.0])
    X = resolvent_solve(A, w, B)
    for k, wk in enumerate(w):
        for j in range(2):
            for i in (0, 3, 7):
                ex = _exact(A, B[:, j], np.eye(n)[i], wk)
                assert abs(X[k, i, j] - ex) <= 1e-13 * abs(ex)


def test_a_block_solve_refuses_what_it_cannot_do():
    A = np.array([[0.0, 1.0], [-4.0, 0.0]])  # eigenvalues +-2j
    with pytest.raises(np.linalg.LinAlgError, match=r"singular at w = -2\.0"):
        resolvent_solve(A, [1.0, -2.0], np.eye(2))
    with pytest.raises(ValueError, match="A must be square"):
        resolvent_solve(np.ones((2, 3)), [1.0], np.eye(2))
    with pytest.raises(ValueError, match="B have its rows"):
        resolvent_solve(A, [1.0], np.eye(3))
    with pytest.raises(ValueError, match="B has an entry that is not finite"):
        resolvent_solve(A, [1.0], np.array([[np.nan], [1.0]]))
    assert resolvent_solve(np.zeros((0, 0)), [1.0, 2.0], np.zeros((0, 2))).shape == (2, 0, 2)
