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

import math
from collections.abc import Callable

import numba
import numpy as np
import scipy.linalg as sla

from robust.analysis.box_subdivision import split_coordinate, subdivide
from robust.analysis.eigen_clusters import _EPS, _disjoint, _with_clusters
from robust.analysis.eigen_clusters import _pseudo_radius as _pseudo_radius
from robust.analysis.eigen_discs import _best_of, _block_discs, _to_blocks, _to_modal
from robust.analysis.eigen_discs import _block_norms as _block_norms
from robust.analysis.eigen_discs import _block_schur as _block_schur

__all__ = ["enclose_eigenvalues", "split_coordinate", "subdivide", "certify_affine_family"]


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
