"""``bdft margin --gamma``: robust performance from the command line, of a user's system and of
the BDFT family's loop through its ports (:func:`backhoe.family_uss`)."""

import json

import control as ct
import numpy as np
import pytest

from backhoe import default_family, family_uss
from bdft import main

# the first-order lag 1 / (s + a), a in [0.5, 3.5] about 2: its gain stays below 1 while
# a > 1, so the box's low end reaches the bound at the scale 2/3 (derived by hand)
LAG = """\
from uncertainty import ureal, uss

a = ureal("a", 2.0, 0.5, 3.5)
system = uss([[-a]], [[1.0]], [[1.0]], [[0.0]], inputs=["w"], outputs=["z"])
"""


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_a_users_system_gets_both_bounds_at_the_hand_derived_scale(tmp_path, capsys):
    f = tmp_path / "lag.py"
    f.write_text(LAG)
    out = _json(capsys, ["margin", "--system", str(f), "--gamma", "1", "--json"])  # 64 members
    assert out["lower"] <= 2 / 3 <= out["upper"]
    assert out["lower"] >= 0.99 * 2 / 3 and out["upper"] <= 1.01 * 2 / 3
    assert out["worst"]["parameters"]["a"] == pytest.approx(1.0, abs=0.01)
    assert out["nominal_norm"] == pytest.approx(0.5, rel=1e-6)  # 1/a at a = 2
    assert (out["gamma"], out["system"]) == (1.0, str(f))
    # a tighter bound, half the gain: a > 2 is needed, which the nominal only just meets
    out = _json(capsys, ["margin", "--system", str(f), "--gamma", "0.4", "--json"])
    assert out["upper"] == 0.0 and out["nominal_norm"] == pytest.approx(1.25, rel=1e-6)
    # the text form names both bounds and the worst member
    assert main(["margin", "--system", str(f), "--gamma", "1"]) == 0
    text = capsys.readouterr().out
    assert "certified lower bound" in text and "worst member" in text and "a " in text


def test_a_bound_over_a_band_from_the_command_line(tmp_path, capsys):
    # above 0.6 rad/s the lag's gain 1 / sqrt(w^2 + a^2) stays below 1 while a > 0.8: the
    # scale 0.8, not the 2/3 of every frequency (derived by hand)
    f = tmp_path / "lag.py"
    f.write_text(LAG)
    band = f"{0.6 / (2 * np.pi)!r},inf"
    out = _json(capsys, ["margin", "--system", str(f), "--gamma", "1", "--band", band, "--json"])
    assert out["lower"] <= 0.8 <= out["upper"]
    assert out["lower"] >= 0.99 * 0.8 and out["upper"] <= 1.01 * 0.8
    # (the JSON writes an infinity as "inf" and six significant digits)
    assert out["band_hz"] == [pytest.approx(0.6 / (2 * np.pi), rel=1e-5), "inf"]
    assert out["certificate"]["stability"]["certified"]


def test_the_familys_loop_through_its_ports(capsys):
    # the literal family's loop with the doubled workspace (stable at its nominal; at the
    # Omni's workspace it is not), intended motion to cylinder position, with a bound 1.3
    # times the nominal gain: both bounds (measured: 0.022468 and 0.022476, 28 s), and the
    # worst member's norm checked by SLICOT on the member built independently (its
    # python-control interconnection of its blocks)
    fam = default_family("literal").with_workspace_factor(2.0)
    G = family_uss(fam, inputs="u", outputs="y")
    nominal = float(ct.linfnorm(G.nominal())[0])
    gamma = 1.3 * nominal
    argv = ["margin", "--human", "literal", "--workspace-factor", "2", "--gamma", f"{gamma!r}"]
    out = _json(capsys, argv + ["--samples", "32", "--time-limit", "120", "--json"])
    assert (out["inputs"], out["outputs"]) == (["u"], ["y"])
    assert out["nominal_norm"] == pytest.approx(1 / 1.3, rel=1e-6)
    # certified to within 1 % of the member found beyond it
    assert 0.99 * out["upper"] <= out["lower"] <= out["upper"] < 1
    w = out["worst"]
    row = np.array([w["parameters"][n] for n in fam.names])
    member = fam.member(row).system(bdft=True, outputs=["y"])
    norm = float(ct.linfnorm(member[0, list(member.input_labels).index("u")])[0])
    assert norm / gamma == pytest.approx(w["norm"], rel=1e-4)
    assert w["norm"] >= 1 - 1e-6


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--outputs", "y"], "--outputs is for robust performance: give --gamma"),
        (["--band", "0,2"], "--band is for robust performance: give --gamma"),
        (["--gamma", "1", "--band", "2,1"], "expected LOW,HIGH in Hz"),
        (["--gamma", "1", "--band", "0"], "expected LOW,HIGH in Hz"),
        (["--gamma", "1", "--region", "decay:0.1"], "--region: robust performance"),
        (["--gamma", "1", "--method", "eigenvalues"], "--method: robust performance"),
        (["--gamma", "0"], "--gamma"),
        (["--gamma", "1", "--outputs", "y,,x"], "--outputs: expected signal names"),
        (["--gamma", "1", "--outputs", "q"], "'q' is not a signal of the loop"),
    ],
)
def test_performance_options_that_do_not_fit_are_refused(extra, message, capsys):
    assert main(["margin", "--human", "literal", *extra]) == 2
    assert message in capsys.readouterr().err
