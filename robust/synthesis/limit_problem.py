"""The cone programs of the achievable limit over the Youla parameter.

:class:`LimitProblem` holds two second-order cone problems of fixed sizes (the least RMS
force under the tracking, feedthrough and effort limits, and the least uniform relaxation
of those limits), written straight into Clarabel's standard form and rebuilt in cvxpy
where Clarabel does not end solved; :func:`gram_factor` gives the square roots of the Gram
matrices their norms use. The problems are the solver side of the limit map; the maps
that fill them are :mod:`robust.synthesis.youla`'s.
"""

from __future__ import annotations

import clarabel
import cvxpy as cp
import numpy as np
import scipy.sparse as sp

from robust.errors import InfeasibleError, ParameterError
from robust.synthesis.solve import solve_problem

__all__ = ["gram_factor", "LimitProblem"]


def gram_factor(W, rows: int) -> np.ndarray:
    """A ``(rows, k)`` matrix ``R`` with ``R' R ~= W`` (the ``rows`` largest eigen-directions).

    Parameters
    ----------
    W : ndarray (k, k)
        Symmetric positive semidefinite matrix.
    rows : int
        Rows of the factor.
    """
    lam, V = np.linalg.eigh(W)
    lam = np.clip(lam, 0.0, None)
    idx = np.argsort(lam)[::-1][:rows]
    R = np.zeros((rows, W.shape[0]))
    R[: idx.size] = np.sqrt(lam[idx])[:, None] * V[:, idx].T
    return R


class LimitProblem:
    """Two second-order cone problems over ``theta`` of fixed sizes, solved many times.

    ``"force"``: minimise ``|| R theta + r0 ||`` (the RMS force over its limit) subject to
    ``|t0_k + T_k theta| <= lim_t`` on the tracking grid, ``|g0_k + G_k theta| <= lim_f``
    on the feedthrough grid and ``|| E_j theta + e_j || <= lim_t`` for each effort Gram.
    ``"relax"``: minimise ``rho`` subject to the same cones with limits times ``rho`` (no
    force objective): the smallest uniform relaxation that any ``theta`` of the basis can
    meet. Both add ``eps || theta ||`` (default ``1e-6``, with ``theta`` in the caller's
    normalised coordinates): directions that barely move the maps are not driven to huge
    values whose cancellations no realisation could evaluate.

    The cones are written straight into Clarabel's standard form (``A x + s = b``, ``s`` in a
    product of second-order cones): the problem's structure never changes, and building it
    through cvxpy's parameterised compilation cost four times the solve (the dense parameter
    matrices' mapping into the problem data). Where Clarabel does not end solved, the same
    problem is built in cvxpy and solved by :func:`robust.synthesis.solve.solve_problem`
    (refined, then SCS): the reference formulation, which the tests compare with this one.

    Parameters
    ----------
    n_theta : int
        Coefficients of the parameter.
    n_track, n_feed : int
        Frequencies of the tracking and feedthrough grids.
    n_force : int
        Rows of the force's Gram factor.
    n_effort : int
        Effort Grams (each of size ``1 + n_theta``).
    """

    def __init__(self, n_theta: int, n_track: int, n_feed: int, n_force: int, n_effort: int = 0):
        self.sizes = (n_theta, n_track, n_feed, n_force, n_effort)
        self.data: dict = {}
        self.stats: dict = {"clarabel": 0, "cvxpy": 0}

    def set(
        self, *, track0, track, feed0, feed, lim_t, lim_f, R=None, r0=None, eps=1e-6, effort=()
    ):
        """Load one plant's data (complex grids; ``R``, ``r0`` the force's Gram factor;
        ``effort``: up to ``n_effort`` Gram matrices ``W`` of ``[1, theta]``, each
        constrained to ``[1, theta]' W [1, theta] <= lim_t^2`` (``(lim_t rho)^2`` in
        ``"relax"``) through its factor (:func:`gram_factor`))."""
        n_theta, n_track, n_feed, n_force, n_effort = self.sizes
        if len(effort) > n_effort:
            raise ParameterError(
                f"LimitProblem.set: effort must hold at most {n_effort} Grams; got {len(effort)}"
            )
        track, feed = np.asarray(track), np.asarray(feed)
        if track.shape != (n_track, n_theta) or feed.shape != (n_feed, n_theta):
            raise ParameterError(
                f"LimitProblem.set: track and feed must be ({n_track}, {n_theta}) and "
                f"({n_feed}, {n_theta}); got {track.shape} and {feed.shape}"
            )
        E = []
        for W in effort:
            F = gram_factor(W, 1 + n_theta)
            E.append((F[:, 1:], F[:, 0]))
        self.data = dict(
            track0=np.asarray(track0),
            track=track,
            feed0=np.asarray(feed0),
            feed=feed,
            lim_t=float(lim_t),
            lim_f=float(lim_f),
            R=None if R is None else np.asarray(R, float),
            r0=None if r0 is None else np.asarray(r0, float),
            eps=float(eps),
            effort=E,
        )

    def _standard_form(self, which: str):
        """``(q, A, b, cones)`` of Clarabel's ``min q'x, A x + s = b, s in cones``.

        Variables ``x = [theta, t, s_eps]`` (``"force"``: ``t`` bounds the force) or
        ``[theta, rho, s_eps]`` (``"relax"``).
        """
        d = self.data
        n = self.sizes[0]
        it, ie = n, n + 1
        relax = which == "relax"
        rows_A, rows_b, cones = [], [], []

        def soc(head_col, head_coef, head_b, M, m0):
            # the cone [head; M x + m0]: s = b - A x
            k = M.shape[0]
            blk = np.zeros((1 + k, n + 2))
            blk[0, head_col] = -head_coef if head_col is not None else 0.0
            blk[1:, :n] = -M
            rows_A.append(blk)
            rows_b.append(np.concatenate([[head_b], m0]))
            cones.append(1 + k)

        for key, lim in (("track", d["lim_t"]), ("feed", d["lim_f"])):
            M, m0 = d[key], d[key + "0"]
            for k in range(M.shape[0]):
                MM = np.vstack([M[k].real, M[k].imag])
                mm = np.array([m0[k].real, m0[k].imag])
                if relax:
                    soc(it, lim, 0.0, MM, mm)
                else:
                    soc(None, 0.0, lim, MM, mm)
        for Ek, ek in d["effort"]:
            if relax:
                soc(it, d["lim_t"], 0.0, Ek, ek)
            else:
                soc(None, 0.0, d["lim_t"], Ek, ek)
        if not relax:
            R = d["R"] if d["R"] is not None else np.zeros((1, n))
            r0 = d["r0"] if d["r0"] is not None else np.zeros(R.shape[0])
            soc(it, 1.0, 0.0, R, r0)
        soc(ie, 1.0, 0.0, np.eye(n), np.zeros(n))
        A = sp.csc_matrix(np.vstack(rows_A))
        b = np.concatenate(rows_b)
        q = np.zeros(n + 2)
        q[it], q[ie] = 1.0, d["eps"]
        if relax:
            # rho >= 0
            A = sp.vstack([sp.csc_matrix(([-1.0], ([0], [it])), shape=(1, n + 2)), A]).tocsc()
            b = np.concatenate([[0.0], b])
            cones = ["nn"] + cones
        return q, A, b, cones

    def _clarabel(self, which: str, refine: bool):
        q, A, b, cones = self._standard_form(which)
        kinds = [
            clarabel.NonnegativeConeT(1) if c == "nn" else clarabel.SecondOrderConeT(c)
            for c in cones
        ]
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.max_threads = 1
        settings.iterative_refinement_enable = refine
        P = sp.csc_matrix((q.size, q.size))
        sol = clarabel.DefaultSolver(P, q, A, b, kinds, settings).solve()
        return sol

    def _cvxpy(self, which: str, step: str):
        """The same problem in cvxpy (constants, no parameters), solved with the fallbacks."""
        d = self.data
        n = self.sizes[0]
        th = cp.Variable(n, name="theta")
        rho = cp.Variable(name="rho")

        def mags(key):
            M, m0 = d[key], d[key + "0"]
            return cp.norm(cp.vstack([M.real @ th + m0.real, M.imag @ th + m0.imag]), 2, axis=0)

        lim = (d["lim_t"], d["lim_f"])
        eff = [cp.norm(Ek @ th + ek, 2) for Ek, ek in d["effort"]]
        if which == "relax":
            cons = [mags("track") <= lim[0] * rho, mags("feed") <= lim[1] * rho, rho >= 0]
            cons += [e <= lim[0] * rho for e in eff]
            obj = rho
        else:
            cons = [mags("track") <= lim[0], mags("feed") <= lim[1]] + [e <= lim[0] for e in eff]
            R = d["R"] if d["R"] is not None else np.zeros((1, n))
            r0 = d["r0"] if d["r0"] is not None else np.zeros(R.shape[0])
            obj = cp.norm(R @ th + r0, 2)
        prob = cp.Problem(cp.Minimize(obj + d["eps"] * cp.norm(th, 2)), cons)
        try:
            solve_problem(prob, step=step, warm_start=False, refine=True)
        except InfeasibleError:
            return None
        value = float(rho.value) if which == "relax" else float(obj.value)
        return np.asarray(th.value, float), value

    def solve(self, which: str, *, step: str):
        """Solve ``"force"`` or ``"relax"``: ``(theta, objective)``, or ``None`` if infeasible.

        Afresh each time (no workspace kept: the answer must not depend on what this process
        solved before). Clarabel with iterative refinement; where that does not end solved or
        certifies infeasibility, the cvxpy formulation with its fallbacks decides.
        """
        if which not in ("force", "relax"):
            raise ParameterError(
                f"LimitProblem.solve: which must be 'force' or 'relax'; got {which!r}"
            )
        if not self.data:
            raise ParameterError("LimitProblem.solve: no data; call set() first")
        n = self.sizes[0]
        # with iterative refinement from the start: unrefined, two thirds of the map's
        # problems end only almost solved or stall, and the second solve costs more than the
        # refinement saves
        for refine in (True,):
            sol = self._clarabel(which, refine)
            if sol.status == clarabel.SolverStatus.Solved:
                self.stats["clarabel"] += 1
                x = np.asarray(sol.x, float)
                value = (
                    x[n]
                    if which == "relax"
                    else float(
                        np.linalg.norm(
                            (self.data["R"] if self.data["R"] is not None else np.zeros((1, n)))
                            @ x[:n]
                            + (self.data["r0"] if self.data["r0"] is not None else 0.0)
                        )
                    )
                )
                return x[:n], float(value)
            if refine and sol.status == clarabel.SolverStatus.PrimalInfeasible:
                self.stats["clarabel"] += 1
                return None
        self.stats["cvxpy"] += 1
        return self._cvxpy(which, step)
