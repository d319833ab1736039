"""The paper's components as named-signal python-control systems.

Humphreys, Book & Huggins, "Modeling of biodynamic feedthrough in backhoe
operation" (the source paper, referred to as *the paper* below) identifies three
blocks from chirp data and closes two loops around them (its Figure 5):

* valve/cylinder, valve command ``e`` -> cylinder position ``y`` (Eqn 3);
* structure, cylinder position ``y`` -> cab acceleration ``c`` (Eqn 4);
* human, cab (seat) acceleration ``c`` -> hand motion relative to the seat ``h``
  (Eqn 5; a pluggable variant, see :mod:`backhoe.model.human`);
* a PI controller closing the cylinder position loop, and the position scale
  factor ``K_PSF`` from handle position to cylinder reference.

Frequencies the paper gives in Hz are stored in Hz and converted with 2*pi when a
system is built; zeros and poles given as plain numbers are rad/s. Signal units
are the paper's own, which it does not state (see :class:`backhoe.model.loop.LoopCalibration`
for the declared loop-scale factor that absorbs them).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import control as ct
import numpy as np

try:
    from slycot import td04ad
except ImportError:  # python-control then realises with scipy, and so does _realise
    td04ad = None

from robust.checks import DAMPING_RATIO, POSITIVE, Spec, check_scalar, validate_fields

__all__ = [
    "ValveCylinderParams",
    "HydraulicLimits",
    "StructureParams",
    "PIParams",
    "valve_cylinder",
    "structure",
    "pi_controller",
    "position_scale",
    "realise_siso",
    "K_PSF_NOMINAL",
    "STRUCTURE_SPECS",
    "VALVE_SPECS",
]

TWO_PI = 2.0 * math.pi

#: Nominal position scale factor: Omni fore-aft workspace (71 mm) over cylinder travel.
K_PSF_NOMINAL = 0.1097

_DAMPING = DAMPING_RATIO

#: What each :class:`ValveCylinderParams` field must satisfy.
VALVE_SPECS = {"k_vc": POSITIVE, "p1": POSITIVE, "wn_hz": POSITIVE, "zeta": _DAMPING}

#: What each :class:`StructureParams` field must satisfy (the family's physical limits too).
STRUCTURE_SPECS = {
    "k_s": POSITIVE,
    "zeta1": _DAMPING,
    "zeta2": _DAMPING,
    "f1_hz": POSITIVE,
    "f2_hz": POSITIVE,
}


@dataclasses.dataclass(frozen=True)
class ValveCylinderParams:
    """Valve/cylinder parameters of the paper's Eqn 3.

    Parameters
    ----------
    k_vc : float
        Gain ``K_VC`` (cylinder position per unit valve command per second), default 36.
    p1 : float
        Real pole ``p_1VC`` in rad/s, default 314.
    wn_hz : float
        Natural frequency ``omega_nVC`` of the valve in Hz, default 5.
    zeta : float
        Damping ratio ``zeta_VC`` in (0, 1), default 0.45.
    """

    k_vc: float = 36.0
    p1: float = 314.0
    wn_hz: float = 5.0
    zeta: float = 0.45

    def __post_init__(self):
        validate_fields(self, VALVE_SPECS)


@dataclasses.dataclass(frozen=True)
class HydraulicLimits:
    """What the linear Eqn 3 leaves out of the valve and the cylinder.

    The linear analyses use Eqn 3; the saturated 1 kHz simulation
    (:func:`backhoe.analysis.saturation.saturated_response`) applies these, and the
    specification's effort checks compare the loop's signals with them.

    Parameters
    ----------
    max_speed_m_s : float
        Flow saturation: the largest cylinder speed, m/s (0.4, stated assumption: a backhoe
        stick cylinder of about 100 mm bore on a pump of about 120 l/min). A proportional
        valve's full opening gives it, so the valve command saturates at
        ``max_speed / K_VC`` (in the loop's units).
    deadband : float
        Spool deadband as a fraction of the valve's command range (0.05, stated assumption;
        the paper names the deadband, not its width; proportional valves without deadband
        compensation have 5-20 %).
    stroke_m : float
        Cylinder travel, m: the paper defines ``K_PSF`` as the Omni's fore-aft workspace
        over the cylinder's travel, so 71 mm / 0.1097 = 0.647 m.
    """

    max_speed_m_s: float = 0.4
    deadband: float = 0.05
    stroke_m: float = 0.071 / K_PSF_NOMINAL

    def __post_init__(self):
        validate_fields(
            self,
            {
                "max_speed_m_s": POSITIVE,
                "deadband": Spec(low=0.0, high=1.0, high_open=True),
                "stroke_m": POSITIVE,
            },
        )


@dataclasses.dataclass(frozen=True)
class StructureParams:
    """Tractor/backhoe structure parameters of the paper's Eqn 4 (steel-stilts values).

    Parameters
    ----------
    k_s : float
        Gain ``K_s``, default 200.
    zeta1, zeta2 : float
        Damping ratios of the two modes, defaults 0.126 and 0.223.
    f1_hz, f2_hz : float
        Natural frequencies of the two modes in Hz, defaults 6.3 and 6.5.
    """

    k_s: float = 200.0
    zeta1: float = 0.126
    zeta2: float = 0.223
    f1_hz: float = 6.3
    f2_hz: float = 6.5

    def __post_init__(self):
        validate_fields(self, STRUCTURE_SPECS)


@dataclasses.dataclass(frozen=True)
class PIParams:
    """Gains of the PI controller closing the cylinder position loop.

    The valve command is ``e = kp * err + ki * integral(err)``, with ``err`` the
    cylinder reference minus the cylinder position. The paper does not print the
    gains; the defaults used by the loop come from :func:`backhoe.analysis.calibration.calibrate`.

    Parameters
    ----------
    kp : float
        Proportional gain (valve command per unit position error), > 0.
    ki : float
        Integral gain (per second), >= 0; 0 gives a pure proportional controller.
    """

    kp: float
    ki: float

    def __post_init__(self):
        validate_fields(self, {"kp": POSITIVE, "ki": Spec(low=0.0)})


def _second_order_coefficients(wn: float, zeta: float, num: list[float]) -> tuple:
    """``(num, den)`` of ``num(s) / (s^2 + 2 zeta wn s + wn^2)``."""
    return num, [1.0, 2.0 * zeta * wn, wn * wn]


#: Parameter sets whose realisation a process keeps: more than a coverage certificate's
#: members (2000 by default, the same members for every design), so that the next design a
#: process checks finds them realised.
REALISATIONS_KEPT = 8192


def _series(*factors) -> ct.TransferFunction:
    """The product of SISO transfer functions given as ``(num, den)`` coefficient lists.

    The coefficients are multiplied as python-control's ``*`` multiplies them, left to
    right (``numpy.polymul``; its sum with the zero transfer function and its products
    with one are exact), into one :class:`control.TransferFunction`: the same polynomials,
    without a system object per intermediate product (0.8 ms of a realisation's 1.2).
    """
    num, den = (np.asarray(c, float) for c in factors[0])
    for n, d in factors[1:]:
        num, den = np.polymul(num, n), np.polymul(den, d)
    return ct.tf(num, den)


@functools.lru_cache(maxsize=REALISATIONS_KEPT)
def _realised(kind: str, params) -> tuple[np.ndarray, ...]:
    """``A, B, C, D`` of a block's transfer function, realised once per parameter set.

    A loop is assembled many times over with the same valve, PI and structure (every
    check of a member builds its loop with and without the compensator and the
    feedthrough); the transfer-function products and their conversion to state space
    (SLICOT ``td04ad``) took most of an assembly. The parameters are frozen, validated
    dataclasses, so they key the cache; each call gets fresh copies of the matrices.
    """
    if kind == "valve_cylinder":
        wn = TWO_PI * params.wn_hz
        g = _series(
            ([params.k_vc * params.p1], [1.0, params.p1, 0.0]),
            _second_order_coefficients(wn, params.zeta, [wn * wn]),
        )
    elif kind == "structure":
        w1, w2 = TWO_PI * params.f1_hz, TWO_PI * params.f2_hz
        g = _series(
            ([params.k_s, 0.0, 0.0], [1.0]),
            _second_order_coefficients(w1, params.zeta1, [2.0 * params.zeta1 * w1, w1 * w1]),
            _second_order_coefficients(w2, params.zeta2, [2.0 * params.zeta2 * w2, w2 * w2]),
        )
    else:  # the PI controller
        g = (
            ct.tf([params.kp, params.ki], [1.0, 0.0])
            if params.ki > 0.0
            else ct.tf([params.kp], [1.0])
        )
    return tuple(np.array(m, float) for m in _realise(g))


def _realise(g: ct.TransferFunction) -> tuple:
    """``ct.ss(g)``'s matrices for a SISO ``g``, without its discarded work.

    python-control's conversion calls SLICOT's ``td04ad`` on ``g``'s common-denominator form,
    after a minimal realisation of ``g`` whose result it does not use (about 0.35 ms of the
    0.5 ms a conversion takes). The same call on the same arrays gives the same matrices
    (a test compares them); without SLICOT, or without that form, ``ct.ss`` itself.
    """
    common = getattr(g, "_common_den", None)
    if td04ad is None or common is None or g.ninputs != 1 or g.noutputs != 1:
        sys = ct.ss(g)
        return sys.A, sys.B, sys.C, sys.D
    num, den, denorder = common()
    n, A, B, C, D = td04ad("C", 1, 1, denorder, den, num, tol=0)
    return A[:n, :n], B[:n, :1], C[:1, :n], D


def realise_siso(num, den) -> tuple[np.ndarray, ...]:
    """``ct.ss(ct.tf(num, den))``'s matrices ``(A, B, C, D)``, without its discarded work.

    Parameters
    ----------
    num, den : array_like
        Numerator and denominator coefficients, highest power first (proper).

    Returns
    -------
    tuple of numpy.ndarray
        ``A`` (n x n), ``B`` (n x 1), ``C`` (1 x n), ``D`` (1 x 1): the realisation
        python-control gives (SLICOT's ``td04ad`` where installed).
    """
    return tuple(np.array(m, float) for m in _realise(ct.tf(num, den)))


def _block(kind: str, params, inputs: str, outputs: str, name: str) -> ct.StateSpace:
    A, B, C, D = (m.copy() for m in _realised(kind, params))
    return ct.ss(A, B, C, D, inputs=inputs, outputs=outputs, name=name)


def valve_cylinder(
    params: ValveCylinderParams | None = None, *, name: str = "valve_cylinder"
) -> ct.StateSpace:
    """Valve/cylinder of the paper's Eqn 3, valve command ``e`` -> cylinder position ``y``.

    ``Y/E = K_VC p1 / (s (s + p1)) * wn^2 / (s^2 + 2 zeta wn s + wn^2)``, with
    ``wn = 2 pi wn_hz``. Order 4, with a free integrator.

    Parameters
    ----------
    params : ValveCylinderParams, optional
        Gain, pole, valve natural frequency and damping; the paper's values
        (``ValveCylinderParams()``) when omitted.
    name : str, optional
        System name given to the python-control system, ``"valve_cylinder"`` by
        default.

    Returns
    -------
    control.StateSpace
        SISO system, input ``e`` (valve command) and output ``y`` (cylinder
        position), both in the paper's units.
    """
    return _block("valve_cylinder", params or ValveCylinderParams(), "e", "y", name)


def structure(params: StructureParams | None = None, *, name: str = "structure") -> ct.StateSpace:
    """Structure, Eqn 4: cylinder position ``y`` -> cab acceleration ``c``.

    ``C/Y = K_s s^2 * prod_i (2 z_i w_i s + w_i^2) / (s^2 + 2 z_i w_i s + w_i^2)``,
    with ``w_i = 2 pi f_i_hz``. Two derivative terms turn the input position into
    the output acceleration, so the block has a double zero at the origin. Order 4,
    biproper.

    Parameters
    ----------
    params : StructureParams, optional
        Gain, damping ratios and natural frequencies of the two structural modes;
        the paper's steel-stilts values (``StructureParams()``) when omitted.
    name : str, optional
        System name given to the python-control system, ``"structure"`` by default.

    Returns
    -------
    control.StateSpace
        SISO system, input ``y`` (cylinder position) and output ``c`` (cab
        acceleration), in the paper's units.
    """
    return _block("structure", params or StructureParams(), "y", "c", name)


def pi_controller(params: PIParams, *, name: str = "pi") -> ct.StateSpace:
    """PI controller of the cylinder position loop, ``e = kp err + ki integral(err)``.

    Parameters
    ----------
    params : PIParams
        Proportional and integral gains. With ``ki == 0`` the controller is a static
        gain (order 0); otherwise it has one integrator state.
    name : str, optional
        System name given to the python-control system, ``"pi"`` by default.

    Returns
    -------
    control.StateSpace
        SISO system, input ``err`` (cylinder reference minus cylinder position) and
        output ``e`` (valve command).
    """
    return _block("pi", params, "err", "e", name)


def position_scale(k_psf: float, *, name: str = "k_psf") -> ct.StateSpace:
    """Position scale factor: handle position ``x`` -> cylinder reference ``r = K_PSF x``.

    ``K_PSF`` is the ratio of the Omni's fore-aft workspace to the cylinder travel
    (nominal 0.1097 for 71 mm); halving it doubles the workspace.

    Parameters
    ----------
    k_psf : float
        The scale factor ``K_PSF`` (cylinder reference per unit handle position,
        dimensionless), > 0; see :data:`K_PSF_NOMINAL`.
    name : str, optional
        System name given to the python-control system, ``"k_psf"`` by default.

    Returns
    -------
    control.StateSpace
        Static (order 0) SISO gain, input ``x`` and output ``r``.

    Raises
    ------
    robust.errors.ParameterError
        If ``k_psf`` is not a finite positive number.
    """
    k = check_scalar("k_psf", k_psf, POSITIVE)
    return ct.ss([], [], [], np.array([[k]]), inputs="x", outputs="r", name=name)
