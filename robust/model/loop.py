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
removed (``x = u``).

The paper leaves three things out, made explicit here as :class:`LoopCalibration`:
the PI gains, the sign ``sigma`` at the handle junction, and one loop-scale
factor ``kappa`` that lumps the unknown unit conversions between the blocks (the
printed gains multiply to about 1e6 at low frequency). Their defaults are the
values found by :func:`robust.analysis.calibration.calibrate`.
"""

from __future__ import annotations

import dataclasses

import control as ct

from robust.checks import NONNEGATIVE as NONNEG
from robust.checks import POSITIVE, check_scalar, validate_fields
from robust.errors import ParameterError
from robust.model.components import (
    K_PSF_NOMINAL,
    PIParams,
    StructureParams,
    ValveCylinderParams,
    pi_controller,
    position_scale,
    structure,
    valve_cylinder,
)
from robust.model.human import HumanModel, LiteralHuman

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
        return PIParams(kp=self.kp, ki=self.ki)


#: Values returned by ``robust.analysis.calibration.calibrate()`` with its default search grid
#: (test ``test_calibration_reproduces_defaults`` re-runs the search and compares).
DEFAULT_CALIBRATION = LoopCalibration(
    kp=0.35,
    ki=0.35,
    loop_scale=3.43e-4,
    handle_sign=-1,
    source="robust.analysis.calibration.calibrate(human='literal') default search",
)


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
    """

    k_psf: float = K_PSF_NOMINAL
    valve: ValveCylinderParams = dataclasses.field(default_factory=ValveCylinderParams)
    struct: StructureParams = dataclasses.field(default_factory=StructureParams)
    human: HumanModel = dataclasses.field(default_factory=LiteralHuman)
    calibration: LoopCalibration = DEFAULT_CALIBRATION

    def __post_init__(self):
        validate_fields(self, {"k_psf": POSITIVE})
        if not isinstance(self.human, HumanModel):
            raise ParameterError(
                f"BDFTLoop.human must implement robust.model.human.HumanModel; got {type(self.human).__name__}"
            )

    def replace(self, **changes) -> BDFTLoop:
        return dataclasses.replace(self, **changes)

    def with_workspace_factor(self, factor: float) -> BDFTLoop:
        """The same loop with the handle workspace multiplied by ``factor`` (``K_PSF / factor``)."""
        f = check_scalar("factor", factor, POSITIVE)
        return self.replace(k_psf=self.k_psf / f)

    # -- blocks ---------------------------------------------------------------------
    def blocks(self, *, bdft: bool = True, controller: ct.StateSpace | None = None) -> list:
        """The named blocks of the loop (see the module diagram).

        With a ``controller`` (inputs among ``x, c, y``; outputs among ``f, r_corr``)
        the cylinder reference becomes ``K_PSF x + r_corr`` and ``f`` drives the
        human's force port.
        """
        cal = self.calibration
        ref_terms = ["r"]
        if controller is not None:
            _check_controller(controller, self.human, bdft)
            if "r_corr" in controller.output_labels:
                ref_terms.append("r_corr")
        cyl_err = ct.summing_junction(inputs=[*ref_terms, "-y"], output="err", name="cyl_err")
        blocks = [
            position_scale(self.k_psf),
            cyl_err,
            pi_controller(cal.pi),
            valve_cylinder(self.valve),
        ]
        if controller is not None:
            blocks.append(controller)
        if not bdft:
            handle = ct.summing_junction(inputs=["u"], output="x", name="handle")
            return blocks + [handle]
        gain = cal.handle_sign * cal.loop_scale
        scale = ct.ss([], [], [], [[gain]], inputs="h", outputs="h_cmd", name="loop_scale")
        handle = ct.summing_junction(inputs=["u", "h_cmd"], output="x", name="handle")
        return blocks + [structure(self.struct), self.human.system(), scale, handle]

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
        """
        outs = list(outputs or (LOOP_OUTPUTS if bdft else ["y", "x", "e"]))
        inputs = ["u"]
        blocks = self.blocks(bdft=bdft, controller=controller)
        if bdft and self.human.has_force_port:
            terms = ["f_ext"]
            if controller is not None and "f" in controller.output_labels:
                terms.append("f_ctrl")
                blocks = [
                    _rename_output(b, "f", "f_ctrl") if b is controller else b for b in blocks
                ]
            blocks.append(ct.summing_junction(inputs=terms, output="f", name="hand_force"))
            inputs.append("f_ext")
            if controller is not None and "f" in controller.output_labels and "f" not in outs:
                outs.append("f")
        if controller is not None and "r_corr" in controller.output_labels and "r_corr" not in outs:
            outs.append("r_corr")
        return ct.interconnect(
            blocks, inputs=inputs, outputs=outs, name="bdft_loop" if bdft else "no_bdft_loop"
        )


def _rename_output(sys: ct.StateSpace, old: str, new: str) -> ct.StateSpace:
    labels = [new if lab == old else lab for lab in sys.output_labels]
    return ct.ss(sys.A, sys.B, sys.C, sys.D, inputs=sys.input_labels, outputs=labels, name=sys.name)


#: Signals a controller may measure and drive.
CONTROLLER_INPUTS = ("x", "c", "y")
CONTROLLER_OUTPUTS = ("f", "r_corr")


def _check_controller(controller, human: HumanModel, bdft: bool) -> None:
    from robust.errors import ModelStructureError

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
            f"controller inputs must be among {CONTROLLER_INPUTS} and outputs among {CONTROLLER_OUTPUTS}; "
            f"got inputs {controller.input_labels}, outputs {controller.output_labels}"
        )
    if "f" in controller.output_labels and not (bdft and human.has_force_port):
        raise ModelStructureError(
            f"controller drives the handle force 'f', but the human variant {human.variant!r} has no force port"
            + ("" if bdft else " (and the loop is built without BDFT)")
        )
    if not bdft and "c" in controller.input_labels:
        raise ModelStructureError(
            "controller measures 'c', which does not exist in the loop without BDFT"
        )
