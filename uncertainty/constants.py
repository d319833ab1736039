"""Named choices and defaults of the families and their margins that need no numerical library.

The command line builds its options from these (choices, defaults, help texts) before it
imports any numerical module, so that ``bdft --help`` answers without NumPy. Each is
defined here once and re-exported by the module it belongs to: :data:`RANGES` by
:mod:`uncertainty.family`, :data:`LOWER_METHODS` and :data:`DEFAULT_BOXES` by
:mod:`uncertainty.margins`, :data:`DEFAULT_CHUNK` by :mod:`uncertainty.validation` (and
:data:`RANGES` and :data:`DEFAULT_CHUNK` by :mod:`uncertainty`).

This module imports nothing.
"""

__all__ = ["RANGES", "LOWER_METHODS", "DEFAULT_BOXES", "DEFAULT_CHUNK"]

#: Ranges a default family can span: the published ones, or the labelled stress variant.
RANGES = ("published", "stress")
#: Lower-bound methods of the robust margin: ``auto`` (the value-set zero exclusion where it
#: applies, else the eigenvalue enclosures), verified eigenvalue enclosures, a quadratic
#: Lyapunov certificate of the interval matrix, or zero exclusion on value sets
#: (:mod:`uncertainty.valueset`).
LOWER_METHODS = ("auto", "eigenvalues", "lyapunov", "valueset", "mu")
#: Sub-boxes tried per scale by the robust margin's lower bound (sets the result on every
#: machine).
DEFAULT_BOXES = 400
#: Members per chunk of batched validation: about 27 MB of closed-loop matrices for a
#: 13-state loop (smaller chunks reuse memory instead of faulting in fresh pages for every
#: batch).
DEFAULT_CHUNK = 20_000
