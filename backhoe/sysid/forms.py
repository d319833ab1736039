"""Model forms of the fits: the paper's Eqns 3, 4, 5 and rational ``"M/N"`` models.

Each fixed form knows how to evaluate itself, how to read a starting point from a
linear rational fit of the response with its known factor ``s^k`` divided out,
and how its parameters map to the unconstrained-where-possible fit vector (gains
and frequencies in logarithms, damping ratios bounded, the structure's modes
ordered by ``f2 = f1 exp(d)``, ``d >= 0``).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable

import control as ct
import numpy as np

from backhoe.model.components import StructureParams, ValveCylinderParams
from backhoe.model.human import LiteralHumanParams
from robust.errors import ParameterError

__all__ = ["FORMS", "FORM_SPECS", "ZETA_BOUNDS", "RationalParams", "form_system", "parse_form"]

TWO_PI = 2.0 * math.pi
#: The paper's fixed forms, by name.
FORMS = ("valve", "structure", "human")
#: Bounds of fitted damping ratios.
ZETA_BOUNDS = (0.005, 0.995)
_ORDER_RE = re.compile(r"^\s*(\d+)\s*/\s*(\d+)\s*$")


@dataclasses.dataclass(frozen=True)
class RationalParams:
    """Coefficients of a general rational fit ``num(s) / den(s)`` (highest power first, rad/s).

    Attributes
    ----------
    num, den : tuple of float
        Numerator (order ``M``) and monic denominator (order ``N``) coefficients.
    """

    num: tuple[float, ...]
    den: tuple[float, ...]

    def __post_init__(self):
        num = tuple(float(x) for x in self.num)
        den = tuple(float(x) for x in self.den)
        if not all(math.isfinite(x) for x in num + den):
            raise ParameterError(
                f"RationalParams coefficients must be finite; got num={num}, den={den}"
            )
        if len(num) > len(den):
            raise ParameterError(
                f"RationalParams must be proper: {len(num) - 1=} > {len(den) - 1=}"
            )
        object.__setattr__(self, "num", num)
        object.__setattr__(self, "den", den)

    def as_dict(self) -> dict[str, float]:
        """Coefficients by name.

        ``b<k>`` multiplies ``s^k`` in the numerator, ``a<k>`` in the denominator.
        """
        out = {f"b{len(self.num) - 1 - i}": v for i, v in enumerate(self.num)}
        out.update({f"a{len(self.den) - 1 - i}": v for i, v in enumerate(self.den)})
        return out

    def transfer_function(self) -> ct.TransferFunction:
        """The model as a :class:`control.TransferFunction` (rad/s)."""
        return ct.tf(list(self.num), list(self.den))


@dataclasses.dataclass(frozen=True)
class _Form:
    """A fixed structure: how to evaluate it and map parameters to/from the fit vector."""

    name: str
    names: tuple[str, ...]  # natural parameter names, in the params class's order
    params_class: type
    s_power: int  # H = s^k R(s)
    init_orders: tuple[int, int]  # (m, n) of R for the linear estimate
    response: Callable[[np.ndarray, np.ndarray], np.ndarray]  # (natural vec, s) -> H
    from_rational: Callable[[np.ndarray, np.ndarray], np.ndarray]  # (num, den) of R -> natural vec
    to_theta: Callable[[np.ndarray], np.ndarray]
    from_theta: Callable[[np.ndarray], np.ndarray]
    theta_bounds: Callable[[float, float], tuple[np.ndarray, np.ndarray]]  # (w_lo, w_hi) rad/s
    theta_labels: tuple[str, ...]  # what each entry of the fit vector is


def _pairs_from_roots(roots: np.ndarray) -> list[tuple[float, float]]:
    """Group roots into (wn, zeta) pairs: complex pairs directly, real roots paired by size."""
    roots = np.asarray(roots, dtype=complex)
    pairs: list[tuple[float, float]] = []
    cplx = sorted([r for r in roots if r.imag > 1e-12 * max(1.0, abs(r))], key=abs)
    real = sorted([abs(r.real) for r in roots if abs(r.imag) <= 1e-12 * max(1.0, abs(r))])
    for r in cplx:
        wn = abs(r)
        pairs.append((wn, min(max(abs(r.real) / wn, ZETA_BOUNDS[0]), ZETA_BOUNDS[1])))
    for r1, r2 in zip(real[0::2], real[1::2]):
        wn = math.sqrt(max(r1 * r2, 1e-300))
        pairs.append((wn, min(max((r1 + r2) / (2.0 * wn), ZETA_BOUNDS[0]), ZETA_BOUNDS[1])))
    return pairs


def _valve_response(p, s):
    k, p1, fn, z = p
    wn = TWO_PI * fn
    return k * p1 * wn * wn / (s * (s + p1) * (s * s + 2.0 * z * wn * s + wn * wn))


def _valve_from_rational(num, den):
    roots = np.roots(den)
    real = [r for r in roots if abs(r.imag) <= 1e-9 * max(1.0, abs(r))]
    cplx = [r for r in roots if r.imag > 1e-9 * max(1.0, abs(r))]
    if cplx and real:
        p1 = abs(real[0].real)
        wn, z = _pairs_from_roots(np.array([cplx[0], np.conj(cplx[0])]))[0]
    else:
        mags = sorted(abs(r.real) for r in roots)
        p1 = mags[-1]
        wn, z = _pairs_from_roots(np.array(mags[:2], dtype=complex))[0]
    k = abs(num[-1] / den[-1]) if den[-1] != 0 else 1.0
    return np.array([k, p1, wn / TWO_PI, z])


def _structure_response(p, s):
    k, z1, z2, f1, f2 = p
    out = k * s * s
    for z, f in ((z1, f1), (z2, f2)):
        w = TWO_PI * f
        out = out * (2.0 * z * w * s + w * w) / (s * s + 2.0 * z * w * s + w * w)
    return out


def _structure_from_rational(num, den):
    pairs = _pairs_from_roots(np.roots(den))
    if len(pairs) < 2:  # pragma: no cover - four roots always give two pairs
        pairs = pairs * 2
    (w1, z1), (w2, z2) = sorted(pairs[:2])
    k = abs(num[-1] / den[-1]) if den[-1] != 0 else 1.0
    return np.array([k, z1, z2, w1 / TWO_PI, w2 / TWO_PI])


def _human_response(p, s):
    k, z1, p1 = p
    return k * (s + z1) ** 2 / (s * s * (s + p1) ** 2)


def _human_from_rational(num, den):
    k = abs(num[0]) if abs(num[0]) > 0 else 1.0
    z1 = math.sqrt(abs(num[-1] / num[0])) if num[0] != 0 else 1.0
    p1 = math.sqrt(abs(den[-1]))
    return np.array([k, z1, p1])


def _log_bounds(idx_log_freq, n, w_lo, w_hi, lin=()):
    lo = np.full(n, -np.inf)
    hi = np.full(n, np.inf)
    for i, unit in idx_log_freq:
        lo[i] = math.log(w_lo / 100.0 / unit)
        hi[i] = math.log(w_hi * 100.0 / unit)
    for i, (a, b) in lin:
        lo[i], hi[i] = a, b
    return lo, hi


FORM_SPECS: dict[str, _Form] = {
    "valve": _Form(
        name="valve",
        names=("k_vc", "p1", "wn_hz", "zeta"),
        params_class=ValveCylinderParams,
        s_power=-1,
        init_orders=(0, 3),
        response=_valve_response,
        from_rational=_valve_from_rational,
        to_theta=lambda p: np.array([math.log(p[0]), math.log(p[1]), math.log(p[2]), p[3]]),
        from_theta=lambda t: np.array([math.exp(t[0]), math.exp(t[1]), math.exp(t[2]), t[3]]),
        theta_bounds=lambda a, b: _log_bounds(
            [(1, 1.0), (2, TWO_PI)], 4, a, b, lin=[(3, ZETA_BOUNDS)]
        ),
        theta_labels=("ln k_vc", "ln p1", "ln wn_hz", "zeta"),
    ),
    "structure": _Form(
        name="structure",
        names=("k_s", "zeta1", "zeta2", "f1_hz", "f2_hz"),
        params_class=StructureParams,
        s_power=2,
        init_orders=(2, 4),
        response=_structure_response,
        from_rational=_structure_from_rational,
        # f2 = f1 * exp(d), d >= 0 keeps the modes ordered (f1 <= f2)
        to_theta=lambda p: np.array(
            [math.log(p[0]), p[1], p[2], math.log(p[3]), math.log(p[4] / p[3])]
        ),
        from_theta=lambda t: np.array(
            [math.exp(t[0]), t[1], t[2], math.exp(t[3]), math.exp(t[3] + t[4])]
        ),
        theta_bounds=lambda a, b: _log_bounds(
            [(3, TWO_PI)],
            5,
            a,
            b,
            lin=[(1, ZETA_BOUNDS), (2, ZETA_BOUNDS), (4, (0.0, math.log(100.0)))],
        ),
        theta_labels=("ln k_s", "zeta1", "zeta2", "ln f1_hz", "ln(f2_hz/f1_hz)"),
    ),
    "human": _Form(
        name="human",
        names=("k_h", "z1", "p1"),
        params_class=LiteralHumanParams,
        s_power=-2,
        init_orders=(2, 2),
        response=_human_response,
        from_rational=_human_from_rational,
        to_theta=lambda p: np.log(np.asarray(p, dtype=float)),
        from_theta=lambda t: np.exp(np.asarray(t, dtype=float)),
        theta_bounds=lambda a, b: _log_bounds([(1, 1.0), (2, 1.0)], 3, a, b),
        theta_labels=("ln k_h", "ln z1", "ln p1"),
    ),
}


def parse_form(form: str) -> str | tuple[int, int]:
    """Return a fixed form's name, or ``(M, N)`` for a rational form written ``"M/N"``.

    Parameters
    ----------
    form : str
        ``"valve"``, ``"structure"``, ``"human"``, or ``"M/N"`` with numerator order
        ``M`` and denominator order ``N`` (``M <= N``).

    Raises
    ------
    ParameterError
        For an unknown name, a malformed order, or ``M > N`` (improper).
    """
    if not isinstance(form, str):
        raise ParameterError(f"form must be a string; got {type(form).__name__}")
    if form in FORM_SPECS:
        return form
    match = _ORDER_RE.match(form)
    if not match:
        raise ParameterError(
            f"form must be one of {FORMS} or 'M/N' (numerator/denominator orders, "
            f"e.g. '2/4'); got {form!r}"
        )
    m, n = int(match.group(1)), int(match.group(2))
    if n < 1 or m > n:
        raise ParameterError(
            f"rational form 'M/N' needs 1 <= N and M <= N (proper); got M={m}, N={n}"
        )
    return (m, n)


def form_system(form: str, params) -> ct.TransferFunction:
    """The transfer function (rad/s) of a parameter object in ``form``.

    Parameters
    ----------
    form : str
        ``"valve"``, ``"structure"``, ``"human"`` or ``"M/N"``.
    params : ValveCylinderParams, StructureParams, LiteralHumanParams or RationalParams
    """
    parsed = parse_form(form)
    if isinstance(parsed, tuple):
        if not isinstance(params, RationalParams):
            raise ParameterError(f"form {form!r} needs RationalParams; got {type(params).__name__}")
        return params.transfer_function()
    spec = FORM_SPECS[parsed]
    if not isinstance(params, spec.params_class):
        raise ParameterError(
            f"form {form!r} needs {spec.params_class.__name__}; got {type(params).__name__}"
        )
    return _tf_of(spec.name, np.array([getattr(params, nm) for nm in spec.names], dtype=float))


def _tf_of(name: str, p: np.ndarray) -> ct.TransferFunction:
    if name == "valve":
        k, p1, fn, z = p
        wn = TWO_PI * fn
        return ct.tf([k * p1 * wn * wn], np.polymul([1.0, p1, 0.0], [1.0, 2.0 * z * wn, wn * wn]))
    if name == "structure":
        k, z1, z2, f1, f2 = p
        num = np.array([k, 0.0, 0.0])
        den = np.array([1.0])
        for z, f in ((z1, f1), (z2, f2)):
            w = TWO_PI * f
            num = np.polymul(num, [2.0 * z * w, w * w])
            den = np.polymul(den, [1.0, 2.0 * z * w, w * w])
        return ct.tf(num, den)
    k, z1, p1 = p
    return ct.tf([k, 2.0 * k * z1, k * z1 * z1], [1.0, 2.0 * p1, p1 * p1, 0.0, 0.0])
