"""Model-based cancellation: subtract an estimate of the hand's motion from the cylinder reference.

The design, top to bottom:

1. family: the default family at the nominal workspace;
2. synthesis: none; the nominal human's seat-acceleration-to-hand path, fed by
   the measured cab acceleration, scaled into the cylinder reference and
   subtracted (:func:`cancellation_controller`); no handle force;
3. validation and export: the common pipeline (:func:`designs.registry.run_design`).

Run it alone with ``python -m designs cancellation [--samples N] [--seed S] [--out DIR]``.
"""

from __future__ import annotations

import dataclasses

import control as ct

from backhoe.model.loop import BDFTLoop
from designs.result import Design, DesignFacts, DesignResult

__all__ = ["CancellationFacts", "cancellation_controller", "build", "DESIGN"]

DESIGN_NAME = "cancellation"
DESCRIPTION = "model-based cancellation of the hand's motion from the measured cab acceleration"


@dataclasses.dataclass(frozen=True)
class CancellationFacts(DesignFacts):
    """What the cancellation design reports of itself.

    Parameters
    ----------
    model : str
        The model the cancellation is built on.
    """

    model: str


def cancellation_controller(loop: BDFTLoop) -> ct.StateSpace:
    """Model-based cancellation at signal level: ``r_corr = -K_PSF*sigma*kappa * H_nom(s) c``.

    ``H_nom`` is the nominal human's seat-acceleration-to-hand path; the estimate
    of the hand's motion built from the measured cab acceleration is subtracted
    from the cylinder reference. No force is applied.

    Parameters
    ----------
    loop : BDFTLoop
        The nominal loop whose human path ``c -> h`` is copied.

    Returns
    -------
    control.StateSpace
        Input ``c`` (measured cab acceleration), output ``r_corr`` (correction of the
        cylinder reference); the order of the nominal human.
    """
    H = loop.human.system()
    ic = H.input_labels.index("c")
    g = -loop.k_psf * loop.handle_gain
    return ct.ss(
        H.A,
        H.B[:, [ic]],
        g * H.C,
        g * H.D[:, [ic]],
        inputs="c",
        outputs="r_corr",
        name="cancellation",
    )


def build(family, samples, limits) -> DesignResult:
    """The cancellation design on ``family`` (built on its nominal member).

    Parameters
    ----------
    family : backhoe.Family
        The default family.
    samples : uncertainty.SampleSet
        Unused: the design is not tuned over members.
    limits : backhoe.model.device.DeviceLimits
        Unused: the design applies no force.

    Returns
    -------
    DesignResult
        Not yet evaluated (the pipeline fills in ``evaluation``).
    """
    K = cancellation_controller(family.member(family.nominal_values()))
    return DesignResult(
        name=DESIGN_NAME,
        description=DESCRIPTION,
        family=family,
        controller=K,
        order_full=K.nstates,
        reduction_error_bound=0.0,
        facts=CancellationFacts(model="nominal physical human, c -> h"),
    )


DESIGN = Design(DESIGN_NAME, DESCRIPTION, build)
