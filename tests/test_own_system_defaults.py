"""A user's own system gets neutral defaults: its damping requirement and the validation's
reported minimum damping cover every pole, not the BDFT band (0.5-10 Hz), unless a band is
asked for; the BDFT family keeps its band."""

import json
import math

import numpy as np
import pytest

from backhoe import default_family
from backhoe.constants import DAMPING_BAND_HZ
from bdft import main
from uncertainty import Region, sample, ureal, uss, validate_family, worst_member
from uncertainty.region import EVERY_FREQUENCY_HZ

# a lightly damped mode at 1 rad/s (0.16 Hz, below the BDFT band) and a well-damped one at
# 30 rad/s (4.8 Hz, inside it)
SYSTEM = """\
from uncertainty import ureal, uss

z = ureal("z", 0.05, 0.03, 0.07)
A = [[0, 1, 0, 0], [-1, -2 * z, 0, 0], [0, 0, 0, 1], [0, 0, -900, -2 * 0.6 * 30]]
system = uss(A, [[0], [1], [0], [1]], [[1, 0, 1, 0]], [[0]])
"""


def _system():
    z = ureal("z", 0.05, 0.03, 0.07)
    A = [[0, 1, 0, 0], [-1, -2 * z, 0, 0], [0, 0, 0, 1], [0, 0, -900, -2 * 0.6 * 30]]
    return uss(A, [[0], [1], [0], [1]], [[1, 0, 1, 0]], [[0]])


def _all_poles_min_damping(G, samples):
    zeta = []
    for i in range(len(samples)):
        p = np.linalg.eigvals(G.at(samples.row(i)).A)
        zeta.append(np.min(-p.real / np.abs(p)))
    return min(zeta)


def test_validation_reports_every_poles_damping_for_a_users_system():
    G = _system()
    members = sample(G, 50, seed=2)
    res = validate_family(G, members)
    assert res.band_hz == EVERY_FREQUENCY_HZ
    assert res.min_damping == pytest.approx(_all_poles_min_damping(G, members), rel=1e-9)
    assert res.min_damping < 0.07  # the slow mode, which the BDFT band would not see
    banded = validate_family(G, members, band_hz=DAMPING_BAND_HZ)
    assert banded.min_damping == pytest.approx(0.6, rel=1e-9)  # only the 4.8 Hz mode


def test_a_damping_region_without_a_band_covers_every_pole_of_a_users_system():
    G = _system()
    region = Region(min_damping=0.1)
    assert region.band_hz is None and Region.parse("damping:0.1") == region
    # the slow mode at the nominal, p = -0.05 +- j sqrt(1 - 0.05^2) (|p| = 1), misses the
    # damping 0.1 by Re p + 0.1 |p| = 0.05
    violation, _ = worst_member(G, 0.0, region=region, samples=10)
    assert violation == pytest.approx(0.05, rel=1e-9)
    # with the BDFT band asked for, only the 4.8 Hz mode counts, and it meets 0.1
    banded, _ = worst_member(G, 0.0, region=Region(min_damping=0.1, band_hz=(0.5, 10)), samples=10)
    assert banded < 0
    assert "at every frequency" in region.with_default_band(EVERY_FREQUENCY_HZ).describe()
    assert Region.parse("damping:0.1@0.1-inf").band_hz == (0.1, math.inf)


def test_the_bdft_family_keeps_its_band():
    fam = default_family("physical")
    members = sample(fam.parameters, 40, seed=5)
    assert validate_family(fam, members).band_hz == DAMPING_BAND_HZ
    region = Region(min_damping=0.05)
    at_default, _ = worst_member(fam, 0.0, region=region, samples=4)
    at_band, _ = worst_member(fam, 0.0, region=Region(0.0, 0.05, DAMPING_BAND_HZ), samples=4)
    assert at_default == at_band


def test_bdft_validate_system_defaults_to_every_frequency(capsys, tmp_path):
    path = tmp_path / "modes.py"
    path.write_text(SYSTEM, encoding="utf-8")
    assert main(["validate", "--system", str(path), "--samples", "50", "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["band_hz"] == [0.0, "inf"] and obj["min_damping"] < 0.07
    assert main(["validate", "--system", str(path), "--samples", "50", "--band", "0.5-10"]) == 0
    assert "min damping       0.6  (poles in 0.5-10 Hz)" in capsys.readouterr().out
    assert main(["validate", "--system", str(path), "--samples", "50"]) == 0
    assert "(poles at every frequency)" in capsys.readouterr().out
    assert main(["validate", "--samples", "50", "--json"]) == 0  # the family: its band
    assert json.loads(capsys.readouterr().out)["band_hz"] == [0.5, 10.0]
