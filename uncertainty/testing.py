"""Assertions for users' own test suites: a controller's robust margin and robust
performance, certified.

A control engineer keeps a controller honest the way a programmer keeps a function honest:
with a test that fails when a change breaks it. :func:`assert_robust_margin` passes when
the *certified* lower bound of the robust margin (:func:`uncertainty.margins.robust_margin`)
reaches the requirement, every member of the box scaled by ``at_least`` about the nominal
having its poles in the region; a sampled check cannot give that. It fails with an
:class:`AssertionError` whose message a reviewer can act on: both bounds of the margin, the
member that breaks the region (its parameters and its worst pole) and the method of each
bound, and whether the requirement is out of reach (a violating member inside the required
box) or only beyond what the certificate reached.

:func:`assert_robust_performance` does the same for a weighted closed-loop bound
(:func:`uncertainty.performance.robust_performance`): every member of the required box
stable with ``||W_out T W_in||_inf < gamma``.

Use them in pytest::

    from uncertainty.testing import assert_robust_margin

    def test_my_controller_holds_the_whole_box():
        assert_robust_margin(system, controller=K, region=Region(decay_rate=0.02), at_least=1.0)
"""

from __future__ import annotations

import math

import control as ct
import numpy as np

from robust.checks import POSITIVE, check_scalar
from uncertainty.constants import DEFAULT_BOXES
from uncertainty.margins import margin_lower_bound, robust_margin
from uncertainty.performance import certify_performance, performance_system, robust_performance
from uncertainty.region import Region

__all__ = ["assert_robust_margin", "assert_robust_performance"]


def assert_robust_margin(
    system,
    *,
    at_least: float,
    controller: ct.StateSpace | None = None,
    region: Region | None = None,
    method: str = "auto",
    max_boxes: int = DEFAULT_BOXES,
    samples: int = 1000,
    seed: int = 0,
) -> dict:
    """Fail unless the certified robust margin of ``system`` reaches ``at_least``.

    The box scaled by ``at_least`` is certified directly (one scale, no search); only when
    that fails are both bounds computed, for the message.

    Parameters
    ----------
    system : backhoe.Family or uncertainty.USS
        The family, or an uncertain system (:func:`uncertainty.uss`).
    at_least : float
        Required margin: the scale of the parameters' box about the nominal (1 = the whole
        box) within which every member must have its poles in ``region``, > 0.
    controller : control.StateSpace, optional
        Compensator, as :func:`uncertainty.margins.robust_margin` takes it.
    region : Region, optional
        Required pole region (default: open left half-plane).
    method : str
        Lower-bound method (:func:`uncertainty.margins.margin_lower_bound`).
    max_boxes : int
        Sub-boxes the certificate may try.
    samples, seed : int
        The upper bound's search, for the message when the certificate fails.

    Returns
    -------
    dict
        The certificate (:func:`uncertainty.margins.margin_lower_bound`'s), when it passes.

    Raises
    ------
    AssertionError
        When the box scaled by ``at_least`` is not certified; the message gives the
        certified and the upper bound, the critical member, its worst pole and the methods.

    Examples
    --------
    >>> from uncertainty import Region, ureal, uss
    >>> a = ureal("a", -1.0, -2.0, -0.5)
    >>> cert = assert_robust_margin(uss([[a]], [[1.0]], [[1.0]], [[0.0]]), at_least=1.0)
    >>> cert["certified_scale"] >= 1.0
    True
    """
    at_least = check_scalar("at_least", at_least, POSITIVE, owner="assert_robust_margin")
    region = region or Region()
    lower, cert = margin_lower_bound(
        system,
        controller=controller,
        region=region,
        k_hint=at_least,
        ladder=0,
        iterations=0,
        max_boxes=max_boxes,
        method=method,
    )
    if lower >= at_least:
        return cert
    res = robust_margin(
        system,
        controller=controller,
        region=region,
        samples=samples,
        seed=seed,
        max_boxes=max_boxes,
        method=method,
    )
    raise AssertionError(_message(res, at_least))


def _message(res, at_least: float) -> str:
    """Why the margin misses ``at_least``: both bounds, the critical member, the methods."""
    lines = [
        f"robust margin: the box scaled by {at_least:g} is not certified for the "
        f"{res.region.describe()}",
        f"  certified lower bound {res.lower:.6g}, upper bound {res.upper:.6g}",
    ]
    lines.append(
        _reach(
            res.upper,
            at_least,
            "violates the region",
            "; a larger certificate budget (max_boxes) may certify it",
        )
    )
    crit = res.critical
    if crit is not None:
        lines.append(f"  critical member: {_member(crit['parameters'])}")
        poles = np.asarray(crit["poles"])
        if poles.size:
            worst = poles[int(np.argmax(poles.real))]
            lines.append(
                f"  its rightmost pole {worst.real:.6g}{worst.imag:+.6g}j, region violated by "
                f"{crit['violation']:.6g} ({crit.get('checked_with', '')})"
            )
    lines.append(f"  lower bound: {res.method['lower']}")
    lines.append(f"  upper bound: {res.method['upper']}")
    if not math.isfinite(res.upper):
        lines.append("  (no violating member found by the search)")
    return "\n".join(lines)


def assert_robust_performance(
    system,
    *,
    at_least: float,
    controller: ct.StateSpace | None = None,
    inputs=None,
    outputs=None,
    input_weight=None,
    output_weight=None,
    gamma: float = 1.0,
    samples: int = 64,
    seed: int = 0,
) -> dict:
    """Fail unless every member of the box scaled by ``at_least`` is certified stable with
    ``||W_out T W_in||_inf < gamma``.

    The box scaled by ``at_least`` is certified directly
    (:func:`uncertainty.performance.certify_performance`, one scale); only when that fails
    are both bounds of the margin computed, for the message.

    Parameters
    ----------
    system : uncertainty.USS
        The uncertain system, closed with ``controller`` when one is given.
    at_least : float
        Required scale of the parameters' box about the nominal (1 = the whole box), > 0.
    controller, inputs, outputs, input_weight, output_weight, gamma
        The weighted closed-loop map, as :func:`uncertainty.performance.performance_system`
        takes them.
    samples, seed : int
        The upper bound's search, for the message when the certificate fails.

    Returns
    -------
    dict
        The certificate, when it passes.

    Raises
    ------
    AssertionError
        When the box is not certified; the message gives both bounds of the robust
        performance margin, the worst member found (its parameters, its exact norm and
        where it peaks), the frequency where the certificate failed and the methods.

    Examples
    --------
    >>> from uncertainty import ureal, uss
    >>> a = ureal("a", 2.0, 1.5, 3.0)
    >>> cert = assert_robust_performance(uss([[-a]], [[1.0]], [[1.0]], [[0.0]]), at_least=1.0)
    >>> cert["certified"]
    True
    """
    at_least = check_scalar("at_least", at_least, POSITIVE, owner="assert_robust_performance")
    weighted = dict(
        controller=controller,
        inputs=inputs,
        outputs=outputs,
        input_weight=input_weight,
        output_weight=output_weight,
        gamma=gamma,
    )
    cert = certify_performance(performance_system(system, **weighted), at_least)
    if cert["certified"]:
        return cert
    res = robust_performance(system, samples=samples, seed=seed, **weighted)
    lines = [
        f"robust performance: the box scaled by {at_least:g} is not certified to keep every "
        f"member stable with its weighted norm below {gamma:g}",
        f"  certified lower bound {res.lower:.6g}, upper bound {res.upper:.6g} "
        f"(nominal weighted norm {res.nominal_norm:.6g})",
        f"  the certificate at {at_least:g}: {cert.get('reason', '')}",
    ]
    lines.append(
        _reach(res.upper, at_least, "breaks the bound", ", and the mu certificate did not reach it")
    )
    w = res.worst
    if w is not None:
        lines.append(f"  worst member: {_member(w['parameters'])}")
        lines.append(
            f"  its weighted norm {w['norm'] * gamma:.6g} (bound {gamma:g}) at "
            f"{w['frequency_hz']:.6g} Hz ({w['checked_with']})"
        )
    lines.append(f"  lower bound: {res.method['lower']}")
    lines.append(f"  upper bound: {res.method['upper']}")
    raise AssertionError("\n".join(lines))


def _reach(upper: float, at_least: float, breaks: str, undecided: str) -> str:
    """Whether a requirement the certificate missed is out of reach or only undecided."""
    if upper <= at_least:
        return f"  out of reach: a member inside the required box (scale {upper:.6g}) {breaks}"
    return f"  not shown either way: no violating member found up to the requirement{undecided}"


def _member(parameters: dict) -> str:
    return ", ".join(f"{k}={v:.6g}" for k, v in parameters.items())
