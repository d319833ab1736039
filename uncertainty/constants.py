"""Named choices and defaults of the robust margins that need no numerical library.

The command line builds its options from these (choices, defaults, help texts) before it
imports any numerical module, so that ``bdft --help`` answers without NumPy. Each is
defined here once and re-exported by the module it belongs to: :data:`LOWER_METHODS` and
:data:`DEFAULT_BOXES` by :mod:`uncertainty.margins`, :data:`DEFAULT_CHUNK` by
:mod:`uncertainty.validation` (and :mod:`uncertainty`). The families' own named choices are
:mod:`backhoe.constants`.

This module imports nothing.
"""

__all__ = ["LOWER_METHODS", "DEFAULT_BOXES", "DEFAULT_CHUNK"]

#: Lower-bound methods of the robust margin: ``auto`` (the value-set zero exclusion where it
#: applies, else the eigenvalue enclosures), verified eigenvalue enclosures, a quadratic
#: Lyapunov certificate of the interval matrix, or zero exclusion on value sets
#: (:mod:`backhoe.families.valueset`).
LOWER_METHODS = ("auto", "eigenvalues", "lyapunov", "valueset", "mu")
#: Sub-boxes tried per scale by the robust margin's lower bound (sets the result on every
#: machine).
DEFAULT_BOXES = 400
#: Members per chunk of batched validation: about 27 MB of closed-loop matrices for a
#: 13-state loop (smaller chunks reuse memory instead of faulting in fresh pages for every
#: batch).
DEFAULT_CHUNK = 20_000
