"""Named choices and defaults of the machine and its families that need no numerical library.

The command line builds its options from these (choices, defaults, help texts) before it
imports any numerical module, so that ``bdft --help`` answers without NumPy. Each is
defined here once and re-exported by the module it belongs to:
:data:`HUMAN_VARIANT_NAMES` by :mod:`backhoe.model.human`, :data:`POSTURES` and
:data:`DEFAULT_POSTURE` by :mod:`backhoe.model.literature`, :data:`RANGES` by
:mod:`backhoe.families.family` (and :mod:`backhoe`), :data:`DAMPING_BAND_HZ` by
:mod:`backhoe` (the BDFT band: the family's, the specification's and the reports' default
band of the damping ratio; the core's functions take a band from their caller).

This module imports nothing.
"""

__all__ = ["HUMAN_VARIANT_NAMES", "POSTURES", "DEFAULT_POSTURE", "RANGES", "DAMPING_BAND_HZ"]

#: Named nominal human variants (:func:`backhoe.model.human.human_variant`).
HUMAN_VARIANT_NAMES = ("literal", "physical", "physical-no-backrest", "eqn5-fit")
#: Named postures of the seated operator.
POSTURES = ("backrest", "no-backrest")
#: The paper's operator sits in the backhoe's seat, which has a backrest (its LifeMOD
#: model, Figure 8, is "a human operator on the backhoe seat").
DEFAULT_POSTURE = "backrest"
#: Ranges a default family can span: the published ones, or the labelled stress variant.
RANGES = ("published", "stress")
#: The one default band (Hz) of the damping ratio, required (the specification's and the
#: pole region's) and reported (validation, sweeps, design evaluations): from below the
#: loop's low-frequency feedthrough mode (about 0.7 Hz) to above the structure's modes
#: (6.3-6.5 Hz in the paper, up to about 9 Hz over the family's cabs).
DAMPING_BAND_HZ = (0.5, 10.0)
