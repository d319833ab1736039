"""Pluggable human-body variants for the BDFT loop.

A human variant maps cab (seat) acceleration ``c`` to hand motion relative to the
seat ``h``; a variant with a force port also takes the force ``f`` the handle
applies to the hand. Everything downstream (loop, analysis, reports) goes through
:class:`HumanModel`, so nothing hard-codes the paper's Eqn 5.

Variants here:

* :class:`LiteralHuman`: the paper's Eqn 5 exactly as printed;
* ``uncertainty.PhysicalHuman``: a lumped mass-spring-damper model fitted to
  Eqn 5 over the coherent band, with a force port.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

import control as ct

from backhoe.constants import HUMAN_VARIANT_NAMES
from backhoe.model.physical import EQN5_FIT, PhysicalHuman, nominal_params
from robust.checks import POSITIVE, validate_fields
from robust.errors import ParameterError

__all__ = [
    "HumanModel",
    "LiteralHumanParams",
    "LiteralHuman",
    "human_variant",
    "HUMAN_VARIANT_NAMES",
    "LITERAL_SPECS",
]

#: What each :class:`LiteralHumanParams` field must satisfy (the family's physical limits too).
LITERAL_SPECS = {"k_h": POSITIVE, "z1": POSITIVE, "p1": POSITIVE}


@runtime_checkable
class HumanModel(Protocol):
    """What the loop needs from a human variant.

    Attributes
    ----------
    variant : str
        Short name (``"literal"``, ``"physical"``) used in reports and the CLI.
    has_force_port : bool
        Whether :meth:`system` has the handle-force input ``f``.
    """

    variant: str
    has_force_port: bool

    def system(self, *, name: str = "human") -> ct.StateSpace:
        """Named system with input ``c`` (and ``f`` if it has a force port) and output ``h``."""
        ...

    def describe(self) -> dict:
        """Parameters and provenance, for reports and artifacts."""
        ...


@dataclasses.dataclass(frozen=True)
class LiteralHumanParams:
    """Parameters of the paper's Eqn 5, ``H/C = K_H (s + z1H)^2 / (s^2 (s + p1H)^2)``.

    Parameters
    ----------
    k_h : float
        Gain ``K_H``, default 5.
    z1 : float
        Double real zero in rad/s, default 50.3.
    p1 : float
        Double real pole in rad/s, default 1.57.
    """

    k_h: float = 5.0
    z1: float = 50.3
    p1: float = 1.57

    def __post_init__(self):
        validate_fields(self, LITERAL_SPECS)


@dataclasses.dataclass(frozen=True)
class LiteralHuman:
    """The paper's Eqn 5 as printed: seat acceleration ``c`` -> hand motion ``h``.

    The hand motion is relative to the seat. Taken literally the model has a double
    integrator: between ``p1`` (0.25 Hz) and ``z1`` (8 Hz) its gain falls like
    1/omega^4, and below ``p1`` like 1/omega^2, so a slow cab motion produces an
    unbounded relative hand motion. It has no force port.

    Parameters
    ----------
    params : LiteralHumanParams, optional
        Gain, double zero and double pole of Eqn 5; the paper's values when omitted.

    Attributes
    ----------
    variant : str
        Always ``"literal"`` (not a constructor argument).
    has_force_port : bool
        Always False (not a constructor argument).
    """

    params: LiteralHumanParams = dataclasses.field(default_factory=LiteralHumanParams)
    variant: str = dataclasses.field(default="literal", init=False)
    has_force_port: bool = dataclasses.field(default=False, init=False)

    def __post_init__(self):
        if not isinstance(self.params, LiteralHumanParams):
            raise ParameterError(
                f"LiteralHuman.params must be LiteralHumanParams; got {type(self.params).__name__}"
            )

    def transfer_function(self) -> ct.TransferFunction:
        """Eqn 5 as a transfer function ``H/C`` (order 4: double pole at 0 and at ``-p1``)."""
        p = self.params
        num = [p.k_h, 2.0 * p.k_h * p.z1, p.k_h * p.z1 * p.z1]
        den = [1.0, 2.0 * p.p1, p.p1 * p.p1, 0.0, 0.0]
        return ct.tf(num, den)

    def system(self, *, name: str = "human") -> ct.StateSpace:
        """Named state-space system, input ``c`` (seat acceleration), output ``h``.

        Parameters
        ----------
        name : str, optional
            System name given to the python-control system, ``"human"`` by default.
        """
        return ct.ss(self.transfer_function(), inputs="c", outputs="h", name=name)

    def describe(self) -> dict:
        """Variant, equation and the Eqn 5 parameters, as a JSON-ready dict."""
        return {
            "variant": self.variant,
            "equation": "paper Eqn 5",
            **dataclasses.asdict(self.params),
        }


# HUMAN_VARIANT_NAMES, the names human_variant knows, is defined in backhoe.constants (the
# command line reads it without this module's libraries)


def human_variant(name: str) -> HumanModel:
    """Return the nominal human variant called ``name``.

    Parameters
    ----------
    name : {"literal", "physical", "physical-no-backrest", "eqn5-fit"}
        ``"literal"``: :class:`LiteralHuman` (Eqn 5 as printed); ``"physical"``: the
        mass-spring-damper chain with a force port
        (:class:`~backhoe.model.physical.PhysicalHuman`), nominal operator of the
        published ranges with a backrest; ``"physical-no-backrest"``: the same without
        a backrest; ``"eqn5-fit"``: the chain with the unconstrained magnitude-only fit
        to Eqn 5 (:data:`~backhoe.model.physical.EQN5_FIT`, outside the published
        ranges), kept for comparison.

    Returns
    -------
    HumanModel
        A new instance of the variant.

    Raises
    ------
    ParameterError
        (a ``ValueError``) If ``name`` is not one of :data:`HUMAN_VARIANT_NAMES`.
    """
    if name == "literal":
        return LiteralHuman()
    if name == "physical":
        return PhysicalHuman()
    if name == "physical-no-backrest":
        return PhysicalHuman(nominal_params("no-backrest"), variant=name)
    if name == "eqn5-fit":
        return PhysicalHuman(EQN5_FIT, variant=name)
    raise ParameterError(f"human variant must be one of {HUMAN_VARIANT_NAMES}; got {name!r}")
