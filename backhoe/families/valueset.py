"""Zero exclusion on value sets: a frequency-domain certificate of the open BDFT loop's margin.

Without a compensator the Figure 5 loop is one loop through three blocks: the tracking loop
``T = P / (1 + P)`` (the PI controller, fixed, and the valve/cylinder of Eqn 3 with the
valve's parameters), the structure ``S_c`` (cylinder position to cab acceleration; the
structure's parameters) and the physical human ``H`` (cab acceleration to hand motion; the
human's parameters), closed through the handle gain ``kappa``. Its characteristic
polynomial factors as::

    det(sI - A_cl) = det(sI - A_T) det(sI - A_S) det(sI - A_H) (1 + L(s)),
    L(s) = kappa T(s) H(s) S_c(s),
    T(s) = N(s) / (D_v(s) + N(s)),   N(s) = K_VC p1 wn^2 (kp s + ki),
    D_v(s) = s^2 (s + p1) (s^2 + 2 zeta wn s + wn^2)   (``ki = 0``: ``N = K_VC p1 wn^2 kp``
    and one ``s`` fewer in ``D_v``),
    S_c(s) = k_s s^2 prod_i (2 zeta_i w_i s + w_i^2) / (s^2 + 2 zeta_i w_i s + w_i^2),
    H(s) = -c_u g (s^2 + d_3 s + R (w_a^2 + w_t^2)) / D(s)

(the determinant lemma for a single loop whose product is strictly proper; ``D`` the
human's characteristic quartic, ``R = 1 + m_arm / m_trunk``). Every factor's numerator and
denominator is enclosed on every cell and must exclude 0 there (the tracking loop's
characteristic polynomial ``D_v + N`` among them, which the valve's spread moves), and the
nominal tracking loop is checked stable. So, the box being connected, its characteristic
polynomials of one degree and its nominal member stable, every member of the box is stable
if and only if ``1 + L(j w) != 0`` for every frequency ``w >= 0`` and every member: *zero
exclusion* (Barmish, *New Tools for Robustness of Linear Systems*, Macmillan 1994, ch. 7;
Frazer & Duncan 1929).

The certificate covers the continuum of members and frequencies. The frequency axis
``[0, w_max]`` (``w_max`` bounds every member's eigenvalue moduli: the Perron root of the
entrywise magnitude bound of the interval closed-loop matrix, by a Collatz-Wielandt
vector) is cut into cells, each a frequency interval times a sub-box of the parameters.
On a cell each factor's value is enclosed by the mean-value form in interval arithmetic
(:class:`robust.analysis.intervals.Gradient`, the frequency one of the variables), a
rectangle of the complex plane, and turned into an interval of its logarithm's real part
(log-magnitude) and of its argument. The factors depend on disjoint parameters, so the
log-magnitudes and arguments of the product add (the hull of a product of value sets in
log-polar coordinates is the sum of the hulls): the cell is certified when the sum
excludes ``log|L| = 0`` or every odd multiple of ``pi`` of the argument. A cell that
fails is split in two along the variable (a parameter or the frequency) whose range
widens the sum most; the scale is certified when every cell is, within a budget of
cells. The factorisation and the enclosures are checked against sampled members (numpy
transfer functions and closed-loop determinants) in the tests.

The route applies to a family with the physical human and no compensator, for the
open left half-plane (:meth:`ValueSetLoop.applies`); there
:func:`uncertainty.margins.robust_margin` and ``bdft margin`` take it by default (method
``"auto"``): on the default family it certifies 0.087 of an upper bound of 0.090, where
the eigenvalue enclosures reach 0.039. Each scale certified is also checked at run time:
the nominal member stable, seeded members of the box stable (numpy eigenvalues).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import control as ct
import numpy as np

from backhoe.families.batched import interconnection, loop_blocks
from backhoe.families.family import Family
from backhoe.families.loop import fixed_parameters
from backhoe.model.blocks import VALVE_FIELDS, parameter_name
from robust.analysis.intervals import Gradient, Interval
from robust.errors import ParameterError

__all__ = ["ValueSetLoop", "certify_scale_valueset"]

#: Frequency cells the axis starts with (geometric above :data:`_W_LOW`).
_W_CELLS = 256
_W_LOW = 1e-2
_HUMAN = (
    parameter_name("human", "body_mass"),
    parameter_name("human", "m_arm"),
    parameter_name("human", "f_arm_hz"),
    parameter_name("human", "zeta_arm"),
    parameter_name("human", "f_trunk_hz"),
    parameter_name("human", "zeta_trunk"),
)
_SECTIONS = (
    (parameter_name("structure", "zeta1"), parameter_name("structure", "f1_hz")),
    (parameter_name("structure", "zeta2"), parameter_name("structure", "f2_hz")),
)
_VALVE = tuple(parameter_name("valve", f) for f in VALVE_FIELDS)
_TAU = 2 * math.pi


def _poly_jw(coeffs, w):
    """Real and imaginary parts of ``sum_k c_k (j w)^k`` (``coeffs`` highest power first)."""
    n = len(coeffs) - 1
    re, im = 0.0, 0.0
    power = None
    for k in range(n + 1):
        c = coeffs[n - k]
        term = c if k == 0 else c * power
        sign = 1.0 if (k // 2) % 2 == 0 else -1.0
        if k % 2 == 0:
            re = re + sign * term
        else:
            im = im + sign * term
        power = w if power is None else power * w
    return re, im


def _safe_reciprocal(x, bad: list):
    """``1 / x`` where the range of ``x`` excludes 0; elsewhere 1, recorded in ``bad``."""
    val = x.val if isinstance(x, Gradient) else x
    zero = val.lo <= 0
    if zero.any():
        bad.append(zero)
        if isinstance(x, Gradient):
            one = Interval(np.where(zero, 1.0, val.mid), np.where(zero, 0.0, val.rad))
            der = Interval(np.where(zero, 0.0, x.der.mid), np.where(zero, 0.0, x.der.rad))
            x = Gradient(one, der)
        else:
            x = Interval(np.where(zero, 1.0, val.mid), np.where(zero, 0.0, val.rad))
    return x.reciprocal()


def _human_value(p, w, bad: list):
    """The physical human's numerator and denominator at ``s = j w`` (module notes), each as
    real and imaginary parts, from its parameters ``p``."""
    r = p["m_arm"] * _safe_reciprocal(p["m_trunk"], bad)
    big_r = 1.0 + r
    wt, wa = _TAU * p["f_trunk_hz"], _TAU * p["f_arm_hz"]
    wt2, wa2 = wt.square(), wa.square()
    st, sa = 2.0 * p["zeta_trunk"] * wt, 2.0 * p["zeta_arm"] * wa
    d3 = big_r * (sa + st)
    d2 = big_r * (wa2 + wt2 + sa * st)
    d1 = big_r * (sa * wt2 + st * wa2)
    d0 = big_r * (wa2 * wt2)
    w2 = w.square()
    dr = w2.square() - d2 * w2 + d0
    di = (d1 - d3 * w2) * w
    k = -p["c_unit"] * p["h_gain"]
    nr = k * (big_r * (wa2 + wt2) - w2)
    ni = k * (d3 * w)
    return (nr, ni), (dr, di)


def _tracking_value(k_vc, p1, wn_hz, zeta, w, kp: float, ki: float):
    """Numerator ``N`` and denominator ``D_v + N`` of the tracking loop ``T`` (module notes)
    at ``s = j w``, each as real and imaginary parts, from the valve's parameters and the PI
    gains ``kp``, ``ki``."""
    wn = _TAU * wn_hz
    b = wn.square()
    a = 2.0 * zeta * wn
    g = k_vc * p1 * b
    # D_v / s^m = s^3 + (p1 + a) s^2 + (b + a p1) s + b p1, m = 2 with an integral gain
    core = [1.0, p1 + a, b + a * p1, b * p1]
    if ki > 0.0:
        num = [g * kp, g * ki]
        den = core + [num[0], num[1]]
    else:
        num = [g * kp]
        den = core + [num[0]]
    return _poly_jw(num, w), _poly_jw(den, w)


def _section_value(zeta, f_hz, w, bad: list):
    """Numerator ``2 zeta w_n s + w_n^2`` and denominator ``s^2 + 2 zeta w_n s + w_n^2`` of a
    structure section at ``s = j w``, each as real and imaginary parts."""
    wn = _TAU * f_hz
    wn2 = wn.square()
    b = 2.0 * zeta * wn * w
    return (wn2 + 0.0 * w, b), (wn2 - w.square(), b)


class ValueSetLoop:
    """The open loop's factors (module notes) for the value-set certificate.

    Parameters
    ----------
    family : Family
        A family with the physical human; analysed without a compensator.

    Raises
    ------
    ParameterError
        If the family's loop does not have the single-loop structure of the module notes
        (:meth:`applies` says whether it does without raising).
    """

    def __init__(self, family: Family):
        why = self.why_not(family)
        if why:
            raise ParameterError(f"value-set certificate: {why}")
        self.family = family
        self.names = tuple(family.names)
        self.logs = np.array([p.distribution == "loguniform" for p in family.parameters])
        nominal = np.array([p.nominal for p in family.parameters], float)
        blocks = loop_blocks(family, nominal[None], check_bounds=False)
        by = {b.name: b for b in blocks}
        M = interconnection(family, blocks, None)
        self.kappa = -float(M[0, 4])
        pi, valve = by["pi"], by["valve"]
        sys_pi = ct.ss(pi.A[0], pi.B[0], pi.C[0], pi.D[0])
        sys_v = ct.ss(valve.A[0], valve.B[0], valve.C[0], valve.D[0])
        T = ct.feedback(sys_v * sys_pi, 1)
        poles = np.linalg.eigvals(T.A)
        if not np.all(poles.real < -1e-6):
            raise ParameterError("value-set certificate: the nominal tracking loop is not stable")
        self.kp, self.ki = float(family.calibration.kp), float(family.calibration.ki)
        self.fixed = fixed_parameters(family)
        phys = family.physical
        self.trunk_share = phys.m_trunk / family.body_mass
        self.index = {n: i for i, n in enumerate(self.names)}

    @staticmethod
    def why_not(family) -> str:
        """Why the route does not apply to ``family`` ('' when it does).

        Parameters
        ----------
        family : Family
            Any family.
        """
        if not isinstance(family, Family):
            return "needs a Family"
        if family.human != "physical":
            return "needs the physical human"
        nominal = np.array([p.nominal for p in family.parameters], float)
        blocks = loop_blocks(family, nominal[None], check_bounds=False)
        if [b.name for b in blocks] != ["pi", "valve", "structure", "human"]:
            return "needs the loop pi, valve, structure, human without a compensator"
        M = interconnection(family, blocks, None)
        expected = np.zeros((5, 5))
        expected[0, 1], expected[1, 0], expected[2, 1], expected[3, 3] = -1.0, 1.0, 1.0, 1.0
        pattern = M.copy()
        pattern[0, 4] = 0.0
        if M[0, 4] == 0 or not np.array_equal(pattern, expected):
            return "the interconnection is not the single BDFT loop"
        return ""

    @classmethod
    def applies(cls, family) -> bool:
        """Whether the route applies to ``family``.

        Parameters
        ----------
        family : Family
            Any family.
        """
        return not cls.why_not(family)

    # -- values of the factors --------------------------------------------------------------
    @staticmethod
    def _variables(lo_t, hi_t, w_lo, w_hi, logs):
        """Gradient variables of the columns (log coordinates where ``logs``) and the
        frequency (last), per cell."""
        n, d = lo_t.shape[0], len(logs) + 1
        out = []
        for j, is_log in enumerate(logs):
            lo, hi = lo_t[:, j], hi_t[:, j]
            if is_log:
                val = Interval.hull(np.exp(lo), np.exp(hi))
                val = Interval(val.mid, val.rad * (1 + 1e-12) + 1e-15 * np.abs(val.mid))
                dmid, drad = val.mid, val.rad
            else:
                val = Interval.hull(lo, hi)
                dmid, drad = np.ones(n), np.zeros(n)
            mid, rad = np.zeros((d, n)), np.zeros((d, n))
            mid[j], rad[j] = dmid, drad
            out.append(Gradient(val, Interval(mid, rad)))
        mid, rad = np.zeros((d, n)), np.zeros((d, n))
        mid[-1] = 1.0
        out.append(Gradient(Interval.hull(w_lo, w_hi), Interval(mid, rad)))
        return out

    @staticmethod
    def _centre(lo_t, hi_t, w_lo, w_hi, logs):
        """The cells' centres as point intervals (same order as :meth:`_variables`)."""
        out = []
        for j, is_log in enumerate(logs):
            t = (lo_t[:, j] + hi_t[:, j]) / 2
            out.append(Interval.point(np.exp(t) if is_log else t))
        out.append(Interval.point((w_lo + w_hi) / 2))
        return out

    @staticmethod
    def _mean_value(fc: Interval, g: Gradient, h: np.ndarray) -> tuple:
        """``[lo, hi]`` of the mean-value form about the centre, cut with the plain range."""
        rad = fc.rad + np.sum(h * (np.abs(g.der.mid) + g.der.rad), axis=0)
        lo = np.maximum(fc.mid - rad, g.val.lo)
        hi = np.minimum(fc.mid + rad, g.val.hi)
        return lo, hi, h * (np.abs(g.der.mid) + g.der.rad)

    def _factor(self, fn, lo_t, hi_t, w_lo, w_hi, logs):
        """A factor's rectangle (re and im ranges) over the cells and per-variable widths."""
        half = [(hi_t[:, j] - lo_t[:, j]) / 2 * (1 + 1e-12) for j in range(len(logs))]
        half.append((w_hi - w_lo) / 2 * (1 + 1e-12))
        h = np.array(half)
        bad = []
        g_re, g_im = fn(self._variables(lo_t, hi_t, w_lo, w_hi, logs), bad)
        c_re, c_im = fn(self._centre(lo_t, hi_t, w_lo, w_hi, logs), bad)
        re_lo, re_hi, re_w = self._mean_value(c_re, g_re, h)
        im_lo, im_hi, im_w = self._mean_value(c_im, g_im, h)
        invalid = np.zeros(lo_t.shape[0], bool)
        for b in bad:
            invalid |= np.broadcast_to(b, invalid.shape)
        rect = (re_lo, re_hi, im_lo, im_hi)
        centre = (c_re.lo, c_re.hi, c_im.lo, c_im.hi)
        return rect, re_w + im_w, invalid, _log_zonotope(rect, centre, g_re.der, g_im.der, h)

    def _human(self, v, bad):
        bm, m_arm, fa, za, ft, zt = v[:6]
        w = v[6]
        p = {
            "m_trunk": self.trunk_share * bm,
            "m_arm": m_arm,
            "f_arm_hz": fa,
            "zeta_arm": za,
            "f_trunk_hz": ft,
            "zeta_trunk": zt,
            "c_unit": self.fixed[parameter_name("human", "c_unit")],
            "h_gain": self.fixed[parameter_name("human", "h_gain")],
        }
        return _human_value(p, w, bad)

    def _tracking(self, v, bad):
        return _tracking_value(*v[:5], self.kp, self.ki)

    def _cols(self, names):
        """Columns of ``names`` among the varied parameters (fixed ones: None)."""
        return [self.index.get(n) for n in names]

    def factors(self, lo_t, hi_t, w_lo, w_hi) -> list:
        """Every factor's log-polar ranges over the cells, and per-cell split scores.

        The zonotope of ``(log|L|, arg L)`` per cell (centre, generators per variable,
        remainder radius, whether it is valid) is left in :attr:`zonotope`.

        Parameters
        ----------
        lo_t, hi_t : numpy.ndarray, shape (n, d)
            The cells' parameter boxes in the family's coordinates.
        w_lo, w_hi : numpy.ndarray, shape (n,)
            The cells' frequency intervals, rad/s.

        Returns
        -------
        (numpy.ndarray, numpy.ndarray, numpy.ndarray, numpy.ndarray, numpy.ndarray)
            Log-magnitude low and high, argument low and high (rad) of ``L`` per cell, and
            the width each variable (family columns, then the frequency) adds, shape
            ``(n, d + 1)``.
        """
        n, d = lo_t.shape
        score = np.zeros((n, d + 1))
        mag_lo, mag_hi = (
            np.full(n, math.log(abs(self.kappa))),
            np.full(n, math.log(abs(self.kappa))),
        )
        arg_lo = np.full(n, 0.0 if self.kappa > 0 else math.pi)
        arg_hi = arg_lo.copy()
        parts = []
        invalid = np.zeros(n, bool)
        # the zonotope of (log|L|, arg L): centre, generators per variable, remainder radius,
        # per-variable remainder share (split score), valid
        zc = np.tile([math.log(abs(self.kappa)), 0.0 if self.kappa > 0 else math.pi], (n, 1))
        zg = np.zeros((n, d + 1, 2))
        zr = np.zeros((n, 2))
        zs = np.zeros((n, d + 1))
        z_ok = np.ones(n, bool)

        # each factor as its numerator and its denominator (log-polar: a sum and a
        # difference, the shared variables' generators adding up)
        def num_den(fn, which):
            return lambda v, bad: fn(v, bad)[which]

        def section(v, bad):
            return _section_value(v[0], v[1], v[2], bad)

        for fn, names in [(self._tracking, _VALVE), (self._human, _HUMAN)] + [
            (section, sec) for sec in _SECTIONS
        ]:
            parts.append((num_den(fn, 0), names, 1.0))
            parts.append((num_den(fn, 1), names, -1.0))
        for fn, names, sign in parts:
            cols = self._cols(names)
            lo_c, hi_c, logs = self._with_fixed(lo_t, hi_t, names, cols)
            rect, widths, bad, zono = self._factor(fn, lo_c, hi_c, w_lo, w_hi, logs)
            invalid |= bad
            z_ok &= zono[4]
            zc += sign * zono[0]
            zr += zono[2]
            for j, c in enumerate(cols):
                if c is not None:
                    zg[:, c] += sign * zono[1][j]
                    zs[:, c] += zono[3][j]
            zg[:, d] += sign * zono[1][-1]
            zs[:, d] += zono[3][-1]
            m_lo, m_hi, a_lo, a_hi = _log_polar(*rect)
            if sign < 0:
                m_lo, m_hi, a_lo, a_hi = -m_hi, -m_lo, -a_hi, -a_lo
            invalid |= _min_modulus(*rect) <= 0
            mag_lo, mag_hi = mag_lo + m_lo, mag_hi + m_hi
            arg_lo, arg_hi = arg_lo + a_lo, arg_hi + a_hi
            # where the zonotope fails: the rectangle's widths relative to its size
            re_lo, re_hi, im_lo, im_hi = rect
            size = np.hypot(
                np.maximum(np.abs(re_lo), np.abs(re_hi)), np.maximum(np.abs(im_lo), np.abs(im_hi))
            )
            scale = 1.0 / np.maximum(size, 1e-300)
            for j, c in enumerate(cols):
                if c is not None:
                    score[:, c] += widths[j] * scale
            score[:, d] += widths[-1] * scale
        # the structure's gain and the s^2 of the acceleration
        ks = self.index.get(parameter_name("structure", "k_s"))
        if ks is None:
            lk = math.log(self.fixed[parameter_name("structure", "k_s")]) * np.ones((2, n))
        else:
            lk = np.array([lo_t[:, ks], hi_t[:, ks]])
            if not self.logs[ks]:
                lk = np.log(lk)
            score[:, ks] += lk[1] - lk[0]
        with np.errstate(divide="ignore"):
            mag_lo = mag_lo + lk[0] + 2 * np.log(w_lo)
        mag_hi = mag_hi + lk[1] + 2 * np.log(w_hi)
        arg_lo, arg_hi = arg_lo + math.pi, arg_hi + math.pi
        # the s^2's share of the frequency's width: 2 log(w_hi / w_lo), and on a cell from
        # w = 0 (where |L| -> 0 and only the upper end counts) what halving it gains,
        # 2 log 2; none on a cell no factor decides (a divisor's range reaches 0 there, which
        # only splitting its own variables can mend)
        s2 = np.where(w_lo > 0, 2 * np.log(w_hi / np.maximum(w_lo, 1e-300)), 2 * math.log(2.0))
        score[:, d] += np.where(invalid, 0.0, s2.clip(max=10.0))
        # the gain k_s (log|k_s| is the coordinate itself for a log-uniform k_s) and s^2
        if ks is None:
            zc[:, 0] += lk[0]
        else:
            half = (lk[1] - lk[0]) / 2
            zc[:, 0] += (lk[0] + lk[1]) / 2
            zr[:, 0] += 1e-12 * np.abs(zc[:, 0])
            zg[:, ks, 0] += half * (1 + 1e-12)
        w_c, w_h = (w_lo + w_hi) / 2, (w_hi - w_lo) / 2
        safe = w_lo > 0
        with np.errstate(divide="ignore"):
            d_lo, d_hi = 2.0 / np.where(safe, w_hi, 1.0), 2.0 / np.where(safe, w_lo, 1.0)
            zc[:, 0] += 2 * np.log(np.where(safe, w_c, 1.0))
        zc[:, 1] += math.pi
        zg[:, d, 0] += w_h * (d_lo + d_hi) / 2
        zr[:, 0] += w_h * (d_hi - d_lo) / 2 + 1e-12 * np.abs(zc[:, 0])
        z_ok &= safe & ~invalid
        zr[:, 1] += 1e-12 * np.abs(zc[:, 1])
        self.zonotope = (zc, zg, zr, z_ok)
        score = np.where(z_ok[:, None], np.abs(zg).sum(axis=2) + zs, score)
        # a cell where a divisor's range reaches 0 proves nothing: a full turn of argument
        mag_lo = np.where(invalid, -np.inf, mag_lo)
        mag_hi = np.where(invalid, np.inf, mag_hi)
        arg_lo = np.where(invalid, -math.pi, arg_lo)
        arg_hi = np.where(invalid, math.pi, arg_hi)
        return mag_lo, mag_hi, arg_lo, arg_hi, score

    def _with_fixed(self, lo_t, hi_t, names, cols):
        """Boxes of ``names`` (fixed parameters as points), in value-or-log coordinates."""
        n = lo_t.shape[0]
        lo, hi, logs = np.zeros((n, len(names))), np.zeros((n, len(names))), []
        for j, (name, c) in enumerate(zip(names, cols)):
            if c is None:
                lo[:, j] = hi[:, j] = self.fixed[name]
                logs.append(False)
            else:
                lo[:, j], hi[:, j] = lo_t[:, c], hi_t[:, c]
                logs.append(bool(self.logs[c]))
        return lo, hi, logs


def _min_modulus(re_lo, re_hi, im_lo, im_hi):
    dx = np.maximum(0.0, np.maximum(re_lo, -re_hi))
    dy = np.maximum(0.0, np.maximum(im_lo, -im_hi))
    return np.hypot(dx, dy)


def _log_polar(re_lo, re_hi, im_lo, im_hi):
    """Ranges of ``log|z|`` and ``arg z`` over rectangles (``-inf``/full turn if 0 inside)."""
    rmin = _min_modulus(re_lo, re_hi, im_lo, im_hi)
    rmax = np.hypot(
        np.maximum(np.abs(re_lo), np.abs(re_hi)), np.maximum(np.abs(im_lo), np.abs(im_hi))
    )
    with np.errstate(divide="ignore"):
        m_lo = np.log(rmin) - 1e-12
    m_hi = np.log(rmax) + 1e-12
    centre = np.arctan2((im_lo + im_hi) / 2, (re_lo + re_hi) / 2)
    rel = []
    for x in (re_lo, re_hi):
        for y in (im_lo, im_hi):
            rel.append(np.angle(np.exp(1j * (np.arctan2(y, x) - centre))))
    rel = np.array(rel)
    a_lo = centre + rel.min(axis=0) - 1e-12
    a_hi = centre + rel.max(axis=0) + 1e-12
    inside = rmin <= 0
    a_lo = np.where(inside, -math.pi, a_lo)
    a_hi = np.where(inside, math.pi, a_hi)
    return m_lo, m_hi, a_lo, a_hi


def _log_zonotope(rect, centre, d_re: Interval, d_im: Interval, h: np.ndarray):
    """A factor's ``(log|f|, arg f)`` over the cells as centre + generators + remainder.

    Mean-value form about the cell's centre: ``d log f / dq = f' / f``, whose real and
    imaginary parts (the derivatives of ``log|f|`` and ``arg f``) are enclosed over the cell
    from the value's rectangle and the derivatives' enclosures; the midpoints times the
    half-widths ``h`` are the generators, the rest the remainder.

    Returns
    -------
    (centre (n, 2), generators (d, n, 2), remainder (n, 2), remainder per variable (d, n),
    valid (n,))
    """
    re_lo, re_hi, im_lo, im_hi = rect
    valid = _min_modulus(*rect) > 0
    safe = lambda a, b: (np.where(valid, a, 1.0), np.where(valid, b, 1.0))  # noqa: E731
    fr = Interval.hull(*safe(re_lo, re_hi))
    fi = Interval.hull(*safe(im_lo, im_hi))
    inv = (fr.square() + fi.square()).reciprocal()
    du = (fr * d_re + fi * d_im) * inv
    dp = (fr * d_im - fi * d_re) * inv
    gen = np.stack([h * du.mid, h * dp.mid], axis=-1)
    rem_var = h * (du.rad + dp.rad)
    rem = np.stack([np.sum(h * du.rad, axis=0), np.sum(h * dp.rad, axis=0)], axis=-1)
    c_ulo, c_uhi, c_alo, c_ahi = _log_polar(*centre)
    ok = valid & (_min_modulus(*centre) > 0)
    cen = np.stack([(c_ulo + c_uhi) / 2, (c_alo + c_ahi) / 2], axis=-1)
    cen = np.where(ok[:, None], cen, 0.0)
    rem = rem + np.stack([(c_uhi - c_ulo) / 2, (c_ahi - c_alo) / 2], axis=-1)
    rem = np.where(ok[:, None], rem, np.inf)
    gen = np.where(ok[None, :, None], gen, 0.0)
    return cen, gen, rem, rem_var, ok


def _zonotope_excludes(zc, zg, zr, ok) -> np.ndarray:
    """Per cell: the zonotope ``zc + sum_i [-1, 1] zg_i + [-zr, zr]`` misses every point
    ``(0, pi + 2 pi k)``, by a separating direction among the generators' normals and the
    axes (exact for a zonotope in the plane)."""
    n, m, _ = zg.shape
    normals = np.concatenate(
        [np.stack([-zg[..., 1], zg[..., 0]], axis=-1), np.broadcast_to(np.eye(2), (n, 2, 2))],
        axis=1,
    )
    support = np.abs(np.einsum("nkd,nid->nki", normals, zg)).sum(axis=2)
    finite = np.all(np.isfinite(zr), axis=1)
    support = support + np.einsum("nkd,nd->nk", np.abs(normals), np.where(finite[:, None], zr, 0.0))
    # the argument's extent stays below a full turn, so only the odd multiples of pi next
    # to the centre's can be inside
    out = ok & finite & (support[:, -1] < math.pi)
    k0 = np.round((zc[:, 1] - math.pi) / (2 * math.pi))
    for dk in (-1.0, 0.0, 1.0):
        p = np.stack([np.zeros(n), math.pi + 2 * math.pi * (k0 + dk)], axis=-1)
        gap = np.abs(np.einsum("nkd,nd->nk", normals, p - zc))
        out &= np.any(gap > support * (1 + 1e-9), axis=1)
    return out


def _excluded(mag_lo, mag_hi, arg_lo, arg_hi) -> np.ndarray:
    """Per cell: the log-polar rectangle misses ``-1`` (log-magnitude 0, argument pi mod 2 pi)."""
    by_mag = (mag_hi < 0) | (mag_lo > 0)
    k = np.ceil((arg_lo - math.pi) / (2 * math.pi))
    by_arg = math.pi + 2 * math.pi * k > arg_hi
    return by_mag | by_arg


#: Surviving cells whose parameter centres a probe tries per round (the nearest ``L = -1``).
PROBE_CELLS = 32


def _probe_cells(probe, lo, hi, centre):
    """``probe`` of the parameter centres of the cells whose ``L`` at the centre is nearest
    ``-1`` (``centre``: log-magnitude and argument there), nearest first."""
    wrapped = np.abs(np.remainder(centre[:, 1], 2 * math.pi) - math.pi)
    near = np.argsort(np.abs(centre[:, 0]) + wrapped, kind="stable")
    first = np.unique(((lo + hi) / 2)[near], axis=0, return_index=True)[1]
    order = near[np.sort(first)][:PROBE_CELLS]
    return probe((lo[order] + hi[order]) / 2)


def certify_scale_valueset(
    loop: ValueSetLoop,
    lo_t,
    hi_t,
    w_max: float,
    max_cells: int,
    probe: Callable[[np.ndarray], np.ndarray] | None = None,
):
    """Zero exclusion over the box ``lo_t .. hi_t`` (family coordinates) and ``[0, w_max]``.

    A cell that survives several rounds of splitting is where ``1 + L`` comes closest to
    zero. With ``probe``, every other round from the fourth the parameter centres of the
    surviving cells nearest ``L = -1`` (at most :data:`PROBE_CELLS` distinct ones) are
    handed to it as candidates: an unstable member it finds from them ends the attempt at
    once (the box is not stable, so no budget of cells could certify it) and is returned,
    a witness for an upper bound.

    Parameters
    ----------
    loop : ValueSetLoop
    lo_t, hi_t : numpy.ndarray, shape (d,)
    w_max : float
        Bound of every member's eigenvalue moduli, rad/s.
    max_cells : int
        Budget of cells.
    probe : callable, optional
        Candidate members (rows of parameter values in the family's coordinates, shape
        ``(m, d)``, the most promising first) -> ``(row, largest real part)`` of an
        unstable member of the box found from them, or None.

    Returns
    -------
    (bool, dict)
        Certified, and statistics (``cells``, ``rounds``; ``left`` when not certified;
        ``unstable``, the coordinates of an unstable member, and ``max_real``, its
        largest real part, when a probe found one).
    """
    edges = np.concatenate([[0.0], np.geomspace(_W_LOW, max(w_max, 2 * _W_LOW), _W_CELLS)])
    w_lo, w_hi = edges[:-1], edges[1:]
    n = len(w_lo)
    lo = np.repeat(np.asarray(lo_t, float)[None], n, 0)
    hi = np.repeat(np.asarray(hi_t, float)[None], n, 0)
    used = 0
    rounds = 0
    while len(w_lo):
        used += len(w_lo)
        rounds += 1
        if used > max_cells:
            return False, {"cells": used, "rounds": rounds, "left": len(w_lo)}
        try:
            mag_lo, mag_hi, arg_lo, arg_hi, score = loop.factors(lo, hi, w_lo, w_hi)
        except ParameterError:
            return False, {"cells": used, "rounds": rounds, "left": len(w_lo), "reason": "zero"}
        ok = _excluded(mag_lo, mag_hi, arg_lo, arg_hi) | _zonotope_excludes(*loop.zonotope)
        keep = ~ok
        lo, hi, w_lo, w_hi, score = lo[keep], hi[keep], w_lo[keep], w_hi[keep], score[keep]
        if not len(w_lo):
            break
        if probe is not None and rounds >= 4 and rounds % 2 == 0:
            found = _probe_cells(probe, lo, hi, loop.zonotope[0][keep])
            if found is not None:
                row, max_real = found
                return False, {
                    "cells": used,
                    "rounds": rounds,
                    "left": len(w_lo),
                    "unstable": row,
                    "max_real": max_real,
                }
        j = np.argmax(score, axis=1)
        d = lo.shape[1]
        on_w = j == d
        # split: the frequency or the parameter
        wm = np.where(on_w, (w_lo + w_hi) / 2, 0.0)
        rows = np.arange(len(j))
        mid = np.where(
            on_w, 0.0, (lo[rows, np.minimum(j, d - 1)] + hi[rows, np.minimum(j, d - 1)]) / 2
        )
        lo2, hi2 = lo.copy(), hi.copy()
        pr = rows[~on_w]
        hi[pr, j[~on_w]] = mid[~on_w]
        lo2[pr, j[~on_w]] = mid[~on_w]
        w_hi_a = np.where(on_w, wm, w_hi)
        w_lo_b = np.where(on_w, wm, w_lo)
        lo, hi = np.concatenate([lo, lo2]), np.concatenate([hi, hi2])
        w_lo, w_hi = np.concatenate([w_lo, w_lo_b]), np.concatenate([w_hi_a, w_hi])
    return True, {"cells": used, "rounds": rounds}
