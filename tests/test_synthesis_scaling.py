"""Plant scaling (robust.synthesis.scaling): every apply/invert pair round-trips, and
controllers and certificates keep their meaning across the scaling.

Plants are seeded random generalized plants (robust.synthesis.testing); the
controllers are LMI designs, so every closed loop here is stable.
"""

import control
import cvxpy as cp
import numpy as np
import pytest

from robust.analysis.norms import hinf_norm
from robust.analysis.stability import poles_stable
from robust.errors import ModelStructureError, VerificationError
from robust.synthesis.genplant import GeneralizedPlant, as_generalized_plant
from robust.synthesis.lmi import PlantBlocks, bounded_real_lmi
from robust.synthesis.nominal import hinfsyn_lmi
from robust.synthesis.scaling import (
    ControllerMatrices,
    D22Removal,
    PlantScaling,
    StateScaling,
)
from robust.synthesis.solve import solve_problem
from robust.synthesis.testing import random_generalized_plant

SEEDS = [(3, 0), (6, 1), (10, 2)]
IDS = [f"n{n}-seed{s}" for n, s in SEEDS]
BLOCKS = ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21")
#: relative round-trip tolerance (a few hundred rounding errors of the largest entry)
RTOL = 1e-12


def _gp(n, seed, **kw):
    return as_generalized_plant(random_generalized_plant(n, seed=seed, d11=True, **kw), 2, 2)


def _blocks(n, seed):
    return PlantBlocks.from_generalized_plant(_gp(n, seed))


def _gp_from_blocks(b: PlantBlocks) -> GeneralizedPlant:
    """The generalized plant of ``b`` with ``D22 = 0`` (inputs w then u, outputs z then y)."""
    n, nw, nu, nz, ny = b.sizes
    sys = control.ss(
        b.A,
        np.hstack([b.B1, b.B2]),
        np.vstack([b.C1, b.C2]),
        np.block([[b.D11, b.D12], [b.D21, np.zeros((ny, nu))]]),
    )
    return GeneralizedPlant.from_counts(sys, nmeas=ny, ncon=nu)


def _assert_close(x, y, rtol=RTOL):
    x, y = np.asarray(x, float), np.asarray(y, float)
    assert x.shape == y.shape
    scale = max(float(np.max(np.abs(y), initial=0.0)), 1e-300)
    assert np.max(np.abs(x - y), initial=0.0) <= rtol * scale


def _assert_blocks_close(b1: PlantBlocks, b2: PlantBlocks, rtol=RTOL):
    for k in BLOCKS:
        _assert_close(getattr(b1, k), getattr(b2, k), rtol)


def _random_controller(rng, nk, nu, ny):
    return ControllerMatrices(
        rng.standard_normal((nk, nk)),
        rng.standard_normal((nk, ny)),
        rng.standard_normal((nu, nk)),
        rng.standard_normal((nu, ny)),
    )


def _stages(b: PlantBlocks):
    """Each stage fitted as PlantScaling.fit fits it, plus the composite."""
    sc = PlantScaling.fit(b)
    return {
        "state": sc.state,
        "time": sc.time,
        "channels": sc.channels,
        "performance": sc.performance,
        "composite": sc,
    }


STAGES = ["state", "time", "channels", "performance", "composite"]


def _K(K: ControllerMatrices, gp: GeneralizedPlant) -> control.StateSpace:
    return control.ss(*K, inputs=list(gp.y), outputs=list(gp.u))


# ------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("stage", STAGES)
@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_plant_round_trip(n, seed, stage):
    b = _blocks(n, seed)
    s = _stages(b)[stage]
    _assert_blocks_close(s.invert(s.apply(b)), b)
    _assert_blocks_close(s.apply(s.invert(b)), b)


@pytest.mark.parametrize("stage", STAGES)
@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_controller_round_trip(n, seed, stage):
    b = _blocks(n, seed)
    s = _stages(b)[stage]
    K = _random_controller(np.random.default_rng(seed), n, 2, 2)
    for a, c in zip(s.invert_controller(s.apply_controller(K)), K):
        _assert_close(a, c)
    for a, c in zip(s.apply_controller(s.invert_controller(K)), K):
        _assert_close(a, c)


@pytest.mark.parametrize("stage", STAGES)
@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_certificate_and_gamma_round_trip(n, seed, stage):
    b = _blocks(n, seed)
    s = _stages(b)[stage]
    rng = np.random.default_rng(seed)
    nk = n
    M = rng.standard_normal((n + nk, n + nk))
    P = M @ M.T + np.eye(n + nk)
    _assert_close(s.invert_certificate(s.apply_certificate(P)), P)
    _assert_close(s.apply_certificate(s.invert_certificate(P)), P)
    assert s.invert_gamma(s.apply_gamma(2.5)) == pytest.approx(2.5, rel=RTOL)
    assert s.apply_gamma(s.invert_gamma(2.5)) == pytest.approx(2.5, rel=RTOL)


@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_composite_maps_are_the_composition_of_the_stages(n, seed):
    b = _blocks(n, seed)
    sc = PlantScaling.fit(b)
    rng = np.random.default_rng(seed)
    K = _random_controller(rng, n, 2, 2)
    M = rng.standard_normal((2 * n, 2 * n))
    P = M @ M.T
    Kc, Pc, gc = K, P, 3.0
    for s in reversed(sc.stages):
        Kc, Pc, gc = s.invert_controller(Kc), s.invert_certificate(Pc), s.invert_gamma(gc)
    for a, c in zip(sc.invert_controller(K), Kc):
        _assert_close(a, c, 1e-14)
    _assert_close(sc.invert_certificate(P), Pc, 1e-14)
    assert sc.invert_gamma(3.0) == pytest.approx(gc, rel=1e-15)


def test_identity_scaling_is_exact():
    b = _blocks(6, 1)
    sc = PlantScaling.identity(6, 2, 2)
    for k in BLOCKS:
        assert np.array_equal(getattr(sc.apply(b), k), getattr(b, k))
    K = _random_controller(np.random.default_rng(0), 6, 2, 2)
    for a, c in zip(sc.invert_controller(K), K):
        assert np.array_equal(a, c)
    assert sc.invert_gamma(1.7) == 1.7


#: the maps each stage leaves alone (the others change the plant, controller, certificate, gamma)
IDENTITY_MAPS = {
    "state": ("controller", "gamma"),
    "time": ("gamma",),
    "channels": ("certificate", "gamma"),
    "performance": ("controller",),
    "d22": ("certificate", "gamma"),
}


@pytest.mark.parametrize("stage", list(IDENTITY_MAPS))
def test_maps_a_stage_leaves_alone_are_exact_identities(stage):
    b = _blocks(6, 1)
    s = D22Removal(np.ones((2, 2))) if stage == "d22" else _stages(b)[stage]
    rng = np.random.default_rng(0)
    K = _random_controller(rng, 6, 2, 2)
    M = rng.standard_normal((12, 12))
    P = M @ M.T
    maps = {
        "controller": lambda f: all(np.array_equal(a, c) for a, c in zip(f(K), K)),
        "certificate": lambda f: np.array_equal(f(P), P),
        "gamma": lambda f: f(1.7) == 1.7,
    }
    for name, is_identity in maps.items():
        for direction in ("apply", "invert"):
            f = getattr(s, f"{direction}_{name}")
            assert is_identity(f) == (name in IDENTITY_MAPS[stage]), f"{stage}.{f.__name__}"


# ------------------------------------------------------------------------- what fit does
@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_fitted_scaling_normalises_the_channels(n, seed):
    b = _blocks(n, seed)
    sc = PlantScaling.fit(b)
    assert sc.state.kind == "balanced"
    bs = sc.apply(b)
    assert np.linalg.norm(np.vstack([bs.B2, bs.D12 * sc.performance.sz]), axis=0) == (
        pytest.approx(np.ones(2), rel=1e-12)
    )
    assert np.linalg.norm(np.hstack([bs.C2, bs.D21 / sc.performance.sw]), axis=1) == (
        pytest.approx(np.ones(2), rel=1e-12)
    )
    assert np.linalg.norm(np.vstack([bs.B1, bs.D21]), 2) == pytest.approx(1.0, rel=1e-12)
    assert np.linalg.norm(np.hstack([bs.C1, bs.D11, bs.D12]), 2) == pytest.approx(1.0, rel=1e-12)
    # time in units of the spectral radius
    assert np.max(np.abs(np.linalg.eigvals(bs.A))) == pytest.approx(1.0, rel=1e-9)


def test_common_scaling_shares_all_but_the_state_transformation():
    b0, b1 = _blocks(6, 1), _blocks(6, 2)
    common = PlantScaling.fit(b0)
    sc = PlantScaling.fit(b1, common=common)
    assert sc.time is common.time
    assert sc.channels is common.channels
    assert sc.performance is common.performance
    assert not np.allclose(sc.state.T, common.state.T)
    _assert_blocks_close(sc.invert(sc.apply(b1)), b1)


def test_certificate_of_the_wrong_order_is_refused():
    sc = PlantScaling.fit(_blocks(6, 1))
    with pytest.raises(ModelStructureError, match=r"P must be a square certificate of order >= 6"):
        sc.invert_certificate(np.eye(4))
    with pytest.raises(ModelStructureError, match="Tb and Tbi must be given together"):
        StateScaling(np.ones(2), Tb=np.eye(2))


# ------------------------------------------------------------------------- meaning is kept
@pytest.fixture(scope="module")
def designs():
    """Per plant: the plant, its scaling, and an LMI design in original coordinates."""
    out = {}
    for n, seed in SEEDS:
        gp = _gp(n, seed)
        out[(n, seed)] = (gp, PlantScaling.fit(PlantBlocks.from_generalized_plant(gp)))
    return out


@pytest.mark.parametrize("stage", STAGES)
@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_controller_mapped_forward_keeps_the_closed_loop_norm(designs, n, seed, stage):
    gp, sc = designs[(n, seed)]
    s = {
        "state": sc.state,
        "time": sc.time,
        "channels": sc.channels,
        "performance": sc.performance,
        "composite": sc,
    }[stage]
    K = ControllerMatrices.from_statespace(hinfsyn_lmi(gp).K)
    g = hinf_norm(gp.closed_loop(_K(K, gp)))
    gps = _gp_from_blocks(s.apply(PlantBlocks.from_generalized_plant(gp)))
    cl_s = gps.closed_loop(_K(s.apply_controller(K), gps))
    assert poles_stable(control.poles(cl_s))
    assert hinf_norm(cl_s) == pytest.approx(s.apply_gamma(g), rel=1e-8)


@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_controller_synthesised_in_scaled_coordinates(designs, n, seed):
    # design for the scaled plant with no further scaling, then map the controller back:
    # the original closed loop has the scaled loop's norm in original units
    gp, sc = designs[(n, seed)]
    gps = _gp_from_blocks(sc.apply(PlantBlocks.from_generalized_plant(gp)))
    res = hinfsyn_lmi(gps, scale=False)
    K = sc.invert_controller(ControllerMatrices.from_statespace(res.K))
    cl = gp.closed_loop(_K(K, gp))
    assert poles_stable(control.poles(cl))
    g = hinf_norm(cl)
    assert g == pytest.approx(sc.invert_gamma(res.gamma), rel=1e-8)
    assert g <= sc.invert_gamma(res.gamma_bound) * (1 + 1e-6)


def _brl_max_eig(cl, P, g):
    A, B, C, D = (np.asarray(m, float) for m in (cl.A, cl.B, cl.C, cl.D))
    M = np.block(
        [
            [A.T @ P + P @ A, P @ B, C.T],
            [B.T @ P, -g * np.eye(B.shape[1]), D.T],
            [C, D, -g * np.eye(C.shape[0])],
        ]
    )
    return float(np.linalg.eigvalsh((M + M.T) / 2).max())


@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_certificate_of_the_scaled_loop_certifies_the_original(designs, n, seed):
    gp, sc = designs[(n, seed)]
    K = ControllerMatrices.from_statespace(hinfsyn_lmi(gp).K)
    gps = _gp_from_blocks(sc.apply(PlantBlocks.from_generalized_plant(gp)))
    cl_s = gps.closed_loop(_K(sc.apply_controller(K), gps))
    g_s = 1.05 * hinf_norm(cl_s)
    # a strict bounded-real certificate of the scaled closed loop at g_s (one small SDP)
    nx = cl_s.nstates
    P = cp.Variable((nx, nx), symmetric=True)
    cons = [
        P >> 1e-6 * np.eye(nx),
        bounded_real_lmi(cl_s.A, cl_s.B, cl_s.C, cl_s.D, P, g_s, margin=1e-6),
    ]
    solve_problem(cp.Problem(cp.Minimize(0), cons), step="test: scaled certificate")
    assert _brl_max_eig(cl_s, P.value, g_s) < 0
    P0 = sc.invert_certificate(P.value)
    cl = gp.closed_loop(_K(K, gp))
    assert np.linalg.eigvalsh(P0).min() > 0
    assert _brl_max_eig(cl, P0, sc.invert_gamma(g_s)) < 0
    # and back: the original certificate maps to one of the scaled loop
    assert _brl_max_eig(cl_s, sc.apply_certificate(P0), g_s) < 0


# ------------------------------------------------------------------------- D22
@pytest.mark.parametrize("n,seed", SEEDS, ids=IDS)
def test_d22_removal_round_trips_and_keeps_the_closed_loop(n, seed):
    gp = _gp(n, seed, d22=True)
    loop = D22Removal(gp.D22)
    gp0 = loop.apply(gp)
    assert not np.any(gp0.D22)
    for k, v in loop.invert(gp0).blocks().items():
        assert np.array_equal(v, gp.blocks()[k])
    K = _random_controller(np.random.default_rng(seed), n, 2, 2)
    for a, c in zip(loop.invert_controller(loop.apply_controller(K)), K):
        _assert_close(a, c, 1e-10)
    for a, c in zip(loop.apply_controller(loop.invert_controller(K)), K):
        _assert_close(a, c, 1e-10)
    # the same closed loop, realization included (controller states are kept)
    K0 = ControllerMatrices.from_statespace(hinfsyn_lmi(gp0).K)
    cl0 = gp0.closed_loop(_K(K0, gp0))
    cl = gp.closed_loop(_K(loop.invert_controller(K0), gp))
    for m in ("A", "B", "C", "D"):
        _assert_close(getattr(cl, m), getattr(cl0, m), 1e-9)
    P = np.eye(cl.nstates)
    assert np.array_equal(loop.invert_certificate(loop.apply_certificate(P)), P)
    assert loop.invert_gamma(loop.apply_gamma(1.5)) == 1.5


def test_d22_removal_refuses_an_ill_posed_loop_and_another_plant():
    gp = _gp(4, 0, d22=True)
    loop = D22Removal(gp.D22)
    K = ControllerMatrices(np.zeros((1, 1)), np.zeros((1, 2)), np.zeros((2, 1)), np.zeros((2, 2)))
    # I + Dk D22 = D22^-1 diag(0, 1) D22: singular, with a unit eigenvalue
    K = K._replace(Dk=-np.linalg.inv(gp.D22) @ np.diag([1.0, 0.0]))
    with pytest.raises(VerificationError, match=r"I \+ Dk\*D22 must have condition number"):
        loop.invert_controller(K)
    with pytest.raises(ModelStructureError, match="D22Removal was built for another D22"):
        loop.apply(_gp(4, 0))
    assert D22Removal(np.zeros((2, 2))).loop_condition(K.Dk) == 1.0
