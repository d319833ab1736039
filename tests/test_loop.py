import control as ct
import numpy as np
import paper_formulas as pf
import pytest

from backhoe import DEFAULT_CALIBRATION, BDFTLoop, LoopCalibration
from robust import ModelStructureError, ParameterError, minimal_realization

FREQS_HZ = np.array([0.1, 0.5, 1.0, 2.0, 6.0, 6.4, 15.0])
CAL = DEFAULT_CALIBRATION


def y_over_u(sys, f_hz):
    resp = np.asarray(sys(2j * np.pi * f_hz, squeeze=False))
    return resp[sys.output_labels.index("y"), sys.input_labels.index("u")]


@pytest.mark.parametrize("k_psf", [0.1097, 0.055, 0.01097], ids=["nominal", "x2", "x10"])
@pytest.mark.parametrize("bdft", [True, False], ids=["bdft", "no-bdft"])
def test_loop_matches_hand_built_feedback_formula(k_psf, bdft):
    loop = BDFTLoop(k_psf=k_psf)
    got = y_over_u(loop.system(bdft=bdft), FREQS_HZ)
    want = pf.loop_u_to_y(
        2j * np.pi * FREQS_HZ, k_psf, CAL.kp, CAL.ki, CAL.loop_scale, CAL.handle_sign, bdft=bdft
    )
    np.testing.assert_allclose(got, want, rtol=1e-7)


def test_loop_signals_and_order():
    sys = BDFTLoop().system()
    assert sys.input_labels == ["u"]
    assert sys.output_labels == ["y", "c", "h", "x", "e"]
    assert sys.nstates == 1 + 4 + 4 + 4  # PI + valve/cylinder + structure + human


def test_sign_flips_the_bdft_path():
    pos = LoopCalibration(kp=CAL.kp, ki=CAL.ki, loop_scale=CAL.loop_scale, handle_sign=+1)
    got = y_over_u(BDFTLoop(calibration=pos).system(), FREQS_HZ)
    want = pf.loop_u_to_y(2j * np.pi * FREQS_HZ, 0.1097, CAL.kp, CAL.ki, CAL.loop_scale, +1)
    np.testing.assert_allclose(got, want, rtol=1e-7)


def test_reference_correction_controller_enters_cylinder_reference():
    # a static controller r_corr = g*c: the loop gain of the BDFT path changes by a known amount
    g = 1e-5
    K = ct.ss([], [], [], [[g]], inputs="c", outputs="r_corr", name="K")
    sys = BDFTLoop().system(controller=K)
    s = 2j * np.pi * FREQS_HZ
    L = pf.pi(s, CAL.kp, CAL.ki) * pf.valve(s)
    t_in = L / (1 + L)
    k = 0.1097
    # y = T (k x + g c), x = u + sigma*kappa*H c, c = S y
    S, H = pf.structure(s), pf.human(s)
    want = k * t_in / (1 - t_in * S * (k * CAL.handle_sign * CAL.loop_scale * H + g))
    np.testing.assert_allclose(y_over_u(sys, FREQS_HZ), want, rtol=1e-7)
    assert "r_corr" in sys.output_labels


def test_force_controller_needs_force_port():
    K = ct.ss([], [], [], [[1.0]], inputs="x", outputs="f", name="K")
    with pytest.raises(ModelStructureError, match="no force port"):
        BDFTLoop().system(controller=K)


@pytest.mark.parametrize(
    "K,match",
    [
        (ct.ss([], [], [], [[1.0]], inputs="h", outputs="r_corr"), r"inputs must be among"),
        (
            ct.ss([], [], [], [[1.0]], inputs="x", outputs="valve"),
            r"outputs among .*got inputs .*outputs \[.valve.\]",
        ),
        (
            ct.ss([[0.5]], [[1]], [[1]], [[0]], dt=0.001, inputs="x", outputs="r_corr"),
            r"continuous-time",
        ),
    ],
    ids=["bad-input", "bad-output", "discrete"],
)
def test_bad_controller_is_refused(K, match):
    with pytest.raises(ModelStructureError, match=match):
        BDFTLoop().system(controller=K)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"handle_sign": 0}, r"handle_sign must be \+1 or -1; got 0"),
        ({"loop_scale": -1e-4}, r"LoopCalibration\.loop_scale .*-0\.0001"),
        ({"kp": float("nan")}, r"LoopCalibration\.kp .*nan"),
    ],
    ids=["sign", "scale", "kp"],
)
def test_bad_calibration(kwargs, match):
    base = dict(kp=0.3, ki=0.3, loop_scale=1e-4, handle_sign=-1)
    with pytest.raises(ParameterError, match=match):
        LoopCalibration(**(base | kwargs))


def test_bad_loop_parameters():
    with pytest.raises(ParameterError, match=r"BDFTLoop\.k_psf .*-0\.1"):
        BDFTLoop(k_psf=-0.1)
    with pytest.raises(ParameterError, match=r"BDFTLoop\.human must implement"):
        BDFTLoop(human="literal")
    with pytest.raises(ParameterError, match=r"factor .*0"):
        BDFTLoop().with_workspace_factor(0)


def _planted(rng, n_min, n_unc, n_unobs):
    """Random system with n_unc uncontrollable and n_unobs unobservable modes planted."""
    n = n_min + n_unc + n_unobs
    A = np.zeros((n, n))
    A[:n_min, :n_min] = rng.normal(size=(n_min, n_min)) - 3 * np.eye(n_min)
    A[n_min:, n_min:] = np.diag(-rng.uniform(0.5, 5, n_unc + n_unobs))
    A[:n_min, n_min:] = rng.normal(
        size=(n_min, n_unc + n_unobs)
    )  # couplings that keep the modes hidden
    B = np.zeros((n, 2))
    B[:n_min] = rng.normal(size=(n_min, 2))
    B[n_min + n_unc :] = rng.normal(size=(n_unobs, 2))
    C = np.zeros((2, n))
    C[:, :n_min] = rng.normal(size=(2, n_min))
    # the unobservable block must not be seen: it must also not feed the observable part
    A[:n_min, n_min + n_unc :] = 0.0
    A[n_min : n_min + n_unc, :] = np.hstack(
        [np.zeros((n_unc, n_min)), A[n_min : n_min + n_unc, n_min:]]
    )
    T = np.linalg.qr(rng.normal(size=(n, n)))[0]
    return T @ A @ T.T, T @ B, C @ T.T, rng.normal(size=(2, 2))


@pytest.mark.parametrize("seed", range(5))
def test_minimal_realization_against_slycot_minreal(seed):
    rng = np.random.default_rng(seed)
    A, B, C, D = _planted(rng, 5, 2, 1)
    m = minimal_realization(A, B, C, D)
    assert m.nstates == 5
    assert m.n_uncontrollable + m.n_unobservable == 3
    ref = ct.minreal(ct.ss(A, B, C, D), tol=1e-8, verbose=False)  # SLICOT tb01pd
    assert ref.nstates == 5
    np.testing.assert_allclose(
        np.sort_complex(np.linalg.eigvals(m.A)), np.sort_complex(ref.poles()), rtol=1e-7, atol=1e-9
    )
    # transfer functions equal at test points
    s = np.array([0.3j, 1 + 2j, 7j])
    for sk in s:
        g_full = C @ np.linalg.solve(sk * np.eye(len(A)) - A, B) + D
        g_min = m.C @ np.linalg.solve(sk * np.eye(m.nstates) - m.A, m.B) + m.D
        np.testing.assert_allclose(g_min, g_full, rtol=1e-8, atol=1e-10)


def test_literal_loop_has_two_hidden_modes_at_origin():
    sys = BDFTLoop().system()
    m = minimal_realization(sys.A, sys.B, sys.C, sys.D)
    assert m.n_uncontrollable == 2 and m.n_unobservable == 0
    assert np.all(np.abs(m.removed_eigenvalues) < 1e-4)


def test_blocks_shared_read_only_and_the_same_loop_as_fresh_blocks():
    # a loop's blocks (all but the controller) are one system per parameter set, read-only;
    # the loop assembled from them is exactly the one from freshly built blocks
    from backhoe import default_family
    from backhoe.model.components import pi_controller, structure, valve_cylinder
    from backhoe.model.wiring import connect

    fam = default_family()
    row = fam.nominal_values()
    a, b = fam.member(row), fam.member(row)
    ba, bb = a.blocks(), b.blocks()
    assert all(x is y for x, y in zip(ba, bb))
    with pytest.raises(ValueError, match="read-only"):
        ba[2].A[0, 0] = 1.0
    fresh = [
        pi_controller(a.calibration.pi),
        valve_cylinder(a.valve),
        structure(a.struct),
        a.human.system(),
    ]
    assert fresh[2] is not ba[2] and fresh[2].A.flags.writeable
    kw = dict(inputs=["u", "f_ext"], outputs=["y", "c", "h", "x", "e"], name="bdft_loop")
    got = a.system()
    want = connect(fresh[:4] + [j.system() for j in a.junctions(force_terms=("f_ext",))], **kw)
    for m in "ABCD":
        np.testing.assert_array_equal(getattr(got, m), getattr(want, m))
    # another member's structure is another block
    other = fam.member(np.where(np.array(fam.names) == "struct.f1_hz", row * 0.9, row))
    assert other.blocks()[2] is not ba[2]


@pytest.mark.parametrize("k_psf", [0.1097, 0.055], ids=["nominal", "x2"])
def test_frequency_response_equals_the_hand_built_formula_and_slicot(k_psf):
    # frequency_response's stacked solve against the paper's feedback formula (independent of
    # any realisation) and against python-control's SLICOT evaluation, through the loop's
    # lightly damped structure modes (6.3 and 6.5 Hz) where the resolvent is worst conditioned
    from robust.analysis.loops import frequency_response

    sys = BDFTLoop(k_psf=k_psf).system(bdft=True)
    f = np.concatenate([FREQS_HZ, np.linspace(6.0, 6.8, 41)])
    got = frequency_response(sys, f)
    want = pf.loop_u_to_y(
        2j * np.pi * f, k_psf, CAL.kp, CAL.ki, CAL.loop_scale, CAL.handle_sign, bdft=True
    )
    # measured: 1.3e-11 at 0.1 Hz (the response cancels to 1e-3 of its terms there), below
    # 1e-13 at the modes; SLICOT's evaluation is 6e-11 and 5e-13 from the formula
    np.testing.assert_allclose(got, want, rtol=1e-10)
    np.testing.assert_allclose(got, y_over_u(sys, f), rtol=1e-9)
    # another channel: the handle's position to the cylinder
    i, o = sys.input_labels.index("u"), sys.output_labels.index("x")
    ref = np.asarray(sys(2j * np.pi * f, squeeze=False))[o, i]
    np.testing.assert_allclose(frequency_response(sys, f, out="x"), ref, rtol=1e-9)
