"""Standing assumptions of H-infinity output-feedback synthesis, checked before any solve.

* continuous time (only continuous-time synthesis is implemented);
* ``(A, B2)`` stabilisable and ``(C2, A)`` detectable: PBH rank tests at every
  mode that is not stable in the sense of :mod:`robust.analysis.stability`;
* regularity: ``D12`` of full column rank and ``D21`` of full row rank.

Singular problems are refused rather than regularised: the messages say which
penalty or noise channel to add to the generalized plant, so that the
regularisation is visible in the design.

Rank decisions are made in the coordinates the LMIs are solved in
(:class:`robust.synthesis.scaling.PlantScaling`: balanced realization, unit
control and measurement channels), so they do not depend on how the plant's
states happen to be scaled.
"""

from __future__ import annotations

import numpy as np

from robust.analysis.stability import stable_mask
from robust.errors import AssumptionError, ModelStructureError, ParameterError
from robust.synthesis.genplant import GeneralizedPlant
from robust.synthesis.lmi import PlantBlocks
from robust.synthesis.scaling import PlantScaling
from robust.synthesis.state_scaling import diagonal_balance

__all__ = [
    "check_detectable",
    "check_hinf_assumptions",
    "check_regularity",
    "check_stabilisable",
    "pbh_failures",
]


def pbh_failures(A, M, *, side: str, w0: float = 1.0, rank_rtol: float = 1e-9) -> list:
    """Modes of ``A`` that are not stable and at which the PBH rank test fails.

    A mode ``lambda`` of ``A`` (in units of ``w0`` rad/s) is tested unless
    ``w0 * lambda`` is stable (:func:`robust.analysis.stability.stable_mask`).
    ``A`` is first balanced by a diagonal similarity
    (:func:`robust.synthesis.scaling.diagonal_balance`, transforming ``M`` with
    it), and the columns (``side="right"``: ``M = B2``) or rows (``side="left"``:
    ``M = C2``) of ``M`` are normalised to unit length, so the signals' units do
    not matter; rank is decided relative to the largest singular value of
    ``[A - lambda I, M]`` (or its transposed form).  Call it in well-scaled state
    coordinates (:func:`check_stabilisable` uses those of
    :class:`robust.synthesis.scaling.PlantScaling`): a rank decision is only as
    good as the coordinates.

    Parameters
    ----------
    A : numpy.ndarray, shape (n, n)
        State matrix, in time units of ``1 / w0`` s.
    M : numpy.ndarray
        ``B2`` (shape (n, nu)) for ``side="right"``, ``C2`` (shape (ny, n)) for
        ``side="left"``.
    side : {"right", "left"}
        Controllability (right) or observability (left) test.
    w0 : float
        Time scale of ``A``, rad/s: the modes in rad/s are ``w0 * eig(A)``.
    rank_rtol : float
        Rank threshold relative to the largest singular value.

    Returns
    -------
    list of complex
        The failing modes, rad/s.
    """
    if side not in ("right", "left"):
        raise ParameterError(f"side must be 'right' or 'left'; got {side!r}")
    n = A.shape[0]
    if n == 0:
        return []
    t = diagonal_balance(A)
    A = A * (1.0 / t)[:, None] * t[None, :]
    if side == "right":
        M = M / t[:, None]
        M = M / np.maximum(np.linalg.norm(M, axis=0), 1e-300)[None, :]
    else:
        M = M * t[None, :]
        M = M / np.maximum(np.linalg.norm(M, axis=1), 1e-300)[:, None]
    bad = []
    for lam in np.linalg.eigvals(A):
        if stable_mask(lam * w0):
            continue
        E = A - lam * np.eye(n)
        T = np.hstack([E, M]) if side == "right" else np.vstack([E, M])
        s = np.linalg.svd(T, compute_uv=False)
        if s[n - 1] <= rank_rtol * s[0]:
            bad.append(lam * w0)
    return bad


def _scaled(blocks: PlantBlocks, scaling: PlantScaling | None):
    scaling = PlantScaling.fit(blocks) if scaling is None else scaling
    return scaling.apply(blocks), scaling.time.w0


def _modes(bad) -> list:
    return np.round(np.asarray(bad), 6).tolist()


def check_stabilisable(blocks: PlantBlocks, *, scaling: PlantScaling | None = None) -> None:
    """Raise :class:`~robust.errors.AssumptionError` unless ``(A, B2)`` is stabilisable.

    Parameters
    ----------
    blocks : PlantBlocks
        Plant in original coordinates.
    scaling : PlantScaling, optional
        Coordinates of the rank decisions (default: ``PlantScaling.fit(blocks)``).

    Raises
    ------
    AssumptionError
        Naming the modes (rad/s) that are not stable and not controllable from u.
    """
    bs, w0 = _scaled(blocks, scaling)
    bad = pbh_failures(bs.A, bs.B2, side="right", w0=w0)
    if bad:
        raise AssumptionError(
            f"(A, B2) is not stabilisable: the mode(s) {_modes(bad)} are unstable and "
            "uncontrollable from u; no controller can stabilise this plant"
        )


def check_detectable(blocks: PlantBlocks, *, scaling: PlantScaling | None = None) -> None:
    """Raise :class:`~robust.errors.AssumptionError` unless ``(C2, A)`` is detectable.

    Parameters
    ----------
    blocks : PlantBlocks
        Plant in original coordinates.
    scaling : PlantScaling, optional
        Coordinates of the rank decisions (default: ``PlantScaling.fit(blocks)``).

    Raises
    ------
    AssumptionError
        Naming the modes (rad/s) that are not stable and not observable from y.
    """
    bs, w0 = _scaled(blocks, scaling)
    bad = pbh_failures(bs.A, bs.C2, side="left", w0=w0)
    if bad:
        raise AssumptionError(
            f"(C2, A) is not detectable: the mode(s) {_modes(bad)} are unstable and "
            "unobservable from y; no controller can stabilise this plant"
        )


def check_regularity(blocks: PlantBlocks, *, rtol: float = 1e-8) -> None:
    """Raise :class:`~robust.errors.AssumptionError` unless the problem is regular.

    Regular: ``D12`` has full column rank and ``D21`` full row rank.

    Parameters
    ----------
    blocks : PlantBlocks
        Plant data.
    rtol : float
        Rank threshold relative to ``max(1, largest singular value)``.

    Raises
    ------
    AssumptionError
        Naming the block, the rank needed and the rank found, with its singular values.
    """
    _n, _nw, nu, _nz, ny = blocks.sizes
    for name, M, need in (("D12", blocks.D12, nu), ("D21", blocks.D21, ny)):
        s = np.linalg.svd(M, compute_uv=False) if M.size else np.zeros(0)
        rank = int(np.sum(s > rtol * max(1.0, s.max() if s.size else 0.0)))
        if rank < need:
            kind = "column" if name == "D12" else "row"
            raise AssumptionError(
                f"{name} must have full {kind} rank {need} (regular H-infinity problem); "
                f"got rank {rank} (singular values {np.array2string(s, precision=3)}). "
                "Add a control-effort penalty (for D12) or measurement noise (for D21) "
                "to the generalized plant"
            )


def check_hinf_assumptions(gp: GeneralizedPlant, *, require_regular: bool = True) -> None:
    """Check the standing assumptions of H-infinity output-feedback synthesis.

    Parameters
    ----------
    gp : GeneralizedPlant
        The plant (``D22`` plays no part: the synthesis removes it by a loop shift).
    require_regular : bool
        Also require ``D12`` of full column rank and ``D21`` of full row rank
        (:func:`check_regularity`).

    Raises
    ------
    ModelStructureError
        If the plant is discrete-time (only continuous time is implemented).
    AssumptionError
        Naming the failed condition: (A, B2) not stabilisable, (C2, A) not
        detectable, D12 without full column rank or D21 without full row rank.
    """
    if not gp.sys.isctime():
        raise ModelStructureError(
            f"hinfsyn_lmi: only continuous-time plants are supported; got dt={gp.dt}. "
            "Design in continuous time and discretise the controller"
        )
    blocks = PlantBlocks.from_generalized_plant(gp)
    scaling = PlantScaling.fit(blocks)
    check_stabilisable(blocks, scaling=scaling)
    check_detectable(blocks, scaling=scaling)
    if require_regular:
        check_regularity(blocks)
