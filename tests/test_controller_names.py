"""Controllers round-trip under any signal names: saved under python-control's default
names, loaded back with them, and validated on a user's own system (``bdft validate
--controller FILE --system FILE.py``); the BDFT loop's names are required where it closes."""

import json

import control as ct
import numpy as np
import pytest

from backhoe.families.files import load_controller, load_system, match_controller
from bdft import main
from robust.errors import ArtifactError, ParameterError
from robust.export import ControllerArtifact, discretize, load_artifact, write_artifact
from uncertainty import sample, validate_family

# a user's own system: two masses on a spring, force on mass 1 -> its position
SYSTEM = """\
from uncertainty import ureal, uss

k = ureal("k", 1.0, 0.5, 2.0, unit="N/m")
m2 = ureal("m2", 1.0, 0.8, 1.5, unit="kg")
c = 0.05
A = [[0, 0, 1, 0], [0, 0, 0, 1], [-k, k, -c, c], [k / m2, -k / m2, c / m2, -c / m2]]
system = uss(A, [[0], [0], [1], [0]], [[1, 0, 0, 0]], [[0]])
"""

# the README's PD controller (2 + 4 s) rolled off at 20 rad/s, in state space
K_PD = ct.ss(ct.tf([4.0, 2.0], [0.05, 1.0]))


def _save(tmp_path, K, name="k.json"):
    art = ControllerArtifact("pd", K, discretize(K, 0.001), None)
    return write_artifact(art, tmp_path / name)["json"]


def _system_file(tmp_path, text=SYSTEM):
    path = tmp_path / "two_mass.py"
    path.write_text(text, encoding="utf-8")
    return path


def test_default_names_round_trip_through_the_artifact(tmp_path):
    assert list(K_PD.input_labels) == ["u[0]"] and list(K_PD.output_labels) == ["y[0]"]
    path = _save(tmp_path, K_PD)
    art = load_artifact(path)
    assert art.inputs == ["u[0]"] and art.outputs == ["y[0]"]
    for got, want in ((art.continuous, K_PD), (art.discrete, discretize(K_PD, 0.001))):
        for M in "ABCD":
            np.testing.assert_array_equal(getattr(got, M), getattr(want, M))
    K = load_controller(path)
    assert list(K.input_labels) == ["u[0]"] and list(K.output_labels) == ["y[0]"]
    np.testing.assert_array_equal(K.A, K_PD.A)
    # any other names too, kept as they are
    other = ct.ss(K_PD.A, K_PD.B, K_PD.C, K_PD.D, inputs="position", outputs="force")
    art = load_artifact(_save(tmp_path, other, "other.json"))
    assert (art.inputs, art.outputs) == (["position"], ["force"])


def test_bdft_validate_a_saved_controller_on_the_users_system(capsys, tmp_path):
    controller = _save(tmp_path, K_PD)
    system_file = _system_file(tmp_path)
    argv = ["validate", "--controller", str(controller), "--system", str(system_file)]
    assert main([*argv, "--samples", "500", "--seed", "3", "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    system, _ = load_system(system_file)
    ref = validate_family(
        system, sample(system, 500, seed=3), controller=match_controller(system, K_PD)
    )
    assert obj["controller"] == str(controller) and obj["system"] == str(system_file)
    assert obj["controller_states"] == 1 and obj["nstates"] == 5
    assert obj["fraction_stable"] == ref.fraction_stable == 1.0
    assert obj["max_real_pole"] == pytest.approx(ref.max_real_pole, rel=1e-5)
    assert obj["max_real_pole"] < 0


def test_names_pair_by_name_or_position():
    from uncertainty import ureal, uss

    k = ureal("k", 1.0, 0.5, 2.0)
    P = uss(
        [[-k, 0], [0, -1]],
        [[1, 0], [0, 1]],
        [[1, 0], [0, 1]],
        [[0, 0], [0, 0]],
        inputs=["f1", "f2"],
        outputs=["x1", "x2"],
    )
    D = [[0.0, 2.0], [5.0, 0.0]]
    by_name = match_controller(P, ct.ss([], [], [], D, inputs=["x2", "x1"], outputs=["f1", "f2"]))
    np.testing.assert_array_equal(by_name.D, [[2.0, 0.0], [0.0, 5.0]])
    assert list(by_name.input_labels) == ["x1", "x2"]
    by_position = match_controller(P, ct.ss([], [], [], D))  # u[0], u[1] -> y[0], y[1]
    np.testing.assert_array_equal(by_position.D, D)
    assert list(by_position.output_labels) == ["f1", "f2"]
    with pytest.raises(ParameterError, match="name some of the system's outputs"):
        match_controller(P, ct.ss([], [], [], D, inputs=["x1", "q"], outputs=["f1", "f2"]))


def test_a_mismatch_is_a_clear_error(capsys, tmp_path):
    system_file = _system_file(tmp_path)
    two_in = ct.ss([[-1.0]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]])
    path = _save(tmp_path, two_in, "two.json")
    assert main(["validate", "--controller", str(path), "--system", str(system_file)]) == 2
    err = capsys.readouterr().err
    assert "bdft validate: error:" in err
    assert "must map the system's 1 outputs ['y[0]'] to its 1 inputs ['u[0]']" in err
    assert "got 2 inputs ['u[0]', 'u[1]'] and 1 outputs ['y[0]']" in err
    # bdft margin --system reads it the same way
    assert main(["margin", "--controller", str(path), "--system", str(system_file)]) == 2
    assert "must map the system's 1 outputs" in capsys.readouterr().err
    # the BDFT family's loop needs its own names, and says where the others go
    assert main(["validate", "--samples", "10", "--controller", str(_save(tmp_path, K_PD))]) == 2
    err = capsys.readouterr().err
    assert "controller inputs must be among ('x', 'c', 'y')" in err and "--system" in err
    with pytest.raises(ArtifactError, match="to close the BDFT loop"):
        load_controller(_save(tmp_path, K_PD, "pd.json"), bdft_loop=True)
