"""Multi-model robust stabilisation of a fixed-order controller over family members.

The LMI multi-model iteration (:func:`robust.synthesis.hinfsyn_multi`) needs a
controller that already stabilises every design member, and on the default
family the nominal H-infinity design leaves most members unstable. This module
supplies the missing step, the first phase of the nonsmooth multi-model
approach of HIFOO (Burke, Henrion, Lewis & Overton, "HIFOO - a MATLAB package
for fixed-order controller design and H-infinity optimization", IFAC ROCOND
2006; Gumussoy, Henrion, Millstone & Overton, "Multiobjective robust control
with HIFOO 2.0", IFAC ROCOND 2009): the controller's state-space entries are
tuned to minimise the largest closed-loop spectral abscissa over a set of
members, by BFGS on its (nonsmooth) objective, which Lewis & Overton ("Nonsmooth
optimization via quasi-Newton methods", Math. Programming 141 (2013) 135-163)
show to work well on such functions. Here the maximum is smoothed by a
log-sum-exp of temperature ``tau`` (rad/s) and a proximal term keeps the
controller near the synthesised one (its performance and force), so the
tuning trades as little of the H-infinity design as stability needs.

The design set grows progressively (scenario enlargement): each round adds the
sampled members on which the current controller does worst, until every sampled
member is stable with the required margin or the rounds run out. Nothing is
claimed between samples; callers validate on a held-out sample as well.

The closed loop of each member is affine in the controller data
``Omega = [[Ak, Bk], [Ck, Dk]]``: ``Acl = A0 + Bb Omega Cb`` with the member's
plant seen from the controller's signals (the Figure 5 loop cut open at the
controller, :func:`open_loop_data`), so eigenvalue gradients are exact:
``d Re(lambda) / d Omega = Re(Bb' conj(l) (Cb r)')`` for the left and right
eigenvectors ``l, r`` of each eigenvalue (``l^H r = 1``).
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np

from backhoe.analysis.sampled import open_plant
from robust.analysis.small_eig import eigvals_stack
from robust.errors import ModelStructureError, ParameterError
from robust.synthesis.minimise import bfgs_minimise
from uncertainty import validate_family

__all__ = [
    "OpenLoopData",
    "open_loop_data",
    "ForceBudget",
    "TrackingBudget",
    "closed_loop_response",
    "force_response",
    "RobustTuning",
    "tune_spectral_abscissa",
]


@dataclasses.dataclass(frozen=True)
class OpenLoopData:
    """Members' plants seen from the controller, stacked over ``N`` members.

    ``x' = A x + B v + Bu u``, ``m = C x + Du u``, ``y = Cy x``: ``v`` are the
    controller's outputs (``nv`` signals), ``m`` its inputs (``nm`` measurements),
    ``u`` the intended motion and ``y`` the cylinder position; ``n`` plant states.

    Parameters
    ----------
    A : ndarray, shape (N, n, n)
        State matrices.
    B : ndarray, shape (N, n, nv)
        Input matrices of the controller's outputs.
    C : ndarray, shape (N, nm, n)
        Output matrices of the controller's inputs.
    Bu : ndarray, shape (N, n)
        Input column of the intended motion ``u``.
    Du : ndarray, shape (N, nm)
        Feedthrough of ``u`` to the measurements.
    Cy : ndarray, shape (N, n)
        Output row of the cylinder position ``y`` (no feedthrough).
    """

    A: np.ndarray  # (N, n, n)
    B: np.ndarray  # (N, n, nv): inputs = the controller's outputs
    C: np.ndarray  # (N, nm, n): outputs = the controller's inputs
    Bu: np.ndarray  # (N, n): intended motion u
    Du: np.ndarray  # (N, nm): feedthrough of u to the measurements
    Cy: np.ndarray  # (N, n): cylinder position y (no feedthrough)


def open_loop_data(members, K, lag_s: float = 0.0) -> OpenLoopData:
    """Cut each member's Figure 5 loop open at ``K``'s signals.

    The plant's inputs are ``u`` and K's outputs, its outputs ``y`` and K's inputs
    (:func:`backhoe.analysis.sampled.open_plant`). With ``lag_s > 0`` every controller
    output reaches the plant through a first-order lag ``1 / (1 + s lag_s)``: at the
    frequencies the loop uses, its phase ``-w lag_s`` is that of a delay ``lag_s``, so a
    controller tuned on these plants keeps its decay rate when the sampled-data loop adds
    the zero-order hold's half-sample delay and the computation's (a lag of one sample
    time covers both). The lag is strictly proper, so the closed loop stays affine in the
    controller's data.

    Parameters
    ----------
    members : sequence of BDFTLoop
        Family members with the same number of states.
    K : control.StateSpace
        Controller in the loop convention; only its signal names are used.
    lag_s : float
        Time constant of the actuator lag, s (0: none).

    Returns
    -------
    OpenLoopData

    Raises
    ------
    ModelStructureError
        If a plant has a direct feedthrough from the controller's outputs, or from ``u``
        to ``y`` (only ``u`` to the measurements is allowed), or if the members' state
        counts differ.
    """
    As, Bs, Cs, Bus, Dus, Cys = [], [], [], [], [], []
    for loop in members:
        G = open_plant(loop, K)  # inputs u, K's outputs; outputs y, K's inputs
        A, B, C, D = (np.asarray(M, float) for M in (G.A, G.B, G.C, G.D))
        if np.any(D[:, 1:] != 0) or D[0, 0] != 0:
            raise ModelStructureError(
                "the plant seen from the controller has a direct feedthrough; "
                "the affine closed-loop form needs D = 0"
            )
        Bv, Cm, Bu, Cy = B[:, 1:], C[1:], B[:, 0], C[0]
        if lag_s > 0:
            n, nv = A.shape[0], Bv.shape[1]
            A = np.block([[A, Bv], [np.zeros((nv, n)), -np.eye(nv) / lag_s]])
            Bv = np.vstack([np.zeros((n, nv)), np.eye(nv) / lag_s])
            Cm = np.hstack([Cm, np.zeros((Cm.shape[0], nv))])
            Bu = np.concatenate([Bu, np.zeros(nv)])
            Cy = np.concatenate([Cy, np.zeros(nv)])
        As.append(A)
        Bs.append(Bv)
        Cs.append(Cm)
        Bus.append(Bu)
        Dus.append(D[1:, 0])
        Cys.append(Cy)
    if len({a.shape for a in As}) != 1:
        raise ModelStructureError("members must have the same number of states to be stacked")
    return OpenLoopData(*(np.array(x) for x in (As, Bs, Cs, Bus, Dus, Cys)))


def _omega(K):
    return np.block(
        [
            [np.asarray(K.A, float), np.asarray(K.B, float)],
            [np.asarray(K.C, float), np.asarray(K.D, float)],
        ]
    )


def _closed_loop(data: OpenLoopData, Om, nk):
    N, n, _ = data.A.shape
    nv, nm = data.B.shape[2], data.C.shape[1]
    Bb = np.zeros((N, n + nk, nk + nv))
    Bb[:, n:, :nk] = np.eye(nk)
    Bb[:, :n, nk:] = data.B
    Cb = np.zeros((N, nk + nm, n + nk))
    Cb[:, :nk, n:] = np.eye(nk)
    Cb[:, nk:, :n] = data.C
    A0 = np.zeros((N, n + nk, n + nk))
    A0[:, :n, :n] = data.A
    return A0 + Bb @ Om @ Cb, Bb, Cb


def spectral_abscissas(data: OpenLoopData, Om, nk) -> np.ndarray:
    """Largest closed-loop real part per member, rad/s.

    Parameters
    ----------
    data : OpenLoopData
        The members' plants seen from the controller.
    Om : ndarray, shape (nk + nv, nk + nm)
        Controller data ``[[Ak, Bk], [Ck, Dk]]``.
    nk : int
        Controller order.

    Returns
    -------
    ndarray, shape (N,)
    """
    Acl, _, _ = _closed_loop(data, Om, nk)
    return np.linalg.eigvals(Acl).real.max(axis=1)


def _eigen_gradients(data: OpenLoopData, Om, nk, floor=None):
    """All closed-loop eigenvalues (N, n) and the gradients of their real parts.

    The gradients are with respect to ``Om``: without ``floor``, of every eigenvalue, shape
    (N, n, *Om.shape); with ``floor``, of the eigenvalues whose real part exceeds it, in
    the row-major order of the mask ``w.real > floor``, shape (n_above, *Om.shape). With a
    floor, eigenvectors are computed only for the members with an eigenvalue near or above
    it (the compiled stacked eigenvalues, :func:`robust.analysis.small_eig.eigvals_stack`,
    pick them: a sixth of the cost of eigenvalues and vectors); those members' eigenvalues
    come from the same decomposition as without a floor, and the others' are all below the
    floor by more than the two computations can differ.
    """
    Acl, Bb, Cb = _closed_loop(data, Om, nk)
    if floor is None:
        w, V = np.linalg.eig(Acl)
        sel = np.arange(Acl.shape[0])
    else:
        w = eigvals_stack(Acl).astype(complex)
        # the decompositions with and without vectors agree to rounding: 1e-6 of the
        # spectrum's size keeps every member that could cross the floor in either
        slack = 1e-6 * (1.0 + np.abs(w).max(axis=1))
        sel = np.flatnonzero((w.real > floor - slack[:, None]).any(axis=1))
        V = np.zeros((0,) + Acl.shape[1:], complex)
        if sel.size:
            w[sel], V = np.linalg.eig(Acl[sel])
    L = np.conj(np.linalg.inv(V)).transpose(0, 2, 1)  # columns: left eigenvectors, l_k^H r_k = 1
    Bs, Cs = Bb[sel], Cb[sel]
    if floor is not None:
        # the selected members' eigenvalues above the floor, in the order of the full mask
        keep = w[sel].real > floor
        pick = np.nonzero(keep)
        left = np.einsum("aji,aj->ai", Bs[pick[0]], np.conj(L[pick[0], :, pick[1]]))
        right = np.einsum("aij,aj->ai", Cs[pick[0]], V[pick[0], :, pick[1]])
        return w, np.real(left[:, :, None] * right[:, None, :])
    left = np.einsum("nji,njk->nki", Bs, np.conj(L))  # (N, n_eig, nk+nv): Bb' conj(l)
    right = np.einsum("nij,njk->nki", Cs, V)  # (N, n_eig, nk+nm): Cb r
    g = np.real(left[..., :, None] * right[..., None, :])
    return w, g


def closed_loop_response(data: OpenLoopData, Om, nk, w, out="y", *, grad: bool = False):
    """Closed-loop response from the intended motion ``u`` at ``w`` rad/s, per member.

    With ``R = (jw - Acl)^-1``, ``Bcl = Bu + Bb Om Du`` and ``M = Cb R Bcl + Du`` (the
    controller's input signals):

    * controller output ``e``: ``T = e' Om M``, ``dT = p dOm M`` with
      ``p = e' + e' Om Cb R Bb``;
    * cylinder position: ``T = cy' R Bcl``, ``dT = p dOm M`` with ``p = cy' R Bb``;

    so ``d|T - r|^2 / dOm = 2 Re(conj(T - r) p M')`` for any fixed ``r``.

    Parameters
    ----------
    data : OpenLoopData
        The members' plants seen from the controller.
    Om : ndarray, shape (nk + nv, nk + nm)
        Controller data ``[[Ak, Bk], [Ck, Dk]]``.
    nk : int
        Controller order.
    w : ndarray, shape (n_w,)
        Frequencies, rad/s.
    out : "y" or int
        ``"y"`` (cylinder position) or the index of a controller output (e.g. the
        handle force).
    grad : bool
        Also return the factors of the gradient.

    Returns
    -------
    T : ndarray of complex, shape (N, n_w)
        The response of every member at every frequency.
    p : ndarray of complex, shape (N, n_w, nk + nv), or None
        Left factor of ``dT = p dOm M`` (``None`` without ``grad``).
    M : ndarray of complex, shape (N, n_w, nk + nm), or None
        Right factor (``None`` without ``grad``).
    """
    Acl, Bb, Cb = _closed_loop(data, Om, nk)
    N, n = Acl.shape[:2]
    nv = data.B.shape[2]
    Du = np.concatenate([np.zeros((N, nk)), data.Du], axis=1)  # (N, nk+nm)
    Bu = np.concatenate([data.Bu, np.zeros((N, nk))], axis=1)  # (N, n_cl)
    Bcl = Bu + np.einsum("nij,jk,nk->ni", Bb, Om, Du)
    lhs = 1j * w[None, :, None, None] * np.eye(n) - Acl[:, None]
    RB = np.linalg.solve(lhs, np.broadcast_to(Bcl[:, None, :, None], (N, w.size, n, 1)))[
        ..., 0
    ]  # (N, nw, n)
    M = np.einsum("nij,nwj->nwi", Cb, RB) + Du[:, None, :]
    if out == "y":
        cy = np.concatenate([data.Cy, np.zeros((N, nk))], axis=1)  # (N, n_cl)
        T = np.einsum("ni,nwi->nw", cy, RB)
        q, E = cy, np.zeros(nk + nv)
    else:
        E = np.zeros(nk + nv)
        E[nk + int(out)] = 1.0
        T = np.einsum("i,nwi->nw", E @ Om, M)
        q = np.einsum("i,nij->nj", E @ Om, Cb)  # (N, n_cl)
    if not grad:
        return T, None, None
    qR = np.linalg.solve(
        np.swapaxes(lhs, -1, -2), np.broadcast_to(q[:, None, :, None], (N, w.size, n, 1))
    )[..., 0]
    p = E[None, None, :] + np.einsum("nwj,njk->nwk", qR, Bb)
    return T, p, M


def _sq_gradient(err, p, M):
    """Gradient of ``|err|^2`` for ``d err = p dOm M``: (N, n_w, *Om.shape)."""
    return 2 * np.real(np.conj(err)[..., None, None] * p[..., :, None] * M[..., None, :])


def force_response(data: OpenLoopData, Om, nk, w, out: int = 0, *, grad: bool = False):
    """Closed-loop ``u -> v_out`` (a controller output) and the gradient of ``|T|^2``.

    Parameters
    ----------
    data : OpenLoopData
        The members' plants seen from the controller.
    Om : ndarray, shape (nk + nv, nk + nm)
        Controller data ``[[Ak, Bk], [Ck, Dk]]``.
    nk : int
        Controller order.
    w : ndarray, shape (n_w,)
        Frequencies, rad/s.
    out : int
        Index of the controller output (the handle force ``f`` in the designs).
    grad : bool
        Also return the gradient.

    Returns
    -------
    T : ndarray of complex, shape (N, n_w)
        The response, controller-output units per handle unit of ``u``.
    gradient : ndarray, shape (N, n_w, nk + nv, nk + nm), or None
        ``d|T|^2 / dOm`` per member and frequency (``None`` without ``grad``).
    """
    T, p, M = closed_loop_response(data, Om, nk, w, out, grad=grad)
    return T, (_sq_gradient(T, p, M) if grad else None)


def _minimise(fun, K, unit, nk, K0, max_iter):
    # the workbench's one BFGS (weak Wolfe line search, Lewis & Overton 2013), the one the
    # tuning of robust.synthesis.tuning runs: SciPy's BFGS stops at the first kink where its
    # line search loses precision, and where it stopped depended on the last bits of the
    # data (the 500-member test sample: 0.924 stable on one CPU, 0.998 on another)
    x, _, _ = bfgs_minimise(fun, (_omega(K) / unit).ravel(), max_iter)
    Om = x.reshape(unit.shape) * unit
    return ct.ss(
        Om[:nk, :nk],
        Om[:nk, nk:],
        Om[nk:, :nk],
        Om[nk:, nk:],
        inputs=K0.input_labels,
        outputs=K0.output_labels,
        name=K0.name,
    )


@dataclasses.dataclass(frozen=True)
class TrackingBudget:
    """Keep ``|Y/Y_ref - 1| <= max_error`` over ``f_hz`` (the intent band) on the members.

    ``y_ref`` is the cylinder response without BDFT and without compensation (the same
    for every member: the human is not in that path). Penalty ``weight * sum over
    members of mean over the grid of relu(|Y/Y_ref - 1| / max_error - 1)^2``.

    Parameters
    ----------
    y_ref : ndarray of complex, shape (n_f,)
        Reference response ``u -> y`` at ``f_hz`` (cylinder position per handle unit).
    max_error : float
        Largest allowed relative tracking error ``|Y/Y_ref - 1|``.
    f_hz : ndarray, shape (n_f,)
        Frequency grid, Hz.
    weight : float
        Weight of the penalty in the tuning objective.
    """

    y_ref: np.ndarray  # complex, at f_hz
    max_error: float
    f_hz: np.ndarray
    weight: float = 10.0

    def penalty(self, data, Om, nk):
        """The penalty and its gradient with respect to ``Om`` for the members of ``data``.

        Parameters
        ----------
        data : OpenLoopData
            The members the budget applies to.
        Om : ndarray, shape (nk + nv, nk + nm)
            Controller data ``[[Ak, Bk], [Ck, Dk]]``.
        nk : int
            Controller order.

        Returns
        -------
        value : float
        gradient : ndarray, shape of ``Om``
        """
        w = 2 * np.pi * np.asarray(self.f_hz, float)
        T, p, M = closed_loop_response(data, Om, nk, w, "y", grad=True)
        err = T - self.y_ref[None, :]
        rel = np.abs(err) / np.abs(self.y_ref)[None, :]
        ex = np.maximum(rel / self.max_error - 1.0, 0.0)
        val = np.sum(np.mean(ex**2, axis=1))
        # d rel / d|err|^2 = 1 / (2 |err| |y_ref|)
        coef = (
            np.where(
                ex > 0,
                2
                * ex
                / self.max_error
                / (2 * np.maximum(np.abs(err), 1e-300) * np.abs(self.y_ref)[None, :]),
                0.0,
            )
            / w.size
        )
        grad = np.einsum("nw,nwij->ij", coef, _sq_gradient(err, p, M))
        return self.weight * val, self.weight * grad


@dataclasses.dataclass(frozen=True)
class ForceBudget:
    """Handle-force budget for an intended motion of amplitude ``amplitude`` swept over ``f_hz``.

    A sine of amplitude ``A`` at ``w`` gives force amplitude ``A |T(jw)|``; a sweep
    spending equal time per decade has RMS ``A sqrt(mean |T|^2 / 2)`` over a log grid.
    The penalty is ``weight * sum over members of (relu(peak/peak_n - 1)^2 mean over
    the grid + relu(rms/rms_n - 1)^2)``.

    Parameters
    ----------
    amplitude : float
        Intended-motion amplitude, handle units.
    peak_n : float
        Peak-force budget, N.
    rms_n : float
        RMS-force budget, N.
    f_hz : ndarray
        Frequency grid of the sweep (log-spaced), Hz.
    weight : float
        Weight of the penalty in the tuning objective.
    output : int
        Index of the force ``f`` among the controller's outputs.
    """

    amplitude: float  # intended-motion amplitude, handle units
    peak_n: float
    rms_n: float
    f_hz: np.ndarray
    weight: float = 10.0
    output: int = 0  # index of the force among the controller's outputs

    def penalty(self, data, Om, nk):
        """The penalty and its gradient with respect to ``Om`` for the members of ``data``.

        Parameters
        ----------
        data : OpenLoopData
            The members the budget applies to.
        Om : ndarray, shape (nk + nv, nk + nm)
            Controller data ``[[Ak, Bk], [Ck, Dk]]``.
        nk : int
            Controller order.

        Returns
        -------
        value : float
        gradient : ndarray, shape of ``Om``
        """
        w = 2 * np.pi * np.asarray(self.f_hz, float)
        T, g = force_response(data, Om, nk, w, self.output, grad=True)
        a2 = self.amplitude**2
        mag2 = a2 * np.abs(T) ** 2
        ex = np.maximum(np.sqrt(mag2) / self.peak_n - 1.0, 0.0)  # (N, nw)
        val = np.sum(np.mean(ex**2, axis=1))
        # d ex / d|T|^2 = a2 / (2 peak_n sqrt(mag2)) where active
        dex = np.where(ex > 0, a2 / (2 * self.peak_n * np.sqrt(np.maximum(mag2, 1e-300))), 0.0)
        grad = np.einsum("nw,nwij->ij", 2 * ex * dex / w.size, g)
        ms = mag2.mean(axis=1) / 2  # (N,)
        rex = np.maximum(np.sqrt(ms) / self.rms_n - 1.0, 0.0)
        val += np.sum(rex**2)
        drex = np.where(rex > 0, 1.0 / (2 * self.rms_n * np.sqrt(np.maximum(ms, 1e-300))), 0.0)
        grad += np.einsum("n,nwij->ij", 2 * rex * drex * a2 / (2 * w.size), g)
        return self.weight * val, self.weight * grad


@dataclasses.dataclass(frozen=True)
class RobustTuning:
    """Result of :func:`tune_spectral_abscissa`.

    Parameters
    ----------
    controller : control.StateSpace
        The tuned controller (signal names of ``K0``).
    design_rows : ndarray, shape (n_design, d)
        Parameter rows of the final design set (the nominal first; columns in
        ``family.names`` order).
    alpha_design : ndarray, shape (n_design,)
        Spectral abscissa of each design member with ``controller``, rad/s.
    history : tuple of tuple
        Per round: ``(design members, worst sampled spectral abscissa in rad/s,
        fraction stable)``.
    rounds : int
        Number of rounds run (``len(history)``).
    converged : bool
        Whether every sampled member is stable with the margin.
    force_phase : dict or None
        Outcome of the second (force and tracking budget) phase: ``accepted``,
        ``worst_sampled_max_real`` (rad/s) and ``fraction_stable``; ``None`` if it
        did not run.
    chosen_round : int
        The entry of ``history`` whose controller is returned: the last when converged,
        else the one with the largest fraction stable (then the lowest worst abscissa);
        ``design_rows`` is that round's design set.
    """

    controller: ct.StateSpace
    design_rows: np.ndarray  # parameter rows of the final design set
    alpha_design: np.ndarray  # spectral abscissa per design member, rad/s
    history: tuple  # per round: (design members, worst sampled alpha, fraction stable)
    rounds: int
    converged: bool  # every sampled member stable with the margin
    force_phase: dict | None = None  # outcome of the force-budget phase (None if not run)
    chosen_round: int = -1  # the history entry whose controller is returned


def _stalled(history, patience: int) -> bool:
    """Whether none of the last ``patience`` rounds of ``history`` improved on the best of the
    rounds before them (more members stable, or as many with a lower worst abscissa)."""
    if patience < 1 or len(history) <= patience:
        return False
    best = min((-h[2], h[1]) for h in history[:-patience])
    return all((-h[2], h[1]) >= best for h in history[-patience:])


def tune_spectral_abscissa(
    family,
    samples,
    K0,
    *,
    margin: float = 0.3,
    tau: float = 0.05,
    prox: float = 1e-3,
    rounds: int = 6,
    add_per_round: int = 12,
    max_iter: int = 300,
    patience: int = 3,
    force=None,
    tracking=None,
    force_while_stabilising: bool = True,
    output_scales=None,
    actuator_lag_s: float = 0.0,
    progress=None,
) -> RobustTuning:
    """Tune ``K0``'s entries so every sampled member's closed loop decays faster than ``margin``.

    The goal is every closed-loop pole of every sampled member with real part below
    ``-margin``.

    Parameters
    ----------
    family : backhoe.Family
        The family (physical human for a force budget); its nominal member starts the
        design set.
    samples : uncertainty.SampleSet
        The scenario set; each round validates on all of it (batched) and adds the
        ``add_per_round`` worst members to the design set (which starts with the nominal).
    K0 : control.StateSpace
        Starting controller (loop convention), e.g. a reduced nominal H-infinity design.
    margin : float
        Required decay rate, rad/s: the objective stops improving below ``-margin``.
    tau : float
        Temperature of the log-sum-exp smoothing of the worst member's abscissa, rad/s.
    prox : float
        Weight of the proximal term: mean squared relative change of the controller's entries.
    rounds, add_per_round, max_iter : int
        Enlargement rounds, members added per round, BFGS iterations per round.
    patience : int
        Stop enlarging after this many rounds in a row that did not improve on the best
        round so far (more sampled members stable, or as many with a lower worst abscissa):
        the best round is the one returned, and a tuning stuck at a kink (a line search that
        cannot leave it) would otherwise repeat the same controller for every round left.
        0 never stops early.
    output_scales : dict, optional
        Typical size of the entries of an output's row (e.g. ``{"r_corr": k_psf}``), for
        outputs that ``K0`` leaves at zero; other entries are scaled by ``K0``'s own.
    force : ForceBudget, optional
        Keep the closed-loop intended-motion-to-force response within the budget (a
        quadratic penalty on the excess): on the nominal member while stabilising, on
        every design member in a second phase, once every sampled member is stable
        with the margin. ``force_while_stabilising=False`` leaves the nominal member's force
        free while stabilising (the force budget then acts only in the second phase).
    tracking : TrackingBudget, optional
        Keep the intended-motion tracking within the budget: on the nominal member while
        stabilising, on every design member in the second phase.
    force_while_stabilising : bool
        Apply the force budget on the nominal member during the stabilising rounds too.
    actuator_lag_s : float
        Time constant of a lag at the controller's outputs in the design members' plants
        (:func:`open_loop_data`; one sample time makes the tuned decay rate survive the
        1 kHz sampled-data loop); the validation of the samples, the stopping rule and the
        reported abscissas are those of the continuous loop without it.
    progress : callable, optional
        Called after each round's validation as ``progress(round, entry)``, ``entry``
        being that round's ``history`` tuple (see :class:`RobustTuning`).

    Returns
    -------
    RobustTuning

    Raises
    ------
    ParameterError
        If ``margin`` or ``tau`` is not a positive number, ``actuator_lag_s`` is negative
        or ``patience`` is not an integer >= 0.
    """
    for name, val in (("margin", margin), ("tau", tau)):
        if not (np.isfinite(val) and val > 0):
            raise ParameterError(f"{name} must be positive; got {val!r}")
    if not (np.isfinite(actuator_lag_s) and actuator_lag_s >= 0):
        raise ParameterError(
            f"actuator_lag_s must be a finite value >= 0, s; got {actuator_lag_s!r}"
        )
    if isinstance(patience, bool) or not isinstance(patience, (int, np.integer)) or patience < 0:
        raise ParameterError(f"patience must be an integer >= 0 (0: never); got {patience!r}")
    nk = K0.nstates
    Om0 = _omega(K0)
    # entrywise units of the parameters (diagonal preconditioning): the controller's
    # entries span decades
    unit = np.maximum(np.abs(Om0), 1e-3 * np.abs(Om0).max() + 1e-300)
    for name, scale in (output_scales or {}).items():
        row = nk + list(K0.output_labels).index(name)
        unit[row] = np.where(Om0[row] == 0, scale, unit[row])
    rows = [family.nominal_values()]
    K = K0
    history = []
    converged = False
    second_phase = False
    data = None
    nominal_data = (
        open_loop_data([family.member(rows[0])], K0, actuator_lag_s)
        if (force or tracking) is not None
        else None
    )

    def fun(theta):
        Om = theta.reshape(Om0.shape) * unit
        w, g = _eigen_gradients(data, Om, nk, floor=-margin)
        # log-sum-exp over every eigenvalue of every design member above the margin: smooth where
        # the rightmost mode changes (between members, or between modes of one member)
        z = (np.maximum(w.real, -margin) + margin) / tau
        zmax = z.max()
        e = np.exp(z - zmax)
        f = tau * (zmax + np.log(e.sum()))
        wts = e / e.sum() * (w.real > -margin)
        d = (Om - Om0) / unit
        val = f + prox * np.sum(d * d) / d.size
        gr = np.einsum("a,aij->ij", wts[w.real > -margin], g) + 2 * prox * d / d.size / unit
        if force is not None and (second_phase or force_while_stabilising):
            pv, pg = force.penalty(data if second_phase else nominal_data, Om, nk)
            val, gr = val + pv, gr + pg
        if tracking is not None:
            pv, pg = tracking.penalty(data if second_phase else nominal_data, Om, nk)
            val, gr = val + pv, gr + pg
        return val, (gr * unit).ravel()

    validated = []  # per history entry: the controller validated and its design set's size
    for r in range(rounds):
        v = validate_family(family, samples, controller=K)
        worst = np.argsort(v.max_real)[::-1]
        history.append((len(rows), float(v.max_real.max()), float(v.fraction_stable)))
        validated.append((K, len(rows)))
        if progress:
            progress(r, history[-1])
        if v.max_real.max() < -margin:
            converged = True
            break
        if _stalled(history, patience):
            break
        new = [samples.values[i] for i in worst[:add_per_round] if v.max_real[i] >= -margin]
        rows += new
        data = open_loop_data([family.member(x) for x in rows], K0, actuator_lag_s)

        K = _minimise(fun, K, unit, nk, K0, max_iter)
    else:
        v = validate_family(family, samples, controller=K)
        history.append((len(rows), float(v.max_real.max()), float(v.fraction_stable)))
        validated.append((K, len(rows)))
        converged = bool(v.max_real.max() < -margin)
    chosen = len(history) - 1
    if not converged:
        # the enlargement need not improve monotonically (a round fitted to the members
        # it added can lose others): keep the round with the most sampled members stable,
        # then the lowest worst abscissa (the fractions are counts: no tie on rounding)
        chosen = min(range(len(history)), key=lambda i: (-history[i][2], history[i][1], i))
        K, n_rows = validated[chosen]
        rows = rows[:n_rows]
    force_phase = None
    if (force is not None or tracking is not None) and converged:
        # second phase: the force budget on the design members, the margin kept by the same term
        data = open_loop_data([family.member(x) for x in rows], K0, actuator_lag_s)
        second_phase = True
        K_f = _minimise(fun, K, unit, nk, K0, max_iter)
        v = validate_family(family, samples, controller=K_f)
        force_phase = {
            "accepted": bool(v.max_real.max() < -margin),
            "worst_sampled_max_real": float(v.max_real.max()),
            "fraction_stable": float(v.fraction_stable),
        }
        if force_phase["accepted"]:
            K = K_f
    data = open_loop_data([family.member(x) for x in rows], K)
    alpha = spectral_abscissas(data, _omega(K), nk)
    return RobustTuning(
        K, np.array(rows), alpha, tuple(history), len(history), converged, force_phase, chosen
    )
