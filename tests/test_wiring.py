"""The Figure 5 junction table and the three assemblies that consume it.

Each consumer is tied to the table: the loop's static blocks are exactly the table's
rows; the batched family assembly gives the poles of the loop built from the table;
the force-feedback generalized plant, closed with a controller, contains every pole
of the loop closed with the same controller. Signal names that do not connect fail.
"""

import warnings

import control as ct
import numpy as np
import pytest

import backhoe.model.wiring as wiring
from backhoe import closed_loop_matrices, default_family
from backhoe.model.wiring import CONTROLLER_FORCE, connect, expand, figure5_junctions
from backhoe.synthesis.forcefb import as_plant_controller, force_feedback_plant
from robust.errors import ModelStructureError


@pytest.fixture(scope="module")
def family():
    return default_family()


@pytest.fixture(scope="module")
def nominal(family):
    return family.member(family.nominal_values())


def _controller(outputs):
    """A stable, seeded 2-state controller x, c, y -> outputs (small gains)."""
    rng = np.random.default_rng(7)
    A = np.array([[-30.0, 5.0], [-5.0, -20.0]])
    B = 1e-3 * rng.standard_normal((2, 3))
    C = rng.standard_normal((len(outputs), 2))
    D = np.zeros((len(outputs), 3))
    return ct.ss(A, B, C, D, inputs=["x", "c", "y"], outputs=list(outputs), name="K")


def _static_rows(blocks):
    rows = {}
    for b in blocks:
        if b.nstates == 0:
            rows[b.name] = (
                b.output_labels[0],
                dict(zip(b.input_labels, np.asarray(b.D, float).ravel())),
            )
    return rows


@pytest.mark.parametrize(
    "bdft,outputs",
    [
        (True, ()),
        (True, ("f",)),
        (True, ("r_corr",)),
        (True, ("f", "r_corr")),
        (False, ("r_corr",)),
    ],
    ids=["bdft", "bdft-force", "bdft-correction", "bdft-both", "no-bdft-correction"],
)
def test_the_loops_static_blocks_are_the_table(nominal, bdft, outputs):
    K = None
    if outputs:
        K = _controller(outputs)
        if not bdft:
            K = ct.ss(
                K.A,
                K.B[:, [0, 2]],
                K.C,
                K.D[:, [0, 2]],
                inputs=["x", "y"],
                outputs=list(outputs),
                name="K",
            )
    external = bdft and nominal.human.has_force_port
    blocks = nominal.blocks(bdft=bdft, controller=K, external_force=external)
    force = (("f_ext",) if external else ()) + ((CONTROLLER_FORCE,) if "f" in outputs else ())
    table = figure5_junctions(
        k_psf=nominal.k_psf,
        handle_gain=nominal.calibration.handle_sign * nominal.calibration.loop_scale,
        bdft=bdft,
        reference_correction="r_corr" in outputs,
        force_terms=force,
    )
    want = {j.name: (j.output, dict(j.terms)) for j in table}
    assert _static_rows(blocks) == want


def test_expand_substitutes_the_junctions(nominal):
    g = nominal.calibration.handle_sign * nominal.calibration.loop_scale
    table = figure5_junctions(
        k_psf=nominal.k_psf,
        handle_gain=g,
        reference_correction=True,
        force_terms=("f_ext", CONTROLLER_FORCE),
    )
    err = expand("err", table)
    assert err == pytest.approx({"h": nominal.k_psf * g, "r_corr": 1.0, "y": -1.0})
    assert expand("x", table) == pytest.approx({"h": g})
    assert expand("f", table) == {CONTROLLER_FORCE: 1.0}
    assert expand("c", table) == {"c": 1.0}


@pytest.mark.parametrize(
    "outputs",
    [(), ("f",), ("r_corr",), ("f", "r_corr")],
    ids=["open", "force", "correction", "both"],
)
def test_batched_assembly_matches_the_loop(family, outputs):
    K = _controller(outputs) if outputs else None
    rng = np.random.default_rng(3)
    lo = np.array([p.low for p in family.parameters])
    hi = np.array([p.high for p in family.parameters])
    rows = lo + (hi - lo) * rng.random((4, len(lo)))
    Acl = closed_loop_matrices(family, rows, controller=K)
    for row, A in zip(rows, Acl):
        want = np.sort_complex(ct.poles(family.member(row).system(controller=K)))
        got = np.sort_complex(np.linalg.eigvals(A))
        np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-7)


def test_force_feedback_plant_contains_the_loop(nominal):
    K = _controller(("f",))
    K = ct.ss(K.A, K.B[:, :2], K.C, K.D[:, :2], inputs=["x", "c"], outputs=["f"], name="K")
    gp = force_feedback_plant(nominal)
    cl = gp.closed_loop(as_plant_controller(K))
    plant_poles = np.linalg.eigvals(np.asarray(cl.A, float))
    for p in ct.poles(nominal.system(controller=K)):
        assert np.min(np.abs(plant_poles - p)) <= 1e-6 * max(1.0, abs(p))


@pytest.mark.parametrize("outputs", [(), ("f",), ("r_corr",)], ids=["open", "force", "correction"])
def test_connect_equals_python_controls_interconnection(family, outputs):
    # the exact closed form against python-control's interconnect (a nonlinear system
    # linearised by finite differences): the same states in the same order, and matrices
    # equal to rounding, with a controller in the loop and with the loop without BDFT
    K = _controller(outputs) if outputs else None
    rows = np.random.default_rng(11).random((3, len(family.names)))
    lo = np.array([p.low for p in family.parameters])
    hi = np.array([p.high for p in family.parameters])
    for row in lo + (hi - lo) * rows:
        m = family.member(row)
        for bdft in (True, False) if K is None else (True,):
            ext = bdft and m.human.has_force_port
            blocks = m.blocks(bdft=bdft, controller=K, external_force=ext)
            ins = ["u", "f_ext"] if ext else ["u"]
            outs = ["y", "c", "h", "x", "e"] if bdft else ["y", "x", "e"]
            outs += list(outputs)
            got = connect(blocks, inputs=ins, outputs=outs, name="loop")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                want = ct.interconnect(blocks, inputs=ins, outputs=outs, check_unused=False)
            assert list(got.state_labels) == list(want.state_labels)
            assert list(got.input_labels) == ins and list(got.output_labels) == outs
            for a, b in ((got.A, want.A), (got.B, want.B), (got.C, want.C), (got.D, want.D)):
                np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())


def test_connect_refuses_clashes_and_algebraic_loops():
    a = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], inputs="u", outputs="y", name="a")
    b = ct.ss([[-2.0]], [[1.0]], [[1.0]], [[0.0]], inputs="u", outputs="y", name="b")
    with pytest.raises(ModelStructureError, match="two blocks drive signal 'y'"):
        connect([a, b], inputs=["u"], outputs=["y"], name="twice")
    with pytest.raises(ModelStructureError, match="no block has the output 'z'"):
        connect([a], inputs=["u"], outputs=["z"], name="unknown")
    d = ct.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.01, inputs="y", outputs="z", name="d")
    with pytest.raises(ModelStructureError, match="different timebases"):
        connect([a, d], inputs=["u"], outputs=["z"], name="mixed")
    # y = u + y has no solution: an algebraic loop through a unit direct feedthrough
    g = ct.ss([], [], [], [[1.0, 1.0]], inputs=["u", "y"], outputs="y", name="g")
    with pytest.raises(ModelStructureError, match="algebraic loop"):
        connect([g], inputs=["u"], outputs=["y"], name="loop")
    # a static gain in a loop with a solution: y = 2 (u - y) -> y = 2/3 u
    h = ct.ss([], [], [], [[2.0, -2.0]], inputs=["u", "y"], outputs="y", name="h")
    sys = connect([h], inputs=["u"], outputs=["y"], name="static")
    assert sys.nstates == 0 and sys.D[0, 0] == pytest.approx(2.0 / 3.0, rel=1e-15)
    # a loop whose gain is unity only up to rounding (1 - 0.1 * 3 / 0.3 ~ 2e-16) is refused
    # too, not solved into a gain of 1e16
    k1 = ct.ss([], [], [], [[1.0, 0.1 * 3.0]], inputs=["u", "q"], outputs="p", name="k1")
    k2 = ct.ss([], [], [], [[1.0 / 0.3]], inputs="p", outputs="q", name="k2")
    with pytest.raises(ModelStructureError, match="algebraic loop.*condition number"):
        connect([k1, k2], inputs=["u"], outputs=["p"], name="near")
    # a chain of large static gains closes no loop (no cycle through the feedthroughs): its
    # series is solved exactly
    c1 = ct.ss([], [], [], [[1e13]], inputs="u", outputs="q", name="c1")
    c2 = ct.ss([], [], [], [[1e13]], inputs="q", outputs="p", name="c2")
    sys = connect([c1, c2], inputs=["u"], outputs=["p", "q"], name="chain")
    assert sys.D[:, 0].tolist() == [1e26, 1e13]
    # a transfer-function block is converted, keeping its name in the state labels
    tf = ct.tf([1.0], [1.0, 3.0], inputs="y", outputs="z", name="tf")
    sys = connect([a, tf], inputs=["u"], outputs=["z"], name="mixed_types")
    assert sys.nstates == 2 and list(sys.state_labels) == ["a_x[0]", "tf_x[0]"]
    np.testing.assert_allclose(sys(0.0), 1.0 / 3.0, rtol=1e-12)
    # repeated names would leave a column or a state unlabelled: refused
    with pytest.raises(ModelStructureError, match=r"repeated external input\(s\) \['u'\]"):
        connect([a], inputs=["u", "u"], outputs=["y"], name="twice_in")
    with pytest.raises(ModelStructureError, match=r"repeated output\(s\) \['y'\]"):
        connect([a], inputs=["u"], outputs=["y", "y"], name="twice_out")
    a2 = ct.ss([[-3.0]], [[1.0]], [[1.0]], [[0.0]], inputs="y", outputs="z", name="a")
    with pytest.raises(ModelStructureError, match=r"repeated block name\(s\) \['a'\]"):
        connect([a, a2], inputs=["u"], outputs=["z"], name="twice_block")


def test_unconnected_inputs_and_unknown_names_fail():
    a = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], inputs="err", outputs="y", name="a")
    b = ct.ss(
        [[-2.0]],
        [
            [1.0],
        ],
        [[1.0]],
        [[0.0]],
        inputs="yy",
        outputs="z",
        name="b",
    )
    with pytest.raises(ModelStructureError, match="Unused input"):
        connect([a, b], inputs=["err"], outputs=["z"], name="typo")
    with pytest.raises(ModelStructureError, match="cannot connect"):
        connect([a], inputs=["nonexistent"], outputs=["y"], name="unknown")
    sys = connect([a, b], inputs=["err"], outputs=["y"], name="ok", ignore_inputs=["yy"])
    assert sys.nstates == 2


def test_a_junction_with_a_non_finite_gain_is_refused():
    with pytest.raises(ModelStructureError, match="gain of 'x'"):
        figure5_junctions(k_psf=float("nan"), handle_gain=1.0)


def test_feedthrough_cycles_are_found_in_any_pattern():
    rng = np.random.default_rng(3)
    for _ in range(500):
        z, v = (int(x) for x in rng.integers(1, 10, 2))
        D = (rng.random((z, v)) < 0.3) * rng.standard_normal((z, v))
        K = (rng.random((v, z)) < 0.3).astype(float)
        P = ((D != 0).astype(int) @ (K != 0).astype(int) > 0).astype(int)
        # a cycle of some length <= z: a nonzero diagonal in one of the first z powers
        power, cycle = P, False
        for _ in range(z):
            cycle |= bool(np.trace(power))
            power = (power @ P > 0).astype(int)
        assert wiring._feedthrough_cycle(D, K) is cycle
