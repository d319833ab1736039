"""The P-step of the P-K iteration: each member's certificates for a fixed controller.

With the controller data fixed, each member's bounded-real and H2 certificates are small
SDPs (``_hinf_analysis_sdp``, ``_h2_analysis_sdp``), written once per size with cvxpy
parameters and kept (an LRU cache of the compiled problems), at a level ``1 +``
:data:`LEVEL_SLACK` above the norm computed directly. ``_p_step`` solves them as
independent tasks on the processes :func:`robust.engine.map_tasks` grants and combines
the answers in order; the result (``_Point``) is what the K-step of
:mod:`robust.synthesis.pk` starts from.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools

import control
import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from robust.analysis.norms import h2_norm, hinf_norm
from robust.engine import jobs_available, map_tasks
from robust.errors import InfeasibleError, VerificationError
from robust.synthesis.pk_members import _Affine
from robust.synthesis.region import recentring, sym
from robust.synthesis.solve import deterministic_solvers, solve_problem, solver_threads

#: Nothing public: :mod:`robust.synthesis.pk`'s own.
__all__: list[str] = []


#: Relative slack of the levels the P-step certifies above the exact norms.
LEVEL_SLACK = 0.02


@dataclasses.dataclass
class _Point:
    """The current iterate: controller data and per-member certificates.

    Each member's certificates are kept as recentring transforms: in coordinates
    ``x = T xt`` the bounded-real certificate at level ``g`` (outputs scaled by ``g``) is
    the identity, and so is the H2 certificate ``Q`` (with output level ``z``).
    """

    Om: np.ndarray
    T_hinf: list
    g_member: list
    T_h2: list
    z_member: list


class _AnalysisSDP:
    """A P-step SDP built once per size, the closed loop's matrices its parameters.

    cvxpy compiles a problem written with :class:`cvxpy.Parameter` data once (disciplined
    parametrised programming) and maps new values into the solver's data without
    compiling again; the P-steps of every member and iteration share one problem per size.
    """

    def __init__(self, problem, data, P, t, level=None):
        self.problem, self.data, self.P, self.t, self.level = problem, data, P, t, level


@functools.lru_cache(maxsize=16)
def _hinf_analysis_sdp(n: int, nw: int, nz: int) -> _AnalysisSDP:
    """``max t`` s.t. ``trace P <= 10 n``, BRL(A, B, C, D; P) at level 1 ``<= -t I``.

    ``P > 0`` is not a constraint of its own: with ``t > 0`` the inequality's first block
    gives ``PA + A'P < 0``, so ``P > 0`` whenever ``A`` is Hurwitz (Lyapunov), and no
    certificate exists when it is not; the answer's ``P`` is checked to be positive
    definite (:func:`_analyse_hinf`). The optimum is the same, and without a cone that
    the solution never touches each solve takes about half the time.
    """
    A, B = cp.Parameter((n, n), name="A"), cp.Parameter((n, nw), name="B")
    C, D = cp.Parameter((nz, n), name="C"), cp.Parameter((nz, nw), name="D")
    P, t = cp.Variable((n, n), symmetric=True), cp.Variable()
    PA, PB = P @ A, P @ B
    M = sym(cp.bmat([[PA + PA.T, PB, C.T], [PB.T, -np.eye(nw), D.T], [C, D, -np.eye(nz)]]))
    problem = cp.Problem(cp.Maximize(t), [cp.trace(P) <= 10 * n, M << -t * np.eye(n + nw + nz)])
    return _AnalysisSDP(problem, (A, B, C, D), P, t)


@functools.lru_cache(maxsize=16)
def _h2_analysis_sdp(n: int, nw: int, nz: int) -> _AnalysisSDP:
    """``max t``: the H2 inequalities in ``(Q, Z)`` with margin ``t``, ``trace Z <= level``.

    ``Q > 0`` is implied by ``[[Q, C'], [C, Z]] >= t I`` with ``t > 0`` (``Q >= t I``), so
    it is not a cone of its own (the same optimum, about half the solve time).
    """
    A, B = cp.Parameter((n, n), name="A"), cp.Parameter((n, nw), name="B")
    C, level = cp.Parameter((nz, n), name="C"), cp.Parameter(nonneg=True, name="level")
    Q, Z, t = (
        cp.Variable((n, n), symmetric=True),
        cp.Variable((nz, nz), symmetric=True),
        cp.Variable(),
    )
    QA, QB = Q @ A, Q @ B
    M = sym(cp.bmat([[QA + QA.T, QB], [QB.T, -np.eye(nw)]]))
    N2 = cp.bmat([[Q, C.T], [C, Z]])
    problem = cp.Problem(
        cp.Maximize(t),
        [
            cp.trace(Q) <= 10 * n,
            M << -t * np.eye(n + nw),
            N2 >> t * np.eye(n + nz),
            cp.trace(Z) <= level,
        ],
    )
    return _AnalysisSDP(problem, (A, B, C), Q, t, level)


def _sizes(data) -> tuple[int, int, int]:
    """``(n, nw, nz)`` of an analysis SDP's data ``(A, B, C, ...)``."""
    A, B, C = data[:3]
    return A.shape[0], B.shape[1], C.shape[0]


def _hinf_analysis_data(cl: _Affine, Om, T_prev):
    """The H-infinity P-step's coordinates, level and SDP data for one member:
    ``(T, g0, (A, B, C, D))``, the closed loop in the coordinates ``T`` (of the previous
    certificate or, first, of the Riccati solution) with its output scaled by the level."""
    A, B, C, D = cl.matrices(Om)
    g = hinf_norm(control.ss(A, B, C, D))
    g0 = (1 + LEVEL_SLACK) * g + 1e-12
    n = A.shape[0]
    if T_prev is None:
        Cs, Ds = C / g0, D / g0
        R = -(np.eye(B.shape[1]) - Ds.T @ Ds)
        try:
            X = sla.solve_continuous_are(A, B, Cs.T @ Cs, R, s=Cs.T @ Ds)
            T_prev = recentring(sym(X) + 1e-6 * np.abs(X).max() * np.eye(n))
        except (np.linalg.LinAlgError, ValueError, VerificationError):
            T_prev = recentring(sla.solve_continuous_lyapunov(A.T, -(Cs.T @ Cs + np.eye(n))))
    return T_prev, g0, cl.transformed(T_prev).scaled_output(g0).matrices(Om)


def _h2_analysis_data(cl: _Affine, Om, T_prev):
    """The H2 P-step's coordinates, level and SDP data for one member: ``(T, z0, (A, B,
    C))`` in the coordinates ``T`` (of the previous certificate or, first, of the inverse
    controllability Gramian)."""
    A, B, C, _ = cl.matrices(Om)
    n = A.shape[0]
    z0 = (1 + LEVEL_SLACK) ** 2 * h2_norm(A, B, C) ** 2 + 1e-300
    if T_prev is None:
        BB = B @ B.T
        S = sla.solve_continuous_lyapunov(A, -(BB + 1e-9 * np.linalg.norm(BB, 2) * np.eye(n)))
        T_prev = recentring(np.linalg.inv(sym(S)))
    return T_prev, z0, cl.transformed(T_prev).matrices(Om)[:3]


def _analyse_hinf(cl: _Affine, Om, T_prev, solvers):
    """P-step for one member: a centred certificate of the shifted H-infinity channel.

    The level is ``(1 + LEVEL_SLACK)`` times the channel's norm (computed directly); the
    SDP maximises the margin of the bounded-real inequality at that level in the
    coordinates of the previous certificate (or, first, of the Riccati solution).
    """
    T_prev, g0, data = _hinf_analysis_data(cl, Om, T_prev)
    sdp = _hinf_analysis_sdp(*_sizes(data))
    sdp.t.value = None
    for par, val in zip(sdp.data, data):
        par.value = val
    # afresh (no reuse of the previous solve's workspace): the answer must not depend on
    # what this process solved before
    sol = solve_problem(
        sdp.problem,
        step="pksyn_multi: H-infinity analysis (P) step",
        solvers=solvers,
        warm_start=False,
    )
    P, t = sdp.P, sdp.t
    if t.value is None or not t.value > 0:
        raise InfeasibleError(
            f"pksyn_multi: no bounded-real certificate at level {g0:.6g} (margin {t.value})"
        )
    # P > 0 is implied for a Hurwitz A only (the SDP does not impose it)
    p_min = float(np.linalg.eigvalsh(sym(P.value))[0])
    if not p_min > 0:
        raise InfeasibleError(
            f"pksyn_multi: no bounded-real certificate at level {g0:.6g}: the member's closed "
            f"loop is not stable (the certificate's smallest eigenvalue is {p_min:.3g})"
        )
    return T_prev @ recentring(sym(P.value)), g0, sol.solve_time


def _analyse_h2(cl: _Affine, Om, T_prev, solvers):
    """P-step for one member: a centred H2 certificate at ``(1 + LEVEL_SLACK)^2`` the norm^2."""
    T_prev, z0, data = _h2_analysis_data(cl, Om, T_prev)
    sdp = _h2_analysis_sdp(*_sizes(data))
    sdp.t.value = None
    for par, val in zip(sdp.data, data):
        par.value = val
    sdp.level.value = z0
    sol = solve_problem(
        sdp.problem, step="pksyn_multi: H2 analysis (P) step", solvers=solvers, warm_start=False
    )
    Q, t = sdp.P, sdp.t
    if t.value is None or not t.value > 0:
        raise InfeasibleError(f"pksyn_multi: no H2 certificate at level {z0:.6g} ({t.value})")
    return T_prev @ recentring(sym(Q.value)), z0, sol.solve_time


def _analyse_task(task):
    """One certificate of a P-step (module level: it runs in worker processes).

    ``task = (kind, cl, Om, T_prev, solvers, threads)``, ``kind`` ``"hinf"`` or ``"h2"``;
    ``threads == 1`` solves on one thread (:func:`deterministic_solvers`), as the caller did.
    """
    kind, cl, Om, T_prev, solvers, threads = task
    with deterministic_solvers() if threads == 1 else contextlib.nullcontext():
        return (_analyse_hinf if kind == "hinf" else _analyse_h2)(cl, Om, T_prev, solvers)


def _p_step(members, Om, prev: _Point | None, solvers, times) -> _Point:
    """The members' certificates for ``Om``: independent SDPs, in the processes granted by
    :func:`robust.engine.nested_jobs` (the same answers in any of them, combined in order)."""
    threads = solver_threads()
    tasks = []
    for i, m in enumerate(members):
        tasks.append(
            ("hinf", m.hinf_shifted, Om, None if prev is None else prev.T_hinf[i], solvers, threads)
        )
        if m.h2 is not None:
            tasks.append(("h2", m.h2, Om, None if prev is None else prev.T_h2[i], solvers, threads))
    jobs = min(jobs_available(), len(tasks))
    answers = iter(map_tasks(_analyse_task, tasks, jobs=jobs, scheduler=None))
    T_h, g_m, T_2, z_m = [], [], [], []
    for m in members:
        T, g, st = next(answers)
        T_h.append(T)
        g_m.append(g)
        times.append(st)
        if m.h2 is not None:
            T, z, st = next(answers)
            times.append(st)
        else:
            T, z = None, 0.0
        T_2.append(T)
        z_m.append(z)
    return _Point(Om, T_h, g_m, T_2, z_m)
