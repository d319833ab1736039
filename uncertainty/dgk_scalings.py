"""The D and G scalings of the D-G-K iteration: their rational fits to the grid's scalings
and the choice of the fits that the next K-step uses.

The mu-step (:mod:`uncertainty.dgk`) gives, at each grid frequency, the D and G scalings of
the current closed loop; here each channel's values are fitted by a stable, minimum-phase
``d(s)`` (``_DFit``) and a stable ``g(s)`` (``_GFit``) of a chosen order, the fitted
scalings' bound on the grid is computed (``_Scalings``), the best pairs of orders are
refined, and ``_fit_all`` keeps the lowest total order within the tolerance. The fits are
apart from the iteration that calls them (the mu-step, the K-step, the certificate), which
stays in :mod:`uncertainty.dgk`.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np
from scipy.optimize import least_squares, minimize

from robust.errors import VerificationError
from robust.synthesis.genplant import GeneralizedPlant
from uncertainty.mucover import G_MAX, _response

#: Nothing public: the fits are :func:`uncertainty.dgk.musyn`'s own.
__all__: list[str] = []


@dataclasses.dataclass(frozen=True)
class _Plant:
    """The LFT of ``P`` as a generalized plant, the performance block padded square."""

    gp: GeneralizedPlant
    R: int  # uncertainty channels
    s: int  # size of the (square) performance block
    true_blocks: tuple
    form: object
    #: ``gp`` measures ``y_scale * y`` and its controls are ``u = u_scale * u'``: the
    #: controller of the plant as given is ``diag(u_scale) K diag(y_scale)`` for ``K`` of ``gp``
    y_scale: np.ndarray | None = None
    u_scale: np.ndarray | None = None


#: Scaled-G bound of the design scalings (``|G_i| <= G_MAX D_i``), that of the mu cover.
G_DESIGN_MAX = G_MAX
#: A fit whose bound exceeds the grid's mu by at most this (relative to mu's peak) is
#: good enough: the lowest total order among such fits wins.
FIT_TOL = 1e-2
#: Fits within this of the least excess count as equally good (the lowest total order wins).
ORDER_SLACK = 2e-3
#: Damping ratios a D fit's second-order sections may take.
ZETA_MIN, ZETA_MAX = 0.02, 5.0
#: Smallest ratio between successive poles of a G fit (keeps its realisation conditioned).
POLE_RATIO = 1.3


# -- the closed loop's matrices --------------------------------------------------------------
def _abcd(sys):
    return tuple(np.asarray(x, float) for x in (sys.A, sys.B, sys.C, sys.D))


# -- the D-step: fits ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class _DFit:
    """``d(s) = gain * prod (s^2 + 2 z_z w_z s + w_z^2) / (s^2 + 2 z_p w_p s + w_p^2)
    * prod (s + z) / (s + p)``, every ``w, z > 0``: stable and minimum phase.

    ``quads`` holds ``(w_z, zeta_z, w_p, zeta_p)`` per second-order section (lightly damped
    ones follow a resonance), ``firsts`` ``(z, p)`` per first-order one; an order ``k`` fit
    has ``k // 2`` of the first and ``k % 2`` of the second."""

    gain: float
    quads: np.ndarray
    firsts: np.ndarray

    @property
    def order(self) -> int:
        """The number of poles."""
        return 2 * self.quads.shape[0] + self.firsts.shape[0]

    @staticmethod
    def constant(gain: float) -> _DFit:
        """The order-0 fit."""
        return _DFit(float(gain), np.zeros((0, 4)), np.zeros((0, 2)))

    @staticmethod
    def from_x(x: np.ndarray, k: int) -> _DFit:
        """From ``[log gain, log quads, log firsts]``."""
        n2, n1 = divmod(k, 2)
        return _DFit(
            float(np.exp(x[0])),
            np.exp(x[1 : 1 + 4 * n2]).reshape(n2, 4),
            np.exp(x[1 + 4 * n2 : 1 + 4 * n2 + 2 * n1]).reshape(n1, 2),
        )

    def x(self) -> np.ndarray:
        """``[log gain, log quads, log firsts]``."""
        return np.log(np.concatenate([[self.gain], self.quads.ravel(), self.firsts.ravel()]))

    def magnitude2(self, w) -> np.ndarray:
        """``|d(jw)|^2``."""
        w2 = np.asarray(w, float)[:, None] ** 2
        out = np.full(w2.shape[0], self.gain**2)
        for wz, zz, wp, zp in self.quads:
            out *= ((wz**2 - w2[:, 0]) ** 2 + 4 * zz**2 * wz**2 * w2[:, 0]) / (
                (wp**2 - w2[:, 0]) ** 2 + 4 * zp**2 * wp**2 * w2[:, 0]
            )
        for z, p in self.firsts:
            out *= (w2[:, 0] + z**2) / (w2[:, 0] + p**2)
        return out

    def log_magnitude2_gradient(self, w) -> np.ndarray:
        """``d log |d(jw)|^2 / d x`` at each ``w`` (rows) for each entry of :meth:`x`
        (columns): every factor's derivative with respect to the log of its parameter."""
        w2 = np.asarray(w, float) ** 2
        cols = [np.full(w2.shape, 2.0)]
        for wz, zz, wp, zp in self.quads:
            for wn, z, sign in ((wz, zz, 1.0), (wp, zp, -1.0)):
                q = (wn**2 - w2) ** 2 + 4 * z**2 * wn**2 * w2
                damp = 8 * z**2 * wn**2 * w2 / q
                cols.append(sign * (4 * wn**2 * (wn**2 - w2) / q + damp))
                cols.append(sign * damp)
        for z, p in self.firsts:
            cols.append(2 * z**2 / (w2 + z**2))
            cols.append(-2 * p**2 / (w2 + p**2))
        return np.stack(cols, axis=1)

    def system(self, inverse: bool = False) -> ct.StateSpace:
        """``d`` (or ``1 / d``): its sections in cascade, each ``1 + (b1 s + b0) / den`` with
        the state ``[w_p q, s q]`` of ``den q = input`` (frequency-scaled companion form)."""
        out = ct.ss([], [], [], [[1.0 / self.gain if inverse else self.gain]])
        for wz, zz, wp, zp in self.quads:
            if inverse:
                wz, zz, wp, zp = wp, zp, wz, zz
            b1, b0 = 2 * zz * wz - 2 * zp * wp, wz**2 - wp**2
            sec = ct.ss([[0, wp], [-wp, -2 * zp * wp]], [[0], [1]], [[b0 / wp, b1]], [[1]])
            out = sec * out
        for z, p in self.firsts:
            if inverse:
                z, p = p, z
            out = ct.ss([[-p]], [[1]], [[z - p]], [[1]]) * out
        return out


@dataclasses.dataclass(frozen=True)
class _GFit:
    """``G_1(w) = sum_j h_j 2 a_j w / (a_j^2 + w^2)``, the value on the imaginary axis of
    ``j Y(jw)`` with ``Y(s) = -sum_j h_j 2 a_j s / (a_j^2 - s^2)`` (para-skew)."""

    a: np.ndarray
    h: np.ndarray

    @staticmethod
    def from_x(x: np.ndarray, k: int) -> _GFit:
        """From ``[log a_1, ..., log a_k, h_1, ..., h_k]``; the poles sorted, each at least
        :data:`POLE_RATIO` above the one before (keeps the realisation conditioned)."""
        return _GFit(_separated(np.exp(x[:k])), np.asarray(x[k : 2 * k], float))

    def x(self) -> np.ndarray:
        """``[log a_1, ..., log a_k, h_1, ..., h_k]``."""
        return np.concatenate([np.log(self.a), self.h])

    def value(self, w) -> np.ndarray:
        """``G_1(w)``."""
        w = np.asarray(w, float)[:, None]
        return np.sum(self.h * 2 * self.a * w / (self.a**2 + w**2), axis=1)

    def value_gradient(self, w, x: np.ndarray) -> np.ndarray:
        """``d G_1(w) / d x`` at each ``w`` (rows) for each entry of ``x`` (columns), the
        vector this fit was made from (:meth:`from_x`): through the sorting and the pole
        separation of :func:`_separated`, piecewise as they are."""
        k = self.a.size
        w = np.asarray(w, float)[:, None]
        den = self.a**2 + w**2
        out = np.zeros((w.shape[0], 2 * k))
        out[:, k:] = 2 * self.a * w / den
        dval_da = 2 * self.h * w * (w**2 - self.a**2) / den**2
        for j, src in enumerate(_separated_sources(np.asarray(x[:k], float))):
            # a_j = exp(x_src) times the separation ratios: d a_j / d x_src = a_j
            out[:, src] += dval_da[:, j] * self.a[j]
        return out

    def stable_part(self):
        """``(A_b, B_b, C_b)`` of ``A(s) Y(s)``, ``A`` the all-pass of :func:`_allpass`:
        strictly proper, a double pole at each ``-a_j``, in Jordan form; the residues by
        least squares on exact evaluations, checked."""
        k = self.a.size
        Ab = np.zeros((2 * k, 2 * k))
        Bb = np.zeros((2 * k, 1))
        for j, a in enumerate(self.a):
            Ab[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] = [[-a, 1.0], [0.0, -a]]
            Bb[2 * j + 1, 0] = 1.0
        s = 1j * np.geomspace(self.a.min() / 30, self.a.max() * 30, 8 * k + 8)
        target = self._ay(s)
        basis = np.empty((s.size, 2 * k), complex)
        for j, a in enumerate(self.a):
            basis[:, 2 * j] = 1 / (s + a) ** 2
            basis[:, 2 * j + 1] = 1 / (s + a)
        lhs = np.vstack([basis.real, basis.imag])
        Cb, *_ = np.linalg.lstsq(lhs, np.concatenate([target.real, target.imag]), rcond=None)
        err = np.max(np.abs(basis @ Cb - target)) / max(np.max(np.abs(target)), 1e-300)
        if err > 1e-8:
            raise VerificationError(
                f"musyn D-step: the realisation of a fitted G scaling misses its transfer "
                f"function by {err:.3g} (relative); poles {self.a}"
            )
        return Ab, Bb, Cb[None, :]

    def _ay(self, s):
        """``A(s) Y(s)`` evaluated term by term in its stable form."""
        s = np.asarray(s)[:, None]
        ap = (self.a - s) / (self.a + s)
        total = np.zeros(s.shape[0], complex)
        for j, a in enumerate(self.a):
            others = np.prod(np.delete(ap, j, axis=1), axis=1)
            total += -self.h[j] * 2 * a * s[:, 0] / (a + s[:, 0]) ** 2 * others
        return total


def _separated(a: np.ndarray) -> np.ndarray:
    """``a`` sorted, each entry raised to at least :data:`POLE_RATIO` times the one before."""
    a = np.sort(np.asarray(a, float))
    for j in range(1, a.size):
        a[j] = max(a[j], a[j - 1] * POLE_RATIO)
    return a


def _separated_sources(xa: np.ndarray) -> list:
    """For each pole of ``_separated(exp(xa))``, the entry of ``xa`` it is a multiple of
    (itself, or the pole below it raised by :data:`POLE_RATIO`), as :func:`_separated`
    decides."""
    order = np.argsort(xa, kind="stable")
    a = np.exp(xa[order])
    src = [int(order[0])] if a.size else []
    for j in range(1, a.size):
        raised = a[j - 1] * POLE_RATIO
        if raised > a[j]:
            a[j] = raised
            src.append(src[-1])
        else:
            src.append(int(order[j]))
    return src


def _d_bounds(w, order: int):
    lw = np.log(w)
    lo, hi = lw.min() - math.log(10), lw.max() + math.log(10)
    zlo, zhi = math.log(ZETA_MIN), math.log(ZETA_MAX)
    n2, n1 = divmod(order, 2)
    return (
        np.concatenate([[-np.inf], np.tile([lo, zlo, lo, zlo], n2), np.full(2 * n1, lo)]),
        np.concatenate([[np.inf], np.tile([hi, zhi, hi, zhi], n2), np.full(2 * n1, hi)]),
    )


def _g_bounds(w, order: int):
    lw = np.log(w)
    lo, hi = lw.min() - math.log(10), lw.max() + math.log(10)
    hmax = 10 * G_DESIGN_MAX
    return (
        np.concatenate([np.full(order, lo), np.full(order, -hmax)]),
        np.concatenate([np.full(order, hi), np.full(order, hmax)]),
    )


def _fit_d(w, mag2, weight, order: int) -> _DFit:
    """Weighted least squares of ``log |d(jw)|^2`` against ``log mag2`` (a few starts: the
    sections spread over the grid, or one at the data's steepest change)."""
    y = np.log(mag2)
    sw = np.sqrt(weight)
    centre = float(np.exp(np.sum(weight * y) / np.sum(weight) / 2))
    if order == 0:
        return _DFit.constant(centre)

    def resid(x):
        return sw * (np.log(_DFit.from_x(x, order).magnitude2(w)) - y)

    def jac(x):
        return sw[:, None] * _DFit.from_x(x, order).log_magnitude2_gradient(w)

    n2, n1 = divmod(order, 2)
    lw = np.log(w)
    slope = np.abs(np.gradient(y, lw))
    steep = lw[np.argmax(slope * sw)]
    starts = []
    for shift in (0.5, -0.5):
        for spread in (True, False):
            c = (
                np.linspace(lw.min(), lw.max(), n2 + n1 + 2)[1:-1]
                if spread
                else np.full(n2 + n1, steep)
            )
            q = [
                [ci + shift, math.log(0.7), ci, math.log(0.3 if not spread else 0.7)]
                for ci in c[:n2]
            ]
            f = [[ci + shift, ci] for ci in c[n2:]]
            starts.append(np.concatenate([[math.log(centre)], np.ravel(q), np.ravel(f)]))
    lo, hi = _d_bounds(w, order)
    best = None
    for x0 in starts:
        x0 = np.clip(x0, lo, hi)
        x0[0] -= np.sum(weight * resid(x0) / sw) / np.sum(weight) / 2
        res = least_squares(resid, x0, jac=jac, bounds=(lo, hi), method="trf", max_nfev=100)
        if best is None or res.cost < best.cost:
            best = res
    return _DFit.from_x(best.x, order)


def _fit_g(w, g1, weight, order: int) -> _GFit:
    """Weighted least squares of ``G_1`` by :class:`_GFit` (the poles by variable projection)."""
    if order == 0 or not np.any(g1 != 0):
        return _GFit(np.zeros(0), np.zeros(0))
    sw = np.sqrt(weight)
    lo, hi = _g_bounds(w, order)

    def solve(xa):
        a = _separated(np.exp(xa))
        Phi = 2 * a * w[:, None] / (a**2 + w[:, None] ** 2)
        h, *_ = np.linalg.lstsq(Phi * sw[:, None], g1 * sw, rcond=None)
        return np.clip(h, lo[order:], hi[order:]), Phi

    big = w[np.abs(g1) * sw >= 0.1 * np.max(np.abs(g1) * sw)]
    start = np.linspace(np.log(big.min()), np.log(big.max()), order)
    xa0 = np.clip(start, lo[:order], hi[:order])
    res = least_squares(
        lambda xa: sw * (solve(xa)[1] @ solve(xa)[0] - g1),
        xa0,
        bounds=(lo[:order], hi[:order]),
        method="trf",
        max_nfev=100,
    )
    return _GFit.from_x(np.concatenate([res.x, solve(res.x)[0]]), order)


@dataclasses.dataclass(frozen=True)
class _Scalings:
    """Per uncertainty channel, ``d_i`` and (empty ``a``: none) ``G_1,i``."""

    d: tuple
    g: tuple

    def orders(self) -> dict:
        """The fits' orders."""
        return {
            "D": max((f.order for f in self.d), default=0),
            "G": max((f.a.size for f in self.g), default=0),
        }

    def diagonals(self, w: np.ndarray, n: int):
        """``(dd, gg)``, shape ``(len(w), n)``: each channel's ``|d(jw)|^2`` and ``G_1(w)``
        (1 and 0 on the channels beyond the scalings', the performance block's)."""
        dd, gg = np.ones((len(w), n)), np.zeros((len(w), n))
        for i, (d, g) in enumerate(zip(self.d, self.g)):
            dd[:, i] = d.magnitude2(w)
            if g.a.size:
                gg[:, i] = g.value(w)
        return dd, gg

    def bounds(self, Mws: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The D-G bound these scalings give ``M(jw)`` at each ``w`` (module notes)."""
        return _scaled_bounds(Mws, *self.diagonals(w, Mws.shape[1]))


def _scaled_matrices(Mws, dd, gg):
    """``(N, N^H, H)`` at each frequency: ``N = D^(1/2) M D^(-1/2)`` and the Hermitian
    ``H = N^H N + j (G_1 N - N^H G_1)`` with ``D = diag(dd)``, ``G = diag(gg dd)``."""
    dh = np.sqrt(dd)
    N = dh[:, :, None] * Mws / dh[:, None, :]
    NH = np.conj(np.swapaxes(N, 1, 2))
    H = NH @ N + 1j * (gg[:, :, None] * N - NH * gg[:, None, :])
    return N, NH, 0.5 * (H + np.conj(np.swapaxes(H, 1, 2)))


def _scaled_bounds(Mws, dd, gg) -> np.ndarray:
    """``sqrt(lambda_max(H))`` (:func:`_scaled_matrices`) at each frequency: the least
    ``beta`` of the D-G condition."""
    H = _scaled_matrices(Mws, dd, gg)[2]
    return np.sqrt(np.maximum(np.linalg.eigvalsh(H)[:, -1], 0.0))


def _scaled_bounds_gradient(Mws, dd, gg):
    """:func:`_scaled_bounds` and, at each frequency, the bound's derivatives with respect
    to ``log dd[:, i]`` and to ``gg[:, i]`` (zero where the bound is zero).

    With ``v`` the unit eigenvector of the largest eigenvalue ``lambda`` of ``H``,
    ``d lambda = v^H dH v`` (a simple eigenvalue; at a repeated one, a subgradient). With
    ``u = N v``, ``q = N^H u``, ``p = G_1 v`` and ``r = N^H p``, and
    ``dN = (E_i N - N E_i) / 2`` for ``d log dd_i = 1`` (``E_i = e_i e_i^T``)::

        d lambda / d log dd_i = |u_i|^2 - Re(conj(q_i) v_i) - Im(conj(p_i) u_i)
                                + Im(conj(r_i) v_i)
        d lambda / d gg_i     = -2 Im(conj(v_i) u_i)

    and ``d beta = d lambda / (2 beta)`` (Magnus, "On differentiating eigenvalues and
    eigenvectors", Econometric Theory 1, 1985)."""
    N, NH, H = _scaled_matrices(Mws, dd, gg)
    lam, V = np.linalg.eigh(H)
    v = V[:, :, -1]
    beta = np.sqrt(np.maximum(lam[:, -1], 0.0))
    u = np.einsum("fab,fb->fa", N, v)
    q = np.einsum("fab,fb->fa", NH, u)
    pv = gg * v
    r = np.einsum("fab,fb->fa", NH, pv)
    d_log_dd = (
        np.abs(u) ** 2 - (np.conj(q) * v).real - (np.conj(pv) * u).imag + (np.conj(r) * v).imag
    )
    d_gg = -2 * (np.conj(v) * u).imag
    half = np.divide(0.5, beta, out=np.zeros_like(beta), where=beta > 0)[:, None]
    return beta, d_log_dd * half, d_gg * half


def _excess(sc: _Scalings, Mws, w, mu) -> np.ndarray:
    """How far the fitted scalings' bound lies above the grid's mu, relative to its peak."""
    return (sc.bounds(Mws, w) - mu) / mu.max()


def _refine(sc: _Scalings, Mws, w, mu) -> _Scalings:
    """The fits' parameters moved to lower their largest excess over the grid's mu (a smooth
    maximum, L-BFGS-B); kept if it drops."""
    kd = [f.order for f in sc.d]
    kg = [g.a.size for g in sc.g]
    parts = [f.x() for f in sc.d] + [g.x() for g in sc.g if g.a.size]
    lo = np.concatenate([_d_bounds(w, k)[0] for k in kd] + [_g_bounds(w, k)[0] for k in kg if k])
    hi = np.concatenate([_d_bounds(w, k)[1] for k in kd] + [_g_bounds(w, k)[1] for k in kg if k])
    x0 = np.clip(np.concatenate(parts), lo, hi)
    lo, hi = np.where(np.isinf(lo), x0 - 20, lo), np.where(np.isinf(hi), x0 + 20, hi)
    cuts = np.cumsum([p.size for p in parts])[:-1]

    def unpack(x):
        xs = np.split(x, cuts)
        R = len(kd)
        rest = iter(xs[R:])
        return _Scalings(
            tuple(_DFit.from_x(xs[i], kd[i]) for i in range(R)),
            tuple(
                _GFit.from_x(next(rest), k) if k else _GFit(np.zeros(0), np.zeros(0)) for k in kg
            ),
        )

    tau = 1e-3
    g_channels = [i for i, k in enumerate(kg) if k]

    def f(x):
        """The smooth maximum of the excess and its gradient (the chain rule through
        :func:`_scaled_bounds_gradient` and the fits' own derivatives)."""
        xs = np.split(x, cuts)
        sc = unpack(x)
        beta, db_dlog_dd, db_dgg = _scaled_bounds_gradient(Mws, *sc.diagonals(w, Mws.shape[1]))
        e = (beta - mu) / mu.max()
        m = e.max()
        soft = np.exp((e - m) / tau)
        total = np.sum(soft)
        weight = soft / total / mu.max()  # d f / d beta at each frequency
        grads = [
            (weight * db_dlog_dd[:, i]) @ d.log_magnitude2_gradient(w) for i, d in enumerate(sc.d)
        ]
        grads += [
            (weight * db_dgg[:, i]) @ sc.g[i].value_gradient(w, xs[len(kd) + j])
            for j, i in enumerate(g_channels)
        ]
        return m + tau * math.log(total), np.concatenate(grads)

    res = minimize(
        f, x0, jac=True, method="L-BFGS-B", bounds=list(zip(lo, hi)), options={"maxiter": 60}
    )
    new = unpack(res.x)
    return new if _excess(new, Mws, w, mu).max() < _excess(sc, Mws, w, mu).max() else sc


# -- the fits for the next K-step ------------------------------------------------------------
def _fit_all(freqs, Ds, Gs, mu, plant: _Plant, cl, orders, with_g: bool):
    """The scalings' fits for the next K-step, and their peak bound on the grid.

    Every channel is fitted at every order (weighted least squares, the weight
    ``(mu / peak)^2``, floored at 1e-2); each pair of ``D`` and ``G`` orders is scored by its
    *excess*, the largest amount by which the bound the fitted scalings give the current
    closed loop exceeds the grid's mu, relative to mu's peak; the two best are refined
    (:func:`_refine`), and the lowest total order whose excess is within
    :data:`FIT_TOL` (or within :data:`ORDER_SLACK` of the least excess) is kept."""
    R = plant.R
    weight = np.maximum((mu / mu.max()) ** 2, 1e-2)
    dpf = np.array([D[-1, -1].real for D in Ds])
    dd = np.clip(np.array([[D[i, i].real for D in Ds] for i in range(R)]) / dpf, 1e-8, 1e8)
    g1 = np.array([[G[i, i].real for G in Gs] for i in range(R)]) / (dd * dpf)
    fd = {k: tuple(_fit_d(freqs, dd[i], weight, k) for i in range(R)) for k in orders}
    gorders = orders if with_g else (0,)
    fg = {k: tuple(_fit_g(freqs, g1[i], weight, k) for i in range(R)) for k in gorders}
    A, B, C, D = _abcd(cl)
    Mws = np.array([_response(A, B, C, D, float(w)) for w in freqs])
    scored = sorted(
        (float(_excess(sc, Mws, freqs, mu).max()), kd + kg, kd, kg, sc)
        for kd in orders
        for kg in gorders
        for sc in [_Scalings(fd[kd], fg[kg])]
    )[:2]
    refined = [(x[1], _refine(x[4], Mws, freqs, mu)) for x in scored]
    refined = [(float(_excess(s, Mws, freqs, mu).max()), k, s) for k, s in refined]
    least = min(e for e, _, _ in refined)
    _, _, sc = min(
        (x for x in refined if x[0] <= max(FIT_TOL, least + ORDER_SLACK)),
        key=lambda x: (x[1], x[0]),
    )
    return sc, float(np.max(sc.bounds(Mws, freqs)))


def _identity(R: int) -> _Scalings:
    return _Scalings(
        tuple(_DFit.constant(1.0) for _ in range(R)),
        tuple(_GFit(np.zeros(0), np.zeros(0)) for _ in range(R)),
    )
