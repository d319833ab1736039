"""Closed loops of interconnected blocks (uncertainty.closeloops): against the formula solved
by LAPACK member by member, against python-control, the algebraic-cycle path, bad input."""

import hashlib

import control as ct
import numpy as np
import pytest
from numba_builds import outputs_here_and_generic, register

from backhoe import default_family
from backhoe.families.batched import closed_loop_matrices, interconnection, loop_blocks
from robust.errors import ModelStructureError
from uncertainty import sample
from uncertainty.closeloops import algebraic_cycle, close_loops


def _reference(As, Bs, Cs, Ds, M, N):
    """blkdiag(A) + B M inv(I - D M) C, member by member, with dense block-diagonal stacks."""
    out = []
    for j in range(N):
        pick = [[x[j if x.shape[0] > 1 else 0] for x in g] for g in (As, Bs, Cs, Ds)]
        A, B, C, D = (_blkdiag(g) for g in pick)
        Z = np.linalg.inv(np.eye(D.shape[0]) - D @ M) @ C
        out.append(A + B @ M @ Z)
    return np.array(out)


def _blkdiag(mats):
    rows = sum(m.shape[0] for m in mats)
    cols = sum(m.shape[1] for m in mats)
    out = np.zeros((rows, cols))
    r = c = 0
    for m in mats:
        out[r : r + m.shape[0], c : c + m.shape[1]] = m
        r, c = r + m.shape[0], c + m.shape[1]
    return out


def _random_loop(rng, N, *, cycle):
    """A ring of 3-4 blocks (sizes 0-4 states, 1-2 inputs and outputs, some fixed), each
    block's inputs fed by the previous block's outputs; feedthrough D only where it makes
    no algebraic cycle unless ``cycle``."""
    K = int(rng.integers(3, 5))
    dims = [
        (int(rng.integers(0, 5)), int(rng.integers(1, 3)), int(rng.integers(1, 3)))
        for _ in range(K)
    ]
    As, Bs, Cs, Ds = [], [], [], []
    for k, (n, m, p) in enumerate(dims):
        lead = 1 if k % 2 == 0 else N
        As.append(rng.normal(size=(lead, n, n)) - 3.0 * np.eye(n))
        Bs.append(rng.normal(size=(lead, n, m)))
        Cs.append(rng.normal(size=(lead, p, n)))
        feed = cycle or k == 0
        Ds.append(0.3 * rng.normal(size=(lead, p, m)) if feed else np.zeros((lead, p, m)))
    m_tot = sum(d[1] for d in dims)
    p_tot = sum(d[2] for d in dims)
    M = np.zeros((m_tot, p_tot))
    us = np.cumsum([0] + [d[1] for d in dims])
    ys = np.cumsum([0] + [d[2] for d in dims])
    for k in range(K):
        prev = (k - 1) % K
        M[us[k] : us[k + 1], ys[prev] : ys[prev + 1]] = 0.5 * rng.normal(
            size=(dims[k][1], dims[prev][2])
        )
    return As, Bs, Cs, Ds, M


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("cycle", [False, True])
def test_equals_the_formula_solved_member_by_member(seed, cycle):
    rng = np.random.default_rng(seed)
    N = 7
    As, Bs, Cs, Ds, M = _random_loop(rng, N, cycle=cycle)
    got = close_loops(As, Bs, Cs, Ds, M)
    ref = _reference(As, Bs, Cs, Ds, M, N)
    assert got.shape == ref.shape
    scale = np.abs(ref).max()
    assert np.abs(got - ref).max() <= 1e-12 * scale


def test_family_loop_has_no_algebraic_cycle_and_matches_the_formula():
    fam = default_family("physical")
    values = np.asarray(sample(fam.parameters, 40, seed=4).values)
    blocks = loop_blocks(fam, values)
    M = interconnection(fam, blocks)
    groups = [[getattr(b, x) for b in blocks] for x in "ABCD"]
    got = close_loops(*groups, M)
    ref = _reference(*groups, M, 40)
    assert np.abs(got - ref).max() <= 1e-13 * np.abs(ref).max()
    # the compiled series, not LAPACK, built it: the pattern of D M has no cycle
    D = _blkdiag([b.D[0] for b in blocks])
    assert not algebraic_cycle((D != 0) @ (M != 0) > 0)


def test_two_blocks_agree_with_python_control_feedback():
    """u1 = r - y2, u2 = y1: python-control's feedback of the same two systems."""
    rng = np.random.default_rng(11)
    g1 = ct.ss(
        rng.normal(size=(4, 4)) - 3 * np.eye(4),
        rng.normal(size=(4, 1)),
        rng.normal(size=(1, 4)),
        0.4,
    )
    g2 = ct.ss(
        rng.normal(size=(3, 3)) - 3 * np.eye(3), rng.normal(size=(3, 1)), rng.normal(size=(1, 3)), 0
    )
    M = np.array([[0.0, -1.0], [1.0, 0.0]])
    Acl = close_loops(
        [g1.A[None], g2.A[None]],
        [g1.B[None], g2.B[None]],
        [g1.C[None], g2.C[None]],
        [g1.D[None], g2.D[None]],
        M,
    )[0]
    ref = ct.feedback(g1, g2).A
    got = np.sort_complex(np.linalg.eigvals(Acl))
    want = np.sort_complex(np.linalg.eigvals(ref))
    assert np.abs(got - want).max() <= 1e-9 * max(1.0, np.abs(want).max())


def test_algebraic_cycle_of_patterns():
    assert not algebraic_cycle(np.zeros((3, 3), bool))
    assert not algebraic_cycle(np.array([[0, 1, 0], [0, 0, 1], [0, 0, 0]], bool))
    assert algebraic_cycle(np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], bool))
    assert algebraic_cycle(np.array([[1]], bool))


def test_singular_loop_is_refused_naming_the_feedthrough():
    # one static block with D = 1 fed back on itself: I - D M = 0
    one = np.ones((1, 1, 1))
    empty = [np.zeros((1, 0, 0)), np.zeros((1, 0, 1)), np.zeros((1, 1, 0)), one]
    with pytest.raises(ModelStructureError, match="ill-posed"):
        close_loops(*([x] for x in empty), np.array([[1.0]]))


def test_bad_shapes_are_refused_naming_the_block():
    A = np.zeros((1, 2, 2))
    B = np.zeros((1, 2, 1))
    C = np.zeros((1, 1, 2))
    D = np.zeros((1, 1, 1))
    with pytest.raises(ModelStructureError, match="block 0's B"):
        close_loops([A], [np.zeros((1, 3, 1))], [C], [D], np.zeros((1, 1)))
    with pytest.raises(ModelStructureError, match=r"M must have shape \(1, 1\)"):
        close_loops([A], [B], [C], [D], np.zeros((2, 1)))
    with pytest.raises(ModelStructureError, match="member counts differ"):
        close_loops([np.zeros((3, 2, 2))], [np.zeros((2, 2, 1))], [C], [D], np.zeros((1, 1)))
    with pytest.raises(ModelStructureError, match="at least one block"):
        close_loops([], [], [], [], np.zeros((0, 0)))


def test_broadcast_blocks_give_one_member():
    rng = np.random.default_rng(2)
    As, Bs, Cs, Ds, M = _random_loop(rng, 1, cycle=False)
    got = close_loops(As, Bs, Cs, Ds, M)
    assert got.shape[0] == 1
    assert np.allclose(got, _reference(As, Bs, Cs, Ds, M, 1), rtol=0, atol=1e-12)


_HASH_SCRIPT = """
import hashlib
import numpy as np
from backhoe import default_family
from uncertainty import sample
from backhoe.families.batched import closed_loop_matrices
fam = default_family("physical")
v = np.asarray(sample(fam.parameters, 500, seed=8).values)
print(hashlib.sha256(closed_loop_matrices(fam, v).tobytes()).hexdigest())
"""
register("interconnect", _HASH_SCRIPT)


@pytest.mark.slow
def test_same_bits_for_a_generic_cpu_build(tmp_path):
    """The compiled loops give the same bits built for a generic x86-64 (no AVX, no FMA)."""
    here, generic = outputs_here_and_generic("interconnect", tmp_path)
    assert len(here) == 64 and here == generic
    fam = default_family("physical")
    v = np.asarray(sample(fam.parameters, 500, seed=8).values)
    assert hashlib.sha256(closed_loop_matrices(fam, v).tobytes()).hexdigest() == here
