"""Named defaults of the analysis layer that need no numerical library.

The command line builds its options from these (choices, defaults, help texts) before it
imports any numerical module, so that ``bdft --help`` answers without NumPy. Each is
defined here once and re-exported by the module it belongs to:
:data:`DAMPING_BAND_HZ` by :mod:`robust.analysis.stability` (and :mod:`uncertainty`). The
machine's own named choices are :mod:`backhoe.constants`.

This module imports nothing.
"""

__all__ = ["DAMPING_BAND_HZ"]

#: The one default band (Hz) of the damping ratio, required (the specification's and the
#: pole region's) and reported (validation, sweeps, design evaluations): from below the
#: loop's low-frequency feedthrough mode (about 0.7 Hz) to above the structure's modes
#: (6.3-6.5 Hz in the paper, up to about 9 Hz over the family's cabs).
DAMPING_BAND_HZ = (0.5, 10.0)
