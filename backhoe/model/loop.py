"""The paper's Figure 5 loop, assembled by signal names.

::

              handle x = u + sigma*kappa*h          cylinder loop
     u ──►(+)──────────► K_PSF ──r──►(+)──err──► PI ──e──► valve/cyl ──┬── y
           ▲                          ▲ -                              │
           │                          └────────────────────────────────┤
           │                                                           ▼
           └─── sigma*kappa ◄── h ── human ◄── c ── structure ◄────────┘

``u`` is the operator's intended handle motion, ``h`` the hand's motion relative
to the seat caused by cab acceleration ``c``. Without BDFT the outer path is
removed (``x = u``). The static junctions come from the one table of
:mod:`backhoe.model.wiring`, which the force-feedback plant and the batched family
assembly consume too.

The paper leaves three things out, made explicit here as :class:`LoopCalibration`:
the PI gains, the sign ``sigma`` at the handle junction, and one loop-scale
factor ``kappa`` that lumps the unknown unit conversions between the blocks (the
printed gains multiply to about 1e6 at low frequency). Their defaults are the
values found by :func:`backhoe.analysis.calibration.calibrate`.
"""

from __future__ import annotations

import dataclasses
import functools

import control as ct

from backhoe.model.components import (
    K_PSF_NOMINAL,
    REALISATIONS_KEPT,
    HydraulicLimits,
    PIParams,
    StructureParams,
    ValveCylinderParams,
    pi_controller,
    structure,
    valve_cylinder,
)
from backhoe.model.device import DeviceLimits
from backhoe.model.human import HumanModel, LiteralHuman
from backhoe.model.wiring import CONTROLLER_FORCE, Junction, connect, figure5_junctions, renamed
from robust.checks import NONNEGATIVE as NONNEG
from robust.checks import POSITIVE, check_scalar, validate_fields
from robust.errors import ModelStructureError, ParameterError

__all__ = [
    "LoopCalibration",
    "BDFTLoop",
    "DEFAULT_CALIBRATION",
    "LOOP_OUTPUTS",
    "CONTROLLER_INPUTS",
    "CONTROLLER_OUTPUTS",
]

#: Signals every assembled loop exposes as outputs.
LOOP_OUTPUTS = ["y", "c", "h", "x", "e"]


@dataclasses.dataclass(frozen=True)
class LoopCalibration:
    """What the paper does not print, as named parameters.

    Parameters
    ----------
    kp, ki : float
        PI gains of the cylinder position loop (valve command = PI output).
    loop_scale : float
        ``kappa``: hand motion in the human model's units -> handle motion in the
        units of ``u``; lumps every unit conversion around the BDFT loop.
    handle_sign : int
        ``sigma`` in ``x = u + sigma*kappa*h``: +1 or -1.
    source : str
        Where the values come from (free text, kept in reports and artifacts).
    """

    kp: float
    ki: float
    loop_scale: float
    handle_sign: int
    source: str = ""

    def __post_init__(self):
        validate_fields(self, {"kp": POSITIVE, "ki": NONNEG, "loop_scale": POSITIVE})
        if self.handle_sign not in (1, -1) or isinstance(self.handle_sign, bool):
            raise ParameterError(
                f"LoopCalibration.handle_sign must be +1 or -1; got {self.handle_sign!r}"
            )

    @property
    def pi(self) -> PIParams:
        """The PI gains as :class:`backhoe.model.components.PIParams`."""
        return PIParams(kp=self.kp, ki=self.ki)


#: Values returned by ``backhoe.analysis.calibration.calibrate()`` with its default search grid
#: (test ``test_calibration_reproduces_defaults`` re-runs the search and compares).
DEFAULT_CALIBRATION = LoopCalibration(
    kp=0.35,
    ki=0.35,
    loop_scale=3.43e-4,
    handle_sign=-1,
    source="backhoe.analysis.calibration.calibrate(human='literal') default search",
)


@functools.lru_cache(maxsize=REALISATIONS_KEPT)
def _shared(build, params) -> ct.StateSpace:
    """``build(params)``, one python-control system per (hashable) parameter set and
    process, its matrices read-only (see :meth:`BDFTLoop.blocks`)."""
    sys = build(params)
    for m in (sys.A, sys.B, sys.C, sys.D):
        m.setflags(write=False)
    return sys


def _shared_human(human) -> ct.StateSpace:
    """The human's system, shared when the model is hashable (the shipped ones are frozen
    dataclasses), else built afresh."""
    try:
        hash(human)
    except TypeError:
        return human.system()
    return _shared(type(human).system, human)


@dataclasses.dataclass(frozen=True)
class BDFTLoop:
    """Everything needed to build the Figure 5 loop.

    Parameters
    ----------
    k_psf : float
        Position scale factor (default 0.1097, the 71 mm workspace).
    valve, struct : parameter dataclasses
        Valve/cylinder (Eqn 3) and structure (Eqn 4) parameters.
    human : HumanModel
        Human variant (default: the paper's Eqn 5 as printed).
    calibration : LoopCalibration
        PI gains, junction sign and loop-scale factor.
    hydraulics : HydraulicLimits
        Flow saturation, deadband and stroke of the valve/cylinder (used by the saturated
        simulation and the effort checks; the linear loop is Eqn 3).
    """

    k_psf: float = K_PSF_NOMINAL
    valve: ValveCylinderParams = dataclasses.field(default_factory=ValveCylinderParams)
    struct: StructureParams = dataclasses.field(default_factory=StructureParams)
    human: HumanModel = dataclasses.field(default_factory=LiteralHuman)
    calibration: LoopCalibration = DEFAULT_CALIBRATION
    hydraulics: HydraulicLimits = HydraulicLimits()

    def __post_init__(self):
        validate_fields(self, {"k_psf": POSITIVE})
        for field, cls in (
            ("valve", ValveCylinderParams),
            ("struct", StructureParams),
            ("calibration", LoopCalibration),
            ("hydraulics", HydraulicLimits),
        ):
            if not isinstance(getattr(self, field), cls):
                raise ParameterError(
                    f"BDFTLoop.{field} must be {cls.__name__}; "
                    f"got {type(getattr(self, field)).__name__}"
                )
        if not isinstance(self.human, HumanModel):
            raise ParameterError(
                "BDFTLoop.human must implement backhoe.model.human.HumanModel; "
                f"got {type(self.human).__name__}"
            )

    def replace(self, **changes) -> BDFTLoop:
        """A copy with ``changes`` applied (``dataclasses.replace``).

        Parameters
        ----------
        **changes
            Field values to change.
        """
        return dataclasses.replace(self, **changes)

    def with_workspace_factor(self, factor: float) -> BDFTLoop:
        """The same loop with the handle workspace multiplied by ``factor`` (``K_PSF / factor``).

        Parameters
        ----------
        factor : float
            Workspace factor (> 0).
        """
        f = check_scalar("factor", factor, POSITIVE)
        return self.replace(k_psf=self.k_psf / f)

    @property
    def handle_gain(self) -> float:
        """``sigma * kappa``: handle units per unit of the human's output ``h``."""
        return self.calibration.handle_sign * self.calibration.loop_scale

    def handle_units_per_m(self, *, signed: bool = False) -> float:
        """Handle units per metre of hand (= handle) motion: ``|sigma * kappa * h_gain|``.

        Parameters
        ----------
        signed : bool
            Keep the sign of the handle axis (``sigma * kappa * h_gain``).

        Raises
        ------
        ModelStructureError
            If the human variant has no metric unit gain ``h_gain`` (the literal Eqn 5).
        """
        h_gain = getattr(getattr(self.human, "params", None), "h_gain", None)
        if h_gain is None:
            raise ModelStructureError(
                f"handle units need a human model with a metric unit gain (h_gain); the "
                f"{self.human.variant!r} variant has none. Use the physical human."
            )
        g = self.handle_gain * h_gain
        return g if signed else abs(g)

    def cylinder_units_per_m(self) -> float:
        """Units of ``y`` (the paper's cylinder position) per metre of cylinder travel.

        The paper defines ``K_PSF`` as the Omni's workspace over the cylinder's travel, and
        the reference is ``r = K_PSF x``: at the nominal scale a metre of handle is
        ``1 / K_PSF_NOMINAL`` metres of cylinder, so a metre of cylinder is
        ``K_PSF_NOMINAL^2`` times the handle units per metre (:meth:`handle_units_per_m`).

        Raises
        ------
        ModelStructureError
            If the human variant has no metric unit gain (the literal Eqn 5).
        """
        return K_PSF_NOMINAL**2 * self.handle_units_per_m()

    def valve_command_limit(self) -> float:
        """The valve command at full opening, loop units: the flow limit's cylinder speed over
        ``K_VC`` (Eqn 3's steady speed per unit command)."""
        return self.hydraulics.max_speed_m_s * self.cylinder_units_per_m() / self.valve.k_vc

    def intended_amplitude(self, limits: DeviceLimits, fraction: float) -> float:
        """Amplitude of the operator's intended motion ``u``, in handle units.

        ``fraction`` of half the handle workspace this loop gives the operator (the
        device's workspace times ``K_PSF_NOMINAL / k_psf``), converted to handle units
        (:meth:`handle_units_per_m`).

        Parameters
        ----------
        limits : DeviceLimits
            The device (its fore-aft workspace).
        fraction : float
            Fraction of the half-workspace, in (0, 1].
        """
        factor = K_PSF_NOMINAL / self.k_psf
        return limits.intended_amplitude_m(fraction, workspace_factor=factor) * (
            self.handle_units_per_m()
        )

    # -- blocks ---------------------------------------------------------------------
    def junctions(
        self,
        *,
        bdft: bool = True,
        reference_correction: bool = False,
        force_terms: tuple[str, ...] = (),
    ) -> tuple[Junction, ...]:
        """This loop's rows of the Figure 5 junction table (:func:`figure5_junctions`).

        Parameters
        ----------
        bdft : bool
            With the feedthrough path.
        reference_correction : bool
            With a correction ``r_corr`` of the cylinder reference.
        force_terms : tuple of str
            Signals summed into the hand force ``f``.
        """
        return figure5_junctions(
            k_psf=self.k_psf,
            handle_gain=self.handle_gain,
            bdft=bdft,
            reference_correction=reference_correction,
            force_terms=force_terms,
        )

    def structure_system(self) -> ct.StateSpace:
        """The structure's block (:func:`backhoe.model.components.structure` of ``struct``): the
        one :meth:`blocks` shares, its matrices read-only.

        Returns
        -------
        control.StateSpace
        """
        return _shared(structure, self.struct)

    def human_system(self) -> ct.StateSpace:
        """The human's block (``human.system()``): the one :meth:`blocks` shares, its matrices
        read-only (a human model that is not hashable is built afresh).

        Returns
        -------
        control.StateSpace
        """
        return _shared_human(self.human)

    def blocks(
        self,
        *,
        bdft: bool = True,
        controller: ct.StateSpace | None = None,
        reference_correction: bool = False,
        external_force: bool = False,
    ) -> list:
        """The named blocks of the loop: dynamic blocks and the junction table.

        With a ``controller`` (inputs among ``x, c, y``; outputs among ``f, r_corr``)
        the cylinder reference becomes ``K_PSF x + r_corr`` and the controller's force
        (renamed :data:`CONTROLLER_FORCE` inside the loop) drives the hand force ``f``.
        Without a controller force and without ``external_force``, the human's force
        input ``f`` is left open for the caller (a generalized plant's control input).

        The blocks other than the controller are shared, one per parameter set and process,
        and their matrices are read-only: a member's checks assemble its loop several times,
        and building python-control systems cost more than the assemblies' arithmetic
        (:func:`backhoe.model.components.structure` and the others hand out copies).

        Parameters
        ----------
        bdft : bool
            With the feedthrough path (structure, human, handle junction).
        controller : control.StateSpace, optional
            The compensator, in the loop's signal convention.
        reference_correction : bool
            Add ``r_corr`` to the cylinder reference even without a controller that
            drives it (an open input for a generalized plant).
        external_force : bool
            Sum an external force ``f_ext`` into the hand force.
        """
        force_terms = []
        rc = reference_correction
        if controller is not None:
            _check_controller(controller, self.human, bdft)
            rc = rc or "r_corr" in controller.output_labels
            if "f" in controller.output_labels:
                force_terms.append(CONTROLLER_FORCE)
        if external_force:
            if not (bdft and self.human.has_force_port):
                raise ModelStructureError(
                    f"an external hand force needs the BDFT loop and a human with a force port; "
                    f"got bdft={bdft}, human {self.human.variant!r}"
                )
            force_terms.insert(0, "f_ext")
        blocks = [_shared(pi_controller, self.calibration.pi), _shared(valve_cylinder, self.valve)]
        if bdft:
            blocks += [self.structure_system(), self.human_system()]
        if controller is not None:
            blocks.append(renamed(controller, {"f": CONTROLLER_FORCE}))
        junctions = self.junctions(
            bdft=bdft, reference_correction=rc, force_terms=tuple(force_terms)
        )
        return blocks + [_shared(Junction.system, j) for j in junctions]

    def system(
        self,
        *,
        bdft: bool = True,
        controller: ct.StateSpace | None = None,
        outputs: list[str] | None = None,
    ) -> ct.StateSpace:
        """Closed Figure 5 loop with input ``u``; outputs ``y, c, h, x, e`` by default.

        With ``bdft=False`` the outer loop is removed (``x = u``) and ``c``, ``h``
        are not available. A human variant with a force port gets the extra
        exogenous input ``f_ext`` (a force on the hand, N) added to the
        controller's force, so force disturbances can be studied.

        Parameters
        ----------
        bdft : bool
            With the feedthrough path.
        controller : control.StateSpace, optional
            The compensator (inputs among ``x, c, y``; outputs among ``f, r_corr``).
        outputs : list of str, optional
            Output signals (default ``y, c, h, x, e``; ``y, x, e`` without BDFT); the
            controller's ``f`` and ``r_corr`` are appended when it drives them.
        """
        outs = list(outputs or (LOOP_OUTPUTS if bdft else ["y", "x", "e"]))
        inputs = ["u"]
        external = bdft and self.human.has_force_port
        if external:
            inputs.append("f_ext")
        blocks = self.blocks(bdft=bdft, controller=controller, external_force=external)
        if controller is not None:
            for s in ("f", "r_corr"):
                if s in controller.output_labels and s not in outs:
                    outs.append(s)
        return connect(
            blocks, inputs=inputs, outputs=outs, name="bdft_loop" if bdft else "no_bdft_loop"
        )


#: Signals a controller may measure and drive.
CONTROLLER_INPUTS = ("x", "c", "y")
CONTROLLER_OUTPUTS = ("f", "r_corr")


def _check_controller(controller, human: HumanModel, bdft: bool) -> None:
    if not isinstance(controller, ct.StateSpace):
        raise ModelStructureError(
            f"controller must be a control.StateSpace; got {type(controller).__name__}"
        )
    if not controller.isctime():
        raise ModelStructureError(
            "controller must be continuous-time for the loop (dt=0 or None); "
            f"got dt={controller.dt}. Validate the continuous design, or use the discrete checks."
        )
    bad_in = [s for s in controller.input_labels if s not in CONTROLLER_INPUTS]
    bad_out = [s for s in controller.output_labels if s not in CONTROLLER_OUTPUTS]
    if bad_in or bad_out:
        raise ModelStructureError(
            f"controller inputs must be among {CONTROLLER_INPUTS} and outputs among "
            f"{CONTROLLER_OUTPUTS}; "
            f"got inputs {controller.input_labels}, outputs {controller.output_labels}"
        )
    if "f" in controller.output_labels and not (bdft and human.has_force_port):
        raise ModelStructureError(
            "controller drives the handle force 'f', but the human variant "
            f"{human.variant!r} has no force port"
            + ("" if bdft else " (and the loop is built without BDFT)")
        )
    if not bdft and "c" in controller.input_labels:
        raise ModelStructureError(
            "controller measures 'c', which does not exist in the loop without BDFT"
        )
