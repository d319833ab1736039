"""The report's robust-margin table says what certified each lower bound."""

from reports.design_sections import _certificate_text
from uncertainty import Region, robust_margin, ureal, uss


def _spring_damper():
    # s^2 + c s + 4, c in [0.2, 3] about 1: decays faster than 0.3 1/s while c > 0.6
    c = ureal("c", 1.0, 0.2, 3.0)
    return uss([[0, 1], [-4, -c]], [[0], [1]], [[1, 0]], [[0]])


def test_the_certificate_column_names_mu_or_the_sub_boxes():
    G = _spring_damper()
    mu = robust_margin(G, region=Region(decay_rate=0.3), method="mu")
    stats = mu.certificate["certified_stats"]
    assert _certificate_text(mu.certificate) == (
        f"mu: {stats['frequencies']} frequencies, peak bound {stats['peak_mu_upper']:.3f}"
    )
    assert stats["frequencies"] >= 1 and stats["peak_mu_upper"] < 1.0
    eig = robust_margin(G, region=Region(decay_rate=0.3), method="eigenvalues")
    assert _certificate_text(eig.certificate).endswith(")") and " sub-boxes (" in (
        _certificate_text(eig.certificate)
    )
    # a region the centre member misses (it decays at 0.5 1/s): nothing is certified
    out = robust_margin(G, region=Region(decay_rate=0.6), method="mu")
    assert out.lower == 0.0
    assert _certificate_text(out.certificate) == "none: the centre member is outside the region"
