"""Enclosures of clusters of eigenvalues: the invariant-subspace operator of a group whose
single enclosures overlap.

When the enclosures of :func:`robust.analysis.eigen_enclosure.enclose_eigenvalues` overlap
(a repeated or nearly repeated eigenvalue of the centre), each group of overlapping ones
is replaced by one enclosure of the cluster's eigenvalues, from Rump's operator on the
invariant subspace (S. M. Rump, Linear Algebra Appl. 324:209-226, 2001), with the
pseudospectral radius of a cluster that the block discs (:mod:`robust.analysis.eigen_discs`)
share; the groups' enclosures must then be disjoint. Apart from the single-eigenvalue
operator so that the main route reads on its own.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

#: Nothing public: these are :mod:`robust.analysis.eigen_enclosure`'s own steps.
__all__: list[str] = []


_EPS = np.finfo(float).eps
#: Eigenvalues closer than this fraction of their modulus form one cluster (block).
CLUSTER_RTOL = 0.02
#: Largest cluster enclosed by the invariant-subspace operator.
MAX_CLUSTER = 4


def _components(link: np.ndarray) -> list:
    """Connected components of a symmetric boolean adjacency matrix, each sorted."""
    n = link.shape[0]
    seen, groups = np.zeros(n, bool), []
    for i in range(n):
        if seen[i]:
            continue
        stack, group = [i], []
        seen[i] = True
        while stack:
            j = stack.pop()
            group.append(j)
            for k in np.flatnonzero(link[j] & ~seen):
                seen[k] = True
                stack.append(int(k))
        groups.append(sorted(group))
    return groups


def _overlaps(c, rr, ri) -> np.ndarray:
    """Pairwise overlap of the rectangles ``c +- (rr, ri)`` (diagonal False)."""
    lo_re, hi_re, lo_im, hi_im = c.real - rr, c.real + rr, c.imag - ri, c.imag + ri
    out = (lo_re[:, None] <= hi_re[None]) & (lo_re[None] <= hi_re[:, None])
    out &= (lo_im[:, None] <= hi_im[None]) & (lo_im[None] <= hi_im[:, None])
    np.fill_diagonal(out, False)
    return out


def _overlap_groups(res: dict) -> list:
    """Groups of eigenvalues whose enclosures overlap (an unverified one joins its nearest)."""
    c, rr, ri, ok = res["centre"], res["rad_re"], res["rad_im"], res["verified"]
    fin = ok & np.isfinite(rr) & np.isfinite(ri)
    link = _overlaps(c, rr, ri) & fin[:, None] & fin[None]
    eig = res["eigs"]
    for i in np.flatnonzero(~fin):
        d = np.abs(eig - eig[i])
        d[i] = np.inf
        j = int(np.argmin(d))
        link[i, j] = link[j, i] = True
    return _components(link)


def _krawczyk_cluster(Ac, J, h, E_rad, idx, inflations):
    """Enclose the ``k = len(idx)`` eigenvalues of a cluster of every matrix of the box.

    Rump's operator for an invariant subspace (S. M. Rump, Linear Algebra Appl.
    324:209-226, 2001, Thm. 3.1; S. M. Rump & J.-P. M. Zemke, BIT 43:823-837, 2003): with
    ``X~`` the cluster's eigenvectors normalised to the identity in ``k`` rows ``U`` and
    ``M~ = (A_c X~)_U``, the zeros of ``f(Y^) = A (X~ + Y) - (X~ + Y)(M~ + Y^_U)``
    (``Y`` = ``Y^`` with rows ``U`` zeroed) are invariant pairs; if the Krawczyk-type
    operator ``K(Y) = -R vec(A X~ - X~ M~) + (I - R B) vec(Y) + R vec(Y Y^_U)`` (``B`` the
    linear part, ``R ~ B_c^-1``) maps a rectangle into itself for every ``A`` of the box,
    then ``A X = X M`` with ``X = X~ + Y`` of full column rank and ``M = M~ + Y^_U``: the
    ``k`` eigenvalues of ``M`` (with multiplicity) are eigenvalues of ``A``. They lie in
    discs about the eigenvalues of the centre ``M~ + zc_U`` of radius
    :func:`_pseudo_radius` of the enclosure's size (the Schur form of the centre bounds
    its departure from normality).

    Returns ``(centres (k,), radius, sensitivity (d,))`` (each parameter's first-order
    share, for choosing a split) or ``None`` if the operator does not contract.
    """
    n, k = Ac.shape[0], len(idx)
    d = J.shape[0]
    lam = np.linalg.eigvals(Ac)
    # an orthonormal basis of the cluster's invariant subspace from an ordered Schur form:
    # unlike the eigenvectors it stays well conditioned where the eigenvalues meet
    inside = np.zeros(n, bool)
    inside[idx] = True
    gap = np.min(np.abs(lam[inside][:, None] - lam[~inside][None])) if (~inside).any() else 1.0
    centre = lam[inside]
    try:
        _, Z, sdim = sla.schur(
            Ac.astype(complex),
            output="complex",
            sort=lambda x: bool(np.min(np.abs(centre - x)) < gap / 2),
        )
    except (np.linalg.LinAlgError, ValueError):
        return None
    if sdim != k:
        return None
    X = Z[:, :k]
    # rows U: a well-conditioned k x k part of X (pivoted QR of X')
    _, _, piv = sla.qr(X.T, pivoting=True)
    U = np.sort(piv[:k])
    try:
        X = X @ np.linalg.inv(X[U])
    except np.linalg.LinAlgError:
        return None
    Vrows = np.setdiff1d(np.arange(n), U)
    AX = Ac @ X
    M = AX[U]
    r_c = AX - X @ M  # rows U vanish up to rounding
    # B: vec(Y^) -> vec(A Y - X Y^_U - Y M~), column-major vec (index c * n + r)
    N = n * k
    B = np.zeros((N, N), complex)
    for c in range(k):
        for r in Vrows:
            col = c * n + r
            B[c * n : (c + 1) * n, col] += Ac[:, r]
            for c2 in range(k):
                B[c2 * n + r, col] -= M[c, c2]
        for q, r in enumerate(U):
            B[c * n : (c + 1) * n, c * n + r] = -X[:, q]
    try:
        R = np.linalg.inv(B)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(R)):
        return None
    gam = (N + 4) * 8 * _EPS
    aR, aX = np.abs(R), np.abs(X)
    vec = lambda Z: Z.reshape(-1, order="F")  # noqa: E731
    zc = -R @ vec(r_c)
    err = gam * (aR @ vec(np.abs(Ac) @ aX + aX @ np.abs(M)) + np.abs(zc))
    # first order in the box: -R vec(J_p X~), one rectangle per parameter
    G = np.stack([R @ vec(Jp @ X) for Jp in J]) if d else np.zeros((0, N), complex)
    rho_re = h @ np.abs(G.real) if d else np.zeros(N)
    rho_im = h @ np.abs(G.imag) if d else np.zeros(N)
    err += gam * (aR @ vec(np.einsum("p,pab->ab", h, np.abs(J)) @ aX)) if d else 0.0
    unstr = aR @ vec(E_rad @ aX) + err
    # |I - R B(A)|: centre, plus the box's change of B through (I_k (x) dA) on rows V
    PV = np.zeros(N, bool)
    for c in range(k):
        PV[c * n + Vrows] = True
    dA = np.einsum("p,pab->ab", h, np.abs(J)) + E_rad
    dB = np.kron(np.eye(k), dA)[:, PV]
    Cabs = np.abs(np.eye(N) - R @ B) + gam * (aR @ np.abs(B))
    Cabs[:, PV] += aR @ dB
    base_re, base_im = rho_re + unstr, rho_im + unstr
    w_re, w_im = base_re * 1.1 + 1e-300, base_im * 1.1 + 1e-300
    iu = np.array([c * n + r for c in range(k) for r in U])  # entries of Y^_U (row r, col c)
    with np.errstate(over="ignore", invalid="ignore"):  # a diverging operator just fails
        return _inflate_cluster(
            zc, w_re, w_im, base_re, base_im, Cabs, aR, U, n, k, gam, M, G, h, d, iu, inflations
        )


def _inflate_cluster(zc, w_re, w_im, base_re, base_im, Cabs, aR, U, n, k, gam, M, G, h, d, iu, its):
    """Epsilon-inflation of the cluster operator (see :func:`_krawczyk_cluster`)."""

    def vec(Z):
        return Z.reshape(-1, order="F")

    for _ in range(its):
        absY = np.abs(zc) + np.hypot(w_re, w_im)
        absYm = absY.reshape(n, k, order="F")
        absYV = absYm.copy()
        absYV[U] = 0.0
        quad = aR @ vec(absYV @ absYm[U])
        s_ = (Cabs @ absY + quad) * (1 + gam) + np.finfo(float).tiny
        new_re, new_im = base_re + s_, base_im + s_
        if not (np.all(np.isfinite(new_re)) and np.all(np.isfinite(new_im))):
            return None
        if np.all(new_re < w_re) and np.all(new_im < w_im):
            Mc = M + zc.reshape(n, k, order="F")[U]
            wU = np.hypot(w_re, w_im).reshape(n, k, order="F")[U]
            T, _ = sla.schur(Mc, output="complex")
            nu = np.linalg.norm(np.triu(T, 1), 2)
            eps = np.linalg.norm(wU) + k * 8 * _EPS * np.abs(Mc).sum()
            # each parameter's first-order share of the cluster's matrix M (for splitting)
            sens = h * np.linalg.norm(G[:, iu], axis=1) if d else np.zeros(0)
            return np.diag(T), _pseudo_radius(eps, nu, k), sens
        w_re, w_im = new_re * 1.1 + 1e-300, new_im * 1.1 + 1e-300
    return None


def _with_clusters(res: dict, Ac, J, h, E_rad, inflations) -> dict | None:
    """Replace each group of overlapping enclosures by its cluster enclosure; ``None`` fails."""
    if not np.all(np.isfinite(res["eigs"])):
        return None
    groups = _overlap_groups(res)
    if all(len(g) == 1 for g in groups) or max(len(g) for g in groups) > MAX_CLUSTER:
        return None
    out = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in res.items()}
    # numpy gives real eigenvalues for a matrix whose spectrum is real; a cluster's
    # centres are complex in general
    out["centre"] = out["centre"].astype(complex)
    owner = np.empty(res["eigs"].size, int)
    # the cluster operator works on the eigenvalues of the balanced centre, in the order
    # of numpy's eig of that matrix: match them to the result's eigenvalues
    lam = np.linalg.eig(Ac)[0]
    for gi, g in enumerate(groups):
        owner[g] = gi
        if len(g) == 1:
            continue
        pick = [int(np.argmin(np.abs(lam - res["eigs"][i]))) for i in g]
        if len(set(pick)) != len(g):
            return None
        enc = _krawczyk_cluster(Ac, J, h, E_rad, pick, inflations)
        if enc is None:
            return None
        centres, r, sens = enc
        out["centre"][g] = centres
        out["rad_re"][g] = r
        out["rad_im"][g] = r
        out["verified"][g] = True
        out["sensitivity"][g] = sens[None, :]
        out["sensitivity_re"][g] = sens[None, :]
    # groups must be pairwise disjoint (within a group the k eigenvalues are counted by the
    # invariant subspace, so its discs may overlap)
    overlap = _overlaps(out["centre"], out["rad_re"], out["rad_im"])
    overlap &= owner[:, None] != owner[None]
    if overlap.any() or not out["verified"].all():
        return None
    out.update(disjoint=False, ok=True, route="clusters")
    return out


def _clusters(lam: np.ndarray, rel: float = CLUSTER_RTOL) -> list:
    """Groups of eigenvalues closer than ``rel`` times their modulus (connected components)."""
    near = np.abs(lam[:, None] - lam[None]) <= rel * np.maximum(
        np.maximum(np.abs(lam)[:, None], np.abs(lam)[None]), 1.0
    )
    np.fill_diagonal(near, False)
    return _components(near)


def _pseudo_radius(eps: float, nu: float, k: int) -> float:
    """Radius ``r`` with ``sum_{m<k} nu^m / r^(m+1) = 1 / eps`` (bisection; exact for k = 1).

    For an upper-triangular ``k x k`` block ``Lambda + N`` (``||N|| <= nu``), the Neumann
    series gives ``||(B - z)^-1|| <= sum_m nu^m / d^(m+1)`` with ``d`` the distance from
    ``z`` to the block's nearest eigenvalue, so ``sigma_min(B - z) <= eps`` needs ``d <= r``.
    """
    if k == 1 or nu == 0:
        return eps

    def g(r):
        return sum(nu**m / r ** (m + 1) for m in range(k)) - 1.0 / eps

    lo, hi = eps, eps + k * max(nu, eps)
    while g(hi) > 0:
        hi *= 2
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        new = (mid, hi) if g(mid) > 0 else (lo, mid)
        if new == (lo, hi):
            # a step that changes nothing is repeated by every later one
            break
        lo, hi = new
    return hi


def _disjoint(res: dict) -> bool:
    if not res["verified"].all():
        return False
    return bool(not _overlaps(res["centre"], res["rad_re"], res["rad_im"]).any())
