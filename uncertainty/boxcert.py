"""Certificates of one box: every member's poles in the region, over the box's continuum.

Two routes certify a sub-box of the scaled box (the lower bound of the robust margin,
:mod:`uncertainty.margins`, cuts the box into them):

* eigenvalue enclosures (:func:`certify_box`): the closed-loop matrix in mean-value form
  about the box's centre (interval forward differentiation; Moore, Kearfott & Cloud,
  *Introduction to Interval Analysis*, SIAM 2009), every eigenvalue of every member enclosed
  in a rectangle by a Krawczyk-type operator in the centre's eigenvector basis
  (:func:`robust.analysis.eigen_enclosure.enclose_eigenvalues`; S. M. Rump, Linear Algebra
  Appl. 324:209-226, 2001; R. Krawczyk, Computing 4:187-201, 1969); the box is certified
  when the rectangles are disjoint and inside the region, and seeded members are
  spot-checked against them;
* a quadratic Lyapunov certificate of the interval matrix ``[A_c - R, A_c + R]``
  (:func:`certify_interval_matrix`): a common Lyapunov function for the norm-bounded set,
  the S-procedure with one multiplier per uncertain entry (Boyd, El Ghaoui, Feron &
  Balakrishnan, *Linear Matrix Inequalities in System and Control Theory*, SIAM 1994,
  Sec. 5.1), from the centre's Lyapunov equation when the Patel-Toda bound holds (Patel &
  Toda, JACC 1980), otherwise from the LMI solved with cvxpy (Clarabel); each certificate is
  rebuilt and checked in numpy.

``_box_task`` is the unit of work of the subdivision (sent to worker processes as
``functools.partial(_box_task, loop, region, method)``). One concern, apart from the
enclosures it takes (:mod:`uncertainty.enclosure`) and the bisection on the scale that
uses it (:mod:`uncertainty.margins`).
"""

from __future__ import annotations

import math

import control as ct
import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from robust.analysis.box_subdivision import split_coordinate
from robust.analysis.eigen_enclosure import enclose_eigenvalues
from robust.analysis.intervals import Interval, norm2_bound
from robust.analysis.stability import STABILITY_TOL
from robust.errors import BDFTError
from robust.synthesis.solve import solve_problem
from uncertainty.enclosure import MarginFamily, _Unbounded, loop_region, margin_loop
from uncertainty.region import Region
from uncertainty.search import _to_values
from uncertainty.uss import USS

__all__ = ["certify_interval_matrix", "certify_box"]

_EPS = float(np.finfo(float).eps)


def _structured(R: np.ndarray, floor: float, rel: float = 1e-9):
    """Split an entrywise bound into its significant entries and a small remainder.

    Returns ``L`` (n x m), ``Rm`` (m x n) with ``E_big = L diag(delta) Rm``,
    ``|delta_k| <= 1``, for the ``m`` entries above ``rel * max(R)``, and the norm bound
    of the remaining entries (rounding-level widening of structurally fixed entries).
    """
    n = R.shape[0]
    big = R > max(rel * (R.max() if R.size else 0.0), floor)
    idx = np.argwhere(big)
    L = np.zeros((n, len(idx)))
    Rm = np.zeros((len(idx), n))
    for k, (i, j) in enumerate(idx):
        L[i, k] = math.sqrt(R[i, j])
        Rm[k, j] = math.sqrt(R[i, j])
    return L, Rm, norm2_bound(np.where(big, 0.0, R))


def _real_modal_basis(A: np.ndarray) -> np.ndarray:
    """Real basis of eigenvectors of ``A`` (``[Re v, Im v]`` per complex pair), columns of
    unit norm; the identity if ``A`` is too close to defective (condition > 1e8)."""
    lam, V = np.linalg.eig(A)
    cols, done = [], set()
    for i in np.argsort(-lam.real):
        if i in done:
            continue
        v = V[:, i]
        if abs(lam[i].imag) > 1e-12 * max(1.0, abs(lam[i])):
            j = int(np.argmin(np.abs(lam - np.conj(lam[i])) + (np.arange(len(lam)) == i)))
            done.update((i, j))
            cols += [v.real, v.imag]
        else:
            done.add(i)
            cols.append(v.real)
    T = np.column_stack(cols)
    T = T / np.linalg.norm(T, axis=0)
    if not np.isfinite(np.linalg.cond(T)) or np.linalg.cond(T) > 1e8:
        return np.eye(A.shape[0])
    return T


def _lmi_matrix(As, P, lam, eps, L, Rm, rho_s):
    """The robust-stability LMI for ``As + L diag(delta) Rm + E_s``, ``|delta| <= 1``,
    ``||E_s|| <= rho_s`` (Boyd et al. 1994, Sec. 5.1; S-procedure with diagonal scalings).
    """
    n, m = As.shape[0], L.shape[1]
    top = As.T @ P + P @ As + Rm.T @ (lam[:, None] * Rm)
    if rho_s == 0:
        return np.block([[top, P @ L], [L.T @ P, -np.diag(lam)]])
    top = top + eps * rho_s**2 * np.eye(n)
    return np.block(
        [
            [top, P @ L, P],
            [L.T @ P, -np.diag(lam), np.zeros((m, n))],
            [P, np.zeros((n, m)), -eps * np.eye(n)],
        ]
    )


def _check(As, P, lam, eps, L, Rm, rho_s) -> float:
    """Largest normalised eigenvalue of the rebuilt LMI (< 0 certifies); ``inf`` if
    ``P``, ``lam`` or ``eps`` is not positive."""
    P = (P + P.T) / 2
    finite = np.all(np.isfinite(P)) and np.all(np.isfinite(lam)) and math.isfinite(eps)
    if not (finite and eps > 0 and np.all(lam > 0) and np.linalg.eigvalsh(P).min() > 0):
        return math.inf
    M = _lmi_matrix(As, P, lam, eps, L, Rm, rho_s)
    # congruence with blkdiag(I, diag(lam)^-1/2, eps^-1/2 I) (definiteness unchanged)
    # brings the multiplier blocks to -I, so the eigenvalues are resolved at every scale
    n = As.shape[0]
    d = np.concatenate(
        [np.ones(n), 1.0 / np.sqrt(lam), np.full(n if rho_s else 0, 1.0 / math.sqrt(eps))]
    )
    M = M * d[:, None] * d[None, :]
    scale = max(1.0, np.abs(M[:n, :n]).max())
    return float(np.linalg.eigvalsh((M + M.T) / 2).max() / scale)


def certify_interval_matrix(
    enclosure: Interval, decay_rate: float = 0.0, *, lmi: bool = True
) -> dict:
    """Certify that every matrix of an interval matrix has its eigenvalues left of ``-a``.

    The perturbation ``E = A - A_c`` (``|E| <= R``) is written entry by entry,
    ``E = sum_k delta_k R_ij e_i e_j'`` with ``|delta_k| <= 1``, plus a remainder of
    rounding-level entries bounded in norm; the certificate is a common quadratic
    Lyapunov function for that set with one S-procedure multiplier per entry.

    Parameters
    ----------
    enclosure : Interval
        Square interval matrix ``[A_c - R, A_c + R]``.
    decay_rate : float
        ``a`` >= 0, rad/s (``STABILITY_TOL`` is used when smaller).
    lmi : bool
        Solve the LMI when the centre's own Lyapunov matrix does not certify (False: the
        cheap route only).

    Returns
    -------
    dict
        ``certified`` (bool), ``route`` (``"lyapunov"``, ``"lmi"`` or ``None``),
        ``rho`` (the unstructured norm bound, for information), ``entries`` (uncertain
        entries), ``check`` (largest normalised eigenvalue of the LMI rebuilt in numpy;
        < 0 certifies), ``centre_violates`` (the centre matrix itself is outside the
        region).
    """
    # a diagonal similarity (balancing of the centre, scipy.linalg.matrix_balance) scales
    # mid and radius alike, E -> S^-1 E S, and leaves every eigenvalue where it is
    _, (s, _) = sla.matrix_balance(enclosure.mid, permute=False, separate=True)
    Ac = enclosure.mid / s[:, None] * s[None, :]
    R = enclosure.rad / s[:, None] * s[None, :]
    rho = norm2_bound(R)
    a = max(float(decay_rate), STABILITY_TOL)
    n = Ac.shape[0]
    L, Rm, rho_s = _structured(R, 1e-13 * max(1.0, np.abs(Ac).max()))
    # real modal coordinates of the centre, x = T z: each rank-one term e_i e_j' becomes
    # (T^-1 e_i)(e_j' T), the remainder's bound grows by cond(T)
    T = _real_modal_basis(Ac)
    Ti = np.linalg.inv(T)
    As = Ti @ Ac @ T + a * np.eye(n)
    L, Rm = Ti @ L, Rm @ T
    rho_s = rho_s * np.linalg.norm(T, 2) * np.linalg.norm(Ti, 2) * (1 + 1e-9)
    if rho_s < 1e-250:  # the remainder holds only exact zeros (norm2_bound adds a tiny floor)
        rho_s = 0.0
    m = L.shape[1]
    out = {
        "certified": False,
        "route": None,
        "rho": rho,
        "entries": m,
        "check": math.inf,
        "centre_violates": bool(np.linalg.eigvals(As).real.max() >= 0),
    }
    if out["centre_violates"]:
        return out
    # cheap route: the centre's Lyapunov matrix and the best scalar multipliers
    try:
        P = sla.solve_continuous_lyapunov(As.T, -np.eye(n))
    except (np.linalg.LinAlgError, ValueError):
        P = None
    if P is not None and np.all(np.isfinite(P)):
        PL = P @ L
        lam = np.maximum(
            np.linalg.norm(PL, axis=0) / np.maximum(np.linalg.norm(Rm, axis=1), 1e-300), 1e-300
        )
        eps = np.linalg.norm(P, 2) / rho_s if rho_s > 0 else 1.0
        chk = _check(As, P, lam, eps, L, Rm, rho_s)
        if chk < 0:
            out.update(certified=True, route="lyapunov", check=chk)
            return out
    if not lmi:
        return out
    Pv = cp.Variable((n, n), symmetric=True)
    lv = cp.Variable(m, pos=True) if m else None
    ev = cp.Variable(pos=True)
    Im = np.eye(n)
    top = As.T @ Pv + Pv @ As + ev * rho_s**2 * Im
    if m:
        top = top + Rm.T @ cp.diag(lv) @ Rm
    if m and rho_s:
        rows = [
            [top, Pv @ L, Pv],
            [L.T @ Pv, -cp.diag(lv), np.zeros((m, n))],
            [Pv, np.zeros((n, m)), -ev * Im],
        ]
    elif m:
        rows = [[top, Pv @ L], [L.T @ Pv, -cp.diag(lv)]]
    else:
        rows = [[top, Pv], [Pv, -ev * Im]] if rho_s else [[top]]
    Mx = cp.bmat(rows)
    size = Mx.shape[0]
    prob = cp.Problem(cp.Minimize(0), [Pv >> Im, (Mx + Mx.T) / 2 << -1e-7 * np.eye(size)])
    try:
        solve_problem(
            prob, step="robust margin: Lyapunov certificate of a sub-box", solvers=("CLARABEL",)
        )
    except BDFTError:
        return out
    if Pv.value is None or (rho_s and ev.value is None) or (m and lv.value is None):
        return out
    lam = np.asarray(lv.value, float) if m else np.zeros(0)
    eps = float(ev.value) if rho_s else 1.0
    chk = _check(As, Pv.value, lam, eps, L, Rm, rho_s)
    out.update(certified=chk < 0, route="lmi" if chk < 0 else None, check=chk)
    return out


def _split_dimension(loop, lo_t, hi_t):
    """The parameter whose range alone widens the enclosure most."""
    centre = (lo_t + hi_t) / 2
    best, best_j = -1.0, 0
    for j in range(len(lo_t)):
        if hi_t[j] <= lo_t[j]:
            continue
        a, b = centre.copy(), centre.copy()
        a[j], b[j] = lo_t[j], hi_t[j]
        enc = loop.enclosure(_to_values(loop, a), _to_values(loop, b), False)
        r = norm2_bound(enc.rad)
        if r > best:
            best, best_j = r, j
    return best_j


def _rectangles_in_region(res: dict, region: Region) -> np.ndarray:
    """Per eigenvalue rectangle: its largest region violation (< 0: inside), rad/s.

    The decay-rate part is ``Re_max + a``; with a damping requirement, a rectangle whose
    frequency range meets the band must have its four corners in the convex sector
    ``Re s + zeta |s| <= 0``, so its violation is the largest ``Re s + zeta |s|`` at a
    corner.
    """
    c, rr, ri = res["centre"], res["rad_re"], res["rad_im"]
    v = c.real + rr + max(region.decay_rate, STABILITY_TOL)
    if region.min_damping > 0:
        f_lo = np.maximum(np.abs(c.imag) - ri, 0.0) / (2 * math.pi)
        f_hi = (np.abs(c.imag) + ri) / (2 * math.pi)
        meets = (f_hi >= region.band_hz[0]) & (f_lo <= region.band_hz[1])
        corners = [(c.real + sr * rr) + 1j * (c.imag + si * ri) for sr in (-1, 1) for si in (-1, 1)]
        sector = np.max([z.real + region.min_damping * np.abs(z) for z in corners], axis=0)
        v = np.maximum(v, np.where(meets, sector, -np.inf))
    return v


def certify_box(
    family: MarginFamily | USS,
    lo,
    hi,
    *,
    controller: ct.StateSpace | None = None,
    region: Region | None = None,
    spot_checks: int = 8,
    seed: int = 0,
) -> dict:
    """Certify that every member of a box has its poles in the region (eigenvalue route).

    The closed-loop matrix over the box is written in mean-value form about the box's
    centre (derivative enclosures by interval forward differentiation,
    :class:`~robust.analysis.intervals.Gradient`) and every eigenvalue of every member is
    enclosed in a rectangle by :func:`robust.analysis.eigen_enclosure.enclose_eigenvalues`.
    The box is certified when the rectangles are disjoint (so they hold every eigenvalue)
    and each lies in the region. Independent check: ``spot_checks`` seeded members of the
    box are assembled by :func:`backhoe.families.batched.closed_loop_matrices` and their
    eigenvalues (numpy) must lie in the rectangles; a miss raises :class:`BDFTError`.

    Parameters
    ----------
    family : Family or USS
        The family, or an uncertain system (closed with ``controller`` by negative
        feedback when one is given).
    lo, hi : array_like, shape (d,)
        The box: bounds of every uncertain parameter (values, family order or the order
        of ``system.parameters``; the box is split in the parameters' coordinates, log for
        log-uniform parameters).
    controller : control.StateSpace, optional
        Compensator in the loop's convention (a family) or in the feedback path.
    region : Region, optional
        Required region (default: open left half-plane).
    spot_checks : int
        Members of the box checked against the enclosures.
    seed : int
        Seed of the spot-checked members.

    Returns
    -------
    dict
        ``certified``, ``centre_violates`` (the box's centre member is outside the region),
        ``check`` (largest violation of a rectangle, rad/s; < 0 certifies), ``split``
        (the parameter whose range moves the eigenvalues most, relative to their distance
        to the region's boundary), ``reason``.
    """
    loop = margin_loop(family, controller)
    logs = np.array([p.distribution == "loguniform" for p in loop.parameters])
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    lo_t = np.where(logs, np.log(np.where(logs, lo, 1.0)), lo)
    hi_t = np.where(logs, np.log(np.where(logs, hi, 1.0)), hi)
    return _certify_box(loop, lo_t, hi_t, loop_region(loop, region), spot_checks, seed)


def _certify_box(loop, lo_t, hi_t, region, spot_checks, seed) -> dict:
    lo_t, hi_t = np.asarray(lo_t, float), np.asarray(hi_t, float)
    ct_ = (lo_t + hi_t) / 2
    # the values of the box's ends and centre as floats; the box is widened by a few ulps
    # so that it covers the exact ends, and the half-widths cover the rounded centre
    # (values of either sign: widened away from zero)
    lo_v = _to_values(loop, lo_t)
    hi_v = _to_values(loop, hi_t)
    lo_v = lo_v - 8 * _EPS * np.abs(lo_v)
    hi_v = hi_v + 8 * _EPS * np.abs(hi_v)
    c_v = _to_values(loop, ct_)
    h = (hi_t - lo_t) / 2 * (1 + 1e-12) + 16 * _EPS * (np.abs(ct_) + 1.0)
    try:
        Ac = loop.enclosure(c_v, c_v, False)
        G = loop.enclosure(lo_v, hi_v, True)
    except _Unbounded as exc:
        # a member with an unbounded matrix is outside every region: no sub-box helps
        return {
            "certified": False,
            "centre_violates": True,
            "check": math.inf,
            "split": 0,
            "reason": str(exc),
        }
    E_rad = Ac.rad + np.einsum("p,pab->ab", h, G.der.rad)
    res = enclose_eigenvalues(Ac.mid, G.der.mid, h, E_rad, margin=region.distance_inside)
    if not np.all(np.isfinite(res["eigs"])):
        res = dict(res, eigs=np.linalg.eigvals(Ac.mid))
    centre_v = region.violation(res["eigs"][None])[0]
    out = {
        "certified": False,
        "centre_violates": bool(centre_v > 0),
        "check": math.inf,
        "split": split_coordinate(
            res,
            max(region.decay_rate, STABILITY_TOL),
            hi_t > lo_t,
            margins=region.distance_inside(res["eigs"]),
            remainder=h * np.linalg.norm(G.der.rad, 2, axis=(1, 2)),
        ),
    }
    if out["centre_violates"]:
        return dict(out, reason="the centre member violates the region")
    if not res["ok"]:
        # a cluster of eigenvalues (e.g. the exact copy of the human's poles in a cancelling
        # controller) defeats simple-eigenvalue enclosures; the quadratic Lyapunov route
        # (its cheap form, the centre's own Lyapunov matrix) may still certify the box
        why = "overlapping enclosures" if res["verified"].all() else "enclosure not verified"
        if region.min_damping == 0:
            enc = loop.enclosure(lo_v, hi_v, False)
            alt = certify_interval_matrix(enc, region.decay_rate, lmi=False)
            if alt["certified"]:
                return dict(
                    out,
                    certified=True,
                    check=alt["check"],
                    route="lyapunov",
                    reason="certified (Lyapunov route: eigenvalue cluster)",
                )
        return dict(out, reason=why)
    v = _rectangles_in_region(res, region)
    out["check"] = float(v.max())
    if out["check"] >= 0:
        return dict(out, reason="an enclosure reaches outside the region")
    # independent check of the enclosures on seeded members of the box
    if spot_checks:
        rng = np.random.default_rng(seed)
        T = lo_t + rng.random((spot_checks, len(lo_t))) * (hi_t - lo_t)
        A = loop.matrices(_to_values(loop, T))
        c, rr, ri = res["centre"], res["rad_re"], res["rad_im"]
        for Ak, poles in zip(A, np.linalg.eigvals(A)):
            # numpy's eigenvalues carry their own rounding error (about eps ||A|| cond)
            tol = 1e-9 * np.linalg.norm(Ak)
            inside = (np.abs(poles.real[:, None] - c.real[None]) <= rr[None] + tol) & (
                np.abs(poles.imag[:, None] - c.imag[None]) <= ri[None] + tol
            )
            if not inside.any(axis=1).all():
                raise BDFTError(
                    "robust margin: a member's eigenvalue lies outside the certified "
                    "enclosures of its box; the certificate is wrong"
                )
    return dict(out, certified=True, route="eigenvalues", reason="certified")


def _box_task(loop, region, method, box) -> dict:
    """One sub-box of the search: ``box = (lo_t, hi_t, index)``; the index seeds its spot checks."""
    a, b, index = box
    if method == "eigenvalues":
        return _certify_box(loop, a, b, region, 8, index)
    try:
        enc = loop.enclosure(_to_values(loop, a), _to_values(loop, b), False)
    except _Unbounded:
        return {"certified": False, "centre_violates": True, "check": math.inf}
    res = certify_interval_matrix(enc, region.decay_rate)
    if not res["certified"] and not res["centre_violates"]:
        res["split"] = _split_dimension(loop, a, b)
    return res


def _boxes_task(task, boxes) -> list:
    """Several sub-boxes of one step in one task: ``[task(box) for box in boxes]``."""
    return [task(box) for box in boxes]
