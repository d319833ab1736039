"""The default family of the BDFT loop: over what its parameters vary, and why.

:func:`default_family` builds a :class:`~backhoe.families.family.Family` around given nominals,
each parameter an :class:`~uncertainty.parameters.UncertainParameter` whose source note says
where its range comes from. The valve/cylinder (Eqn 3, every variant) varies its gain, real
pole, valve frequency and damping ratio over stated assumptions (:data:`VALVE_GAIN_SPREAD`
and the constants beside it); the structure (Eqn 4) from the stilts values to a machine on
its tyres; the physical human over the published ranges of the posture
(:mod:`backhoe.model.literature`), or the labelled stress variant beyond them; the literal
human (Eqn 5) its gain over one order of magnitude and its pole x0.5..x2.
"""

from __future__ import annotations

import math

from backhoe.constants import RANGES
from backhoe.families.family import _MODAL, HUMAN_VARIANTS, Family
from backhoe.model.anthropometry import NOMINAL_BODY_MASS
from backhoe.model.blocks import parameter_name
from backhoe.model.components import K_PSF_NOMINAL, StructureParams, ValveCylinderParams
from backhoe.model.human import LiteralHumanParams
from backhoe.model.literature import DEFAULT_POSTURE, POSTURES, published_box, stress_box
from backhoe.model.loop import DEFAULT_CALIBRATION, LoopCalibration
from backhoe.model.physical import PhysicalHumanParams, nominal_params
from robust.errors import ParameterError
from uncertainty.parameters import UncertainParameter

__all__ = [
    "default_family",
    "VALVE_GAIN_SPREAD",
    "VALVE_POLE_SPREAD",
    "VALVE_FREQUENCY_SPREAD",
    "VALVE_DAMPING_RANGE",
]

#: Relative half-width of the valve/cylinder's velocity gain ``K_VC`` about its nominal.
VALVE_GAIN_SPREAD = 0.25
#: Relative half-width of the real pole ``p1`` of Eqn 3 about its nominal.
VALVE_POLE_SPREAD = 0.3
#: Relative half-width of the valve's natural frequency about its nominal.
VALVE_FREQUENCY_SPREAD = 0.2
#: Range of the valve's damping ratio (widened to hold a nominal outside it).
VALVE_DAMPING_RANGE = (0.3, 0.7)
#: Total width (high/low) of the literal human's log-uniform gain range.
HUMAN_SPREAD = 10.0
#: Lowest structure frequency as a fraction of the stilts value.
WHEELS_FREQUENCY_FRACTION = 0.4


def _valve_parameters(v: ValveCylinderParams) -> list[UncertainParameter]:
    """Eqn 3's gain, pole, valve natural frequency and damping ratio about the nominal ``v``.

    The paper identified Eqn 3 on one machine at one operating condition; every range here
    is a stated assumption (no measured spread is published for this valve), argued from
    how a proportional valve and a cylinder behave, and uniform: nothing says where in the
    range a machine sits.
    """
    g, q, f = VALVE_GAIN_SPREAD, VALVE_POLE_SPREAD, VALVE_FREQUENCY_SPREAD
    z_lo, z_hi = min(VALVE_DAMPING_RANGE[0], v.zeta), max(VALVE_DAMPING_RANGE[1], v.zeta)
    return [
        UncertainParameter(
            parameter_name("valve", "k_vc"),
            v.k_vc,
            (1.0 - g) * v.k_vc,
            (1.0 + g) * v.k_vc,
            "uniform",
            "-",
            f"Eqn 3 gain x{1 - g:g}..x{1 + g:g} (stated assumption): a valve's flow, hence the "
            "cylinder's speed per command, goes with the square root of its pressure drop "
            "(orifice equation; Merritt, Hydraulic Control Systems, 1967, ch. 3), which stick "
            "load (bucket empty or full, digging) and pump margin move by about x0.55..x1.55; "
            "oil temperature (viscosity) moves the flow at small openings and the pump's leakage",
        ),
        UncertainParameter(
            parameter_name("valve", "p1"),
            v.p1,
            (1.0 - q) * v.p1,
            (1.0 + q) * v.p1,
            "uniform",
            "rad/s",
            f"Eqn 3 real pole x{1 - q:g}..x{1 + q:g} (stated assumption): a hydraulic lag of "
            "the cylinder and its lines; hydraulic stiffness goes with the oil's bulk modulus, "
            "which entrained air and temperature lower by up to half (about x0.7 in frequency), "
            "and with the oil volume trapped at the cylinder's stroke",
        ),
        UncertainParameter(
            parameter_name("valve", "wn_hz"),
            v.wn_hz,
            (1.0 - f) * v.wn_hz,
            (1.0 + f) * v.wn_hz,
            "uniform",
            "Hz",
            f"Eqn 3 valve natural frequency x{1 - f:g}..x{1 + f:g} (stated assumption): "
            "proportional-valve datasheets show the spool's bandwidth falling with signal "
            "amplitude and with cold, viscous oil, and it differs between valves of one type",
        ),
        UncertainParameter(
            parameter_name("valve", "zeta"),
            v.zeta,
            z_lo,
            z_hi,
            "uniform",
            "-",
            f"Eqn 3 valve damping ratio {z_lo:g}..{z_hi:g} about the paper's value (stated "
            "assumption): the spool's damping rises with oil viscosity (cold oil) and differs "
            "between valves; datasheet step responses range from overshooting to barely so",
        ),
    ]


def _structure_parameters(s: StructureParams) -> list[UncertainParameter]:
    lo_f = WHEELS_FREQUENCY_FRACTION
    return [
        UncertainParameter(
            parameter_name("structure", "k_s"),
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
            parameter_name("structure", "zeta1"),
            s.zeta1,
            0.5 * s.zeta1,
            min(2.0 * s.zeta1, 0.6),
            "uniform",
            "-",
            "Eqn 4 stilts value x0.5..x2: tyres add damping, soil and outriggers change it (paper)",
        ),
        UncertainParameter(
            parameter_name("structure", "zeta2"),
            s.zeta2,
            0.5 * s.zeta2,
            min(2.0 * s.zeta2, 0.6),
            "uniform",
            "-",
            "Eqn 4 stilts value x0.5..x2: tyres add damping, soil and outriggers change it (paper)",
        ),
        UncertainParameter(
            parameter_name("structure", "f1_hz"),
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
            parameter_name("structure", "f2_hz"),
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


def _physical_parameters(
    p: PhysicalHumanParams, body_mass: float, box: dict
) -> list[UncertainParameter]:
    """Body mass, arm and trunk modal parameters over the ranges of ``box``, nominal ``p``."""
    nominal = {"body_mass": body_mass, **{f: getattr(p, f) for f in _MODAL}}
    out = []
    for name in ("body_mass", *_MODAL):
        r = box[name]
        v = float(nominal[name])
        if not r.contains(v):
            raise ParameterError(
                f"default_family: the nominal {parameter_name('human', name)} = {v:.6g} "
                f"{r.units} lies outside its range [{r.low:g}, {r.high:g}]; give a nominal "
                "inside the range (backhoe.model.physical.nominal_params gives the published "
                "nominal)"
            )
        out.append(
            UncertainParameter(
                parameter_name("human", name), v, r.low, r.high, r.distribution, r.units, r.source
            )
        )
    return out


def _literal_parameters(p: LiteralHumanParams) -> list[UncertainParameter]:
    return [
        _spread(
            parameter_name("human", "k_h"),
            p.k_h,
            "-",
            "Eqn 5 gain spread over one order of magnitude (human variability, paper)",
        ),
        UncertainParameter(
            parameter_name("human", "p1"),
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
    posture: str = DEFAULT_POSTURE,
    ranges: str = "published",
) -> Family:
    """The default family (BRIEF section 5) around the given nominals.

    Structure: natural frequencies from the stilts values down to x0.4 (a machine
    on its tyres), damping ratios x0.5..x2, gain x1..x3 (larger cab motion on
    tyres). Physical human: body mass, arm-endpoint effective mass, natural frequency
    and damping ratio, trunk natural frequency and damping ratio, each over its
    published range for the posture (:mod:`backhoe.model.literature`; the source of
    every range is in the parameter's source note), around the nominal operator
    fitted inside those ranges; ``ranges="stress"`` widens them beyond the published
    ones (a labelled stress variant). Literal human: gain over one order of
    magnitude, pole x0.5..x2. Valve/cylinder (Eqn 3, every variant): gain x0.75..x1.25,
    real pole x0.7..x1.3, valve natural frequency x0.8..x1.2 and damping ratio 0.3..0.7
    (:data:`VALVE_GAIN_SPREAD` and the constants beside it), stated assumptions whose
    reasons are in the parameters' source notes.

    Parameters
    ----------
    human : {"physical", "literal"}
        Human variant.
    k_psf : float
        Position scale factor of every member.
    valve, struct, literal, physical : optional
        Nominal parameters (default: the paper's values and, for the physical human,
        the nominal operator of ``posture``, :func:`backhoe.model.physical.nominal_params`).
    body_mass : float
        Body mass (kg) the physical nominal masses belong to.
    calibration : LoopCalibration
        Loop calibration (default :data:`backhoe.model.loop.DEFAULT_CALIBRATION`).
    posture : {"backrest", "no-backrest"}
        Posture whose published trunk ranges the physical family spans.
    ranges : {"published", "stress"}
        The published ranges, or the stress variant beyond them.

    Returns
    -------
    Family
        Named ``"default-<human>"`` (``-<posture>`` for a posture other than the
        default, ``stress-`` instead of ``default-`` for the stress variant); five
        four valve/cylinder and five structure parameters plus six (physical) or two
        (literal) human parameters.

    Raises
    ------
    ParameterError
        If ``human``, ``posture`` or ``ranges`` is not known, or a physical nominal
        lies outside its range.
    """
    if posture not in POSTURES:
        raise ParameterError(f"default_family: posture must be one of {POSTURES}; got {posture!r}")
    if ranges not in RANGES:
        raise ParameterError(f"default_family: ranges must be one of {RANGES}; got {ranges!r}")
    struct = struct or StructureParams()
    literal = literal or LiteralHumanParams()
    physical = physical or nominal_params(posture)
    valve = valve or ValveCylinderParams()
    params = _valve_parameters(valve) + _structure_parameters(struct)
    if human == "physical":
        box = published_box(posture) if ranges == "published" else stress_box(posture)
        params += _physical_parameters(physical, body_mass, box)
    elif human == "literal":
        params += _literal_parameters(literal)
    else:
        raise ParameterError(
            f"default_family: human must be one of {HUMAN_VARIANTS}; got {human!r}"
        )
    prefix = "default" if ranges == "published" else "stress"
    suffix = "" if (human == "literal" or posture == DEFAULT_POSTURE) else f"-{posture}"
    return Family(
        parameters=tuple(params),
        human=human,
        k_psf=k_psf,
        valve=valve,
        struct=struct,
        literal=literal,
        physical=physical,
        body_mass=body_mass,
        calibration=calibration,
        name=f"{prefix}-{human}{suffix}",
        posture=posture,
        ranges=ranges,
    )
