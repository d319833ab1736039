"""Block Gershgorin discs and the changes of basis of the eigenvalue enclosures.

The last route of :func:`robust.analysis.eigen_enclosure.enclose_eigenvalues`: where a
cluster's eigenvalues may meet inside the box, the box is brought to a block-diagonalising
basis of its centre (rounding bounded) and every eigenvalue lies in the union of discs of
the block Gershgorin theorem (Feingold & Varga, 1962), scaled to fit a target region when
one is given. Also here: the similarity that carries a box to another basis with its
rounding (the modal basis of the first route uses it) and the choice between two results.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from robust.analysis.eigen_clusters import _EPS, _clusters, _disjoint, _pseudo_radius

#: Nothing public: these are :mod:`robust.analysis.eigen_enclosure`'s own steps.
__all__: list[str] = []


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
