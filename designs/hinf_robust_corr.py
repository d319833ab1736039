"""Robust H-infinity handle force plus a cylinder-reference correction, with a tracking budget.

The design is :mod:`designs.hinf_robust` with a second controller output, a
correction ``r_corr`` of the cylinder reference (signal level, no force), starting
from zero; the tuning keeps the nominal tracking error ``|Y/Y_ref - 1|`` over
0.05-2 Hz below 0.5 (a reference correction could otherwise stabilise by cancelling
the operator's command) and asks a decay-rate margin of 0.15 rad/s. Validation and
export: the common pipeline (:func:`designs.registry.run_design`).

Run it alone with ``python -m designs hinf-robust-corr [--samples N] [--seed S] [--out DIR]``.
"""

from __future__ import annotations

from designs.hinf_robust import build_robust
from designs.result import Design, DesignResult

__all__ = ["build", "DESIGN"]

DESIGN_NAME = "hinf-robust-corr"
DESCRIPTION = (
    "robust H-infinity handle force plus cylinder-reference correction, tuned over family "
    "members with a tracking budget"
)


def build(family, samples, limits) -> DesignResult:
    """The robust design with a reference correction on ``family``.

    Parameters
    ----------
    family : backhoe.Family
        The default family.
    samples : uncertainty.SampleSet
        The scenario set.
    limits : backhoe.model.device.DeviceLimits
        Device limits.
    """
    return build_robust(
        family,
        samples,
        limits,
        name=DESIGN_NAME,
        description=DESCRIPTION,
        reference_correction=True,
        margin=0.15,
        tracking_error=0.5,
    )


DESIGN = Design(DESIGN_NAME, DESCRIPTION, build)
