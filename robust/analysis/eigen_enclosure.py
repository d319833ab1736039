"""Verified enclosures of every eigenvalue of every matrix in a parametric box.

The matrices are ``A(t) = A_c + E(t)`` for ``t`` in a box of half-widths ``h`` about its
centre, with the perturbation given in mean-value form::

    E(t) = sum_p delta_p h_p J_p + E_r,   |delta_p| <= 1,   |E_r| <= E_rad (entrywise)

(``J_p`` the midpoints of interval enclosures of ``dA/dt_p`` over the box, ``E_r`` the
remainder: the radii of those enclosures times ``h`` and the rounding of ``A_c``). The
``delta_p`` are the same real numbers in every entry, so the first-order part keeps the
correlation between entries that a plain interval matrix loses, and it stays real: a
parameter that moves a lightly damped pole along the imaginary axis does not widen the
enclosure of its real part.

Method: for each eigenpair ``(lambda~, x~)`` of ``A_c`` (``x~`` normalised to 1 in its
largest component ``u``), the eigenpairs ``(lambda~ + mu, x~ + y)``, ``y_u = 0``, of ``A``
are the zeros of ``f(y^) = (A - lambda~ I) x~ + B y^ - y^_u y`` with ``y^ = y + mu e_u``
and ``B`` = ``A - lambda~ I`` with column ``u`` replaced by ``-x~``. With ``R ~ B_c^-1``,
if the Krawczyk-type operator::

    K(Y) = -R (A - lambda~ I) x~ + (I - R B) Y + R (Y_u . Y with entry u zeroed)

evaluated over every ``A`` of the box and every ``y^`` in a rectangle ``Y`` (complex,
real and imaginary parts as intervals) lies inside ``Y``, Brouwer's fixed-point theorem
gives, for every matrix of the box, an eigenvalue in ``lambda~ + Y_u`` (S. M. Rump,
"Computational error bounds for multiple or nearly multiple eigenvalues", Linear
Algebra Appl. 324:209-226, 2001, Thm. 3.1; R. Krawczyk, Computing 4:187-201, 1969).
``Y`` is found by epsilon-inflation. When the ``n`` enclosures are pairwise disjoint
they hold ``n`` distinct eigenvalues, hence every eigenvalue of every matrix of the
box, each simple.

Enclosures and rounding: the first-order term is kept as a rectangle (real and
imaginary radii ``sum_p h_p |Re(R J_p x~)|``, ``sum_p h_p |Im(R J_p x~)|``); the
remainder, the second-order terms and the floating-point error of every product
(bounded by ``(n + 4) * 4 eps`` times the products of magnitudes) are added to both
radii through moduli. A cluster of eigenvalues that cannot be separated (a repeated or
nearly repeated eigenvalue of ``A_c``) makes the enclosures overlap: the result then
says so and certifies nothing. All matrices are first balanced by one diagonal
similarity of powers of 2 (exact in floating point; ``scipy.linalg.matrix_balance`` of
the centre), which leaves the eigenvalues and the bounds' validity unchanged.
"""

from __future__ import annotations

import collections
import math
import time
from collections.abc import Callable

import numba
import numpy as np
import scipy.linalg as sla

__all__ = ["enclose_eigenvalues", "split_coordinate", "subdivide", "certify_affine_family"]

_EPS = np.finfo(float).eps
#: Eigenvalues closer than this fraction of their modulus form one cluster (block).
CLUSTER_RTOL = 0.02
#: Largest cluster enclosed by the invariant-subspace operator.
MAX_CLUSTER = 4


def enclose_eigenvalues(
    Ac: np.ndarray,
    J: np.ndarray,
    h: np.ndarray,
    E_rad: np.ndarray,
    *,
    basis: str = "modal",
    inflations: int = 12,
    margin: Callable[[np.ndarray], np.ndarray] | None = None,
) -> dict:
    """Rectangles that enclose every eigenvalue of every matrix of a parametric box.

    Parameters
    ----------
    Ac : ndarray, shape (n, n)
        Real centre matrix.
    J : ndarray, shape (d, n, n)
        First-order directions (midpoints of the derivative enclosures).
    h : ndarray, shape (d,)
        Half-widths of the box, >= 0.
    E_rad : ndarray, shape (n, n)
        Entrywise bound of the remainder, >= 0.
    basis : str
        ``"modal"``: the operator is built both in the eigenvector basis of the (balanced)
        centre, where it contracts for boxes as wide as the eigenvalues' separation
        allows, and in the balanced coordinates (better when the eigenvectors are
        ill-conditioned), and each eigenvalue keeps the narrower of its two verified
        enclosures; ``"balanced"``: the balanced coordinates only.
    inflations : int
        Epsilon-inflation steps tried per eigenvalue.
    margin : callable, optional
        ``margin(eigs)``: distance of eigenvalues to the edge of the region the caller
        will test; when the eigenvalues cluster, the block enclosures are scaled to fit
        it (:func:`_block_discs`).

    Returns
    -------
    dict
        ``centre`` (complex, shape (n,)), ``rad_re``, ``rad_im`` (radii of the real and
        imaginary parts), ``verified`` (per eigenvalue: its operator contracted),
        ``disjoint`` (all rectangles pairwise disjoint), ``ok`` (every eigenvalue
        verified and the rectangles disjoint: every eigenvalue of every matrix lies in
        their union), ``eigs`` (the eigenvalues of ``Ac``), ``sensitivity`` (shape
        (n, d): ``h_p |d lambda_i / d t_p|`` to first order, for choosing a split),
        ``sensitivity_re`` (the same for the real parts), ``route`` (``"krawczyk"``:
        disjoint verified enclosures; ``"clusters"``: overlapping enclosures replaced by
        those of the clusters' invariant subspaces, disjoint between groups, see
        :func:`_krawczyk_cluster`; ``"blocks"``: discs from a block-diagonal form that
        hold every eigenvalue but may overlap, see :func:`_block_discs`).
    """
    Ac = np.asarray(Ac, float)
    n = Ac.shape[0]
    J = np.asarray(J, float).reshape(-1, n, n)
    h = np.asarray(h, float)
    E_rad = np.asarray(E_rad, float)
    if n:
        # a diagonal similarity by powers of 2 (exact in floating point) balances the
        # centre and is applied alike to the directions and the remainder bound
        _, (sc, _) = sla.matrix_balance(Ac, permute=False, separate=True)
        Ac = Ac / sc[:, None] * sc[None, :]
        J = J / sc[None, :, None] * sc[None, None, :]
        E_rad = E_rad / sc[:, None] * sc[None, :]
    plain = _krawczyk(Ac, J, h, E_rad, inflations)
    if basis != "modal" or not n:
        return dict(plain, route="krawczyk")
    moved = _to_modal(Ac, J, h, E_rad)
    if moved is None:
        return dict(plain, route="krawczyk")
    best = _best_of(_krawczyk(*moved[:2], h, moved[2], inflations), plain)
    if best["ok"]:
        return dict(best, route="krawczyk")
    # eigenvalues whose enclosures overlap: enclose each group's invariant subspace at once
    # (Rump's operator for clusters); the groups' enclosures must then be disjoint
    grouped = _with_clusters(best, Ac, J, h, E_rad, inflations)
    if grouped is not None:
        return grouped
    # a cluster of eigenvalues that the box lets meet: the counting argument of disjoint
    # enclosures is lost; discs from the pseudospectra of a block-diagonal form still hold
    # every eigenvalue
    blocked = _to_blocks(Ac, J, h, E_rad)
    return best if blocked is None else _block_discs(best, *blocked, h, margin)


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


def _to_blocks(Ac, J, h, E_rad):
    """The box in a block-diagonalising basis of the centre, with its rounding bounded.

    ``T = [v_i for isolated eigenvalues | orthonormal bases of clusters' invariant
    subspaces]``: well conditioned where the eigenvector basis is not. As in
    :func:`_to_modal`, the exact similarity with the computed inverse ``W`` puts the
    rounding and ``Phi W A T`` into the remainder. Returns ``(A1, J1, E1, sizes,
    eigenvalues in the blocks' order)`` or ``None``.
    """
    try:
        lam, V = np.linalg.eig(Ac)
    except np.linalg.LinAlgError:
        return None
    groups = _clusters(lam)
    cols = []
    for g in groups:
        if len(g) == 1:
            v = V[:, g[0]]
            cols.append(v[:, None] / np.linalg.norm(v))
        else:
            q, _ = np.linalg.qr(V[:, g])
            cols.append(q)
    moved = _similarity(Ac, J, h, E_rad, np.hstack(cols))
    if moved is None:
        return None
    order = [i for g in groups for i in g]
    return (*moved, [len(g) for g in groups], lam[order])


def _gershgorin_scaling(N, schur, margin) -> np.ndarray:
    """Block scaling ``x > 0`` that shrinks each block's Gershgorin radius below its budget.

    ``eps_max_j`` is the largest ``eps`` whose pseudospectral discs stay within
    ``margin`` of block ``j``'s eigenvalues; if ``rho(diag(1/eps_max) N) < 1`` its Perron
    vector ``x`` gives ``(N x)_j / x_j < eps_max_j`` for every ``j``. Without a margin,
    or when no scaling fits, ``x = 1``.
    """
    m = N.shape[0]
    if margin is None or m == 0:
        return np.ones(m)
    budget = np.empty(m)
    for j, (ev, nu) in enumerate(schur):
        d = float(np.min(margin(ev)))
        if not d > 0:
            return np.ones(m)
        k = ev.size
        budget[j] = 1.0 / sum(nu**q / d ** (q + 1) for q in range(k))
    M = N / budget[:, None] + 1e-300
    w, V = np.linalg.eig(M)
    i = int(np.argmax(w.real))
    x = np.abs(V[:, i].real)
    if not (w[i].real < 1 and np.all(x > 0) and np.all(np.isfinite(x))):
        return np.ones(m)
    return x / x.max()


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


#: Magnitudes whose square neither underflows nor overflows: there ``sqrt(x * x)`` is ``|x|``
#: exactly in binary floating point (round to nearest).
_SQUARE_SAFE = (1e-150, 1e150)


def _block_norms(F: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Frobenius norms of the blocks ``F[starts[j]:starts[j+1], starts[l]:starts[l+1]]``.

    Exactly :func:`numpy.linalg.norm` of each block (``sqrt`` of the block's dot product with
    itself): the norm of a ``1 x 1`` block is its entry's magnitude (``sqrt(x * x) = |x|``
    where the square is exact enough, :data:`_SQUARE_SAFE`), so only the blocks of a cluster
    and entries outside that range are computed one by one (most blocks are ``1 x 1``: a
    35-state loop has about a thousand).
    """
    first = starts[:-1]
    single = np.diff(starts) == 1
    N = np.abs(F[np.ix_(first, first)])
    lo, hi = _SQUARE_SAFE
    one_by_one = np.outer(single, single) & ((N == 0) | ((N >= lo) & (N <= hi)))
    for j, k in zip(*np.nonzero(~one_by_one)):
        N[j, k] = np.linalg.norm(F[starts[j] : starts[j + 1], starts[k] : starts[k + 1]])
    return N


#: Magnitudes of a ``1 x 1`` matrix that ``zgees`` does not scale (its ``SMLNUM`` is
#: ``sqrt(safe minimum) / eps``, about 6.7e-139, and ``BIGNUM`` its inverse), with room to spare.
_UNSCALED = (1e-130, 1e130)


def _block_schur(B: np.ndarray) -> tuple[np.ndarray, np.float64]:
    """A diagonal block's eigenvalues from its complex Schur form ``T`` and ``||triu(T, 1)||_2``.

    A ``1 x 1`` block is its own Schur form: LAPACK's ``zgees`` returns the entry as it is,
    with nothing above the diagonal, unless the entry lies outside the range where it is not
    scaled first (about 7e-139 to 1e138, :data:`_UNSCALED`; scaled, its last bit may change).
    In that range, or for 0, the entry and 0 are returned without the call: the same numbers
    (most blocks are ``1 x 1``, and the call cost more than the rest of the discs).
    """
    if B.shape == (1, 1):
        x = float(np.abs(B[0, 0]))
        if x == 0.0 or _UNSCALED[0] <= x <= _UNSCALED[1]:
            return B[0].astype(complex), np.float64(0.0)
    T, _ = sla.schur(B, output="complex")
    return np.diag(T), np.linalg.norm(np.triu(T, 1), 2)


def _block_discs(res: dict, A1, J1, E1, sizes, lam, h, margin=None) -> dict:
    """Discs about the centre's eigenvalues that hold every eigenvalue of every matrix.

    In the block basis a matrix of the box is exactly ``D + F`` with ``D`` block
    diagonal (``1 x 1`` blocks for isolated eigenvalues, a ``k x k`` block per cluster)
    and ``|F| <= |A1 - D| + sum_p h_p |J1_p| + E1`` entrywise. By the block Gershgorin
    theorem (D. G. Feingold & R. S. Varga, Pacific J. Math. 12:1241-1250, 1962) every
    eigenvalue lies in some set ``{z : sigma_min(D_j - z) <= eps_j}``,
    ``eps_j = ||F_jj|| + sum_{l != j} ||F_jl||``: a disc of radius ``eps_j`` about an
    isolated eigenvalue, discs of radius :func:`_pseudo_radius` about a cluster's
    eigenvalues (the block's Schur form bounds its departure from normality; a
    near-double eigenvalue gives the square-root growth of a defective one). The discs
    need not be disjoint: no counting is needed to place every eigenvalue in their
    union. Returned as squares (``rad_re = rad_im``).

    Gershgorin sets depend on the scaling of the blocks: with ``margin(ev)``, the distance
    of eigenvalues to the edge of a target region, a positive block scaling ``x`` (the
    Perron vector of ``diag(1 / eps_max) N``, ``N`` the block norms of ``F``; Varga,
    *Gersgorin and His Circles*, Springer 2004, ch. 1) makes every disc fit when any
    scaling can.
    """
    n = A1.shape[0]
    gam = (n + 4) * 4 * _EPS
    starts = np.cumsum([0, *sizes])
    D = np.zeros_like(A1)
    for a, b in zip(starts[:-1], starts[1:]):
        D[a:b, a:b] = A1[a:b, a:b]
    Fabs = np.abs(A1 - D) + E1 + np.einsum("p,pab->ab", h, np.abs(J1))
    Fabs = Fabs * (1 + gam) + gam * np.abs(A1)
    if not np.all(np.isfinite(Fabs)):
        return res
    blocks = list(zip(starts[:-1], starts[1:]))
    N = _block_norms(Fabs, starts)
    schur = [_block_schur(D[a:b, a:b]) for a, b in blocks]
    x = _gershgorin_scaling(N, schur, margin)
    centre = np.empty(n, complex)
    rad = np.empty(n)
    for j, (a, b) in enumerate(blocks):
        # the blocks scaled by diag(x_j I): a similarity, so the theorem holds for it
        ev, nu = schur[j]
        # the computed Schur form is exactly that of the block plus a perturbation below
        # k * 8 eps ||B||_1, added to the block's Gershgorin radius
        eps = float(N[j] @ x) / x[j] + (b - a) * 8 * _EPS * np.abs(D[a:b, a:b]).sum()
        centre[a:b], rad[a:b] = ev, _pseudo_radius(eps, nu, b - a)
    out = dict(res)
    out.update(
        centre=centre,
        rad_re=rad,
        rad_im=rad.copy(),
        verified=np.ones(n, bool),
        disjoint=False,
        ok=True,
        route="blocks",
        eigs=lam,
    )
    return out


def _best_of(a: dict, b: dict) -> dict:
    """Per eigenvalue the narrower verified enclosure of two runs (each rectangle is a
    valid statement on its own), matched by the centre's eigenvalues; disjointness is
    checked again on the combination."""
    if not np.all(np.isfinite(a["eigs"])) or not np.all(np.isfinite(b["eigs"])):
        return a if a["ok"] else b
    n = len(a["eigs"])
    cost = np.abs(a["eigs"][:, None] - b["eigs"][None])
    match = np.argmin(cost, axis=1)
    if len(set(match.tolist())) != n:
        return a if a["ok"] else b
    out = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in a.items()}
    take = b["verified"][match] & (
        ~a["verified"] | (b["rad_re"][match] + b["rad_im"][match] < a["rad_re"] + a["rad_im"])
    )
    for key in ("centre", "rad_re", "rad_im", "verified"):
        out[key][take] = b[key][match][take]
    out["disjoint"] = _disjoint(out)
    out["ok"] = out["disjoint"]
    return out


def _disjoint(res: dict) -> bool:
    if not res["verified"].all():
        return False
    return bool(not _overlaps(res["centre"], res["rad_re"], res["rad_im"]).any())


def _similarity(Ac, J, h, E_rad, T):
    """The box in the basis ``T``, exactly: ``(A1, J1, E1)`` or ``None``.

    With ``W`` the computed inverse of ``T``, the exact similarity is
    ``T^-1 A T = (I + Phi) W A T`` with ``||Phi|| <= f / (1 - f)``, ``f >= ||I - W T||``; the
    term ``Phi W A T`` and the rounding of the products ``W A_c T``, ``W J_p T`` and
    ``W E T`` go into the remainder ``E1``. ``None`` when ``T`` is too ill-conditioned.
    """
    n = Ac.shape[0]
    try:
        W = np.linalg.inv(T)
    except np.linalg.LinAlgError:
        return None
    if not (np.all(np.isfinite(T)) and np.all(np.isfinite(W))):
        return None
    gam = 2 * (n + 4) * 4 * _EPS
    aW, aT = np.abs(W), np.abs(T)
    f = np.linalg.norm(np.eye(n) - W @ T) + gam * np.linalg.norm(aW @ aT)
    if not f < 0.25:
        return None
    A1 = W @ Ac @ T
    J1 = W[None] @ J @ T[None]
    E1 = (aW @ E_rad @ aT) * (1 + gam)
    E1 += gam * (aW @ np.abs(Ac) @ aT)
    E1 += gam * np.einsum("p,pab->ab", h, aW[None] @ np.abs(J) @ aT[None])
    phi = f / (1 - f)
    size = np.linalg.norm(A1) + np.einsum("p,p->", h, np.linalg.norm(J1, axis=(1, 2)))
    E1 += phi * (size + np.linalg.norm(E1)) * (1 + gam)
    return A1, J1, E1


def _to_modal(Ac, J, h, E_rad):
    """The box in the eigenvector basis ``T`` of the centre (:func:`_similarity`)."""
    try:
        _, T = np.linalg.eig(Ac)
    except np.linalg.LinAlgError:
        return None
    return _similarity(Ac, J, h, E_rad, T / np.linalg.norm(T, axis=0))


#: Rows of the stacked ``R`` per product in :func:`_weighted_product_moduli` (their temporaries
#: stay in the cache: one product of all rows at once took twice as long).
_ROWS_PER_PRODUCT = 64


def _weighted_product_moduli(R: np.ndarray, J: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``sum_p h_p |R_i J_p|`` for every ``i``, shape ``(n, n, n)``.

    Every ``R_i J_p`` comes out of matrix products of the stacked ``R`` (rows ``(i, a)``, in
    blocks) and the side-by-side ``J`` (columns ``(c, p)``), in real and imaginary parts (a
    real ``J`` takes two real products, where a complex product would multiply its zeros;
    the modulus of the parts costs less than that of complex numbers); the moduli are
    weighted over ``p`` in one matrix-vector product. The batched products ``R_i J_p`` this
    replaces took a third of a Krawczyk step.
    """
    n, d = R.shape[0], J.shape[0]
    Js = J.transpose(1, 2, 0).reshape(n, n * d)
    Rs = R.reshape(n * n, n)

    def parts(M):
        # contiguous parts: a strided operand would be copied at every product
        if np.iscomplexobj(M):
            return np.ascontiguousarray(M.real), np.ascontiguousarray(M.imag)
        return M, None

    (Rr, Ri), (Jr, Ji) = parts(Rs), parts(Js)
    out = np.empty(n * n * n)
    for a in range(0, n * n, _ROWS_PER_PRODUCT):
        b = min(a + _ROWS_PER_PRODUCT, n * n)
        re = Rr[a:b] @ Jr
        if Ri is not None and Ji is not None:
            re -= Ri[a:b] @ Ji
            im = Ri[a:b] @ Jr + Rr[a:b] @ Ji
        elif Ri is not None:
            im = Ri[a:b] @ Jr
        elif Ji is not None:
            im = Rr[a:b] @ Ji
        else:
            im = None
        if im is None:
            np.abs(re, out=re)
        else:
            re *= re
            im *= im
            re += im
            np.sqrt(re, out=re)
        out[a * n : b * n] = re.reshape((b - a) * n, d) @ h
    return out.reshape(n, n, n)


def _krawczyk(Ac, J, h, E_rad, inflations):
    n = Ac.shape[0]
    d = J.shape[0]
    fail = {
        "centre": np.zeros(n, complex),
        "rad_re": np.full(n, np.inf),
        "rad_im": np.full(n, np.inf),
        "verified": np.zeros(n, bool),
        "disjoint": False,
        "ok": False,
        "eigs": np.full(n, np.nan + 0j),
        "sensitivity": np.ones((n, d)),
        "sensitivity_re": np.ones((n, d)),
    }
    if n == 0:
        return dict(
            fail,
            ok=True,
            disjoint=True,
            sensitivity=np.zeros((0, d)),
            sensitivity_re=np.zeros((0, d)),
        )
    try:
        lam, X = np.linalg.eig(Ac)
    except np.linalg.LinAlgError:
        return fail
    if not (np.all(np.isfinite(lam)) and np.all(np.isfinite(X))):
        return fail
    u = np.argmax(np.abs(X), axis=0)
    X = X / X[u, np.arange(n)]  # each eigenvector 1 in its largest component
    eye = np.eye(n)
    Bc = Ac[None] - lam[:, None, None] * eye  # (n_eig, n, n): A_c - lambda_i I
    r_c = np.einsum("iab,bi->ia", Bc, X)  # residuals (A_c - lambda_i I) x_i
    absBx = np.einsum("iab,bi->ia", np.abs(Bc), np.abs(X))
    B = Bc.copy()
    B[np.arange(n), :, u] = -X.T
    try:
        R = np.linalg.inv(B)
    except np.linalg.LinAlgError:
        return dict(fail, eigs=lam)
    if not np.all(np.isfinite(R)):
        return dict(fail, eigs=lam)
    gam = (n + 4) * 4 * _EPS
    aR = np.abs(R)
    zc = -np.einsum("iab,ib->ia", R, r_c)
    err = gam * (np.einsum("iab,ib->ia", aR, absBx) + np.abs(zc))
    # first-order term, kept as a rectangle: R_i J_p x_i, shape (n_eig, d, n), from
    # J_p X as one product and R_i (J_p x_i)_p as one batched product (BLAS)
    JX = (J.reshape(d * n, n) @ X).reshape(d, n, n)  # [p, b, i]: J_p x_i
    G = (R @ JX.transpose(2, 1, 0)).transpose(0, 2, 1)
    rho_re = np.einsum("p,ipa->ia", h, np.abs(G.real))
    rho_im = np.einsum("p,ipa->ia", h, np.abs(G.imag))
    # rounding of J_p x_i: |R_i| sum_p h_p |J_p| |x_i|
    hJ = np.tensordot(h, np.abs(J), axes=1)
    err += gam * np.einsum("iab,bi->ia", aR, hJ @ np.abs(X))
    # remainder through moduli
    unstr = np.einsum("iab,bi->ia", aR, E_rad @ np.abs(X)) + err
    # |I - R B| with the perturbation of B (column u of E removed) and rounding
    # (first-order part per parameter, so |R_i J_p| is not overestimated by |R_i| |J_p|)
    Cabs = np.abs(eye[None] - R @ B) + gam * (aR @ np.abs(B))
    # sum_p h_p |R_i J_p| (_weighted_product_moduli); the rounding term sum_p h_p |R_i| |J_p|
    # is |R_i| (sum_p h_p |J_p|)
    RJ = _weighted_product_moduli(R, J, h)
    RJ += gam * (aR @ hJ)
    Er = np.repeat(E_rad[None], n, axis=0)
    RJ += aR @ Er
    RJ[np.arange(n), :, u] = 0.0
    Cabs += RJ
    base_re, base_im = rho_re + unstr, rho_im + unstr
    w_re, w_im = base_re * 1.1 + 1e-300, base_im * 1.1 + 1e-300
    w_re, w_im, verified = _inflation(
        np.ascontiguousarray(zc),
        w_re,
        w_im,
        u.astype(np.int64),
        np.ascontiguousarray(Cabs),
        np.ascontiguousarray(aR),
        base_re,
        base_im,
        gam,
        int(inflations),
        np.finfo(float).tiny,
    )
    idx = np.arange(n)
    centre = lam + zc[idx, u]
    rad_re = np.where(verified, w_re[idx, u] + gam * np.abs(centre), np.inf)
    rad_im = np.where(verified, w_im[idx, u] + gam * np.abs(centre), np.inf)
    disjoint = _disjoint(
        {"centre": centre, "rad_re": rad_re, "rad_im": rad_im, "verified": verified}
    )
    sens = h[None, :] * np.abs(G[idx, :, u])
    sens_re = h[None, :] * np.abs(G[idx, :, u].real)
    return {
        "centre": centre,
        "rad_re": rad_re,
        "rad_im": rad_im,
        "verified": verified,
        "disjoint": disjoint,
        "ok": disjoint,
        "eigs": lam,
        "sensitivity": sens,
        "sensitivity_re": sens_re,
    }


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _inflation(zc, w_re, w_im, u, Cabs, aR, base_re, base_im, gam, inflations, tiny):
    """Epsilon-inflation of every eigenvalue's operator: ``(w_re, w_im, verified)``.

    Per eigenvalue ``i`` (the rows are independent), up to ``inflations`` times: the
    operator's bound over the rectangle ``zc_i +- (w_re_i, w_im_i)``,
    ``s = (Cabs_i |Y| + |R_i| (|Y_u| |Y| with entry u zeroed)) (1 + gam) + tiny`` with
    ``|Y| = |zc_i| + hypot(w_re_i, w_im_i)``; the rectangle is verified when
    ``base + s`` lies strictly inside it, else it is inflated to ``1.1 (base + s)``. A
    diverging row (overflow, NaN) just fails. The sums of ``n`` non-negative terms have a
    relative rounding error below ``gam`` in any order. Compiled: the loop in NumPy, a
    dozen small array operations per step, took a third of an enclosure.
    """
    n = zc.shape[0]
    w_re = w_re.copy()
    w_im = w_im.copy()
    verified = np.zeros(n, np.bool_)
    absY = np.empty(n)
    new_re = np.empty(n)
    new_im = np.empty(n)
    for i in range(n):
        ui = u[i]
        for _ in range(inflations):
            for a in range(n):
                absY[a] = abs(zc[i, a]) + np.hypot(w_re[i, a], w_im[i, a])
            yu = absY[ui]
            inside = True
            for a in range(n):
                lin = 0.0
                quad = 0.0
                for b in range(n):
                    lin += Cabs[i, a, b] * absY[b]
                    if b != ui:
                        quad += aR[i, a, b] * (yu * absY[b])
                s = (lin + quad) * (1 + gam) + tiny
                new_re[a] = base_re[i, a] + s
                new_im[a] = base_im[i, a] + s
                if not (new_re[a] < w_re[i, a] and new_im[a] < w_im[i, a]):
                    inside = False
            if inside:
                verified[i] = True
                break
            for a in range(n):
                w_re[i, a] = new_re[a] * 1.1 + 1e-300
                w_im[i, a] = new_im[a] * 1.1 + 1e-300
    return w_re, w_im, verified


def split_coordinate(
    res: dict,
    decay_rate: float,
    open_: np.ndarray,
    margins: np.ndarray | None = None,
    remainder: np.ndarray | None = None,
) -> int:
    """The coordinate to halve when a box fails: the one that moves the eigenvalues most
    relative to their distance to the line ``Re s = -decay_rate``.

    A coordinate moves the eigenvalues through the first-order term (``sensitivity``) and
    through the spread of its derivative over the box (``remainder``): a parameter that
    enters at second order about the centre (a derivative zero there) has no first-order
    sensitivity but still widens every enclosure, and halving it shrinks that spread.

    Parameters
    ----------
    res : dict
        A result of :func:`enclose_eigenvalues` (its ``eigs`` and ``sensitivity``).
    decay_rate : float
        The required decay rate, >= 0.
    open_ : ndarray of bool, shape (d,)
        Coordinates with a nonzero width (only those can be halved).
    margins : ndarray, shape (n,), optional
        Each eigenvalue's distance to the edge of the region (default: to the line
        ``Re s = -decay_rate``).
    remainder : ndarray, shape (d,), optional
        Each coordinate's share of the remainder bound, ``h_p ||rad(dA/dt_p)||_2`` (added
        to every eigenvalue's sensitivity to it).
    """
    if margins is None:
        margins = -(res["eigs"].real + decay_rate)
    margins = np.maximum(np.asarray(margins, float), 1e-9)
    sens = res["sensitivity"]
    if remainder is not None:
        sens = sens + np.asarray(remainder, float)[None, :]
    score = (sens / margins[:, None]).sum(axis=0)
    score = np.where(open_, np.nan_to_num(score, nan=0.0, posinf=1e300), -1.0)
    return int(np.argmax(score))


def subdivide(
    certify: Callable[[np.ndarray, np.ndarray], dict],
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    max_boxes: int,
    deadline: float = math.inf,
    wave: int = 1,
    certify_many: Callable[[list], list] | None = None,
) -> tuple[bool, dict]:
    """Branch and bound: certify a box by certifying sub-boxes, halving the ones that fail.

    The boxes wait in a queue (breadth first: the larger boxes, which fail more often, are
    tried before their descendants). Each step takes up to ``wave`` boxes from its front
    and certifies them together (``certify_many``, e.g. on several processes), then reads
    the answers in the order taken. Whether the box is certified does not depend on
    ``wave``: every sub-box's answer and split depend on that sub-box alone, so the tree
    of sub-boxes is the same, and the box is certified exactly when that tree holds at most
    ``max_boxes`` boxes and none whose centre violates; only the statistics of a failure
    (boxes tried, the reason met first) do. The search stops as soon as the boxes tried
    plus those waiting exceed ``max_boxes``: each waiting box is a box of the tree, so the
    tree cannot fit, and the boxes it would still try cannot change the verdict. Every
    failed box leaves one more waiting, so that stop comes after about ``max_boxes / 2``
    failures; breadth first, few certified boxes are tried before them (a scale of the
    robust margin searches that fails on its budget: about 207 boxes of 400 tried, against
    207-399 depth first, the same verdicts).

    Parameters
    ----------
    certify : callable
        ``certify(lo, hi)`` returns a dict with ``certified`` (bool), ``centre_violates``
        (bool: the box holds a point that fails, so no subdivision can succeed), ``check``
        (float, < 0 when certified) and ``split`` (the coordinate to halve on failure).
    lo, hi : ndarray, shape (d,)
        The box.
    max_boxes : int
        Boxes tried before giving up (sets the result on every machine).
    deadline : float
        ``time.perf_counter()`` value after which the search stops (a safety limit; the
        statistics say when it was hit).
    wave : int
        Boxes taken from the queue per step (1: one at a time).
    certify_many : callable, optional
        ``certify_many([(lo, hi), ...])`` returns the answers of ``certify`` for those boxes,
        in order (default: ``certify`` on each in turn).

    Returns
    -------
    certified : bool
    stats : dict
        ``boxes`` tried, ``certified_boxes``, ``worst_check`` over the certified boxes,
        ``reason``, ``routes`` (certified boxes per ``route`` named by ``certify``) and,
        when the budget is exceeded, ``pending`` (boxes left waiting).
    """
    many = certify_many or (lambda boxes: [certify(a, b) for a, b in boxes])
    queue = collections.deque([(np.asarray(lo, float), np.asarray(hi, float))])
    stats = {"boxes": 0, "certified_boxes": 0, "worst_check": -math.inf}
    while queue:
        # every box waiting in the queue is one more box of the tree: once the boxes tried
        # and those waiting exceed the budget, the tree cannot fit in it (the same verdict as
        # trying them, at about half the cost of a failure)
        if stats["boxes"] + len(queue) > max_boxes:
            return False, dict(stats, reason="box budget", pending=len(queue))
        if time.perf_counter() > deadline:
            return False, dict(stats, reason="time limit (result depends on the machine)")
        batch = [queue.popleft() for _ in range(min(wave, len(queue), max_boxes - stats["boxes"]))]
        stats["boxes"] += len(batch)
        for (a, b), res in zip(batch, many(batch)):
            if res["certified"]:
                stats["certified_boxes"] += 1
                if res.get("route"):
                    routes = stats.setdefault("routes", {})
                    routes[res["route"]] = routes.get(res["route"], 0) + 1
                stats["worst_check"] = max(stats["worst_check"], float(res["check"]))
                continue
            if res["centre_violates"]:
                return False, dict(stats, reason="a member violates the region")
            j = int(res["split"])
            mid = (a[j] + b[j]) / 2
            b1, a2 = b.copy(), a.copy()
            b1[j], a2[j] = mid, mid
            queue.extend([(a, b1), (a2, b)])
    return True, dict(stats, reason="certified")


def certify_affine_family(
    A0,
    J,
    lo,
    hi,
    *,
    decay_rate: float = 0.0,
    max_boxes: int = 400,
) -> tuple[bool, dict]:
    """Certify that every ``A0 + sum_p q_p J_p``, ``lo <= q <= hi``, has its eigenvalues left
    of ``-decay_rate``.

    The affine case of the enclosure (no remainder beyond rounding), with subdivision: e.g.
    the companion matrices of an interval polynomial, whose answer Kharitonov's theorem
    gives in closed form.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        Constant part.
    J : array_like, shape (d, n, n)
        Directions.
    lo, hi : array_like, shape (d,)
        The box of the coefficients ``q``.
    decay_rate : float
        Required decay rate, >= 0.
    max_boxes : int
        Sub-boxes tried.

    Returns
    -------
    certified : bool
    stats : dict
        As :func:`subdivide`.
    """
    A0 = np.asarray(A0, float)
    J = np.asarray(J, float)
    n = A0.shape[0]
    a = float(decay_rate)

    def certify(lo_q, u):
        c, h = (lo_q + u) / 2, (u - lo_q) / 2
        Ac = A0 + np.einsum("p,pab->ab", c, J)
        rnd = (
            (J.shape[0] + 2)
            * 4
            * _EPS
            * (np.abs(A0) + np.einsum("p,pab->ab", np.abs(c), np.abs(J)))
        )
        res = enclose_eigenvalues(Ac, J, h, rnd)
        if not np.all(np.isfinite(res["eigs"])):
            res = dict(res, eigs=np.linalg.eigvals(Ac))
        out = {
            "certified": False,
            "centre_violates": bool(np.max(res["eigs"].real) + a >= 0),
            "check": math.inf,
            "split": split_coordinate(res, a, u > lo_q),
        }
        if res["ok"]:
            out["check"] = float(np.max(res["centre"].real + res["rad_re"]) + a)
            out["certified"] = out["check"] < 0
        return out

    if n == 0:
        return True, {"boxes": 0, "certified_boxes": 0, "worst_check": -math.inf, "reason": "empty"}
    return subdivide(certify, np.asarray(lo, float), np.asarray(hi, float), max_boxes=max_boxes)
