"""The cylinder's response to the operator's intent against the BDFT-free response.

The specification's intended-motion requirement (:mod:`designs.spec`) bounds the deviation
``R = Y/Y_ref - 1`` at every frequency by two stable rational weights: ``W_t``, the tracking
tolerance, and ``W_f`` times the uncompensated deviation ``R0``, the feedthrough's reduction
over the structure modes and the tolerance elsewhere. This module holds the weights (their
defaults and the checks of a user's own), the deviation as a closed-loop map of a member, and
its exact check (:func:`robust.analysis.bounds.bound_ratio`).
"""

from __future__ import annotations

import functools
import math

import control as ct
import numpy as np

from backhoe.model.components import REALISATIONS_KEPT
from backhoe.model.loop import BDFTLoop
from robust.analysis.bounds import BoundRatio, bound_ratio
from robust.errors import ParameterError

__all__ = [
    "NOTCH_POLE_DAMPING",
    "default_tracking_weight",
    "default_feedthrough_weight",
    "check_weight",
    "weight_system",
    "deviation_maps",
    "deviation_checks",
    "deviation_bound_checks",
]


#: Damping ratio of the poles of the default feedthrough weight (the notch's width).
NOTCH_POLE_DAMPING = 1.0


def default_tracking_weight(tol: float, floor: float, top_hz: float) -> tuple:
    """The default ``W_t``: ``tol`` through the operator's band, ``floor`` far above it.

    A second-order shelf ``tol (s^2/wz^2 + sqrt(2) s/wz + 1) / (s^2/wp^2 + sqrt(2) s/wp + 1)``
    with ``wp = 2 pi (2 top_hz)`` (a Butterworth corner an octave above the band: at least
    0.97 ``tol`` through it) and ``wz = wp sqrt(tol / floor)`` (so that ``|W_t| -> floor``).

    Parameters
    ----------
    tol : float
        Allowed ``|Y/Y_ref - 1|`` in the operator's band.
    floor : float
        Allowed ``|Y/Y_ref - 1|`` far above it.
    top_hz : float
        Top of the operator's band, Hz.

    Returns
    -------
    tuple
        ``(num, den)``, coefficient tuples in descending powers of ``s``.
    """
    wp = 2 * math.pi * 2.0 * top_hz
    wz = wp * math.sqrt(tol / floor)
    r2 = math.sqrt(2.0)
    num = (tol / wz**2, tol * r2 / wz, tol)
    den = (1 / wp**2, r2 / wp, 1.0)
    return tuple(float(x) for x in num), tuple(float(x) for x in den)


def default_feedthrough_weight(band_hz, reduction_db: float, tolerance_db: float) -> tuple:
    """The default ``W_f``: ``10^(-reduction_db/20)`` over the band, ``10^(tolerance_db/20)``
    far from it.

    A second-order notch ``k (s^2 + 2 zz wn s + wn^2) / (s^2 + 2 zp wn s + wn^2)`` centred at
    the band's geometric mean ``wn``, ``k = 10^(tolerance_db/20)``, ``zp`` =
    :data:`NOTCH_POLE_DAMPING` (more where the reduction asks for a deeper notch), and
    ``zz`` chosen so that the magnitude at both band edges is exactly the reduction (the
    notch is symmetric in log frequency; inside the band it is deeper).

    Parameters
    ----------
    band_hz : (float, float)
        The structure modes' band, Hz.
    reduction_db : float
        Required reduction of the feedthrough over the band, dB (positive: reduce).
    tolerance_db : float
        Allowed growth of the deviation far from the band, dB.

    Returns
    -------
    tuple
        ``(num, den)``.
    """
    lo, hi = band_hz
    wn = 2 * math.pi * math.sqrt(lo * hi)
    x = lo / math.sqrt(lo * hi)
    a, b = (1 - x * x) ** 2, (2 * x) ** 2
    k = 10 ** (tolerance_db / 20)
    q2 = (10 ** (-reduction_db / 20) / k) ** 2
    zp = NOTCH_POLE_DAMPING
    if q2 * (a + b * zp * zp) <= a:
        # a deeper notch than the default width allows: widen it
        zp = math.sqrt(max(4 * a / q2 - a, 0.0) / b)
    zz = math.sqrt(max(q2 * (a + b * zp * zp) - a, 0.0) / b)
    num = (k, k * 2 * zz * wn, k * wn * wn)
    den = (1.0, 2 * zp * wn, wn * wn)
    return tuple(float(v) for v in num), tuple(float(v) for v in den)


def check_weight(name: str, value) -> tuple:
    """A user's weight (``(num, den)`` or a SISO python-control system), checked: proper,
    stable, finite, no zero on the imaginary axis.

    Parameters
    ----------
    name : str
        The field's name, for messages (``Specification.<name>``).
    value : (num, den) or control.TransferFunction or control.StateSpace
        The weight.

    Returns
    -------
    tuple
        ``(num, den)`` as tuples of floats, leading zeros trimmed.
    """
    label = f"Specification.{name}"
    if isinstance(value, (ct.TransferFunction, ct.StateSpace)):
        tf = ct.tf(value)
        if tf.ninputs != 1 or tf.noutputs != 1:
            raise ParameterError(
                f"{label} must be single-input single-output; got {tf.ninputs}"
                f" inputs and {tf.noutputs} outputs"
            )
        num, den = (np.atleast_1d(np.squeeze(x[0][0])) for x in (tf.num, tf.den))
    else:
        try:
            num, den = value
            num, den = np.atleast_1d(np.asarray(num, float)), np.atleast_1d(np.asarray(den, float))
        except (TypeError, ValueError):
            raise ParameterError(
                f"{label} must be (num, den) coefficient sequences or a SISO control system; "
                f"got {value!r}"
            ) from None
    num, den = np.trim_zeros(num, "f"), np.trim_zeros(den, "f")
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))) or not den.size or not num.size:
        raise ParameterError(f"{label}: coefficients must be finite, not all zero; got {value!r}")
    if num.size > den.size:
        raise ParameterError(
            f"{label} must be proper (numerator degree <= denominator's); "
            f"got degrees {num.size - 1} and {den.size - 1}"
        )
    poles, zeros = np.roots(den), np.roots(num)
    if poles.size and not np.all(poles.real < 0):
        raise ParameterError(
            f"{label} must be stable (poles in the open left half-plane); got poles {poles}"
        )
    if zeros.size and np.any(np.abs(zeros.real) <= 1e-12 * np.maximum(np.abs(zeros), 1.0)):
        raise ParameterError(
            f"{label} must have no zero on the imaginary axis (a bound of 0 "
            f"there); got zeros {zeros}"
        )
    return tuple(float(x) for x in num), tuple(float(x) for x in den)


@functools.lru_cache(maxsize=32)
def weight_system(weight: tuple) -> ct.StateSpace:
    """A weight ``(num, den)`` as a python-control state-space system (cached).

    Parameters
    ----------
    weight : tuple
        ``(num, den)`` coefficient tuples.
    """
    return ct.ss(ct.tf(list(weight[0]), list(weight[1])))


def _deviation(sys: ct.StateSpace, k_psf: float) -> tuple:
    """``R = x/u - 1 + (r_corr/u) / K_PSF`` of a closed loop, ``(A, B, C, D)``."""
    iu, jx = sys.input_labels.index("u"), sys.output_labels.index("x")
    A = np.asarray(sys.A, float)
    B = np.asarray(sys.B, float)[:, [iu]]
    C = np.asarray(sys.C, float)[[jx]].copy()
    D = np.asarray(sys.D, float)[[jx]][:, [iu]] - 1.0
    if "r_corr" in sys.output_labels:
        jr = sys.output_labels.index("r_corr")
        C = C + np.asarray(sys.C, float)[[jr]] / k_psf
        D = D + np.asarray(sys.D, float)[[jr]][:, [iu]] / k_psf
    return A, B, C, D


def _series(first: tuple, then: tuple) -> tuple:
    """``then(s) first(s)`` of two SISO ``(A, B, C, D)``."""
    A1, B1, C1, D1 = first
    A2, B2, C2, D2 = then
    n1, n2 = A1.shape[0], A2.shape[0]
    A = np.block([[A1, np.zeros((n1, n2))], [B2 @ C1, A2]])
    B = np.vstack([B1, B2 @ D1])
    C = np.hstack([D2 @ C1, C2])
    return A, B, C, D2 @ D1


def _reference_loop(loop: BDFTLoop, reference_k_psf) -> BDFTLoop:
    """The uncompensated loop the feedthrough is compared with: the member at
    ``reference_k_psf`` (``None``: its own)."""
    if reference_k_psf is None or reference_k_psf == loop.k_psf:
        return loop
    return loop.replace(k_psf=float(reference_k_psf))


@functools.lru_cache(maxsize=REALISATIONS_KEPT)
def _feedthrough_bound(loop: BDFTLoop, weight: tuple, reference_k_psf=None) -> tuple:
    """``W_f R0`` of a member (the uncompensated deviation, formal even where that loop is
    unstable); every design's checks of a member share it."""
    ref = _reference_loop(loop, reference_k_psf)
    r0 = _deviation(ref.system(bdft=True), ref.k_psf)
    w = weight_system(weight)
    out = _series(r0, tuple(np.asarray(m, float) for m in (w.A, w.B, w.C, w.D)))
    for m in out:
        m.setflags(write=False)
    return out


def deviation_maps(loop: BDFTLoop, controller=None, *, closed=None, reference_k_psf=None) -> tuple:
    """The deviation from the BDFT-free response with and without the compensator.

    ``R = Y/Y_ref - 1``, with ``Y`` the cylinder's response to the intended motion ``u``
    and ``Y_ref`` the response without BDFT and without compensation. Since the cylinder
    loop sees only its reference ``K_PSF x + r_corr``, ``R`` is the closed-loop map
    ``u -> (x - u) + r_corr / K_PSF`` exactly: a proper rational function, stable with the
    closed loop (``Y - Y_ref = Y_ref R``, and ``Y_ref`` has no zero on the imaginary axis).

    Parameters
    ----------
    loop : BDFTLoop
        One member.
    controller : control.StateSpace or None
        The compensator.
    closed : control.StateSpace, optional
        ``loop.system(bdft=True, controller=controller)`` if built already.
    reference_k_psf : float, optional
        ``K_PSF`` of the uncompensated loop ``R0`` is taken from (default: the member's own;
        the specification's ``reference_k_psf`` compares every design with the paper's
        machine, so that a design that changes the workspace gets credit for it).

    Returns
    -------
    (tuple, tuple)
        ``R`` and ``R0`` (no compensator) as ``(A, B, C, D)``.
    """
    if closed is None:
        closed = loop.system(bdft=True, controller=controller)
    r = _deviation(closed, loop.k_psf)
    ref = _reference_loop(loop, reference_k_psf)
    if controller is None and ref is loop:
        return r, r
    return r, _deviation(ref.system(bdft=True), ref.k_psf)


def deviation_checks(
    loop: BDFTLoop, spec, controller=None, *, closed=None, rtol: float = 1e-6
) -> tuple[BoundRatio, BoundRatio]:
    """The ``"tracking"`` and ``"feedthrough"`` checks of one stable member, exact.

    ``sup |R| / |W_t|`` over ``[0, split_hz]`` and ``sup |R| / max(|W_t|, |W_f R0|)`` over
    ``[split_hz, inf)`` (:func:`deviation_maps`, :func:`robust.analysis.bounds.bound_ratio`):
    each holds when at most 1, at every frequency.

    Parameters
    ----------
    loop : BDFTLoop
        One member whose closed loop is stable.
    spec : Specification
    controller : control.StateSpace or None
    closed : control.StateSpace, optional
        The member's closed loop if built already.
    rtol : float
        Relative accuracy of the suprema.

    Returns
    -------
    (BoundRatio, BoundRatio)
    """
    if closed is None:
        closed = loop.system(bdft=True, controller=controller)
    return deviation_bound_checks(_deviation(closed, loop.k_psf), loop, spec, rtol=rtol)


def deviation_bound_checks(
    r: tuple, loop: BDFTLoop, spec, *, rtol: float = 1e-6
) -> tuple[BoundRatio, BoundRatio]:
    """:func:`deviation_checks` of a deviation ``R`` given as a realisation.

    For closed loops that are not built as a :class:`BDFTLoop` with a controller (the limit
    map's full-information loops): ``r`` is ``(A, B, C, D)`` of ``u -> R``.

    Parameters
    ----------
    r : tuple
        ``(A, B, C, D)`` of the deviation, stable.
    loop : BDFTLoop
        The member (its uncompensated deviation ``R0``).
    spec : Specification
    rtol : float
        Relative accuracy of the suprema.

    Returns
    -------
    (BoundRatio, BoundRatio)
    """
    wt = weight_system(spec.tracking_weight)
    wt = tuple(np.asarray(m, float) for m in (wt.A, wt.B, wt.C, wt.D))
    ref = spec.reference_k_psf
    try:
        hash(loop)
        b2 = _feedthrough_bound(loop, spec.feedthrough_weight, ref)
    except TypeError:
        b2 = _feedthrough_bound.__wrapped__(loop, spec.feedthrough_weight, ref)
    split = spec.split_hz
    tr = bound_ratio(r, [wt], band_hz=(0.0, split), rtol=rtol, stop_above=1.0)
    fb = bound_ratio(r, [wt, b2], band_hz=(split, math.inf), rtol=rtol, stop_above=1.0)
    return tr, fb
