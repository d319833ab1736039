"""Bad input at the public API: a named error from robust.errors, never a crash or a wrong answer.

Every case calls one public function with one bad argument and asserts the error class and
that the message names the culprit (the parameter, the member row, the matrix or the
signal). The positive tests check the escape hatches (``check_bounds=False``), that a bad
member costs no work and that the sampling limit holds at its boundary.
"""

import types

import control as ct
import numpy as np
import pytest

from backhoe import (
    Family,
    batched_poles,
    closed_loop_matrices,
    default_family,
    family_nominals,
    member_metrics,
)
from backhoe.analysis.calibration import calibrate
from backhoe.analysis.claims import ratio_study
from backhoe.analysis.loops import critical_k_psf
from backhoe.analysis.simulation import simulate
from backhoe.families.batched import loop_blocks
from backhoe.families.sweeps import structure_frequency_sweep, workspace_sweep
from backhoe.model.anthropometry import segment_masses
from backhoe.model.human import human_variant
from backhoe.model.loop import BDFTLoop
from backhoe.model.modal import modal_to_physical
from backhoe.model.physical import physical_human_matrices
from backhoe.sysid.experiment import simulate_response
from backhoe.sysid.fit import coherence_threshold
from backhoe.sysid.model_file import save_component_fit
from bdft import main
from robust.analysis.loops import frequency_response
from robust.analysis.norms import hinf_norm, is_stable, sigma_max
from robust.analysis.realization import minimal_realization
from robust.analysis.reduction import balanced_truncation
from robust.analysis.stability import stability_bound
from robust.errors import DataError, ModelStructureError, ParameterError
from robust.sysid.linear import levy_sk
from uncertainty import SampleSet, UncertainParameter, sample, validate_family
from uncertainty import sampling as sampling_module

PHYS = default_family("physical")
LIT = default_family("literal")
NAMES = PHYS.names
NOMINAL = PHYS.nominal_values()
LOOP = BDFTLoop()
SYS = ct.ss([[-1.0, 2.0], [0.0, -3.0]], [[1.0], [1.0]], [[1.0, 0.0]], [[0.1]])


def rows(n=5, **changes):
    """``n`` nominal members of the physical family, with ``{(row, name): value}`` changes."""
    v = np.tile(NOMINAL, (n, 1))
    for key, value in changes.items():
        row, name = key.split("__")
        v[int(row[1:]), NAMES.index(name.replace("_dot_", "."))] = value
    return v


def samples_of(values, family=PHYS):
    return SampleSet(family.names, values, "mc", 0, len(values))


def lit_rows(**changes):
    v = LIT.nominal_values()[None].copy()
    for name, value in changes.items():
        v[0, LIT.names.index(name.replace("_dot_", "."))] = value
    return v


class _SS:
    """A duck-typed state-space system (python-control refuses NaN or bad shapes itself)."""

    def __init__(self, A, B, C, D, dt=0):
        self.A, self.B, self.C, self.D, self.dt = A, B, C, D, dt

    def isctime(self):
        return self.dt == 0


T = np.arange(200) / 1000.0
U = np.sin(2 * np.pi * 3.0 * T)


def _with(arr, i, value):
    out = np.array(arr, float)
    out[i] = value
    return out


# -- family members ---------------------------------------------------------------------------
MEMBER_CASES = [
    (
        "validate-negative-arm-mass",
        lambda: validate_family(PHYS, samples_of(rows(r3__human_dot_m_arm=-1.0))),
        r"validate_family: member row 3: human\.m_arm must be a finite value in \(0, inf\]; "
        r"got -1\.0",
    ),
    (
        "validate-nan-arm-frequency",
        lambda: validate_family(PHYS, samples_of(rows(r1__human_dot_f_arm_hz=np.nan))),
        r"member row 1: human\.f_arm_hz must be a finite value .*got nan",
    ),
    (
        "validate-negative-trunk-damping",
        lambda: validate_family(PHYS, samples_of(rows(r4__human_dot_zeta_trunk=-0.2))),
        r"member row 4: human\.zeta_trunk .*got -0\.2",
    ),
    (
        "validate-outside-family-bounds",
        lambda: validate_family(PHYS, samples_of(rows(r0__struct_dot_f1_hz=20.0))),
        r"member row 0: struct\.f1_hz must be a finite value in \[2\.52, 6\.3\]; got 20\.0 "
        r"\(the bounds of family 'default-physical'; pass check_bounds=False",
    ),
    (
        "validate-unbounded-still-physical",
        lambda: validate_family(
            PHYS, samples_of(rows(r2__struct_dot_k_s=-200.0)), check_bounds=False
        ),
        r"member row 2: struct\.k_s must be a finite value in \(0, inf\]; got -200\.0",
    ),
    (
        "validate-zero-frequency-unbounded",
        lambda: validate_family(
            PHYS, samples_of(rows(r1__struct_dot_f2_hz=0.0)), check_bounds=False
        ),
        r"member row 1: struct\.f2_hz .*got 0\.0",
    ),
    (
        "validate-samples-not-a-sampleset",
        lambda: validate_family(PHYS, rows()),
        r"validate_family: samples must be an uncertainty\.SampleSet; got ndarray",
    ),
    (
        "validate-nan-threshold",
        lambda: validate_family(PHYS, samples_of(rows()), stability_threshold=float("nan")),
        r"validate_family: stability_threshold must be a finite value; got nan",
    ),
    (
        "validate-progress-not-callable",
        lambda: validate_family(PHYS, samples_of(rows()), progress=3),
        r"validate_family\.progress must be callable or None; got int",
    ),
    (
        "closed-loop-inf-damping",
        lambda: closed_loop_matrices(PHYS, rows(r2__struct_dot_zeta1=np.inf)),
        r"closed_loop_matrices: member row 2: struct\.zeta1 .*got inf",
    ),
    (
        "closed-loop-wrong-shape",
        lambda: closed_loop_matrices(PHYS, rows()[:, :-1]),
        rf"closed_loop_matrices: member must have shape \(N, {len(NAMES)}\) .*"
        rf"got \(5, {len(NAMES) - 1}\)",
    ),
    (
        "closed-loop-not-numeric",
        lambda: closed_loop_matrices(PHYS, [["a"] * len(NAMES)]),
        r"closed_loop_matrices: member must be numeric",
    ),
    (
        "member-metrics-zero-body-mass",
        lambda: member_metrics(PHYS, rows(r0__human_dot_body_mass=0.0)),
        r"member_metrics: member row 0: human\.body_mass must be a finite value in \(0, inf\]",
    ),
    (
        "member-metrics-zero-chunk",
        lambda: member_metrics(PHYS, rows(), chunk=0),
        r"member_metrics: chunk must be an integer in \[1, inf\]; got 0",
    ),
    (
        "member-metrics-inverted-band",
        lambda: member_metrics(PHYS, rows(), band_hz=(5.0, 2.0)),
        r"member_metrics: band_hz must satisfy 0 <= low < high; got \(5\.0, 2\.0\)",
    ),
    (
        "member-metrics-nan-band",
        lambda: member_metrics(PHYS, rows(), band_hz=(np.nan, 2.0)),
        r"member_metrics: band_hz\[0\] must be a finite value; got nan",
    ),
    (
        "member-negative-arm-damping",
        lambda: PHYS.member({"human.zeta_arm": -0.1}),
        r"Family\.member: member row 0: human\.zeta_arm must be a finite value in \(0, inf\]",
    ),
    (
        "member-wrong-length",
        lambda: PHYS.member([1.0, 2.0]),
        rf"Family\.member: values must have {len(NAMES)} entries .*got 2",
    ),
    (
        "model-arrays-negative-literal-gain",
        lambda: LIT.model_arrays(lit_rows(human_dot_k_h=-5.0)),
        r"Family\.model_arrays: member row 0: human\.k_h must be .*got -5\.0",
    ),
    (
        "batched-poles-zero-literal-pole",
        lambda: batched_poles(LIT, lit_rows(human_dot_p1=0.0), check_bounds=False),
        r"closed_loop_matrices: member row 0: human\.p1 .*got 0\.0",
    ),
    (
        "loop-blocks-negative-frequency",
        lambda: loop_blocks(PHYS, rows(r1__struct_dot_f2_hz=-6.5)),
        r"loop_blocks: member row 1: struct\.f2_hz .*got -6\.5",
    ),
    (
        "family-non-physical-bounds",
        lambda: Family(parameters=(UncertainParameter("struct.k_s", 1.0, -1.0, 2.0),)),
        r"Family: parameter 'struct\.k_s' low=-1\.0 is not physical",
    ),
    (
        "sweep-not-a-family",
        lambda: workspace_sweep("default", members=4),
        r"family must be a backhoe\.Family; got str",
    ),
    (
        "sweep-negative-scale",
        lambda: structure_frequency_sweep(PHYS, scales=[0.5, -1.0], members=4),
        r"scales must be a non-empty 1-D array of positive numbers",
    ),
    (
        "family-nominals-not-a-fit",
        lambda: family_nominals([object()], human="physical"),
        r"family_nominals: fits\[0\] must be a component fit",
    ),
    (
        "family-nominals-unknown-human",
        lambda: family_nominals([], human="robot"),
        r"family_nominals: human must be one of \('physical', 'literal'\); got 'robot'",
    ),
]

# -- sampling -------------------------------------------------------------------------------
SAMPLING_CASES = [
    (
        "sample-trillion-mc",
        lambda: sample(PHYS.parameters, 10**12, method="mc"),
        rf"sample: n=1000000000000 asks for 1000000000000 members of {len(NAMES)} parameters.*"
        r"MAX_SAMPLE_BYTES",
    ),
    (
        "sample-trillion-grid",
        lambda: sample(PHYS.parameters, 10**12, method="grid"),
        # k points per axis, k**d <= n < (k + 1)**d
        rf"sample: n=1000000000000 asks for \d+ members "
        rf"\({max(k for k in range(1, 100) if k ** len(NAMES) <= 10**12)}\*\*{len(NAMES)} "
        r"grid points\)",
    ),
    (
        "sample-float-n",
        lambda: sample(PHYS.parameters, 10.0),
        r"sample: n must be a positive integer; got 10\.0",
    ),
    (
        "sample-one-parameter-not-a-sequence",
        lambda: sample(PHYS.parameters[0], 10),
        r"sample: parameters must be a sequence of UncertainParameter",
    ),
    (
        "ppf-quantile-above-one",
        lambda: PHYS.parameter("struct.k_s").ppf([0.5, 1.5]),
        r"UncertainParameter 'struct\.k_s': ppf quantile u\[1\] must be a finite value in "
        r"\[0, 1\]; got 1\.5",
    ),
]

# -- analysis ---------------------------------------------------------------------------------
ANALYSIS_CASES = [
    (
        "simulate-nan-input",
        DataError,
        lambda: simulate(LOOP, T, _with(U, 5, np.nan)),
        r"simulate: input signal u\[5\] must be a finite value; got nan",
    ),
    (
        "simulate-inf-time",
        DataError,
        lambda: simulate(LOOP, _with(T, 7, np.inf), U),
        r"simulate: time vector t\[7\] must be a finite value; got inf",
    ),
    (
        "simulate-time-not-increasing",
        DataError,
        lambda: simulate(LOOP, T[::-1], U),
        r"simulate: time vector t must be strictly increasing",
    ),
    (
        "simulate-time-unequal-steps",
        DataError,
        lambda: simulate(LOOP, T**1.5, U),
        r"simulate: time vector t must be equally spaced",
    ),
    (
        "simulate-length-mismatch",
        DataError,
        lambda: simulate(LOOP, T, U[:-1]),
        r"simulate: input signal u must have one sample per time in t \(200\); got 199",
    ),
    (
        "hinf-nan-in-A",
        ModelStructureError,
        lambda: hinf_norm(_SS([[-1.0, np.nan], [0.0, -2.0]], [[1.0], [0.0]], [[1.0, 1.0]], [[0]])),
        r"sys\.A contains 1 non-finite entries",
    ),
    (
        "hinf-inf-in-D",
        ModelStructureError,
        lambda: hinf_norm(_SS([[-1.0]], [[1.0]], [[1.0]], [[np.inf]])),
        r"sys\.D contains 1 non-finite entries",
    ),
    (
        "hinf-nonconformal-B",
        ModelStructureError,
        lambda: hinf_norm(_SS([[-1.0, 0.0], [0.0, -2.0]], [[1.0]], [[1.0, 1.0]], [[0.0]])),
        r"sys: with A 2x2 and D 1x1, B must be 2x1 and C 1x2; got B 1x1",
    ),
    (
        "hinf-rtol-not-a-number",
        ParameterError,
        lambda: hinf_norm(SYS, rtol="tight"),
        r"hinf_norm: rtol must be a real number; got 'tight'",
    ),
    (
        "sigma-max-nan-frequency",
        ParameterError,
        lambda: sigma_max(SYS, [1.0, np.nan]),
        r"sigma_max: omega\[1\] must be a finite value; got nan",
    ),
    (
        "is-stable-negative-margin",
        ParameterError,
        lambda: is_stable(SYS, margin=-1.0),
        r"margin must be a finite value in \[0, inf\]; got -1\.0",
    ),
    (
        "stability-bound-nan-margin",
        ParameterError,
        lambda: stability_bound(float("nan")),
        r"margin must be a finite value in \[0, inf\]; got nan",
    ),
    (
        "calibrate-junction-sign-zero",
        ParameterError,
        lambda: calibrate(signs=(0,)),
        r"calibrate: junction sign signs\[0\] must be \+1 or -1; got 0",
    ),
    (
        "calibrate-junction-sign-two",
        ParameterError,
        lambda: calibrate(signs=(1, 2)),
        r"calibrate: junction sign signs\[1\] must be \+1 or -1; got 2",
    ),
    (
        "calibrate-negative-kp",
        ParameterError,
        lambda: calibrate(kp_grid=(0.1, -0.2)),
        r"calibrate: kp_grid\[1\] must be a finite value in \(0, inf\]; got -0\.2",
    ),
    (
        "calibrate-one-gain-point",
        ParameterError,
        lambda: calibrate(g_points=1),
        r"calibrate: g_points must be an integer in \[2, inf\]; got 1",
    ),
    (
        "calibrate-inverted-gain-range",
        ParameterError,
        lambda: calibrate(g_min=1.0, g_max=0.1),
        r"calibrate: g_min must be below g_max; got g_min=1\.0, g_max=0\.1",
    ),
    (
        "calibrate-phase-margin-200",
        ParameterError,
        lambda: calibrate(min_phase_margin_deg=200.0),
        r"calibrate: min_phase_margin_deg must be a finite value in \[0, 180\)",
    ),
    (
        "minimal-realization-nan-C",
        ModelStructureError,
        lambda: minimal_realization([[-1.0]], [[1.0]], [[np.nan]], [[0.0]]),
        r"minimal_realization\.C contains 1 non-finite entries",
    ),
    (
        "frequency-response-negative-frequency",
        ParameterError,
        lambda: frequency_response(LOOP.system(), [-1.0, 2.0]),
        r"frequency_response: freqs_hz\[0\] must be a finite value in \[0, inf\]; got -1\.0",
    ),
    (
        "frequency-response-unknown-output",
        ModelStructureError,
        lambda: frequency_response(LOOP.system(), [1.0], out="q"),
        r"frequency_response: the system has no output 'q'",
    ),
    (
        "critical-kpsf-one-grid-point",
        ParameterError,
        lambda: critical_k_psf(LOOP, n_grid=1),
        r"critical_k_psf: n_grid must be an integer in \[2, inf\]; got 1",
    ),
    (
        "ratio-study-no-low-band",
        ParameterError,
        lambda: ratio_study(LOOP, factors=[2.0], freqs_hz=[2.0, 3.0]),
        r"ratio_study: freqs_hz must include frequencies below 1 Hz",
    ),
    (
        "balanced-truncation-fractional-order",
        ParameterError,
        lambda: balanced_truncation(SYS, order=1.5),
        r"balanced_truncation: order must be an integer; got 1\.5",
    ),
]

# -- model and system identification --------------------------------------------------------
MODEL_CASES = [
    (
        "modal-negative-arm-damping",
        ParameterError,
        lambda: modal_to_physical(40.0, 2.0, 3.0, 0.3, 3.0, -0.1),
        r"modal_to_physical: zeta_arm must be a finite value in \(0, inf\]; got -0\.1",
    ),
    (
        "chain-matrices-zero-mass",
        ParameterError,
        lambda: physical_human_matrices(40.0, [2.0, 0.0], 1e4, 500.0, 800.0, 30.0, 1.0),
        r"physical_human_matrices: m_arm\[1\] must be a finite value in \(0, inf\]; got 0\.0",
    ),
    (
        "segment-masses-negative-body",
        ParameterError,
        lambda: segment_masses(-75.0),
        r"segment_masses: body_mass must be a finite value in \(0, inf\]; got -75\.0",
    ),
    (
        "loop-struct-wrong-type",
        ParameterError,
        lambda: BDFTLoop(struct={"k_s": 200.0}),
        r"BDFTLoop\.struct must be StructureParams; got dict",
    ),
    (
        "unknown-human-variant",
        ParameterError,
        lambda: human_variant("robot"),
        r"human variant must be one of .*got 'robot'",
    ),
    (
        "levy-sk-nan-response",
        DataError,
        lambda: levy_sk([1.0, 2.0, 3.0], [1.0, np.nan, 1.0], 0, 1),
        r"levy_sk: h\[1\] must be finite; got",
    ),
    (
        "levy-sk-negative-frequency",
        DataError,
        lambda: levy_sk([1.0, -2.0, 3.0], [1.0, 1.0, 1.0], 0, 1),
        r"levy_sk: omega\[1\] must be a finite value in \(0, inf\]; got -2\.0",
    ),
    (
        "simulate-response-inf-input",
        DataError,
        lambda: simulate_response(ct.tf([1.0], [1.0, 1.0]), _with(U, 3, np.inf), 1000.0),
        r"simulate_response: input u\[3\] must be a finite value; got inf",
    ),
    (
        "coherence-threshold-significance-above-one",
        ParameterError,
        lambda: coherence_threshold(10.0, 1.5),
        r"coherence_threshold: significance must be a finite value in \(0, 1\); got 1\.5",
    ),
]


@pytest.mark.parametrize(
    "call, match", [c[1:] for c in MEMBER_CASES], ids=[c[0] for c in MEMBER_CASES]
)
def test_bad_family_members_are_refused_by_name(call, match):
    with pytest.raises(ParameterError, match=match):
        call()


@pytest.mark.parametrize(
    "call, match", [c[1:] for c in SAMPLING_CASES], ids=[c[0] for c in SAMPLING_CASES]
)
def test_bad_sampling_requests_are_refused_by_name(call, match):
    with pytest.raises(ParameterError, match=match):
        call()


@pytest.mark.parametrize(
    "error, call, match", [c[1:] for c in ANALYSIS_CASES], ids=[c[0] for c in ANALYSIS_CASES]
)
def test_bad_analysis_input_is_refused_by_name(error, call, match):
    with pytest.raises(error, match=match):
        call()


@pytest.mark.parametrize(
    "error, call, match", [c[1:] for c in MODEL_CASES], ids=[c[0] for c in MODEL_CASES]
)
def test_bad_model_and_sysid_input_is_refused_by_name(error, call, match):
    with pytest.raises(error, match=match):
        call()


# -- what the checks must not cost ----------------------------------------------------------
def test_a_bad_last_member_costs_no_work():
    bad = rows(n=300, r299__human_dot_m_arm=-1.0)
    done = []
    with pytest.raises(ParameterError, match="member row 299: human.m_arm"):
        validate_family(PHYS, samples_of(bad), chunk=50, progress=done.append)
    assert done == []  # refused before the first chunk's poles


def test_members_beyond_the_bounds_with_check_bounds_false_match_the_single_member():
    row = NOMINAL.copy()
    row[NAMES.index("struct.f1_hz")] = 9.0  # stiffer than the family's stilts value
    got = np.sort_complex(batched_poles(PHYS, row[None], check_bounds=False)[0])
    ref = np.sort_complex(ct.poles(PHYS.member(row, check_bounds=False).system()))
    assert got == pytest.approx(ref, rel=1e-9, abs=1e-9)
    res = validate_family(PHYS, samples_of(np.tile(row, (3, 1))), check_bounds=False)
    assert res.max_real_pole == pytest.approx(float(np.max(got.real)), rel=1e-9)


def test_values_a_few_ulps_outside_the_bounds_are_inside():
    p = PHYS.parameter("struct.f1_hz")
    row = NOMINAL.copy()
    row[NAMES.index("struct.f1_hz")] = p.low * (1 - 1e-12)
    assert closed_loop_matrices(PHYS, row[None]).shape == (1, 13, 13)


def test_a_huge_chunk_changes_no_number():
    S = sample(PHYS.parameters, 40, method="mc", seed=2)
    a = validate_family(PHYS, S, chunk=7)
    b = validate_family(PHYS, S, chunk=10**15)
    assert np.array_equal(a.max_real, b.max_real)
    assert np.array_equal(a.member_min_damping, b.member_min_damping)


def test_the_sample_limit_holds_at_its_boundary(monkeypatch):
    monkeypatch.setattr(sampling_module, "MAX_SAMPLE_BYTES", 8 * len(NAMES) * 100)
    assert len(sample(PHYS.parameters, 100, method="mc")) == 100
    with pytest.raises(ParameterError, match=r"n=101 .*at most 100 members"):
        sample(PHYS.parameters, 101, method="mc")


def test_save_component_fit_refuses_a_bad_rate_before_writing(tmp_path):
    fit = types.SimpleNamespace(form="structure", params_dict=dict)
    target = tmp_path / "fit.json"
    with pytest.raises(ParameterError, match=r"save_component_fit: fs must be .*got nan"):
        save_component_fit(target, fit, fs=float("nan"), seed=None, source="x.csv")
    assert not target.exists()


def test_cli_refuses_a_trillion_samples_without_allocating(capsys):
    try:
        code = main(["validate", "--samples", "1000000000000", "--json"])
    except SystemExit as exc:  # argparse-style exit
        code = exc.code
    assert code == 2
    assert "1000000000000" in capsys.readouterr().err
