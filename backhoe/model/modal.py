"""Modal and physical parameters of the seated chain: the two views and the maps between them.

Biodynamics papers report the arm and the trunk by their natural frequency and
damping ratio; the chain of :mod:`backhoe.model.physical` needs stiffnesses and
dampings. The definitions (uncoupled modes):

* arm endpoint with the trunk held: ``k_arm = m_arm w_a^2``,
  ``c_arm = 2 zeta_arm m_arm w_a``, ``w_a = 2 pi f_arm_hz``;
* trunk on the seat, the arm moving with it (total upper-body mass
  ``M = m_trunk + m_arm``): ``k_trunk = M w_t^2``, ``c_trunk = 2 zeta_trunk M w_t``.

The coupled chain's modes differ slightly from these (the arm is light beside the
trunk); :meth:`backhoe.model.physical.PhysicalHumanParams.modes` gives the coupled ones.
"""

from __future__ import annotations

import numpy as np

from robust.checks import POSITIVE, check_array

__all__ = ["modal_to_physical", "physical_to_modal"]


def _positive(owner: str, **arrays) -> list[np.ndarray]:
    """Every argument as a float array, checked finite and strictly positive (named)."""
    return [check_array(f"{owner}: {k}", v, POSITIVE) for k, v in arrays.items()]


def modal_to_physical(m_trunk, m_arm, f_trunk_hz, zeta_trunk, f_arm_hz, zeta_arm):
    """Stiffnesses and dampings from masses, natural frequencies and damping ratios.

    Parameters
    ----------
    m_trunk, m_arm : float or array_like
        Upper-body and effective arm-endpoint masses, kg.
    f_trunk_hz, zeta_trunk : float or array_like
        Natural frequency (Hz) and damping ratio of the upper body on the seat.
    f_arm_hz, zeta_arm : float or array_like
        Natural frequency (Hz) and damping ratio of the arm endpoint, trunk held.

    Returns
    -------
    k_trunk, c_trunk, k_arm, c_arm : float or ndarray
        N/m, N s/m, N/m, N s/m (broadcast shapes).

    Raises
    ------
    robust.errors.ParameterError
        If an argument is not finite and strictly positive (the message names it).
    """
    m_t, m_a, f_t, z_t, f_a, z_a = _positive(
        "modal_to_physical",
        m_trunk=m_trunk,
        m_arm=m_arm,
        f_trunk_hz=f_trunk_hz,
        zeta_trunk=zeta_trunk,
        f_arm_hz=f_arm_hz,
        zeta_arm=zeta_arm,
    )
    w_t = 2.0 * np.pi * f_t
    w_a = 2.0 * np.pi * f_a
    M = m_t + m_a
    k_t = M * w_t**2
    c_t = 2.0 * z_t * M * w_t
    k_a = m_a * w_a**2
    c_a = 2.0 * z_a * m_a * w_a
    return k_t, c_t, k_a, c_a


def physical_to_modal(m_trunk, m_arm, k_trunk, c_trunk, k_arm, c_arm):
    """Natural frequencies and damping ratios from masses, stiffnesses and dampings.

    The inverse of :func:`modal_to_physical`.

    Parameters
    ----------
    m_trunk, m_arm : float or array_like
        Upper-body and effective arm-endpoint masses, kg.
    k_trunk, c_trunk : float or array_like
        Seat-trunk stiffness (N/m) and damping (N s/m).
    k_arm, c_arm : float or array_like
        Trunk-arm stiffness (N/m) and damping (N s/m).

    Returns
    -------
    f_trunk_hz, zeta_trunk, f_arm_hz, zeta_arm : float or ndarray

    Raises
    ------
    robust.errors.ParameterError
        If an argument is not finite and strictly positive (the message names it).
    """
    m_t, m_a, k_t, c_t, k_a, c_a = _positive(
        "physical_to_modal",
        m_trunk=m_trunk,
        m_arm=m_arm,
        k_trunk=k_trunk,
        c_trunk=c_trunk,
        k_arm=k_arm,
        c_arm=c_arm,
    )
    M = m_t + m_a
    w_t, w_a = np.sqrt(k_t / M), np.sqrt(k_a / m_a)
    return (
        w_t / (2.0 * np.pi),
        c_t / (2.0 * M * w_t),
        w_a / (2.0 * np.pi),
        c_a / (2.0 * m_a * w_a),
    )
