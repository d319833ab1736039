"""GeneralizedPlant: partitions by name and by count, blocks, closed loop."""

import control
import numpy as np
import pytest

from robust.errors import ModelStructureError
from robust.synthesis.genplant import GeneralizedPlant, as_generalized_plant
from robust.synthesis.testing import random_generalized_plant


def _fr(sys, w):
    """Frequency response array, shape (outputs, inputs, len(w))."""
    return np.stack([np.atleast_2d(sys(1j * x)) for x in np.atleast_1d(w)], axis=-1)


@pytest.fixture
def named_plant():
    P = random_generalized_plant(3, seed=1, nw=2, nz=2, nu=1, ny=1, d11=True, d22=True)
    # shuffle the signal order so that name-based partitioning has work to do
    perm_in, perm_out = [2, 0, 1], [1, 2, 0]
    return control.ss(
        P.A,
        P.B[:, perm_in],
        P.C[perm_out, :],
        P.D[np.ix_(perm_out, perm_in)],
        inputs=[P.input_labels[i] for i in perm_in],
        outputs=[P.output_labels[i] for i in perm_out],
    ), P


def test_from_system_reorders_by_name(named_plant):
    shuffled, P = named_plant
    gp = GeneralizedPlant.from_system(shuffled, w=["w0", "w1"], u=["u0"], z=["z0", "z1"], y=["y0"])
    ref = GeneralizedPlant.from_counts(P, nmeas=1, ncon=1)
    for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21", "D22"):
        np.testing.assert_array_equal(getattr(gp, k), getattr(ref, k), err_msg=k)
    assert (gp.nx, gp.nw, gp.nu, gp.nz, gp.ny) == (3, 2, 1, 2, 1)
    assert list(gp.sys.input_labels) == ["w0", "w1", "u0"]


def test_blocks_shapes():
    gp = GeneralizedPlant.from_counts(random_generalized_plant(5, seed=0), nmeas=2, ncon=2)
    shapes = {k: v.shape for k, v in gp.blocks().items()}
    assert shapes == {
        "A": (5, 5),
        "B1": (5, 4),
        "B2": (5, 2),
        "C1": (4, 5),
        "C2": (2, 5),
        "D11": (4, 4),
        "D12": (4, 2),
        "D21": (2, 4),
        "D22": (2, 2),
    }


def test_closed_loop_matches_python_control_feedback():
    # u = K y with a static K: F_l(P, K) equals the textbook formula for D22 = 0
    P = random_generalized_plant(4, seed=3, nw=2, nz=2, nu=1, ny=1, d11=True)
    gp = as_generalized_plant(P, 1, 1)
    K = control.ss([[-2.0]], [[1.0]], [[0.5]], [[0.3]])
    cl = gp.closed_loop(K)
    w = np.array([0.0, 0.7, 5.0])
    Pf = _fr(P, w)
    Kf = _fr(K, w)
    for k in range(len(w)):
        P11, P12, P21, P22 = Pf[:2, :2, k], Pf[:2, 2:, k], Pf[2:, :2, k], Pf[2:, 2:, k]
        Kk = Kf[:, :, k]
        ref = P11 + P12 @ Kk @ np.linalg.solve(np.eye(1) - P22 @ Kk, P21)
        np.testing.assert_allclose(_fr(cl, w[k : k + 1])[:, :, 0], ref, rtol=1e-10)


def test_closed_loop_with_d22():
    P = random_generalized_plant(3, seed=4, nw=2, nz=2, nu=1, ny=1, d22=True)
    gp = as_generalized_plant(P, 1, 1)
    K = control.ss([[-1.0]], [[1.0]], [[0.2]], [[0.4]])
    w = np.array([1.3])
    Pf = _fr(P, w)[:, :, 0]
    Kk = _fr(K, w)[:, :, 0]
    ref = Pf[:2, :2] + Pf[:2, 2:] @ Kk @ np.linalg.solve(np.eye(1) - Pf[2:, 2:] @ Kk, Pf[2:, :2])
    np.testing.assert_allclose(_fr(gp.closed_loop(K), w)[:, :, 0], ref, rtol=1e-10)


def test_with_blocks_round_trip():
    gp = as_generalized_plant(random_generalized_plant(3, seed=2), 2, 2)
    gp2 = gp.with_blocks(D22=np.ones((2, 2)))
    np.testing.assert_array_equal(gp2.D22, np.ones((2, 2)))
    np.testing.assert_array_equal(gp2.A, gp.A)
    with pytest.raises(ModelStructureError, match="block D22 must have shape"):
        gp.with_blocks(D22=np.ones((3, 2)))


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (
            {"w": ["w0"], "u": ["u0"], "z": ["z0", "z1"], "y": ["y0"]},
            r"inputs \['w1'\] are in no partition",
        ),
        ({"w": ["w0", "w1"], "u": ["w1"], "z": ["z0", "z1"], "y": ["y0"]}, "listed in both"),
        ({"w": ["w0", "w1"], "u": ["u9"], "z": ["z0", "z1"], "y": ["y0"]}, "'u9' is not an input"),
        (
            {"w": ["w0", "w1", "u0"], "u": [], "z": ["z0", "z1"], "y": ["y0"]},
            "at least one control input",
        ),
    ],
    ids=["unlisted", "duplicate", "unknown", "no-control"],
)
def test_partition_errors(kwargs, match):
    P = random_generalized_plant(2, seed=0, nw=2, nz=2, nu=1, ny=1)
    with pytest.raises(ModelStructureError, match=match):
        GeneralizedPlant.from_system(P, **kwargs)


def test_count_errors():
    P = random_generalized_plant(2, seed=0, nw=2, nz=2, nu=1, ny=1)
    with pytest.raises(ModelStructureError, match="nmeas must be an integer"):
        GeneralizedPlant.from_counts(P, nmeas=3, ncon=1)
    with pytest.raises(ModelStructureError, match="nmeas and ncon are required"):
        as_generalized_plant(P)
    gp = as_generalized_plant(P, 1, 1)
    assert as_generalized_plant(gp) is gp
    with pytest.raises(ModelStructureError, match="contradict"):
        as_generalized_plant(gp, 2, 1)
    with pytest.raises(ModelStructureError, match="K must have 1 inputs"):
        gp.closed_loop(control.ss([], [], [], np.ones((1, 2))))
