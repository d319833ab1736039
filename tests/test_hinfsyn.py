"""LMI H-infinity synthesis: references, certificates, assumptions, multi-model design.

Reference comparisons use what python-control's Riccati ``hinfsyn`` (SLICOT
``sb10ad``) *achieves* in closed loop, recomputed here, not the gamma it reports.
"""

import control
import numpy as np
import pytest

from robust.analysis.norms import hinf_norm
from robust.analysis.stability import poles_stable, stability_bound
from robust.errors import AssumptionError, InfeasibleError, ModelStructureError
from robust.synthesis.genplant import GeneralizedPlant, as_generalized_plant
from robust.synthesis.lmi import PlantBlocks
from robust.synthesis.multi import hinfsyn_multi
from robust.synthesis.nominal import LMISynthesisProblem, hinfsyn_lmi
from robust.synthesis.testing import (
    dgkf_scalar_gamma_opt,
    dgkf_scalar_plant,
    random_generalized_plant,
)


def _check_certificate(gp, res):
    """Closed-loop poles and two independent norms against the returned numbers."""
    cl = gp.closed_loop(res.K)
    poles = control.poles(cl)
    assert poles_stable(poles), f"closed loop unstable: max Re = {poles.real.max()}"
    assert res.spectral_abscissa == pytest.approx(poles.real.max(), rel=1e-6, abs=1e-9)
    ref = hinf_norm(cl, method="slicot")
    assert res.gamma == pytest.approx(ref, rel=1e-6)
    assert hinf_norm(cl, method="grid") <= res.gamma_bound * (1 + 1e-6)
    assert res.gamma <= res.gamma_bound * (1 + 1e-6)
    # gamma_opt carries the strictness margin (about 1e-6 of scaled gamma), so it may sit a
    # hair above
    assert res.gamma_opt <= res.gamma * (1 + 1e-5)


# --------------------------------------------------------------------------- textbook values
@pytest.mark.parametrize("a", [0.0, 1.0, 2.0], ids=["a0", "a1", "a2"])
def test_dgkf_scalar_problem_optimal_gamma(a):
    # Doyle, Glover, Khargonekar & Francis (1989), Theorem 3 applied to the first-order
    # normalised problem (robust.synthesis.testing.dgkf_scalar_plant): gamma_opt solves X(g) = g;
    # for a = 0 it is sqrt(2) exactly.
    expected = np.sqrt(2.0) if a == 0.0 else dgkf_scalar_gamma_opt(a)
    P = dgkf_scalar_plant(a)
    res = hinfsyn_lmi(P, 1, 1)
    assert res.gamma_opt == pytest.approx(expected, rel=1e-5)
    assert res.gamma <= expected * (1 + 2 * res.backoff)
    _check_certificate(as_generalized_plant(P, 1, 1), res)


def test_dgkf_scalar_gamma_formula_at_zero():
    assert dgkf_scalar_gamma_opt(0.0) == pytest.approx(np.sqrt(2.0), rel=1e-12)


# --------------------------------------------------------------------------- against SLICOT
CASES = [(4, 0), (4, 1), (6, 2), (8, 0), (8, 3), (12, 1), (16, 0)]


def _compare_with_slicot(n, seed, **kw):
    P = random_generalized_plant(n, seed=seed, **kw)
    gp = as_generalized_plant(P, 2, 2)
    res = hinfsyn_lmi(P, 2, 2)
    _check_certificate(gp, res)
    K_ref, _, _, _ = control.hinfsyn(P, 2, 2)
    cl_ref = gp.closed_loop(K_ref)
    achieved_ref = hinf_norm(cl_ref)  # inf when SLICOT's loop is unstable
    # the LMI optimum bounds every stabilising controller's norm from below, up to the
    # accuracy of an interior-point optimum with strict-LMI margins (about 1e-5 relative here)
    assert res.gamma_opt <= achieved_ref * (1 + 1e-4)
    if np.isfinite(achieved_ref):
        assert res.gamma <= 1.01 * achieved_ref
    return res, achieved_ref


@pytest.mark.parametrize("n,seed", CASES, ids=[f"n{n}-seed{s}" for n, s in CASES])
def test_random_plants_against_slicot(n, seed):
    _compare_with_slicot(n, seed)


@pytest.mark.slow
@pytest.mark.parametrize("n,seed", [(24, 0)], ids=["n24-seed0"])
def test_random_plant_order_24_against_slicot(n, seed):
    _compare_with_slicot(n, seed)


def test_d11_and_d22_nonzero_against_slicot():
    res, _ = _compare_with_slicot(5, 11, d11=True, d22=True)
    assert res.condition["cond_I_D22Dk"] >= 1.0


def test_result_fields_and_generalized_plant_input():
    P = random_generalized_plant(5, seed=4)
    res = hinfsyn_lmi(P, 2, 2)
    assert res.solver == "CLARABEL"
    assert res.status in ("optimal", "optimal_inaccurate")
    assert res.iterations > 0 and res.solve_time > 0 and res.wall_time >= res.solve_time
    assert {"cond_X", "cond_Phi", "cond_LPL", "lmi_max_eig"} <= set(res.condition)
    assert 0 < res.backoff < 0.1
    assert res.K.ninputs == 2 and res.K.noutputs == 2
    # the first scaling attempt produced it, and its optimum passed the independent check
    assert res.scaling == "full" and res.gamma_opt_certified and res.notes == ()
    assert res.certificate["gamma_lmi"] == res.gamma_opt
    assert res.certificate["dual_bound"] <= res.gamma * (1 + 1e-9)
    gp = GeneralizedPlant.from_system(
        P, w=["w0", "w1", "w2", "w3"], u=["u0", "u1"], z=["z0", "z1", "z2", "z3"], y=["y0", "y1"]
    )
    res2 = hinfsyn_lmi(gp)
    assert res2.gamma_opt == pytest.approx(res.gamma_opt, rel=1e-6)
    assert list(res2.K.input_labels) == ["y0", "y1"]
    assert list(res2.K.output_labels) == ["u0", "u1"]


def test_compiled_problem_is_reused_across_gamma_levels():
    gp = as_generalized_plant(random_generalized_plant(4, seed=5), 2, 2)
    prob = LMISynthesisProblem(
        PlantBlocks(gp.A, gp.B1, gp.B2, gp.C1, gp.C2, gp.D11, gp.D12, gp.D21), margin=1e-6
    )
    prob.solve(gamma_floor=0.0)
    g_opt = float(prob.lmis.gamma.value)
    compiled = prob.problem._cache.param_prog
    assert compiled is not None
    for factor in (1.01, 1.1, 2.0):
        prob.solve(gamma_floor=factor * g_opt)
        assert prob.lmis.gamma.value == pytest.approx(factor * g_opt, rel=1e-6)
        assert prob.problem._cache.param_prog is compiled


# --------------------------------------------------------------------------- assumptions
def _plant(A, B1, B2, C1, C2, D11, D12, D21, dt=0):
    B = np.hstack([B1, B2])
    C = np.vstack([C1, C2])
    D = np.block([[D11, D12], [D21, np.zeros((C2.shape[0], B2.shape[1]))]])
    return control.ss(A, B, C, D, dt)


_OK = {
    "A": np.diag([1.0, -1.0]),
    "B1": np.array([[1.0, 0.0], [1.0, 0.0]]),
    "B2": np.array([[1.0], [1.0]]),
    "C1": np.array([[1.0, 1.0], [0.0, 0.0]]),
    "C2": np.array([[1.0, 1.0]]),
    "D11": np.zeros((2, 2)),
    "D12": np.array([[0.0], [1.0]]),
    "D21": np.array([[0.0, 1.0]]),
}


@pytest.mark.parametrize(
    "change,error,match",
    [
        ({"B2": np.array([[0.0], [1.0]])}, AssumptionError, r"\(A, B2\) is not stabilisable"),
        ({"C2": np.array([[0.0, 1.0]])}, AssumptionError, r"\(C2, A\) is not detectable"),
        ({"D12": np.zeros((2, 1))}, AssumptionError, "D12 must have full column rank"),
        ({"D21": np.zeros((1, 2))}, AssumptionError, "D21 must have full row rank"),
        ({"dt": 0.01}, ModelStructureError, "only continuous-time"),
    ],
    ids=["unstabilisable", "undetectable", "D12-rank", "D21-rank", "discrete"],
)
def test_assumption_failures(change, error, match):
    P = _plant(**dict(_OK, **change))
    with pytest.raises(error, match=match):
        hinfsyn_lmi(P, 1, 1)


def test_baseline_of_assumption_cases_is_solvable():
    res = hinfsyn_lmi(_plant(**_OK), 1, 1)
    assert res.spectral_abscissa < stability_bound()


def test_infeasible_gamma_max_names_the_condition():
    P = dgkf_scalar_plant(0.0)
    with pytest.raises(
        InfeasibleError, match=r"no controller achieves gamma <= gamma_max=1\.3.*coupling"
    ):
        hinfsyn_lmi(P, 1, 1, gamma_max=1.3)
    assert hinfsyn_lmi(P, 1, 1, gamma_max=1.5).gamma <= 1.5


# --------------------------------------------------------------------------- multi-model
def _spring_family(n_members, seed):
    """Mass-spring-damper members (stiffness, damping vary: A differs between members).

    w = [force disturbance, sensor noise], u = actuator force, z = [position, 0.1*u],
    y = position + 0.1*noise.
    """
    rng = np.random.default_rng(seed)
    members = []
    for _ in range(n_members):
        k, c = rng.uniform(0.5, 2.0), rng.uniform(0.05, 0.5)
        members.append(
            _plant(
                np.array([[0.0, 1.0], [-k, -c]]),
                np.array([[0.0, 0.0], [1.0, 0.0]]),
                np.array([[0.0], [1.0]]),
                np.array([[1.0, 0.0], [0.0, 0.0]]),
                np.array([[1.0, 0.0]]),
                np.zeros((2, 2)),
                np.array([[0.0], [0.1]]),
                np.array([[0.0, 0.1]]),
            )
        )
    return members


def test_multi_model_16_members_per_member_norms():
    plants = _spring_family(16, seed=0)
    res = hinfsyn_multi(plants, 1, 1)
    assert res.gammas.shape == (16,)
    gps = [as_generalized_plant(P, 1, 1) for P in plants]
    for i, gp in enumerate(gps):
        cl = gp.closed_loop(res.K)
        assert poles_stable(control.poles(cl)), f"member {i} unstable"
        assert res.gammas[i] == pytest.approx(hinf_norm(cl, method="slicot"), rel=1e-6)
        assert res.gammas[i] <= res.gamma_bound * (1 + 1e-6)
        # the Lyapunov certificate: P_i > 0 and the bounded-real matrix negative definite
        P = res.certificates[i]
        assert np.linalg.eigvalsh(P).min() > 0
        A, B, C, D = cl.A, cl.B, cl.C, cl.D
        g = res.gamma_bound
        M = np.block(
            [[A.T @ P + P @ A, P @ B, C.T], [B.T @ P, -g * np.eye(2), D.T], [C, D, -g * np.eye(2)]]
        )
        assert np.linalg.eigvalsh(M).max() < 0
    # iterations never make the worst member worse, and they improve on the initial design
    assert all(b <= a for a, b in zip(res.history, res.history[1:]))
    assert res.gamma <= res.history[0]
    # no single member's nominal optimum can beat the common controller's worst case
    assert res.gamma >= max(hinfsyn_lmi(gps[i]).gamma_opt for i in (0, 5)) * (1 - 1e-6)


def test_multi_model_input_errors():
    plants = _spring_family(2, seed=1)
    with pytest.raises(ModelStructureError, match="at least one member"):
        hinfsyn_multi([], 1, 1)
    other = random_generalized_plant(2, seed=0)
    with pytest.raises(ModelStructureError, match="same \\(nw, nu, nz, ny\\)"):
        hinfsyn_multi([as_generalized_plant(plants[0], 1, 1), as_generalized_plant(other, 2, 2)])
    with_d22 = as_generalized_plant(plants[1], 1, 1).with_blocks(D22=[[0.5]])
    with pytest.raises(AssumptionError, match="member 1: hinfsyn_multi requires D22 = 0"):
        hinfsyn_multi([as_generalized_plant(plants[0], 1, 1), with_d22])


def test_multi_model_with_no_iteration_certifies_the_given_controller():
    # max_iter = 0: the given static controller, certified member by member (the P-step's
    # level sits 2 % above each norm: LEVEL_SLACK) and re-checked here from scratch
    plants = [dgkf_scalar_plant(0.0), dgkf_scalar_plant(0.5)]
    K0 = control.ss([], [], [], [[-2.0]])
    res = hinfsyn_multi(plants, 1, 1, K0=K0, max_iter=0)
    np.testing.assert_array_equal(res.K.D, K0.D)
    g = res.gamma_bound
    norms = []
    for P, Pcert, gam in zip(plants, res.certificates, res.gammas):
        cl = as_generalized_plant(P, 1, 1).closed_loop(res.K)
        A, B, C, D = cl.A, cl.B, cl.C, cl.D
        M = np.block(
            [
                [A.T @ Pcert + Pcert @ A, Pcert @ B, C.T],
                [B.T @ Pcert, -g * np.eye(B.shape[1]), D.T],
                [C, D, -g * np.eye(C.shape[0])],
            ]
        )
        assert np.linalg.eigvalsh(Pcert).min() > 0
        assert np.linalg.eigvalsh(M).max() < 0
        norms.append(hinf_norm(cl, method="slicot"))
        assert gam == pytest.approx(norms[-1], rel=1e-6)
    assert max(norms) <= g <= 1.021 * max(norms)
    assert res.iterations == 0 and len(res.history) == 1


# --------------------------------------------------------------------------- solver wrapper
def test_scs_fallback_when_clarabel_fails(monkeypatch):
    import cvxpy as cp

    original = cp.Problem.solve

    def failing_clarabel(self, *args, **kwargs):
        if kwargs.get("solver") == "CLARABEL":
            raise cp.error.SolverError("simulated Clarabel failure")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(cp.Problem, "solve", failing_clarabel)
    P = dgkf_scalar_plant(0.0)
    res = hinfsyn_lmi(P, 1, 1)
    assert res.solver == "SCS"
    assert res.gamma_opt == pytest.approx(np.sqrt(2.0), rel=1e-4)
    _check_certificate(as_generalized_plant(P, 1, 1), res)


def test_no_usable_solver_raises_solver_error():
    import cvxpy as cp

    from robust.errors import ParameterError, SolverError

    # a name cvxpy does not know is bad input, refused before any work
    with pytest.raises(ParameterError, match=r"solvers: \['NOT_A_SOLVER'\] is not a solver"):
        hinfsyn_lmi(dgkf_scalar_plant(0.0), 1, 1, solvers=("NOT_A_SOLVER",))
    # a known SDP solver that is not installed here: every scaling attempt finds no solver
    missing = [s for s in ("MOSEK", "COPT", "SDPA", "CVXOPT") if s not in cp.installed_solvers()]
    if not missing:
        pytest.skip("every candidate SDP solver is installed")
    with pytest.raises(SolverError, match=r"no solver returned a usable answer.*not installed"):
        hinfsyn_lmi(dgkf_scalar_plant(0.0), 1, 1, solvers=(missing[0],))


def test_scherer_gahinet_chilali_example_against_slicot():
    # Plant of Scherer, Gahinet & Chilali (1997), IEEE TAC 42(7), Example 7 (p. 907), as
    # transcribed in dkpy.utilities.example_scherer1997_p907.  Reference: the norm SLICOT's
    # controller achieves, from
    #   K = control.hinfsyn(P, 1, 1)[0]
    #   robust.hinf_norm(GeneralizedPlant.from_counts(P, nmeas=1, ncon=1).closed_loop(K))
    # -> 9.50808550543373 (control 0.10.2, slycot sb10ad); the LMI optimum cannot be above it.
    A = np.array([[0.0, 10.0, 2.0], [-1.0, 1.0, 0.0], [0.0, 2.0, -5.0]])
    P = _plant(
        A,
        np.array([[1.0], [0.0], [1.0]]),
        np.array([[0.0], [1.0], [0.0]]),
        np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
        np.array([[0.0, 1.0, 0.0]]),
        np.zeros((2, 1)),
        np.array([[0.0], [1.0]]),
        np.array([[2.0]]),
    )
    res = hinfsyn_lmi(P, 1, 1)
    assert res.gamma_opt == pytest.approx(9.50808550543373, rel=1e-4)
    assert res.gamma <= 1.01 * 9.50808550543373
    _check_certificate(as_generalized_plant(P, 1, 1), res)


def test_unverified_controller_is_never_returned(monkeypatch):
    # replace the reconstruction by one that returns a zero controller: on this open-loop
    # unstable plant its loop is unstable, so every attempt must fail verification
    import robust.synthesis.nominal as nominal
    from robust.errors import VerificationError

    def zero_controller(blocks, R, S, gamma, **kw):
        n, _, nu, _, ny = blocks.sizes
        zeros = (np.zeros((n, n)), np.zeros((n, ny)), np.zeros((nu, n)), np.zeros((nu, ny)))
        return zeros, {
            "order": n,
            "cond_X": 1.0,
            "cond_Phi": 1.0,
            "cond_LPL": 1.0,
            "lmi_max_eig": 0.0,
            "mu": 1.0,
        }

    monkeypatch.setattr(nominal, "reconstruct_controller", zero_controller)
    with pytest.raises(
        VerificationError, match="no reconstructed controller passed.*closed loop unstable"
    ):
        hinfsyn_lmi(random_generalized_plant(3, seed=0), 2, 2)


def test_multi_model_members_of_different_order():
    # two spring members plus two with a first-order actuator lag (3 states): one controller
    base = _spring_family(4, seed=2)
    members = base[:2]
    for P in base[2:]:
        gp = as_generalized_plant(P, 1, 1)
        tau = 0.05  # s, actuator time constant
        A = np.block([[gp.A, gp.B2], [np.zeros((1, 2)), -np.eye(1) / tau]])
        B1 = np.vstack([gp.B1, np.zeros((1, 2))])
        B2 = np.vstack([np.zeros((2, 1)), np.eye(1) / tau])
        C1 = np.hstack([gp.C1, np.zeros((2, 1))])
        C2 = np.hstack([gp.C2, np.zeros((1, 1))])
        members.append(_plant(A, B1, B2, C1, C2, gp.D11, gp.D12, gp.D21))
    res = hinfsyn_multi(members, 1, 1, max_iter=3)
    assert [c.shape[0] for c in res.certificates] == [2 + res.K.nstates] * 2 + [
        3 + res.K.nstates
    ] * 2
    for P, g in zip(members, res.gammas):
        cl = as_generalized_plant(P, 1, 1).closed_loop(res.K)
        assert poles_stable(control.poles(cl))
        assert g == pytest.approx(hinf_norm(cl, method="slicot"), rel=1e-6)
        assert g <= res.gamma_bound * (1 + 1e-6)
