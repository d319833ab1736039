"""The one definition of stability used throughout the workbench.

A continuous-time pole ``p`` (rad/s) is

* *stable* when ``Re(p) < -STABILITY_TOL``,
* *unstable* when ``Re(p) > +STABILITY_TOL``,
* *marginal* otherwise (on the imaginary axis within the tolerance).

A system, a loop or a family member is stable when every pole is stable. The
tolerance is absolute (rad/s): it sits far below every decay rate the workbench
designs for (0.01 rad/s and more) and far above the rounding error of the
eigenvalues of the loops it builds (about ``1e-16 * ||A||``, below 1e-11 rad/s for
these models). Decay-rate requirements are stated separately, as a ``margin``:
``Re(p) < -margin``.
"""

from __future__ import annotations

import numpy as np

from robust.checks import NONNEGATIVE, check_scalar

__all__ = [
    "STABILITY_TOL",
    "stable_mask",
    "unstable_mask",
    "poles_stable",
    "stability_bound",
    "in_band",
    "damping_in_band",
]

#: Half-width of the marginal band around the imaginary axis, rad/s.
STABILITY_TOL = 1e-9


def stability_bound(margin: float = 0.0) -> float:
    """Largest real part a stable pole may have, rad/s: ``-max(margin, STABILITY_TOL)``.

    Parameters
    ----------
    margin : float
        Required decay rate, rad/s, finite and >= 0 (0: plain stability).

    Raises
    ------
    robust.errors.ParameterError
        If ``margin`` is not a finite number >= 0.
    """
    return -max(check_scalar("margin", margin, NONNEGATIVE), STABILITY_TOL)


def stable_mask(poles, *, margin: float = 0.0) -> np.ndarray:
    """Boolean mask of the poles with ``Re(p) < stability_bound(margin)``.

    Parameters
    ----------
    poles : array_like of complex
        Poles, rad/s, any shape.
    margin : float
        Required decay rate, rad/s.
    """
    return np.real(np.asarray(poles)) < stability_bound(margin)


def unstable_mask(poles) -> np.ndarray:
    """Boolean mask of the poles with ``Re(p) > STABILITY_TOL`` (open right half-plane).

    Parameters
    ----------
    poles : array_like of complex
        Poles, rad/s, any shape.
    """
    return np.real(np.asarray(poles)) > STABILITY_TOL


def poles_stable(poles, *, margin: float = 0.0) -> bool:
    """Whether every pole is stable (``True`` for an empty set).

    Parameters
    ----------
    poles : array_like of complex
        Poles, rad/s.
    margin : float
        Required decay rate, rad/s.
    """
    return bool(np.all(stable_mask(poles, margin=margin)))


def in_band(poles, band_hz) -> np.ndarray:
    """Boolean mask of the poles whose frequency ``|Im p| / (2 pi)`` lies in ``band_hz``.

    Parameters
    ----------
    poles : array_like of complex
        Poles, rad/s, any shape.
    band_hz : (float, float)
        The band, Hz, both ends included.
    """
    f = np.abs(np.imag(np.asarray(poles))) / (2 * np.pi)
    return (f >= band_hz[0]) & (f <= band_hz[1])


def damping_in_band(poles, band_hz) -> np.ndarray:
    """Smallest damping ratio ``-Re p / |p|`` of the poles in ``band_hz``, along the last axis.

    Parameters
    ----------
    poles : array_like of complex
        Poles, rad/s, shape ``(..., n)`` (one set of poles per row).
    band_hz : (float, float)
        The band, Hz (:func:`in_band`).

    Returns
    -------
    numpy.ndarray, shape ``(...)``
        ``inf`` where no pole (other than one at the origin) lies in the band.
    """
    p = np.asarray(poles)
    mag = np.abs(p)
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = np.where(
            in_band(p, band_hz) & (mag > 0), -p.real / np.where(mag > 0, mag, 1.0), np.inf
        )
    return zeta.min(axis=-1) if zeta.shape[-1] else np.full(zeta.shape[:-1], np.inf)
