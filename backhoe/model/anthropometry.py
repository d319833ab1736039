"""Segment masses of a seated operator from body mass (anthropometric fractions).

Reference: D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th
ed., Wiley, 2009, Table 4.1 (segment mass / total body mass).
"""

from __future__ import annotations

import numpy as np

from robust.checks import POSITIVE, check_array

__all__ = ["SEGMENT_MASS_FRACTIONS", "NOMINAL_BODY_MASS", "segment_masses"]

#: Segment mass / body mass (Winter 2009, Table 4.1).
SEGMENT_MASS_FRACTIONS = {
    "hand": 0.006,
    "forearm": 0.016,
    "upper_arm": 0.028,
    "trunk": 0.497,
    "head_neck": 0.081,
}

#: Body mass of the nominal operator, kg (about a median adult male).
NOMINAL_BODY_MASS = 75.0


def segment_masses(body_mass):
    """Lumped masses of the chain for an operator of ``body_mass`` kg.

    Parameters
    ----------
    body_mass : float or array_like
        Total body mass in kg; an array gives arrays of the same shape (one
        operator per element).

    Returns
    -------
    dict
        ``trunk`` (trunk + head-neck + the idle arm, which ride on the trunk),
        ``arm`` (upper arm + forearm + hand of the operating arm), and for the
        3-DOF exploration ``upper_arm`` and ``forearm_hand``; all in kg.
        The thighs and legs rest on the seat and are not part of the chain.

    Raises
    ------
    robust.errors.ParameterError
        If a body mass is not a finite positive number.
    """
    fr = SEGMENT_MASS_FRACTIONS
    arm = fr["upper_arm"] + fr["forearm"] + fr["hand"]
    checked = check_array("segment_masses: body_mass", body_mass, POSITIVE)
    bm = checked if np.ndim(body_mass) else float(checked)
    return {
        "trunk": (fr["trunk"] + fr["head_neck"] + arm) * bm,
        "arm": arm * bm,
        "upper_arm": fr["upper_arm"] * bm,
        "forearm_hand": (fr["forearm"] + fr["hand"]) * bm,
    }
