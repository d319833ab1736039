"""The BDFT loop is written once: its batched, interval and uncertain-system evaluations agree."""

from __future__ import annotations

import control as ct
import numpy as np
import pytest

from backhoe import closed_loop_matrices, default_family, family_uss
from backhoe.families.enclosure import closed_loop_enclosure
from robust.errors import ParameterError
from uncertainty import Region, sample, validate_family, worst_member
from uncertainty.boxcert import certify_box
from uncertainty.search import scaled_bounds

# each valve parameter of Eqn 3 away from its nominal, in its own direction
VALVE_EDGES = {"valve.k_vc": "high", "valve.p1": "low", "valve.wn_hz": "low", "valve.zeta": "low"}


def _controller(output):
    # a small strictly proper compensator from the handle and the cylinder to the force (or
    # to the cylinder reference's correction)
    A, B = [[-30.0, 5.0], [-5.0, -20.0]], [[1.0, -0.5], [0.3, 0.8]]
    return ct.ss(A, B, [[0.02, -0.01]], [[0, 0]], inputs=["x", "c"], outputs=[output], name="K")


@pytest.mark.parametrize("human", ["literal", "physical"])
@pytest.mark.parametrize("with_controller", [False, True])
def test_three_evaluations_agree_on_seeded_members(human, with_controller):
    fam = default_family(human)
    output = "f" if human == "physical" else "r_corr"
    K = _controller(output) if with_controller else None
    loop = family_uss(fam, K)
    assert list(loop.parameters) == list(fam.names)
    rows = sample(fam.parameters, 64, method="mc", seed=11).values
    # the members' valves differ (Eqn 3's four parameters vary in the family)
    for name in VALVE_EDGES:
        assert np.ptp(rows[:, fam.names.index(name)]) > 0.3 * np.ptp(
            [fam.parameter(name).low, fam.parameter(name).high]
        )
    batched = closed_loop_matrices(fam, rows, controller=K)
    from_uss = loop.state_matrices(rows)
    assert from_uss.shape == batched.shape
    scale = np.abs(batched).max(axis=(1, 2))[:, None, None]
    assert np.abs(from_uss - batched).max() <= 1e-12 * scale.max()
    for r, A in zip(rows[:8], batched[:8]):
        enc = closed_loop_enclosure(fam, r, r, controller=K)  # a point box
        assert np.all((enc.lo <= A) & (A <= enc.hi))
        assert np.abs(enc.mid - A).max() <= 1e-12 * np.abs(A).max()
    # python-control's poles of one member's uncertain-system form
    poles = np.sort_complex(ct.poles(loop.at(dict(zip(fam.names, rows[0])))))
    assert poles == pytest.approx(np.sort_complex(np.linalg.eigvals(batched[0])), rel=1e-9)


def test_the_family_and_its_uncertain_system_give_the_same_answers():
    fam = default_family("physical")
    loop = family_uss(fam)
    members = sample(fam.parameters, 3000, method="mc", seed=5)
    a, b = validate_family(fam, members), validate_family(loop, members)
    assert b.fraction_stable == a.fraction_stable and b.worst == a.worst
    assert b.max_real_pole == pytest.approx(a.max_real_pole, rel=1e-12)
    # the same worst-case search on both (same coordinates, same seed)
    region = Region(decay_rate=0.1)
    va, ra = worst_member(fam, 0.05, region=region, samples=100, seed=2)
    vb, rb = worst_member(loop, 0.05, region=region, samples=100, seed=2)
    assert vb == pytest.approx(va, abs=1e-9) and rb == pytest.approx(ra, rel=1e-9)
    # a small box about the nominal is certified through either form
    lo, hi = scaled_bounds(fam, 0.01)
    assert certify_box(fam, lo, hi)["certified"]
    assert certify_box(loop, lo, hi)["certified"]


def test_recalled_blocks_give_the_enclosures_of_fresh_ones_to_the_bit():
    # a parent box, its halves in a human and in a structure parameter, and the parent again:
    # the assembly that recalls the blocks of recent boxes gives each enclosure exactly as a
    # new assembly (no memory) does, and builds a block only for parameters it has not seen
    from backhoe.families import loop as loopmod
    from backhoe.families.enclosure import _Assembly

    fam = default_family("physical")
    K = _controller("f")
    lo, hi = scaled_bounds(fam, 0.05)
    names = list(fam.names)
    boxes = [(lo, hi)]
    for name in ("human.f_arm_hz", "struct.f1_hz"):
        j = names.index(name)
        mid = 0.5 * (lo[j] + hi[j])
        a_hi, b_lo = hi.copy(), lo.copy()
        a_hi[j], b_lo[j] = mid, mid
        boxes += [(lo, a_hi), (b_lo, hi)]
    boxes.append((lo, hi))
    calls = {"structure": 0, "human": 0}
    s_orig, h_orig = loopmod.structure_block, loopmod.physical_human_block

    def s_count(*a):
        calls["structure"] += 1
        return s_orig(*a)

    def h_count(*a):
        calls["human"] += 1
        return h_orig(*a)

    kept = _Assembly(fam, K)
    try:
        loopmod.structure_block, loopmod.physical_human_block = s_count, h_count
        got = [kept.matrix(a, b, derivatives=True) for a, b in boxes]
    finally:
        loopmod.structure_block, loopmod.physical_human_block = s_orig, h_orig
    for (a, b), g in zip(boxes, got):
        ref = _Assembly(fam, K).matrix(a, b, derivatives=True)
        for x, y in ((g.val, ref.val), (g.der, ref.der)):
            np.testing.assert_array_equal(x.mid, y.mid)
            np.testing.assert_array_equal(x.rad, y.rad)
    # the human split's halves keep the parent's structure, the structure split's halves its
    # human, and the parent again is recalled whole: 3 builds of each block instead of 6
    assert calls == {"structure": 3, "human": 3}
    # the recalled arrays are read-only: no later operation can change them in place
    block = next(iter(kept._recent.values()))
    assert not block[0].val.mid.flags.writeable


def test_parameter_names_are_spelled_in_the_model_module_only():
    # every evaluation reads a block's parameters through backhoe.model.blocks: no other
    # source file spells a parameter's name in a string or a docstring's literal (attribute
    # access such as `family.struct.k_s` or `valve.k_vc` is not a name, and is allowed)
    import re
    from pathlib import Path

    from backhoe.model.blocks import BLOCK_FIELDS, parameter_name

    names = sorted({parameter_name(b, f) for b, fields in BLOCK_FIELDS.items() for f in fields})
    pattern = re.compile(r"[\"'`](" + "|".join(re.escape(n) for n in names) + r")\b")
    root = Path(__file__).resolve().parents[1]
    found = []
    for package in ("robust", "uncertainty", "backhoe", "designs", "reports", "bdft"):
        for path in sorted((root / package).rglob("*.py")):
            if path.name == "blocks.py" and path.parent.name == "model":
                continue
            for k, line in enumerate(path.read_text().splitlines(), 1):
                if pattern.search(line):
                    found.append(f"{path.relative_to(root)}:{k}: {line.strip()}")
    assert not found, "\n".join(found)
    # and the model module does spell them
    text = (root / "backhoe" / "model" / "blocks.py").read_text()
    assert "_PREFIX" in text and all(f in text for f in BLOCK_FIELDS["valve"])


def _valve_moved(fam):
    row = fam.nominal_values()
    for name, edge in VALVE_EDGES.items():
        p = fam.parameter(name)
        row[fam.names.index(name)] = getattr(p, edge)
    return row


def _matched(ref, got):
    """Largest |ref - got| / max(1, |ref|) over a one-to-one matching of two pole sets."""
    from scipy.optimize import linear_sum_assignment

    d = np.abs(ref[:, None] - got[None, :])
    r, c = linear_sum_assignment(d)
    return float(np.max(d[r, c] / np.maximum(1.0, np.abs(ref[r]))))


@pytest.mark.parametrize("human", ["literal", "physical"])
def test_a_member_with_its_valve_moved_has_the_same_poles_in_every_evaluation(human):
    # the valve at the edges of the family's ranges (gain up, pole, bandwidth and damping
    # down): batched matrices, python-control's loop of the member, the uncertain system and
    # the interval enclosure all take the valve from the member, not the family's nominal
    from robust.analysis.eigen_enclosure import enclose_eigenvalues
    from robust.analysis.realization import minimal_realization

    fam = default_family(human)
    row = _valve_moved(fam)
    same_valve = fam.nominal_values()
    batched = np.linalg.eigvals(closed_loop_matrices(fam, row[None])[0])
    nominal_valve = np.linalg.eigvals(closed_loop_matrices(fam, same_valve[None])[0])
    # the valve moves the loop's poles (an evaluator with the nominal valve would fail below)
    assert _matched(nominal_valve, batched) > 1e-2

    member = fam.member(row)
    assert member.valve.k_vc == fam.parameter("valve.k_vc").high
    assert member.valve.wn_hz == fam.parameter("valve.wn_hz").low
    sys = member.system()
    if human == "literal":  # python-control keeps Eqn 5's two cancelled modes at s = 0
        m = minimal_realization(sys.A, sys.B, sys.C, sys.D)
        ref = np.linalg.eigvals(m.A)
    else:
        ref = ct.poles(sys)
    assert _matched(ref, batched) < 1e-8

    uss = family_uss(fam).at(dict(zip(fam.names, row)))
    assert _matched(ct.poles(uss), batched) < 1e-9

    # the interval enclosure over a small box about the member (valve parameters +-0.1 %)
    # holds every pole of python-control's loop in its verified, disjoint rectangles
    lo, hi = row.copy(), row.copy()
    for name in VALVE_EDGES:
        j = fam.names.index(name)
        lo[j], hi[j] = row[j] * 0.999, row[j] * 1.001
    centre = closed_loop_enclosure(fam, row, row)
    grad = closed_loop_enclosure(fam, lo, hi, derivatives=True)
    logs = np.array([p.distribution == "loguniform" for p in fam.parameters])
    h = np.where(logs, np.log(hi / lo) / 2, (hi - lo) / 2) * (1 + 1e-9)
    assert np.all(np.abs(grad.der.mid).sum(axis=(1, 2))[[fam.names.index(n) for n in VALVE_EDGES]])
    E_rad = centre.rad + np.einsum("p,pab->ab", h, grad.der.rad)
    enc = enclose_eigenvalues(centre.mid, grad.der.mid, h, E_rad)
    assert enc["ok"]
    c, rr, ri = enc["centre"], enc["rad_re"], enc["rad_im"]
    inside = (np.abs(ref.real[:, None] - c.real[None]) <= rr[None]) & (
        np.abs(ref.imag[:, None] - c.imag[None]) <= ri[None]
    )
    assert inside.any(axis=1).all()
    # and the rectangles are tight enough to tell this valve from the nominal one
    far = (np.abs(nominal_valve.real[:, None] - c.real[None]) <= rr[None]) & (
        np.abs(nominal_valve.imag[:, None] - c.imag[None]) <= ri[None]
    )
    assert not far.any(axis=1).all()


@pytest.mark.parametrize("human", ["literal", "physical"])
def test_the_loops_ports_give_each_members_own_closed_loop(human):
    # the family's uncertain loop with exogenous inputs and named outputs, at seeded
    # members, against python-control's interconnection of the same member (its own
    # blocks and junctions): every channel's frequency response, to 1e-6 of the channel's
    # peak. The two realisations' floating-point evaluations differ by up to 5e-8 near the
    # arm's modes at 3 Hz; evaluated in 40 digits (mpmath) they agree to 1e-12 there, so
    # that is rounding in the evaluation of the uncertain form's badly scaled states, not a
    # difference of models; a wrong coefficient or sign is an error of order one
    fam = default_family(human)
    output = "f" if human == "physical" else "r_corr"
    K = _controller(output)
    inputs = ["u", "f_ext"] if human == "physical" else ["u"]
    outputs = ["y", "c", "h", "x", "e", output, "r", "err"]
    G = family_uss(fam, K, inputs=inputs, outputs=outputs)
    assert (G.inputs, G.outputs) == (inputs, outputs)
    rows = sample(fam.parameters, 3, method="mc", seed=21).values
    s = 2j * np.pi * np.array([0.05, 0.7, 3.0, 9.0, 40.0])
    for row in [fam.nominal_values(), *rows]:
        got = G.at(dict(zip(fam.names, row)))
        ref = fam.member(row).system(bdft=True, controller=K, outputs=outputs[:5])
        assert list(ref.input_labels) == inputs
        for z in outputs[:5] + [output]:
            for w in inputs:
                g = got[outputs.index(z), inputs.index(w)]
                r = ref[list(ref.output_labels).index(z), list(ref.input_labels).index(w)]
                hg, hr = g(s), r(s)
                assert np.abs(hg - hr).max() <= 1e-6 * max(np.abs(hr).max(), 1e-12), (z, w)
        # the junctions: the handle x = u + sigma kappa h, the reference r = K_PSF x, and
        # the cylinder loop's error r (+ r_corr) - y
        hx, hy = got[outputs.index("x"), 0](s), got[outputs.index("y"), 0](s)
        assert (
            np.abs(got[outputs.index("r"), 0](s) - fam.k_psf * hx).max()
            <= 1e-9 * np.abs(fam.k_psf * hx).max()
        )
        corr = got[outputs.index(output), 0](s) if output == "r_corr" else 0.0
        err = fam.k_psf * hx + corr - hy
        assert np.abs(got[outputs.index("err"), 0](s) - err).max() <= 1e-9 * np.abs(err).max()
    # the state matrix is the one of the loop without ports
    assert (
        np.abs(
            G.at(dict(zip(fam.names, rows[0]))).A - family_uss(fam, K).state_matrices(rows[:1])[0]
        ).max()
        <= 1e-12 * np.abs(G.nominal().A).max()
    )


def test_ports_that_the_loop_does_not_have_are_refused():
    fam = default_family("literal")
    with pytest.raises(ParameterError, match="inputs: 'x' is not an exogenous input"):
        family_uss(fam, inputs="x", outputs="y")
    with pytest.raises(ParameterError, match="outputs: 'q' is not a signal of the loop"):
        family_uss(fam, inputs="u", outputs="q")
    with pytest.raises(ParameterError, match="'f_ext' reaches no block"):
        family_uss(fam, inputs=["u", "f_ext"], outputs="y")
    with pytest.raises(ParameterError, match="must not repeat"):
        family_uss(fam, inputs="u", outputs=["y", "y"])
