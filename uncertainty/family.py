"""Parametric families of the BDFT loop: which parameters vary, over what, and why.

A :class:`Family` is the fixed part of the loop (valve/cylinder, calibration,
position scale factor, human variant) plus a tuple of
:class:`~uncertainty.parameters.UncertainParameter`. Parameters the family does
not vary stay at the nominal values the family holds, so a fitted component
(:mod:`uncertainty.files`) changes the family by changing its nominals.

Parameter names:

* structure (Eqn 4): ``struct.k_s``, ``struct.zeta1``, ``struct.zeta2``,
  ``struct.f1_hz``, ``struct.f2_hz``;
* physical human: ``human.body_mass`` (scales both masses), ``human.k_trunk``,
  ``human.c_trunk``, ``human.k_arm``, ``human.c_arm``;
* literal human (Eqn 5): ``human.k_h``, ``human.p1``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np

from robust.checks import POSITIVE, check_scalar
from robust.errors import ParameterError
from robust.model.anthropometry import NOMINAL_BODY_MASS
from robust.model.components import K_PSF_NOMINAL, StructureParams, ValveCylinderParams
from robust.model.human import LiteralHuman, LiteralHumanParams
from robust.model.loop import DEFAULT_CALIBRATION, BDFTLoop, LoopCalibration
from robust.model.physical import PhysicalHuman, PhysicalHumanParams
from uncertainty.parameters import UncertainParameter

__all__ = ["HUMAN_VARIANTS", "Family", "default_family", "MODEL_PARAMETERS"]

HUMAN_VARIANTS = ("physical", "literal")

_STRUCT = ("k_s", "zeta1", "zeta2", "f1_hz", "f2_hz")
_PHYS = ("m_trunk", "m_arm", "k_trunk", "c_trunk", "k_arm", "c_arm", "h_gain", "c_unit")
_LIT = ("k_h", "z1", "p1")

#: Names of the family parameters each variant accepts.
MODEL_PARAMETERS = {
    "physical": tuple(f"struct.{n}" for n in _STRUCT)
    + ("human.body_mass",)
    + tuple(f"human.{n}" for n in _PHYS if n not in ("m_trunk", "m_arm")),
    "literal": tuple(f"struct.{n}" for n in _STRUCT) + tuple(f"human.{n}" for n in _LIT),
}


@dataclasses.dataclass(frozen=True)
class Family:
    """A set of BDFT loops: fixed parts, nominal values and uncertain parameters.

    Parameters
    ----------
    parameters : tuple of UncertainParameter
        What varies; names from :data:`MODEL_PARAMETERS` for the ``human`` variant.
    human : {"physical", "literal"}
        Human variant of every member.
    k_psf : float
        Position scale factor of every member.
    valve, struct, literal, physical : parameter dataclasses
        Nominal values (the valve does not vary).
    body_mass : float
        Nominal body mass (kg) that ``physical``'s masses belong to; a member with
        ``human.body_mass = M`` has both masses scaled by ``M / body_mass``.
    calibration : LoopCalibration
        PI gains, junction sign and loop-scale factor of every member.
    name : str
        Label for reports.
    """

    parameters: tuple[UncertainParameter, ...]
    human: str = "physical"
    k_psf: float = K_PSF_NOMINAL
    valve: ValveCylinderParams = dataclasses.field(default_factory=ValveCylinderParams)
    struct: StructureParams = dataclasses.field(default_factory=StructureParams)
    literal: LiteralHumanParams = dataclasses.field(default_factory=LiteralHumanParams)
    physical: PhysicalHumanParams = dataclasses.field(default_factory=PhysicalHumanParams)
    body_mass: float = NOMINAL_BODY_MASS
    calibration: LoopCalibration = DEFAULT_CALIBRATION
    name: str = "default"

    def __post_init__(self):
        if self.human not in HUMAN_VARIANTS:
            raise ParameterError(
                f"Family.human must be one of {HUMAN_VARIANTS}; got {self.human!r}"
            )
        object.__setattr__(
            self, "k_psf", check_scalar("k_psf", self.k_psf, POSITIVE, owner="Family")
        )
        object.__setattr__(
            self, "body_mass", check_scalar("body_mass", self.body_mass, POSITIVE, owner="Family")
        )
        params = tuple(self.parameters)
        allowed = MODEL_PARAMETERS[self.human]
        for p in params:
            if not isinstance(p, UncertainParameter):
                raise ParameterError(
                    f"Family.parameters must be UncertainParameter; got {type(p).__name__}"
                )
            if p.name not in allowed:
                raise ParameterError(
                    f"Family: parameter {p.name!r} is not a parameter of the {self.human} variant; "
                    f"choose from {list(allowed)}"
                )
        names = [p.name for p in params]
        if len(set(names)) != len(names):
            raise ParameterError(f"Family: parameter names must be unique; got {names}")
        object.__setattr__(self, "parameters", params)

    # -- views -------------------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        """Names of the uncertain parameters, in order (the columns of member values)."""
        return tuple(p.name for p in self.parameters)

    def parameter(self, name: str) -> UncertainParameter:
        """The uncertain parameter called ``name``.

        Parameters
        ----------
        name : str
            A name of :attr:`names`, e.g. ``"struct.f1_hz"``.

        Raises
        ------
        ParameterError
            If the family does not vary a parameter of that name.
        """
        for p in self.parameters:
            if p.name == name:
                return p
        raise ParameterError(f"Family has no uncertain parameter {name!r}; have {list(self.names)}")

    def nominal_values(self) -> np.ndarray:
        """Nominal value of every uncertain parameter, shape (d,)."""
        return np.array([p.nominal for p in self.parameters])

    def replace(self, **changes) -> Family:
        """A copy with the given fields changed (validated again).

        Parameters
        ----------
        **changes
            Field names and new values, as for :func:`dataclasses.replace`.
        """
        return dataclasses.replace(self, **changes)

    def with_workspace_factor(self, factor: float) -> Family:
        """The same family with ``K_PSF`` divided by ``factor`` (workspace multiplied).

        Parameters
        ----------
        factor : float
            Workspace factor, > 0 (2 doubles the handle workspace).
        """
        f = check_scalar("factor", factor, POSITIVE)
        return self.replace(k_psf=self.k_psf / f)

    # -- members -------------------------------------------------------------------------------
    def model_arrays(self, values: np.ndarray) -> dict[str, np.ndarray]:
        """Every model parameter of every member, as arrays.

        Parameters
        ----------
        values : ndarray, shape (N, d)
            Uncertain-parameter values, columns in the order of :attr:`names`.

        Returns
        -------
        dict
            ``"struct.<field>"`` and ``"human.<field>"`` (fields of
            :class:`~robust.model.components.StructureParams` and of the variant's human
            parameters) -> array of shape (N,).
        """
        v = np.asarray(values, float)
        if v.ndim != 2 or v.shape[1] != len(self.parameters):
            raise ParameterError(
                f"Family.model_arrays: values must have shape (N, {len(self.parameters)}); "
                f"got {v.shape}"
            )
        n = v.shape[0]
        cols = {name: v[:, j] for j, name in enumerate(self.names)}
        out = {}
        for f in _STRUCT:
            out[f"struct.{f}"] = cols.get(f"struct.{f}", np.full(n, getattr(self.struct, f)))
        if self.human == "literal":
            for f in _LIT:
                out[f"human.{f}"] = cols.get(f"human.{f}", np.full(n, getattr(self.literal, f)))
        else:
            scale = cols.get("human.body_mass", np.full(n, self.body_mass)) / self.body_mass
            out["human.m_trunk"] = self.physical.m_trunk * scale
            out["human.m_arm"] = self.physical.m_arm * scale
            for f in _PHYS[2:]:
                out[f"human.{f}"] = cols.get(f"human.{f}", np.full(n, getattr(self.physical, f)))
        return out

    def member(self, values: Sequence[float] | Mapping[str, float]) -> BDFTLoop:
        """The python-control loop of one member (slow; for checks and single members).

        Parameters
        ----------
        values : sequence of float (length d) or mapping name -> value
            Uncertain-parameter values; missing names take the nominal.
        """
        if isinstance(values, Mapping):
            unknown = set(values) - set(self.names)
            if unknown:
                raise ParameterError(
                    f"Family.member: unknown parameters {sorted(unknown)}; have {list(self.names)}"
                )
            row = [values.get(p.name, p.nominal) for p in self.parameters]
        else:
            row = list(values)
        arrays = self.model_arrays(np.asarray(row, float)[None, :])
        one = {k: float(a[0]) for k, a in arrays.items()}
        struct = StructureParams(**{f: one[f"struct.{f}"] for f in _STRUCT})
        if self.human == "literal":
            human = LiteralHuman(LiteralHumanParams(**{f: one[f"human.{f}"] for f in _LIT}))
        else:
            human = PhysicalHuman(PhysicalHumanParams(**{f: one[f"human.{f}"] for f in _PHYS}))
        return BDFTLoop(
            k_psf=self.k_psf,
            valve=self.valve,
            struct=struct,
            human=human,
            calibration=self.calibration,
        )

    def describe(self) -> dict:
        """JSON-ready description (fixed parts, nominals and parameters)."""
        return {
            "name": self.name,
            "human": self.human,
            "k_psf": self.k_psf,
            "valve": dataclasses.asdict(self.valve),
            "struct": dataclasses.asdict(self.struct),
            "human_nominal": dataclasses.asdict(
                self.literal if self.human == "literal" else self.physical
            ),
            "calibration": dataclasses.asdict(self.calibration),
            "parameters": [p.describe() for p in self.parameters],
        }


# -- the default family ------------------------------------------------------------------------
#: Total width (high/low) of the log-uniform human stiffness and damping ranges.
HUMAN_SPREAD = 10.0
#: Lowest structure frequency as a fraction of the stilts value.
WHEELS_FREQUENCY_FRACTION = 0.4


def _structure_parameters(s: StructureParams) -> list[UncertainParameter]:
    lo_f = WHEELS_FREQUENCY_FRACTION
    return [
        UncertainParameter(
            "struct.k_s",
            s.k_s,
            s.k_s,
            3.0 * s.k_s,
            "loguniform",
            "-",
            # the paper: on its wheels the cab moves with larger amplitude than on stilts
            "Eqn 4 gain on stilts (lower bound); softer support on tyres gives larger cab "
            "motion, up to 3x",
        ),
        UncertainParameter(
            "struct.zeta1",
            s.zeta1,
            0.5 * s.zeta1,
            min(2.0 * s.zeta1, 0.6),
            "uniform",
            "-",
            "Eqn 4 stilts value x0.5..x2: tyres add damping, soil and outriggers change it (paper)",
        ),
        UncertainParameter(
            "struct.zeta2",
            s.zeta2,
            0.5 * s.zeta2,
            min(2.0 * s.zeta2, 0.6),
            "uniform",
            "-",
            "Eqn 4 stilts value x0.5..x2: tyres add damping, soil and outriggers change it (paper)",
        ),
        UncertainParameter(
            "struct.f1_hz",
            s.f1_hz,
            lo_f * s.f1_hz,
            s.f1_hz,
            "uniform",
            "Hz",
            # tyre-supported machines have rigid-body cab modes near 2.5-3 Hz; stilts are
            # stiffer
            "stilts value (paper, stiffest case) down to x0.4 (about 2.5 Hz), a machine "
            "rocking on its tyres",
        ),
        UncertainParameter(
            "struct.f2_hz",
            s.f2_hz,
            lo_f * s.f2_hz,
            s.f2_hz,
            "uniform",
            "Hz",
            "stilts value (paper, stiffest case) down to x0.4 (about 2.6 Hz), a machine "
            "rocking on its tyres",
        ),
    ]


def _spread(name, nominal, units, source):
    r = math.sqrt(HUMAN_SPREAD)
    return UncertainParameter(name, nominal, nominal / r, nominal * r, "loguniform", units, source)


def _physical_parameters(p: PhysicalHumanParams, body_mass: float) -> list[UncertainParameter]:
    note = (
        "fit to Eqn 5 (paper: Hybrid III x0.6) spread over one order of magnitude, "
        "as literature values vary (paper)"
    )
    return [
        UncertainParameter(
            "human.body_mass",
            body_mass,
            min(50.0, body_mass),
            max(110.0, body_mass),
            "uniform",
            "kg",
            "small (about 5th percentile female, 50 kg) to large (about 95th percentile "
            "male, 110 kg) operator",
        ),
        _spread("human.k_trunk", p.k_trunk, "N/m", note),
        _spread("human.c_trunk", p.c_trunk, "N s/m", note),
        _spread("human.k_arm", p.k_arm, "N/m", note + "; grip and posture change the arm most"),
        _spread("human.c_arm", p.c_arm, "N s/m", note + "; active vs passive grip (paper)"),
    ]


def _literal_parameters(p: LiteralHumanParams) -> list[UncertainParameter]:
    return [
        _spread(
            "human.k_h",
            p.k_h,
            "-",
            "Eqn 5 gain spread over one order of magnitude (human variability, paper)",
        ),
        UncertainParameter(
            "human.p1",
            p.p1,
            0.5 * p.p1,
            2.0 * p.p1,
            "loguniform",
            "rad/s",
            "Eqn 5 pole x0.5..x2: fitted to low-coherence data (paper)",
        ),
    ]


def default_family(
    human: str = "physical",
    *,
    k_psf: float = K_PSF_NOMINAL,
    valve: ValveCylinderParams | None = None,
    struct: StructureParams | None = None,
    literal: LiteralHumanParams | None = None,
    physical: PhysicalHumanParams | None = None,
    body_mass: float = NOMINAL_BODY_MASS,
    calibration: LoopCalibration = DEFAULT_CALIBRATION,
) -> Family:
    """The default family (BRIEF section 5) around the given nominals.

    Structure: natural frequencies from the stilts values down to x0.4 (a machine
    on its tyres), damping ratios x0.5..x2, gain x1..x3 (larger cab motion on
    tyres). Physical human: stiffnesses and dampings log-uniform over one order of
    magnitude around the fit, body mass 50-110 kg. Literal human: gain over one
    order of magnitude, pole x0.5..x2. The valve/cylinder does not vary.

    Parameters
    ----------
    human : {"physical", "literal"}
        Human variant.
    k_psf : float
        Position scale factor of every member.
    valve, struct, literal, physical : optional
        Nominal parameters (default: the paper's values and the physical fit).
    body_mass : float
        Body mass (kg) the physical nominal masses belong to.
    calibration : LoopCalibration
        Loop calibration (default :data:`robust.model.loop.DEFAULT_CALIBRATION`).

    Returns
    -------
    Family
        Named ``"default-<human>"``; five structure parameters plus five
        (physical) or two (literal) human parameters.

    Raises
    ------
    ParameterError
        If ``human`` is not a known variant.
    """
    struct = struct or StructureParams()
    literal = literal or LiteralHumanParams()
    physical = physical or PhysicalHumanParams()
    params = _structure_parameters(struct)
    if human == "physical":
        params += _physical_parameters(physical, body_mass)
    elif human == "literal":
        params += _literal_parameters(literal)
    else:
        raise ParameterError(
            f"default_family: human must be one of {HUMAN_VARIANTS}; got {human!r}"
        )
    return Family(
        parameters=tuple(params),
        human=human,
        k_psf=k_psf,
        valve=valve or ValveCylinderParams(),
        struct=struct,
        literal=literal,
        physical=physical,
        body_mass=body_mass,
        calibration=calibration,
        name=f"default-{human}",
    )
