"""Bad input to the LMI synthesis never crashes: it raises a named error up front.

Each case calls :func:`robust.synthesis.nominal.hinfsyn_lmi`,
:func:`robust.synthesis.multi.hinfsyn_multi` or
:func:`robust.synthesis.solve.solve_problem` with one bad argument and checks the error
type and that the message names the culprit (and, where it helps, what was expected).
Options are validated before any assumption check or solve, so these cases are fast.
"""

import control
import cvxpy as cp
import numpy as np
import pytest

from robust.errors import ModelStructureError, ParameterError
from robust.synthesis.multi import hinfsyn_multi
from robust.synthesis.nominal import hinfsyn_lmi
from robust.synthesis.solve import check_solvers, solve_problem
from robust.synthesis.testing import dgkf_scalar_plant

# the DGKF first-order plant: inputs w1, w2, u; outputs z1, z2, y (nmeas = ncon = 1)
_A, _B = [[0.0]], [[1.0, 0.0, 1.0]]
_C, _D = [[1.0], [0.0], [1.0]], [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]


def _with(**blocks):
    """The DGKF plant with some of A, B, C, D replaced (entries may be NaN or inf)."""
    m = {"A": _A, "B": _B, "C": _C, "D": _D, **blocks}
    return control.ss(m["A"], m["B"], m["C"], m["D"])


def _B_with_inf():
    B = np.array(_B)
    B[0, 2] = np.inf
    return B


# (id, keyword arguments of hinfsyn_lmi beyond the plant, error, regex naming the culprit)
HINFSYN_OPTION_CASES = [
    ("solvers-empty", {"solvers": ()}, ParameterError, r"solvers must name at least one"),
    ("solvers-unknown", {"solvers": ("CLARABLE",)}, ParameterError, r"\['CLARABLE'\] is not a"),
    ("solvers-bare-string", {"solvers": "CLARABEL"}, ParameterError, r"solvers .*got the string"),
    ("solvers-not-sdp", {"solvers": ("OSQP",)}, ParameterError, r"'OSQP'.*semidefinite"),
    ("solvers-not-str", {"solvers": (None,)}, ParameterError, r"solvers must contain solver"),
    ("solvers-number", {"solvers": 5}, ParameterError, r"solvers must be a sequence.*got 5"),
    ("gamma_max-str", {"gamma_max": "big"}, ParameterError, r"gamma_max must be a real number"),
    ("gamma_max-nan", {"gamma_max": float("nan")}, ParameterError, r"gamma_max must be .*nan"),
    ("gamma_max-inf", {"gamma_max": float("inf")}, ParameterError, r"gamma_max must be .*inf"),
    ("gamma_max-negative", {"gamma_max": -1.0}, ParameterError, r"gamma_max .*\(0, inf\].*-1"),
    ("gamma_max-bool", {"gamma_max": True}, ParameterError, r"gamma_max must be a real number"),
    ("backoff-nan", {"backoff": float("nan")}, ParameterError, r"backoff .*\(0, 1\); got nan"),
    ("backoff-one", {"backoff": 1.0}, ParameterError, r"backoff .*\(0, 1\); got 1"),
    ("backoff-zero", {"backoff": 0}, ParameterError, r"backoff .*\(0, 1\); got 0"),
    ("backoff-list", {"backoff": [0.1]}, ParameterError, r"backoff must be a real number"),
    ("verify_rtol-inf", {"verify_rtol": np.inf}, ParameterError, r"verify_rtol .*got inf"),
    ("verify_rtol-negative", {"verify_rtol": -1e-6}, ParameterError, r"verify_rtol .*-1e-06"),
    ("verify_rtol-none", {"verify_rtol": None}, ParameterError, r"verify_rtol must be a real"),
    ("scale-str", {"scale": "yes"}, ParameterError, r"scale must be True or False"),
    ("verbose-int", {"verbose": 1}, ParameterError, r"verbose must be True or False"),
]


@pytest.mark.parametrize(
    "kwargs,error,match",
    [c[1:] for c in HINFSYN_OPTION_CASES],
    ids=[c[0] for c in HINFSYN_OPTION_CASES],
)
def test_hinfsyn_lmi_bad_options(kwargs, error, match):
    with pytest.raises(error, match=match):
        hinfsyn_lmi(dgkf_scalar_plant(0.0), 1, 1, **kwargs)


# (id, plant factory, nmeas, ncon, error, regex)
HINFSYN_PLANT_CASES = [
    ("A-nan", lambda: _with(A=[[np.nan]]), 1, 1, ModelStructureError, r"sys\.A contains 1 non"),
    ("B-inf", lambda: _with(B=_B_with_inf()), 1, 1, ModelStructureError, r"sys\.B contains 1"),
    (
        "D-nan",
        lambda: _with(D=np.where(np.eye(3) > 0, np.nan, _D)),
        1,
        1,
        ModelStructureError,
        r"sys\.D contains 3 non-finite",
    ),
    (
        "tf-nan",
        lambda: control.tf([[[np.nan, 1.0]]], [[[1.0, 1.0]]]),
        1,
        1,
        ModelStructureError,
        r"P: the transfer function's num contains non-finite",
    ),
    ("P-str", lambda: "plant", 1, 1, ModelStructureError, r"P must be a control\.StateSpace"),
    ("P-none", lambda: None, 1, 1, ModelStructureError, r"P must be .*got NoneType"),
    (
        "P-static",
        lambda: control.ss([], [], [], _D),
        1,
        1,
        ModelStructureError,
        r"P must have at least one state",
    ),
    ("nmeas-zero", lambda: _with(), 0, 1, ModelStructureError, r"nmeas must be an integer"),
    ("nmeas-float", lambda: _with(), 1.5, 1, ModelStructureError, r"nmeas .*got 1\.5"),
    ("ncon-bool", lambda: _with(), 1, True, ModelStructureError, r"ncon .*got True"),
    ("ncon-missing", lambda: _with(), 1, None, ModelStructureError, r"nmeas and ncon are req"),
    (
        "discrete",
        lambda: control.c2d(_with(), 0.1),
        1,
        1,
        ModelStructureError,
        r"only continuous-time plants.*dt=0\.1",
    ),
]


@pytest.mark.parametrize(
    "factory,nmeas,ncon,error,match",
    [c[1:] for c in HINFSYN_PLANT_CASES],
    ids=[c[0] for c in HINFSYN_PLANT_CASES],
)
def test_hinfsyn_lmi_bad_plants(factory, nmeas, ncon, error, match):
    with pytest.raises(error, match=match):
        hinfsyn_lmi(factory(), nmeas, ncon)


def _k(A, B, C, D, dt=0):
    return control.ss(A, B, C, D, dt)


# (id, plants factory, keyword arguments, error, regex)
MULTI_CASES = [
    ("solvers-empty", None, {"solvers": []}, ParameterError, r"hinfsyn_multi: solvers must name"),
    ("max_iter-float", None, {"max_iter": 2.5}, ParameterError, r"max_iter .*got 2\.5"),
    ("max_iter-bool", None, {"max_iter": True}, ParameterError, r"max_iter .*got True"),
    ("max_iter-negative", None, {"max_iter": -1}, ParameterError, r"max_iter .*got -1"),
    ("rtol-nan", None, {"rtol": float("nan")}, ParameterError, r"rtol must be .*nan"),
    ("rtol-one", None, {"rtol": 1.0}, ParameterError, r"rtol must be .*\[0, 1\)"),
    ("trust-negative", None, {"trust": -0.5}, ParameterError, r"trust must be .*-0\.5"),
    ("trust-inf", None, {"trust": np.inf}, ParameterError, r"trust must be .*inf"),
    ("verify_rtol-str", None, {"verify_rtol": "a"}, ParameterError, r"verify_rtol must be a real"),
    ("verbose-str", None, {"verbose": "no"}, ParameterError, r"verbose must be True or False"),
    (
        "plants-single-system",
        lambda: _with(),
        {},
        ModelStructureError,
        r"plants must be a sequence .*single StateSpace",
    ),
    ("plants-none", lambda: None, {}, ModelStructureError, r"plants must be a sequence"),
    ("plants-empty", lambda: [], {}, ModelStructureError, r"at least one member"),
    (
        "member-nan",
        lambda: [_with(), _with(A=[[np.nan]])],
        {},
        ModelStructureError,
        r"sys\.A contains 1 non-finite",
    ),
    ("K0-str", None, {"K0": "K"}, ParameterError, r"K0 must be a control\.StateSpace"),
    (
        "K0-nan",
        None,
        {"K0": _k([[np.nan]], [[1.0]], [[1.0]], [[0.0]])},
        ParameterError,
        r"K0\.A must be finite",
    ),
    (
        "K0-size",
        None,
        {"K0": _k(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0)), np.zeros((2, 2)))},
        ModelStructureError,
        r"K0 must have 1 input\(s\) \(y\) and 1 output\(s\) \(u\); got 2 and 2",
    ),
    (
        "K0-discrete",
        None,
        {"K0": _k([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1)},
        ModelStructureError,
        r"K0 must be a continuous-time controller; got dt=0\.1",
    ),
]


@pytest.mark.parametrize(
    "factory,kwargs,error,match",
    [c[1:] for c in MULTI_CASES],
    ids=[c[0] for c in MULTI_CASES],
)
def test_hinfsyn_multi_bad_input(factory, kwargs, error, match):
    plants = [_with(), _with(A=[[0.5]])] if factory is None else factory()
    with pytest.raises(error, match=match):
        hinfsyn_multi(plants, 1, 1, **kwargs)


def _lp():
    x = cp.Variable()
    return cp.Problem(cp.Minimize(x), [x >= 1])


# (id, keyword arguments of solve_problem, error, regex)
SOLVE_CASES = [
    ("problem-none", {"problem": None}, ParameterError, r"problem must be a cvxpy\.Problem"),
    ("step-not-str", {"step": 3}, ParameterError, r"step must be a str"),
    ("gap_tol-negative", {"gap_tol": -1.0}, ParameterError, r"gap_tol must be .*got -1"),
    ("gap_tol-nan", {"gap_tol": float("nan")}, ParameterError, r"gap_tol must be .*nan"),
    ("solvers-empty", {"solvers": ()}, ParameterError, r"test: solvers must name at least one"),
    ("solvers-unknown", {"solvers": ("FOO",)}, ParameterError, r"\['FOO'\] is not a solver"),
    ("verbose-none", {"verbose": None}, ParameterError, r"verbose must be a bool"),
    ("refine-str", {"refine": "yes"}, ParameterError, r"test: refine must be a bool; got 'yes'"),
]


@pytest.mark.parametrize(
    "kwargs,error,match", [c[1:] for c in SOLVE_CASES], ids=[c[0] for c in SOLVE_CASES]
)
def test_solve_problem_bad_input(kwargs, error, match):
    args = {"problem": _lp(), "step": "test", **kwargs}
    problem = args.pop("problem")
    with pytest.raises(error, match=match):
        solve_problem(problem, **args)


def test_check_solvers_normalises_names():
    assert check_solvers(["clarabel", "SCS", "CLARABEL"], sdp=True) == ("CLARABEL", "SCS")
    # a solver cvxpy knows but that is not installed is accepted here (solve_problem skips it)
    assert check_solvers(("MOSEK",), sdp=True) == ("MOSEK",)


def test_good_options_still_solve():
    # the validation accepts numpy scalars and lower-case solver names
    res = hinfsyn_lmi(
        dgkf_scalar_plant(0.0), 1, 1, backoff=np.float32(0.01), solvers=["clarabel", "scs"]
    )
    assert res.solver == "CLARABEL"
    assert res.gamma_opt == pytest.approx(np.sqrt(2.0), rel=1e-5)
