"""The tuning's objective: region, H-infinity and H2 terms of a fixed-order controller.

``_Terms`` evaluates, for the controller entries ``Omega``, each term of the objective
that :mod:`robust.synthesis.tuning` minimises (the soft maximum of the region violations,
the barrier, the tracking, response and H2 terms, the utilisations) with its exact gradient:
eigenvalue derivatives, frequency-response derivatives and the adjoint Lyapunov equation
(the formulas are in :mod:`robust.synthesis.tuning`). The BFGS tuning and the minimax
start share it; it is apart from them as the function they search.
"""

from __future__ import annotations

import numpy as np

from robust.analysis.lyapunov import lyapunov, lyapunov_solver
from robust.synthesis.pk_members import responses
from robust.synthesis.pole_derivatives import eigen_derivatives_many

#: Nothing public: the objective is :mod:`robust.synthesis.tuning`'s own.
__all__: list[str] = []


class _Terms:
    """The objective's terms on the scaled members (time tau = w0 t, unit channels)."""

    def __init__(self, scaled, region, w_rad, margin, tau, g_t, h2_bound):
        self.reg = [m.region for m in scaled]
        self.hinf = [m.hinf for m in scaled]
        self.h2 = [m.h2 for m in scaled if m.h2 is not None]
        self.resp = [(m.hinf, m.response, m.w_resp) for m in scaled if m.response is not None]
        self.region, self.w, self.margin, self.tau = region, w_rad, margin, tau
        self.g_t, self.h2_bound = g_t, h2_bound
        self._eig_key, self._eig = None, []

    def _eigen(self, Om) -> list:
        """:func:`eigen_derivatives` of every region member at ``Om``, kept for the last
        ``Om`` (the barrier and the utilisations of one evaluation ask for the same)."""
        key = (Om.shape, Om.tobytes())
        if key != self._eig_key:
            self._eig = eigen_derivatives_many(self.reg, Om)
            self._eig_key = key
        return self._eig

    def region_term(self, Om):
        vs, gs = zip(*self._violations(Om))
        v, g = np.concatenate(vs), np.concatenate(gs)
        zz = (np.maximum(v, -self.margin) + self.margin) / self.tau
        e = np.exp(zz - zz.max())
        # log of the mean, not the sum: 0 when every pole is inside with the margin, so the
        # budget terms are not lost against a constant in the line search
        val = self.tau * (zz.max() + np.log(e.mean()))
        wts = e / e.sum() * (v > -self.margin)
        return val, np.einsum("k,kij->ij", wts, g), float(v.max())

    def barrier_term(self, Om):
        """``-sum log(-v_j)`` over the region violations (``inf`` outside the region)."""
        val, grad = 0.0, np.zeros_like(Om)
        for v, g in self._violations(Om):
            if v.max() >= 0:
                return np.inf, grad
            val -= float(np.sum(np.log(-v)))
            grad -= np.einsum("k,kij->ij", 1.0 / v, g)
        return val, grad

    def _violations(self, Om):
        z = self.region.min_damping
        for lam, dl in self._eigen(Om):
            yield lam.real + self.region.decay_rate, dl.real
            if z > 0:
                mag = np.maximum(np.abs(lam), 1e-300)
                grad = dl.real + z * (lam.conj()[:, None, None] * dl).real / mag[:, None, None]
                yield lam.real + z * mag, grad

    def utilisations(self, Om):
        """Every utilisation (1 at its limit) and its gradient in ``Om``.

        The utilisations are those of the specification: per pole of every member
        ``alpha / -Re p`` and ``zeta |p| / -Re p`` (required over achieved decay rate and
        damping ratio), ``|T(jw)| / g_t`` on the grid, ``h2 / h2_bound`` per member and the
        response bounds' ``|offset + gain T| / bound``. Minimising the soft maximum
        equalises the slack of all constraints: the design with the most room for the
        members between the design members.
        """
        us, dus = [], []
        a, z = self.region.decay_rate, self.region.min_damping
        for lam, dl in self._eigen(Om):
            neg = np.minimum(lam.real, -1e-12)
            mag = np.maximum(np.abs(lam), 1e-300)
            # decay: a / -Re p
            if a > 0:
                us.append(a / -neg)
                dus.append((a / neg**2)[:, None, None] * dl.real)
            if z > 0:
                dmag = (lam.conj()[:, None, None] * dl).real / mag[:, None, None]
                u = z * mag / -neg
                du = z * (dmag / -neg[:, None, None] + (mag / neg**2)[:, None, None] * dl.real)
                us.append(u)
                dus.append(du)
        for cl in self.hinf:
            T, dT = responses(cl, Om, self.w)
            mag = np.maximum(np.abs(T), 1e-300)
            us.append(mag / self.g_t)
            dus.append((np.conj(T)[:, None, None] * dT).real / mag[:, None, None] / self.g_t)
        for cl, rb, w in self.resp:
            T, dT = responses(cl, Om, w)
            r = rb.offset + rb.gain * T
            mag = np.maximum(np.abs(r), 1e-300)
            us.append(mag / rb.bound)
            dus.append(
                (np.conj(r)[:, None, None] * rb.gain[:, None, None] * dT).real
                / (mag * rb.bound)[:, None, None]
            )
        if np.isfinite(self.h2_bound):
            for cl in self.h2:
                A, B, C, _ = cl.matrices(Om)
                W = lyapunov(A, -B @ B.T)
                Lo = lyapunov(A.T, -C.T @ C)
                h = np.sqrt(max(float(np.trace(C @ W @ C.T)), 1e-300))
                dJ = 2 * (cl.Bb.T @ Lo @ W @ cl.Cb.T + cl.D12b.T @ C @ W @ cl.Cb.T)
                dJ += 2 * cl.Bb.T @ Lo @ B @ cl.D21b.T
                us.append(np.array([h / self.h2_bound]))
                dus.append((dJ / (2 * h * self.h2_bound))[None])
        return np.concatenate(us), np.concatenate(dus)

    def utilisation_term(self, Om, q: float = 8.0):
        """Soft maximum ``(mean u^q)^(1/q)`` of every utilisation (see :meth:`utilisations`)."""
        u, du = self.utilisations(Om)
        m = np.mean(u**q)
        val = m ** (1 / q)
        grad = m ** (1 / q - 1) * np.einsum("k,kij->ij", u ** (q - 1), du) / u.size
        return float(val), grad, float(u.max())

    def tracking_term(self, Om):
        """Soft maximum ``(mean |T / g_t|^q)^(1/q)`` over members and frequencies (q = 8).

        Minimised rather than only kept below the bound: spare force budget buys tracking
        margin, which is what lets the members between the design members meet the
        specification too.
        """
        q = 8.0
        xs, dxs = [], []
        for cl in self.hinf:
            T, dT = responses(cl, Om, self.w)
            mag = np.maximum(np.abs(T), 1e-300)
            xs.append(mag / self.g_t)
            dxs.append((np.conj(T)[:, None, None] * dT).real / mag[:, None, None] / self.g_t)
        x, dx = np.concatenate(xs), np.concatenate(dxs)
        m = np.mean(x**q)
        val = m ** (1 / q)
        grad = m ** (1 / q - 1) * np.einsum("k,kij->ij", x ** (q - 1), dx) / x.size
        return float(val), grad, float(x.max() * self.g_t)

    def response_term(self, Om):
        """Hinge penalty of the members' response bounds (e.g. the feedthrough)."""
        val, grad, worst = 0.0, np.zeros_like(Om), 0.0
        for cl, rb, w in self.resp:
            T, dT = responses(cl, Om, w)
            r = rb.offset + rb.gain * T
            rel = np.abs(r) / rb.bound
            worst = max(worst, float(rel.max()))
            ex = np.maximum(rel - 1.0, 0.0)
            drel = (np.conj(r)[:, None, None] * rb.gain[:, None, None] * dT).real / (
                np.maximum(np.abs(r), 1e-300) * rb.bound
            )[:, None, None]
            val += float(np.sum(ex**2)) / w.size
            grad += np.einsum("k,kij->ij", 2 * ex / w.size, drel)
        return val, grad, worst

    def h2_term(self, Om):
        val, grad, worst = 0.0, np.zeros_like(Om), 0.0
        for cl in self.h2:
            A, B, C, _ = cl.matrices(Om)
            # one Schur form: the eigenvalues, then the controllability Gramian
            gram = lyapunov_solver(A)
            if gram.eigenvalues.real.max() >= 0:
                return 1e6, grad, np.inf
            W = gram.solve(-B @ B.T)
            Lo = lyapunov(A.T, -C.T @ C)
            J = float(np.trace(C @ W @ C.T))
            h = np.sqrt(max(J, 0.0))
            worst = max(worst, h)
            ex = h / self.h2_bound - 1.0
            if ex <= 0:
                continue
            dJ = 2 * (cl.Bb.T @ Lo @ W @ cl.Cb.T + cl.D12b.T @ C @ W @ cl.Cb.T)
            dJ += 2 * cl.Bb.T @ Lo @ B @ cl.D21b.T
            val += ex * ex
            grad += 2 * ex * dJ / (2 * max(h, 1e-300) * self.h2_bound)
        return val, grad, worst
