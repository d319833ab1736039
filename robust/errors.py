"""Exception hierarchy of the workbench.

Every error the workbench raises on purpose derives from :class:`BDFTError` and
from the built-in exception a caller would expect (``ValueError`` for bad input,
``RuntimeError`` for a failed computation), so ``except ValueError`` keeps
working for code that does not know this module.

Messages name the parameter or the step, what was expected and what was got, and
where possible what to try.
"""

from __future__ import annotations

__all__ = [
    "BDFTError",
    "ParameterError",
    "DataError",
    "ModelStructureError",
    "AssumptionError",
    "InfeasibleError",
    "SolverError",
    "VerificationError",
    "ArtifactError",
]


class BDFTError(Exception):
    """Base class of every error raised on purpose by the workbench."""


class ParameterError(BDFTError, ValueError):
    """A parameter is non-finite, of the wrong sign, out of range or inconsistent."""


class DataError(BDFTError, ValueError):
    """Measured data are malformed: NaN, wrong shape, non-uniform sampling, too short."""


class ModelStructureError(BDFTError, ValueError):
    """A system does not have the signals, sizes or time base a step needs."""


class AssumptionError(BDFTError, ValueError):
    """A standing assumption of an algorithm fails (stabilisability, rank of D12, ...)."""


class InfeasibleError(BDFTError, RuntimeError):
    """An optimisation problem (LMI, fit) has no solution satisfying its constraints."""


class SolverError(BDFTError, RuntimeError):
    """A numerical solver failed or returned an answer that could not be used."""


class VerificationError(BDFTError, RuntimeError):
    """An independent check contradicts a solver's answer; the answer is not returned."""


class ArtifactError(BDFTError, ValueError):
    """A controller artifact file is malformed or fails validation on load."""
