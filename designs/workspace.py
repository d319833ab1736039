"""Workspace scaling: the paper's own remedy, a larger handle workspace (smaller K_PSF).

The design, top to bottom:

1. family: the default family at the nominal workspace;
2. synthesis: none; a scan of the workspace factor (``K_PSF = 0.1097 / factor``)
   over the sample, then bisection to the smallest factor whose every sampled
   member has its closed-loop poles left of ``-margin`` (:func:`design_workspace`);
3. validation and export: the common pipeline (:func:`designs.registry.run_design`);
   there is no controller to export, only the changed loop.

Run it alone with ``python -m designs workspace [--samples N] [--seed S] [--out DIR]``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from designs.result import Design, DesignFacts, DesignResult
from uncertainty import validate_family

__all__ = ["WorkspaceResult", "design_workspace", "build", "DESIGN"]

DESCRIPTION = "workspace scaling: smallest handle-workspace factor that stabilises the family"

#: Default scan of workspace factors: 1 to 10 in steps of 0.5, then up to 200.
DEFAULT_FACTORS = tuple(np.arange(1.0, 10.01, 0.5)) + (
    12.0,
    15.0,
    20.0,
    30.0,
    50.0,
    70.0,
    100.0,
    150.0,
    200.0,
)


@dataclasses.dataclass(frozen=True)
class WorkspaceResult(DesignFacts):
    """Outcome of the workspace-scaling search: the design's facts.

    Parameters
    ----------
    factor : float
        Smallest factor that stabilises every sampled member (or the best found).
    stabilises_family : bool
        Whether ``factor`` stabilises every sampled member with the margin.
    factors : tuple of float
        The scanned factors.
    fraction_stable : tuple of float
        Fraction of stable members at each scanned factor.
    max_real_pole : tuple of float
        Worst largest real part at each scanned factor, rad/s.
    """

    factor: float
    stabilises_family: bool
    factors: tuple[float, ...]
    fraction_stable: tuple[float, ...]
    max_real_pole: tuple[float, ...]

    def to_json(self) -> dict:
        """The facts under ``bdft design --json``'s keys (the scan in ``scan``)."""
        return {
            "factor": self.factor,
            "stabilises_family": self.stabilises_family,
            "scan": {
                "factor": list(self.factors),
                "fraction_stable": list(self.fraction_stable),
                "max_real_pole": list(self.max_real_pole),
            },
        }


def design_workspace(
    family, samples, *, factors=None, refine: int = 12, margin: float = 0.01
) -> WorkspaceResult:
    """Smallest workspace factor (``K_PSF = 0.1097 / factor``) that stabilises every sampled member.

    "Stabilises" means every closed-loop pole has real part below ``-margin`` rad/s
    (default 0.01: the human's passive arm modes decay at a few hundredths of a rad/s
    in the lightest-damped members, so the loop cannot be asked for more), so the
    chosen factor is not on the stability boundary itself.

    Scans ``factors``, then bisects between the last failing and the first passing
    factor ``refine`` times. If no factor passes, the one with the largest fraction
    stable is returned with ``stabilises_family=False``.

    Parameters
    ----------
    family : backhoe.Family
        The family at the nominal workspace.
    samples : uncertainty.SampleSet
        Members to check.
    factors : sequence of float, optional
        Factors to scan (default :data:`DEFAULT_FACTORS`).
    refine : int
        Bisection steps between the last failing and the first passing factor.
    margin : float
        Required decay rate, rad/s.

    Returns
    -------
    WorkspaceResult
    """
    grid = list(factors) if factors is not None else list(DEFAULT_FACTORS)
    fr, mr = [], []

    def run(f):
        v = validate_family(family.with_workspace_factor(f), samples)
        return v.fraction_stable, v.max_real_pole

    def passes(res):
        return res[1] < -margin

    for f in grid:
        a, b = run(f)
        fr.append(a)
        mr.append(b)
    passing = [i for i in range(len(grid)) if passes((fr[i], mr[i]))]
    if not passing:
        best = int(np.argmax(fr))
        return WorkspaceResult(grid[best], False, tuple(grid), tuple(fr), tuple(mr))
    i = passing[0]
    if i == 0:
        return WorkspaceResult(grid[0], True, tuple(grid), tuple(fr), tuple(mr))
    lo, hi = grid[i - 1], grid[i]
    for _ in range(refine):
        mid = 0.5 * (lo + hi)
        if passes(run(mid)):
            hi = mid
        else:
            lo = mid
    return WorkspaceResult(hi, True, tuple(grid), tuple(fr), tuple(mr))


def build(family, samples, limits) -> DesignResult:
    """The workspace design on ``family``: the scaled family, no controller.

    Parameters
    ----------
    family : backhoe.Family
        The family at the nominal workspace.
    samples : uncertainty.SampleSet
        Members the factor must stabilise.
    limits : backhoe.model.device.DeviceLimits
        Device limits (unused: the design applies no force).

    Returns
    -------
    DesignResult
        Not yet evaluated; its family has the chosen workspace factor.
    """
    res = design_workspace(family, samples)
    notes = []
    if not res.stabilises_family:
        notes.append(
            f"no workspace factor up to {max(res.factors):g} stabilises every sampled member; "
            f"best x{res.factor:g} with {max(res.fraction_stable):.4f} stable"
        )
    cost = (
        f"workspace factor x{res.factor:.3g} (the handle's travel covers 1/{res.factor:.3g} "
        "of the stick's)"
    )
    return DesignResult(
        name=DESIGN_NAME,
        description=DESCRIPTION,
        family=family.with_workspace_factor(res.factor),
        controller=None,
        order_full=0,
        reduction_error_bound=0.0,
        facts=res,
        notes=tuple(notes),
        cost_note=cost,
    )


DESIGN_NAME = "workspace"
DESIGN = Design(DESIGN_NAME, DESCRIPTION, build)
