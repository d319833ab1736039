"""Parametric families of the BDFT loop: which parameters vary.

A :class:`Family` is the fixed part of the loop (calibration, position scale factor,
human variant) and the nominal values of its blocks, plus a tuple of
:class:`~uncertainty.parameters.UncertainParameter`. Parameters the family does
not vary stay at the nominal values the family holds, so a fitted component
(:mod:`backhoe.families.files`) changes the family by changing its nominals.

Parameter names are the model's (:func:`backhoe.model.blocks.parameter_name`: the block and
the field, e.g. the valve's gain, the structure's first natural frequency or the arm's
effective mass); :data:`MODEL_PARAMETERS` lists the ones each human variant accepts. The
valve/cylinder (Eqn 3) varies its gain, real pole, valve frequency and damping ratio in
every variant. The physical human is varied as biodynamics papers report it
(:mod:`backhoe.model.literature`): body mass (which scales the upper-body mass), the arm
endpoint's effective mass, natural frequency and damping ratio with the trunk held, the
trunk's natural frequency and damping ratio on the seat; stiffnesses and dampings are
derived (:mod:`backhoe.model.modal`). The literal human (Eqn 5) varies its gain and pole.

Over what each parameter of the default family varies, and why:
:mod:`backhoe.families.family_ranges` (:func:`~backhoe.families.family_ranges.default_family`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from backhoe.constants import RANGES
from backhoe.model.anthropometry import NOMINAL_BODY_MASS
from backhoe.model.blocks import (
    LITERAL_HUMAN_FIELDS,
    STRUCTURE_FIELDS,
    VALVE_FIELDS,
    block_of,
    field_of,
    parameter_name,
)
from backhoe.model.components import K_PSF_NOMINAL, StructureParams, ValveCylinderParams
from backhoe.model.human import LITERAL_SPECS, LiteralHuman, LiteralHumanParams
from backhoe.model.literature import DEFAULT_POSTURE, POSTURES
from backhoe.model.loop import DEFAULT_CALIBRATION, BDFTLoop, LoopCalibration
from backhoe.model.modal import modal_to_physical
from backhoe.model.physical import MODAL_SPECS, PHYSICAL_SPECS, PhysicalHuman, PhysicalHumanParams
from robust.checks import NONZERO, POSITIVE, Spec, check_columns, check_scalar
from robust.errors import ParameterError
from uncertainty.parameters import BOUNDS_RTOL, UncertainParameter

__all__ = [
    "HUMAN_VARIANTS",
    "RANGES",
    "Family",
    "MODEL_PARAMETERS",
    "PHYSICAL_LIMITS",
    "BOUNDS_RTOL",
]

HUMAN_VARIANTS = ("physical", "literal")
# RANGES (the published ranges or the labelled stress variant) is defined in
# uncertainty.constants (the command line reads it without NumPy)

_VALVE = VALVE_FIELDS
_STRUCT = STRUCTURE_FIELDS
_PHYS = ("m_trunk", "m_arm", "k_trunk", "c_trunk", "k_arm", "c_arm", "h_gain", "c_unit")
_MODAL = ("m_arm", "f_arm_hz", "zeta_arm", "f_trunk_hz", "zeta_trunk")
_LIT = LITERAL_HUMAN_FIELDS

#: Names of the family parameters each variant accepts.
MODEL_PARAMETERS = {
    "physical": tuple(parameter_name("valve", n) for n in _VALVE)
    + tuple(parameter_name("structure", n) for n in _STRUCT)
    + (parameter_name("human", "body_mass"),)
    + tuple(parameter_name("human", n) for n in _MODAL)
    + (parameter_name("human", "h_gain"), parameter_name("human", "c_unit")),
    "literal": tuple(parameter_name("valve", n) for n in _VALVE)
    + tuple(parameter_name("structure", n) for n in _STRUCT)
    + tuple(parameter_name("human", n) for n in _LIT),
}

#: What every value of a family parameter must satisfy to be a physical loop at all, whatever
#: the family's bounds (the check of ``check_bounds=False``): finite, with positive gains,
#: masses, natural frequencies and damping ratios and a nonzero unit gain ``h_gain`` -- the
#: sign constraints of the model's parameter dataclasses
#: (:data:`backhoe.model.components.VALVE_SPECS`, :data:`~backhoe.model.components.STRUCTURE_SPECS`,
#: :data:`backhoe.model.human.LITERAL_SPECS`, :data:`backhoe.model.physical.PHYSICAL_SPECS` and
#: :data:`~backhoe.model.physical.MODAL_SPECS`). A structure or valve damping ratio of 1 or more
#: (overdamped) is physical and the batched loop handles it; :meth:`Family.member` builds a
#: :class:`~backhoe.model.components.StructureParams` and a
#: :class:`~backhoe.model.components.ValveCylinderParams`, which hold it below 1.
PHYSICAL_LIMITS: dict[str, Spec] = {
    **{parameter_name("valve", n): POSITIVE for n in _VALVE},
    **{parameter_name("structure", n): POSITIVE for n in _STRUCT},
    **{parameter_name("human", n): LITERAL_SPECS[n] for n in _LIT},
    parameter_name("human", "body_mass"): POSITIVE,
    parameter_name("human", "m_arm"): PHYSICAL_SPECS["m_arm"],
    **{parameter_name("human", n): MODAL_SPECS[n] for n in _MODAL if n != "m_arm"},
    parameter_name("human", "h_gain"): NONZERO,
    parameter_name("human", "c_unit"): PHYSICAL_SPECS["c_unit"],
}


def _ndim(x) -> int:
    try:
        return int(np.ndim(x))
    except (TypeError, ValueError):  # ragged nested sequences
        return -1


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
        Nominal values: what a member takes for a model parameter the family does not vary.
    body_mass : float
        Nominal body mass (kg) that ``physical``'s upper-body mass belongs to; a member
        with body mass ``M`` has it scaled by ``M / body_mass``.
    calibration : LoopCalibration
        PI gains, junction sign and loop-scale factor of every member.
    name : str
        Label for reports.
    posture : {"backrest", "no-backrest"}
        Posture of the physical human's ranges (a label; the ranges are in ``parameters``).
    ranges : {"published", "stress"}
        Whether the human ranges are the published ones or the stress variant beyond them.
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
    posture: str = DEFAULT_POSTURE
    ranges: str = "published"

    def __post_init__(self):
        if self.human not in HUMAN_VARIANTS:
            raise ParameterError(
                f"Family.human must be one of {HUMAN_VARIANTS}; got {self.human!r}"
            )
        if self.posture not in POSTURES:
            raise ParameterError(f"Family.posture must be one of {POSTURES}; got {self.posture!r}")
        if self.ranges not in RANGES:
            raise ParameterError(f"Family.ranges must be one of {RANGES}; got {self.ranges!r}")
        object.__setattr__(
            self, "k_psf", check_scalar("k_psf", self.k_psf, POSITIVE, owner="Family")
        )
        object.__setattr__(
            self, "body_mass", check_scalar("body_mass", self.body_mass, POSITIVE, owner="Family")
        )
        for field, cls in (
            ("valve", ValveCylinderParams),
            ("struct", StructureParams),
            ("literal", LiteralHumanParams),
            ("physical", PhysicalHumanParams),
            ("calibration", LoopCalibration),
        ):
            if not isinstance(getattr(self, field), cls):
                raise ParameterError(
                    f"Family.{field} must be {cls.__name__}; "
                    f"got {type(getattr(self, field)).__name__}"
                )
        if isinstance(self.parameters, (str, bytes)) or not isinstance(self.parameters, Sequence):
            raise ParameterError(
                "Family.parameters must be a sequence of UncertainParameter; "
                f"got {type(self.parameters).__name__}"
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
            limit = PHYSICAL_LIMITS[p.name]
            for edge in ("low", "high"):
                if not limit.contains(getattr(p, edge)):
                    raise ParameterError(
                        f"Family: parameter {p.name!r} {edge}={getattr(p, edge)!r} is not "
                        f"physical; every value of {p.name} must be {limit.describe()}"
                    )
            if limit.nonzero and p.low <= 0.0 <= p.high:
                raise ParameterError(
                    f"Family: parameter {p.name!r} range [{p.low!r}, {p.high!r}] contains 0; "
                    f"every value of {p.name} must be {limit.describe()}"
                )
        names = [p.name for p in params]
        if len(set(names)) != len(names):
            raise ParameterError(f"Family: parameter names must be unique; got {names}")
        object.__setattr__(self, "parameters", params)

    # -- views -------------------------------------------------------------------------------
    @property
    def trunk_share(self) -> float:
        """The physical human's upper-body mass per unit body mass."""
        return self.physical.m_trunk / self.body_mass

    def fixed_value(self, name: str) -> float:
        """The value the family holds for a model parameter it may vary (its nominal).

        Parameters
        ----------
        name : str
            A name of :data:`MODEL_PARAMETERS` for the family's human variant.
        """
        if name not in MODEL_PARAMETERS[self.human]:
            raise ParameterError(
                f"Family.fixed_value: {name!r} is not a parameter of the {self.human} variant; "
                f"choose from {list(MODEL_PARAMETERS[self.human])}"
            )
        block, field = block_of(name), field_of(name)
        if block == "structure":
            return float(getattr(self.struct, field))
        if block == "valve":
            return float(getattr(self.valve, field))
        if field == "body_mass":
            return float(self.body_mass)
        return float(getattr(self.literal if self.human == "literal" else self.physical, field))

    def fixed_model_values(self) -> dict[str, float]:
        """Every model parameter of the variant (:data:`MODEL_PARAMETERS`) at the value the
        family holds (its nominal), by name."""
        return {name: self.fixed_value(name) for name in MODEL_PARAMETERS[self.human]}

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the uncertain parameters, in order (the columns of member values)."""
        return tuple(p.name for p in self.parameters)

    def parameter(self, name: str) -> UncertainParameter:
        """The uncertain parameter called ``name``.

        Parameters
        ----------
        name : str
            A name of :attr:`names`.

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
    def check_members(
        self,
        values,
        *,
        check_bounds: bool = True,
        row_offset: int = 0,
        where: str = "Family",
    ) -> np.ndarray:
        """Check member values once, vectorised; return them as an (N, d) float array.

        Every value must be finite and physical (:data:`PHYSICAL_LIMITS`: positive
        masses, gains, natural frequencies and damping ratios, a nonzero ``h_gain``)
        and, with ``check_bounds``, lie
        in the family's range ``[low, high]`` of its parameter (to within
        :data:`BOUNDS_RTOL`). A few comparisons per value: cheap beside the
        eigenvalues, even for millions of members.

        Parameters
        ----------
        values : array_like, shape (N, d)
            Uncertain-parameter values, columns in the order of :attr:`names`.
        check_bounds : bool
            Also require each value within the family's bounds (default). Pass False to
            analyse members beyond them (scaled boxes for robust margins, sweeps beyond
            the family); non-physical values are refused either way.
        row_offset : int
            Added to the row index in the message (``values`` being a slice of a larger set).
        where : str
            Name of the caller, first in the message.

        Returns
        -------
        numpy.ndarray
            ``values`` as a float array of shape (N, d).

        Raises
        ------
        ParameterError
            If ``values`` is not numeric or not of shape (N, d), or a value is non-finite,
            non-physical or (with ``check_bounds``) outside the family's bounds; the
            message names the member row, the parameter, what was expected and the value.
        """
        names = self.names
        v = check_columns(
            f"{where}: member",
            values,
            [PHYSICAL_LIMITS[n] for n in names],
            names,
            row_offset=row_offset,
            note=" (not physical)",
        )
        if check_bounds and v.size:
            specs = []
            for p in self.parameters:
                tol = BOUNDS_RTOL * max(abs(p.low), abs(p.high))
                specs.append(Spec(low=p.low - tol, high=p.high + tol))
            check_columns(
                f"{where}: member",
                v,
                specs,
                names,
                row_offset=row_offset,
                note=(
                    f" (the bounds of family {self.name!r}; pass check_bounds=False to "
                    "analyse members beyond them)"
                ),
            )
        return v

    def model_arrays(
        self, values: np.ndarray, *, check_bounds: bool = True
    ) -> dict[str, np.ndarray]:
        """Every model parameter of every member, as arrays.

        Parameters
        ----------
        values : ndarray, shape (N, d)
            Uncertain-parameter values, columns in the order of :attr:`names`; checked
            by :meth:`check_members`.
        check_bounds : bool
            Require the values within the family's bounds (default); physical limits
            are checked either way.

        Returns
        -------
        dict
            The model parameter names of the valve, the structure and the human
            (:func:`backhoe.model.blocks.parameter_name` of the fields of
            :class:`~backhoe.model.components.StructureParams` and of the variant's human
            parameters) -> array of shape (N,), in the fields' units (the valve's pole in rad/s,
            the valve's and the structure's frequencies in Hz).

        Raises
        ------
        ParameterError
            As :meth:`check_members`.
        """
        v = self.check_members(values, check_bounds=check_bounds, where="Family.model_arrays")
        return self._model_arrays(v)

    def _model_arrays(self, v: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`model_arrays` of values that passed :meth:`check_members` (no check)."""
        n = v.shape[0]
        cols = {name: v[:, j] for j, name in enumerate(self.names)}
        out = {}
        for f in _VALVE:
            name = parameter_name("valve", f)
            out[name] = cols.get(name, np.full(n, getattr(self.valve, f)))
        for f in _STRUCT:
            out[parameter_name("structure", f)] = cols.get(
                parameter_name("structure", f), np.full(n, getattr(self.struct, f))
            )
        if self.human == "literal":
            for f in _LIT:
                out[parameter_name("human", f)] = cols.get(
                    parameter_name("human", f), np.full(n, getattr(self.literal, f))
                )
        else:
            scale = (
                cols.get(parameter_name("human", "body_mass"), np.full(n, self.body_mass))
                / self.body_mass
            )
            # the nominal's modal values only for the parameters that do not vary (each
            # attribute of the physical parameters recomputes all four modal values)
            modal = {
                f: cols[parameter_name("human", f)]
                if parameter_name("human", f) in cols
                else np.full(n, getattr(self.physical, f))
                for f in _MODAL
            }
            m_trunk = self.physical.m_trunk * scale
            k_t, c_t, k_a, c_a = modal_to_physical(
                m_trunk,
                modal["m_arm"],
                modal["f_trunk_hz"],
                modal["zeta_trunk"],
                modal["f_arm_hz"],
                modal["zeta_arm"],
            )
            out[parameter_name("human", "m_trunk")] = m_trunk
            out[parameter_name("human", "m_arm")] = modal["m_arm"]
            out[parameter_name("human", "k_trunk")], out[parameter_name("human", "c_trunk")] = (
                k_t,
                c_t,
            )
            out[parameter_name("human", "k_arm")], out[parameter_name("human", "c_arm")] = k_a, c_a
            for f in ("h_gain", "c_unit"):
                out[parameter_name("human", f)] = cols.get(
                    parameter_name("human", f), np.full(n, getattr(self.physical, f))
                )
        return out

    def member(
        self, values: Sequence[float] | Mapping[str, float], *, check_bounds: bool = True
    ) -> BDFTLoop:
        """The python-control loop of one member (slow; for checks and single members).

        Parameters
        ----------
        values : sequence of float (length d) or mapping name -> value
            Uncertain-parameter values; missing names take the nominal.
        check_bounds : bool
            Require the values within the family's bounds (default); physical limits
            are checked either way (:meth:`check_members`).

        Raises
        ------
        ParameterError
            For unknown names, a wrong number of values, or values that fail
            :meth:`check_members`.
        """
        if isinstance(values, Mapping):
            unknown = set(values) - set(self.names)
            if unknown:
                raise ParameterError(
                    f"Family.member: unknown parameters {sorted(unknown)}; have {list(self.names)}"
                )
            row = [values.get(p.name, p.nominal) for p in self.parameters]
        elif isinstance(values, (str, bytes)) or _ndim(values) != 1:
            raise ParameterError(
                f"Family.member: values must be a sequence of {len(self.names)} numbers or a "
                f"mapping name -> value; got {values!r}"
            )
        else:
            row = list(values)
        if len(row) != len(self.names):
            raise ParameterError(
                f"Family.member: values must have {len(self.names)} entries "
                f"({list(self.names)}); got {len(row)}"
            )
        v = self.check_members([row], check_bounds=check_bounds, where="Family.member")
        arrays = self._model_arrays(v)
        one = {k: float(a[0]) for k, a in arrays.items()}
        valve = ValveCylinderParams(**{f: one[parameter_name("valve", f)] for f in _VALVE})
        struct = StructureParams(**{f: one[parameter_name("structure", f)] for f in _STRUCT})
        if self.human == "literal":
            human = LiteralHuman(
                LiteralHumanParams(**{f: one[parameter_name("human", f)] for f in _LIT})
            )
        else:
            human = PhysicalHuman(
                PhysicalHumanParams(**{f: one[parameter_name("human", f)] for f in _PHYS})
            )
        return BDFTLoop(
            k_psf=self.k_psf,
            valve=valve,
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
            "posture": self.posture,
            "ranges": self.ranges,
            "parameters": [p.describe() for p in self.parameters],
        }
