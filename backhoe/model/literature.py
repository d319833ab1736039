"""Published ranges of the seated operator's arm and trunk dynamics (fore-aft), with sources.

The physical human (:mod:`backhoe.model.physical`) is parameterised the way
biodynamics papers report it:

* the **arm endpoint** with the trunk held: effective mass at the hand ``m_arm``,
  natural frequency ``f_arm_hz`` and damping ratio ``zeta_arm`` of the hand on its
  handle in the fore-aft direction (hand-arm endpoint impedance);
* the **trunk on the seat**: natural frequency ``f_trunk_hz`` and damping ratio
  ``zeta_trunk`` of the upper body (with the arm moving with it) on the seat in
  fore-aft whole-body vibration, the peak of the seated fore-aft apparent mass. It
  depends on the posture: with a backrest the upper body is stiffened and the peak
  moves up; without one the upper body rocks at low frequency;
* the **body mass** (the upper-body mass follows from Winter's segment fractions).

:data:`PUBLISHED` holds, per named posture, the range of each parameter that the
default family spans; :data:`STRESS` widens them beyond the published ranges (a
labelled stress variant, never the default). Each :class:`HumanRange` carries its
source note: reference, table or figure, condition, and what of it was checked in
the source itself. Where a number could only be traced to a secondary account of a
paper (its tables were not at hand), the note says so; those rows are the ones to
check first against the originals.

References
----------
* van Beek, Bergmann Tiest, Mugge & Kappers (2015), "Haptic perception of force
  magnitude and its relation to postural arm dynamics in 3D", Sci. Rep. 5:18004.
* Tsuji, Morasso, Goto & Ito (1995), "Human hand impedance characteristics during
  maintained posture", Biol. Cybern. 72:475-485.
* Dolan, Friedman & Nagurka (1993), "Dynamic and loaded impedance components in the
  maintenance of human arm posture", IEEE Trans. SMC 23(3):698-709.
* Perreault, Kirsch & Crago (2004), "Multijoint dynamics and postural stability of
  the human arm", Exp. Brain Res. 157:507-517.
* Fu & Cavusoglu (2012), "Human-arm-and-hand-dynamic model with variability analyses
  for a stylus-based haptic interface", IEEE Trans. SMC-B 42(6):1633-1644.
* Venrooij, Abbink, Mulder & van Paassen (2011), "A method to measure the
  relationship between biodynamic feedthrough and neuromuscular admittance", IEEE
  Trans. SMC-B 41(4):1158-1169.
* Fairley & Griffin (1990), "The apparent mass of the seated human body in the
  fore-and-aft and lateral directions", J. Sound Vib. 139(2):299-306.
* Mansfield & Lundström (1999), "The apparent mass of the human body exposed to
  non-orthogonal horizontal vibration", J. Biomech. 32:1269-1278.
* Nawayseh & Griffin (2005), "Tri-axial forces at the seat and backrest during
  whole-body fore-and-aft vibration", J. Sound Vib. 281:921-942.
* Amari & Perrin (2022), seated apparent mass in nine postures, rigid seat without
  backrest, 14 subjects, Ergonomics.
* ISO 5982:2019, Mechanical vibration and shock: range of idealized values to
  characterize human biodynamic response under whole-body vibration (x-axis
  apparent mass, seated, with and without backrest).
* Winter (2009), Biomechanics and Motor Control of Human Movement, 4th ed., Table 4.1.
"""

from __future__ import annotations

import dataclasses

from backhoe.constants import DEFAULT_POSTURE, POSTURES
from robust.checks import POSITIVE, validate_fields
from robust.errors import ParameterError

__all__ = [
    "HumanRange",
    "POSTURES",
    "DEFAULT_POSTURE",
    "MODAL_NAMES",
    "PUBLISHED",
    "STRESS",
    "published_box",
    "stress_box",
]

# POSTURES and DEFAULT_POSTURE (the backhoe's seat, with its backrest) are defined in
# backhoe.constants (the command line reads them without this module's libraries)
#: The modal parameters of the physical human, in the order families list them.
MODAL_NAMES = ("body_mass", "m_arm", "f_arm_hz", "zeta_arm", "f_trunk_hz", "zeta_trunk")


@dataclasses.dataclass(frozen=True)
class HumanRange:
    """A published range of one physical-human parameter.

    Parameters
    ----------
    name : str
        One of :data:`MODAL_NAMES`.
    low, high : float
        The range, in ``units``.
    distribution : {"uniform", "loguniform"}
        How a family samples it.
    units : str
        Units of the values.
    source : str
        Reference, table or figure, condition, and what was checked in the source.
    """

    name: str
    low: float
    high: float
    distribution: str
    units: str
    source: str

    def __post_init__(self):
        validate_fields(self, {"low": POSITIVE, "high": POSITIVE})
        if self.name not in MODAL_NAMES:
            raise ParameterError(f"HumanRange.name must be one of {MODAL_NAMES}; got {self.name!r}")
        if not self.low < self.high:
            raise ParameterError(
                f"HumanRange {self.name!r}: low < high required; got [{self.low}, {self.high}]"
            )
        if self.distribution not in ("uniform", "loguniform"):
            raise ParameterError(
                f"HumanRange {self.name!r}: distribution must be 'uniform' or 'loguniform'; "
                f"got {self.distribution!r}"
            )

    def contains(self, value: float) -> bool:
        """Whether ``value`` lies in ``[low, high]``.

        Parameters
        ----------
        value : float
            A parameter value, in :attr:`units`.
        """
        return self.low <= value <= self.high


_BODY = HumanRange(
    "body_mass",
    50.0,
    110.0,
    "uniform",
    "kg",
    "adult operators, small (about 5th percentile female) to large (about 95th percentile "
    "male); seated vibration studies test this span, e.g. male groups near 55, 75 and 98 kg "
    "(Rakheja et al., Int. J. Ind. Ergon., doi 10.1016/j.ergon.2007.10.026) [checked: "
    "abstract]",
)
_M_ARM = HumanRange(
    "m_arm",
    0.5,
    3.0,
    "loguniform",
    "kg",
    "effective mass at the hand, fore-aft, handle gripped: van Beek et al. 2015 Fig. 3 "
    "(seated, shoulder strapped) one trial M = 0.554 kg [checked: figure caption]; a two-link "
    "arm with Winter/de Leva segment data gives 1.3-2.5 kg for a 75 kg operator with the "
    "elbow near 90 deg [computed]; Tsuji et al. 1995, Dolan et al. 1993 and Perreault et al. "
    "2004 report endpoint inertias within 0.5-2.5 kg [tables not checked in the source]",
)
_F_ARM = HumanRange(
    "f_arm_hz",
    1.0,
    5.0,
    "loguniform",
    "Hz",
    "hand-arm endpoint natural frequency sqrt(K/M)/(2 pi): van Beek et al. 2015 Fig. 3 trial "
    "K = 135 N/m, M = 0.554 kg -> 2.48 Hz [checked: caption; computed]; endpoint stiffness "
    "100-1000 N/m over 0.5-2.5 kg in Tsuji et al. 1995 / Perreault et al. 2004 spans about "
    "1-5 Hz; grip force and task raise it, a force task lowers it (Venrooij et al. 2011; Fu "
    "& Cavusoglu 2012 on a Phantom stylus) [ranges not checked in the source tables]",
)
_Z_ARM = HumanRange(
    "zeta_arm",
    0.15,
    0.5,
    "uniform",
    "-",
    "hand-arm endpoint damping ratio B/(2 sqrt(K M)): van Beek et al. 2015 Fig. 3 trial "
    "B = 6.45 N s/m -> 0.37 [checked: caption; computed]; endpoint viscosity grows with "
    "stiffness (Dolan et al. 1993; Perreault et al. 2004), keeping the ratio near 0.15-0.5 "
    "[range not checked in the source tables]",
)
_F_TRUNK = {
    "backrest": HumanRange(
        "f_trunk_hz",
        2.0,
        5.0,
        "uniform",
        "Hz",
        "seated fore-aft apparent-mass peak WITH a backrest: a back support stiffens the body "
        "and limits the low-frequency rocking of the upper body (Rakheja group, back-support "
        "study) [checked: abstract, qualitative]; peaks near 2-5 Hz (Nawayseh & Griffin 2005; "
        "ISO 5982:2019 x-axis idealised values, with backrest) [values not checked in the "
        "source]",
    ),
    "no-backrest": HumanRange(
        "f_trunk_hz",
        0.7,
        1.5,
        "uniform",
        "Hz",
        "seated fore-aft apparent-mass peak WITHOUT a backrest: a peak near 1 Hz in the x "
        "direction (Amari & Perrin 2022, rigid seat, 14 subjects) [checked: abstract]; peaks "
        "near 0.7-1.5 Hz (Fairley & Griffin 1990; Mansfield & Lundstrom 1999) [values not "
        "checked in the source]",
    ),
}
_Z_TRUNK = HumanRange(
    "zeta_trunk",
    0.2,
    0.5,
    "uniform",
    "-",
    "damping ratio of the seated fore-aft apparent-mass peak: the peaks are broad, about "
    "0.2-0.5 in lumped-model fits to Fairley & Griffin 1990 and ISO 5982:2019 x-axis data "
    "[not checked in the source: an inference from the published curves' width]",
)

#: Published ranges per posture: name -> HumanRange.
PUBLISHED = {
    posture: {r.name: r for r in (_BODY, _M_ARM, _F_ARM, _Z_ARM, _F_TRUNK[posture], _Z_TRUNK)}
    for posture in POSTURES
}

_STRESS_NOTE = "STRESS VARIANT, beyond the published range: "


def _widen(r: HumanRange, low: float, high: float) -> HumanRange:
    return dataclasses.replace(r, low=low, high=high, source=_STRESS_NOTE + r.source)


#: Stress ranges per posture (beyond the published ones; labelled wherever shown).
STRESS = {
    posture: {
        "body_mass": _widen(_BODY, 45.0, 130.0),
        "m_arm": _widen(_M_ARM, 0.3, 5.0),
        "f_arm_hz": _widen(_F_ARM, 0.7, 8.0),
        "zeta_arm": _widen(_Z_ARM, 0.1, 0.8),
        "f_trunk_hz": _widen(
            _F_TRUNK[posture], *((1.5, 7.0) if posture == "backrest" else (0.4, 3.0))
        ),
        "zeta_trunk": _widen(_Z_TRUNK, 0.1, 0.8),
    }
    for posture in POSTURES
}


def _check_posture(posture: str) -> str:
    if posture not in POSTURES:
        raise ParameterError(f"posture must be one of {POSTURES}; got {posture!r}")
    return posture


def published_box(posture: str = DEFAULT_POSTURE) -> dict[str, HumanRange]:
    """The published ranges of the physical human's parameters for ``posture``.

    Parameters
    ----------
    posture : {"backrest", "no-backrest"}
        The operator's posture.
    """
    return dict(PUBLISHED[_check_posture(posture)])


def stress_box(posture: str = DEFAULT_POSTURE) -> dict[str, HumanRange]:
    """The stress ranges (beyond the published ones) for ``posture``.

    Parameters
    ----------
    posture : {"backrest", "no-backrest"}
        The operator's posture.
    """
    return dict(STRESS[_check_posture(posture)])
