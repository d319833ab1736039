"""Closed-loop poles of every member of a family, assembled in batches.

Each block of the Figure 5 loop is realised as arrays ``A, B, C, D`` with a
leading member axis (a fixed block has axis length 1 and broadcasts), the block
outputs are wired to the block inputs by one constant matrix ``M`` built from the
signal names, and the loop is closed for all members at once::

    x' = A x + B u,   y = C x + D u,   u = M y
    =>  A_cl = A + B M (I - D M)^{-1} C

by the compiled loops of :func:`uncertainty.interconnect.close_loops` (the series of
``(D M)^k`` when the feedthroughs form no algebraic cycle, as in the family's loop; LAPACK's
solve otherwise). No python-control object is built per member. The eigenvalues of the stack are
taken chunk by chunk, so memory stays bounded, by the compiled loop of
:func:`robust.analysis.small_eig.eigvals_stack` (LAPACK's to rounding).

Realisations: every block but the controller is :mod:`robust.model.blocks`' one
definition, evaluated over numpy batches (:data:`robust.model.blocks.NUMPY`):

* PI: one integrator state, ``e = kp err + ki xi``;
* valve/cylinder (Eqn 3): cascade form, spool, cylinder speed and position
  (:func:`valve_blocks`; one block that every member shares when the family does not vary
  the valve);
* structure (Eqn 4): ``C/Y = K_s s^2 T1(s) T2(s)`` with
  ``Ti = (2 zi wi s + wi^2)/(s^2 + 2 zi wi s + wi^2)``. The strictly proper
  ``v = K_s T1 T2 y`` (the cab displacement, ``c = s^2 v``) is realised as two
  scaled sections in cascade; because ``T1 T2`` has relative
  degree 2, ``c = C_v A^2 x + C_v A B y`` is a static output of the same 4 states;
* literal human (Eqn 5): the double pole at ``s = 0`` of Eqn 5 cancels the
  structure's double zero at ``s = 0`` exactly, so the literal human is driven by
  ``v`` through ``K_H (s + z1)^2 / (s + p1)^2`` (2 states). This is the minimal
  loop: python-control's series connection keeps the two cancelled modes at
  ``s = 0`` (uncontrollable and unobservable), which
  :func:`robust.analysis.realization.minimal_realization` removes; the batched poles equal
  the poles of that minimal realisation;
* physical human: :func:`robust.model.physical.physical_human_matrices` (the chain's
  masses, stiffnesses and dampings into :func:`robust.model.blocks.physical_human_block`);
* controller: the given continuous state-space compensator, inputs among
  ``x, c, y`` and outputs among ``f, r_corr`` (the convention of
  :mod:`robust.model.loop`).

Bad members: every public function here checks the member values once, vectorised,
before any matrix is built (:meth:`uncertainty.family.Family.check_members`, about 0.1 s per
million members): NaN, inf and non-physical values (a non-positive mass, gain, natural
frequency or damping ratio) and, by default, values outside the family's bounds raise
:class:`~robust.errors.ParameterError` naming the member row and the parameter.
``check_bounds=False`` admits members beyond the bounds (a scaled box for robust margins)
while still refusing non-physical ones. ``chunk`` is capped by :data:`MAX_CHUNK_BYTES`.

Static relations (intended motion ``u = 0`` and external hand force ``f_ext = 0``,
which do not affect poles), from the junction table of
:func:`robust.model.wiring.figure5_junctions`: ``x = sigma kappa h``,
``err = K_PSF x + r_corr - y``, ``f = f_controller``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import control as ct
import numpy as np

from robust.analysis.small_eig import eigvals_stack
from robust.analysis.stability import DAMPING_BAND_HZ, damping_in_band, stability_bound
from robust.checks import FINITE, check_callable, check_int, check_scalar
from robust.engine import map_tasks, scheduler_address
from robust.errors import ModelStructureError, ParameterError
from robust.model.blocks import (
    LITERAL_HUMAN_FIELDS,
    NUMPY,
    STRUCTURE_FIELDS,
    VALVE_FIELDS,
    as_batch,
    literal_human_block,
    parameter_name,
    pi_block,
    structure_block,
    valve_block,
)
from robust.model.loop import CONTROLLER_INPUTS, CONTROLLER_OUTPUTS
from robust.model.physical import physical_human_matrices
from robust.model.wiring import CONTROLLER_FORCE, figure5_junctions, interconnection_matrix
from uncertainty.constants import DEFAULT_CHUNK
from uncertainty.family import BOUNDS_RTOL, Family
from uncertainty.interconnect import close_loops
from uncertainty.region import EVERY_FREQUENCY_HZ
from uncertainty.sampling import SampleSet
from uncertainty.uss import USS

__all__ = [
    "STABILITY_THRESHOLD",
    "DEFAULT_CHUNK",
    "Block",
    "valve_blocks",
    "loop_blocks",
    "closed_loop_matrices",
    "interconnection",
    "batched_poles",
    "ValidationResult",
    "validate_family",
    "member_metrics",
    "MAX_CHUNK_BYTES",
    "CHECK_ROWS",
]

#: A member is stable when every closed-loop pole has real part below this, rad/s
#: (the definition of :mod:`robust.analysis.stability`).
STABILITY_THRESHOLD = stability_bound(0.0)
# DEFAULT_CHUNK (members per chunk) is defined in uncertainty.constants (the command line
# reads it without NumPy)
#: Memory budget of one chunk, bytes (about ``chunk * n^2 * 40`` for an ``n``-state loop): a
#: larger ``chunk`` is reduced to fit, so a huge ``chunk`` never allocates more than this
#: (chunking does not change any result).
MAX_CHUNK_BYTES = 2**30
#: Rows checked per pass by :meth:`uncertainty.family.Family.check_members` before any pole is
#: computed (bounded memory for the check of millions of members).
CHECK_ROWS = 1_000_000


@dataclasses.dataclass(frozen=True)
class Block:
    """One block of the loop for a batch of members.

    The matrices have a leading member axis of length ``N``, or 1 for a block that
    is the same for every member (it broadcasts).

    Parameters
    ----------
    name : str
        Block name (``"pi"``, ``"valve"``, ``"structure"``, ``"human"``,
        ``"controller"``).
    A : ndarray, shape (N or 1, n, n)
        State matrices (``n`` states, possibly 0).
    B : ndarray, shape (N or 1, n, n_in)
        Input matrices.
    C : ndarray, shape (N or 1, n_out, n)
        Output matrices.
    D : ndarray, shape (N or 1, n_out, n_in)
        Feedthrough matrices.
    inputs : tuple of str
        Names of the ``n_in`` input signals (the loop's signal names).
    outputs : tuple of str
        Names of the ``n_out`` output signals.

    Attributes
    ----------
    nstates : int
        Number of states ``n``.
    """

    name: str
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]

    @property
    def nstates(self) -> int:
        """Number of states of the block."""
        return self.A.shape[-1]


def _const(name, A, B, C, D, inputs, outputs) -> Block:
    return Block(
        name, *(np.asarray(x, float)[None] for x in (A, B, C, D)), tuple(inputs), tuple(outputs)
    )


def _block(name: str, mats: tuple, inputs, outputs, n: int | None = None) -> Block:
    """A :class:`Block` of matrices from :mod:`robust.model.blocks` (``NUMPY`` algebra),
    each broadcast to the batch of ``n`` members (the batch of its varied entries when
    ``n`` is None)."""
    return Block(name, *as_batch(mats, n), tuple(inputs), tuple(outputs))


def structure_blocks(k_s, zeta1, zeta2, f1_hz, f2_hz) -> Block:
    """Structure (Eqn 4) for arrays of parameters: input ``y``, outputs ``v`` and ``c``.

    ``v = c / s^2`` is the cab displacement, ``c`` the cab acceleration; 4 states
    (:func:`robust.model.blocks.structure_block`).

    Parameters
    ----------
    k_s : ndarray, shape (N,)
        Gain ``K_s``.
    zeta1, zeta2 : ndarray, shape (N,)
        Damping ratios of the two modes.
    f1_hz, f2_hz : ndarray, shape (N,)
        Natural frequencies of the two modes, Hz.

    Returns
    -------
    Block
    """
    values = dict(zip(STRUCTURE_FIELDS, (k_s, zeta1, zeta2, f1_hz, f2_hz)))
    p = {parameter_name("structure", f): np.asarray(v, float) for f, v in values.items()}
    n = max(v.shape[0] for v in p.values())
    return _block("structure", structure_block(p, NUMPY), ("y",), ("v", "c"), n)


def valve_blocks(k_vc, p1, wn_hz, zeta) -> Block:
    """Valve/cylinder (Eqn 3) for arrays of parameters: input ``e``, output ``y``.

    ``Y/E = K_VC p1 / (s (s + p1)) * wn^2 / (s^2 + 2 zeta wn s + wn^2)`` with
    ``wn = 2 pi wn_hz``, in the cascade coordinates of
    :func:`robust.model.blocks.valve_block` (4 states).

    Parameters
    ----------
    k_vc : ndarray, shape (N,)
        Gain ``K_VC`` (cylinder position per unit valve command per second).
    p1 : ndarray, shape (N,)
        Real pole, rad/s.
    wn_hz : ndarray, shape (N,)
        Valve natural frequency, Hz.
    zeta : ndarray, shape (N,)
        Valve damping ratio.

    Returns
    -------
    Block
    """
    values = dict(zip(VALVE_FIELDS, (k_vc, p1, wn_hz, zeta)))
    p = {parameter_name("valve", f): np.asarray(v, float) for f, v in values.items()}
    n = max(v.shape[0] for v in p.values())
    return _block("valve", valve_block(p, NUMPY), ("e",), ("y",), n)


def literal_human_cancelled(k_h, z1, p1) -> Block:
    """Eqn 5 times ``s^2``: ``K_H (s + z1)^2 / (s + p1)^2``, input ``v``, output ``h``.

    Driven by the cab displacement ``v`` instead of the acceleration, so the double
    pole at ``s = 0`` of Eqn 5 is cancelled (2 states; see the module notes and
    :func:`robust.model.blocks.literal_human_block`).

    Parameters
    ----------
    k_h : ndarray, shape (N,)
        Gain ``K_H``.
    z1 : ndarray, shape (N,)
        Double real zero, rad/s.
    p1 : ndarray, shape (N,)
        Double real pole, rad/s.

    Returns
    -------
    Block
    """
    values = dict(zip(LITERAL_HUMAN_FIELDS, (k_h, z1, p1)))
    p = {parameter_name("human", f): np.asarray(v, float) for f, v in values.items()}
    n = max(v.shape[0] for v in p.values())
    return _block("human", literal_human_block(p, NUMPY), ("v",), ("h",), n)


def _controller_block(controller: ct.StateSpace, has_force_port: bool) -> Block:
    if not isinstance(controller, ct.StateSpace):
        raise ModelStructureError(
            f"controller must be a control.StateSpace; got {type(controller).__name__}"
        )
    if not controller.isctime():
        raise ModelStructureError(f"controller must be continuous-time; got dt={controller.dt}")
    ins, outs = list(controller.input_labels), list(controller.output_labels)
    bad_in = [s for s in ins if s not in CONTROLLER_INPUTS]
    bad_out = [s for s in outs if s not in CONTROLLER_OUTPUTS]
    if bad_in or bad_out or len(set(ins)) != len(ins) or len(set(outs)) != len(outs):
        raise ModelStructureError(
            f"controller inputs must be distinct names among {CONTROLLER_INPUTS} and outputs among "
            f"{CONTROLLER_OUTPUTS}; got inputs {ins}, outputs {outs}"
        )
    if "f" in outs and not has_force_port:
        raise ModelStructureError(
            "controller drives the handle force 'f', but the literal human has no force port; "
            "use the physical human"
        )
    mats = [np.asarray(x, float) for x in (controller.A, controller.B, controller.C, controller.D)]
    for label, x in zip("ABCD", mats):
        if not np.all(np.isfinite(x)):
            raise ModelStructureError(f"controller.{label} contains non-finite entries")
    internal = [CONTROLLER_FORCE if s == "f" else s for s in outs]
    return _const("controller", *mats, ins, internal)


@functools.lru_cache(maxsize=16)
def _valve_block(valve) -> Block:
    """The valve/cylinder's block of a family that does not vary it, built once per
    parameter set and process."""
    return valve_blocks(*([getattr(valve, f)] for f in VALVE_FIELDS))


def _check_family(family, where: str) -> None:
    if not isinstance(family, Family):
        raise ParameterError(
            f"{where}: family must be an uncertainty.Family; got {type(family).__name__}"
        )


def loop_blocks(
    family: Family,
    values: np.ndarray,
    *,
    controller: ct.StateSpace | None = None,
    check_bounds: bool = True,
) -> list[Block]:
    """The dynamic blocks of the loop for members ``values``.

    In order: the PI controller (one state, or none when ``ki = 0``), the
    valve/cylinder, the structure, the human and, if given, the controller.

    Parameters
    ----------
    family : Family
        The family (its calibration, ``K_PSF``, valve and human variant).
    values : ndarray, shape (N, d)
        Uncertain-parameter values (columns in ``family.names`` order).
    controller : control.StateSpace, optional
        Continuous-time compensator, inputs among ``x, c, y`` and outputs among
        ``f, r_corr``.
    check_bounds : bool
        Require the values within the family's bounds (default); non-finite and
        non-physical values are refused either way
        (:meth:`uncertainty.family.Family.check_members`).

    Returns
    -------
    list of Block

    Raises
    ------
    ParameterError
        If a member's values are non-finite, non-physical or (with ``check_bounds``)
        outside the family's bounds; the message names the row and the parameter.
    ModelStructureError
        If the controller is not a continuous-time ``control.StateSpace`` with
        distinct, known signal names and finite matrices, or drives ``f`` with the
        literal human (which has no force port).
    """
    _check_family(family, "loop_blocks")
    v = family.check_members(values, check_bounds=check_bounds, where="loop_blocks")
    return _loop_blocks(family, v, controller)


def _loop_blocks(family: Family, values: np.ndarray, controller) -> list[Block]:
    """:func:`loop_blocks` of checked values."""
    p = family._model_arrays(values)
    cal = family.calibration
    blocks = []
    blocks.append(_const("pi", *pi_block(cal.kp, cal.ki), ["err"], ["e"]))
    valve_names = [parameter_name("valve", f) for f in VALVE_FIELDS]
    if set(valve_names) & set(family.names):
        blocks.append(valve_blocks(*(p[name] for name in valve_names)))
    else:  # a valve the family does not vary: one block that every member shares
        v = _valve_block(family.valve)
        # (copies: the cached block stays as it was whatever a caller does with the list)
        blocks.append(
            dataclasses.replace(v, A=v.A.copy(), B=v.B.copy(), C=v.C.copy(), D=v.D.copy())
        )
    blocks.append(structure_blocks(*(p[parameter_name("structure", f)] for f in STRUCTURE_FIELDS)))
    if family.human == "literal":
        blocks.append(
            literal_human_cancelled(*(p[parameter_name("human", f)] for f in LITERAL_HUMAN_FIELDS))
        )
    else:
        names = ("m_trunk", "m_arm", "k_trunk", "c_trunk", "k_arm", "c_arm", "h_gain", "c_unit")
        A, B, C, D = physical_human_matrices(*(p[parameter_name("human", f)] for f in names))
        blocks.append(Block("human", A, B, C, D, ("c", "f"), ("h",)))
    if controller is not None:
        blocks.append(_controller_block(controller, family.human == "physical"))
    return blocks


def interconnection(family: Family, blocks: list[Block], controller=None) -> np.ndarray:
    """Constant ``M`` with ``u = M y`` (block inputs from block outputs) of the family's loop.

    Every block input is expanded through the Figure 5 junction table
    (:func:`robust.model.wiring.figure5_junctions`, the same table
    :class:`robust.model.loop.BDFTLoop` is built from) with the exogenous inputs
    ``u`` and ``f_ext`` at zero (:func:`robust.model.wiring.interconnection_matrix`).

    Parameters
    ----------
    family : Family
        The family (its position scale factor, calibration and human variant).
    blocks : list of Block
        The loop's blocks, as :func:`loop_blocks` returns them.
    controller : control.StateSpace, optional
        The compensator among the blocks (its outputs decide the junctions).
    """
    ctrl_outs = () if controller is None else tuple(controller.output_labels)
    force = ("f_ext", CONTROLLER_FORCE) if "f" in ctrl_outs else ("f_ext",)
    cal = family.calibration
    return _interconnection(  # (a copy: the cached matrix stays as it was)
        float(family.k_psf),
        float(cal.handle_sign * cal.loop_scale),
        "r_corr" in ctrl_outs,
        force if family.human == "physical" else (),
        tuple(s for b in blocks for s in b.inputs),
        tuple(s for b in blocks for s in b.outputs),
    ).copy()


@functools.lru_cache(maxsize=64)
def _interconnection(k_psf, handle_gain, reference_correction, force_terms, ins, outs):
    """:func:`interconnection`'s matrix from what it depends on, made once per process."""
    junctions = figure5_junctions(
        k_psf=k_psf,
        handle_gain=handle_gain,
        reference_correction=reference_correction,
        force_terms=force_terms,
    )
    return interconnection_matrix(list(ins), list(outs), junctions)


def closed_loop_matrices(
    family: Family,
    values: np.ndarray,
    *,
    controller: ct.StateSpace | None = None,
    check_bounds: bool = True,
) -> np.ndarray:
    """Closed-loop state matrices of members ``values``.

    Parameters
    ----------
    family : Family
        The family the members belong to.
    values : ndarray, shape (N, d)
        Uncertain-parameter values (columns in ``family.names`` order): finite, physical
        and, with ``check_bounds``, within the family's bounds.
    controller : control.StateSpace, optional
        Compensator at the handle-force and measurement signals.
    check_bounds : bool
        Require the values within the family's bounds (default); pass False for members
        beyond them (scaled boxes), which must still be physical.

    Returns
    -------
    ndarray, shape (N, n, n)
        ``n`` = 13 (+ controller states) for the physical human, 11 (+ controller
        states) for the literal human (minimal loop, see the module docstring).

    Raises
    ------
    ParameterError
        If a member's values are non-finite, non-physical or (with ``check_bounds``)
        outside the family's bounds; the message names the row and the parameter.
    ModelStructureError
        If the algebraic loop ``I - D M`` is singular for a member (ill-posed loop).
    """
    _check_family(family, "closed_loop_matrices")
    v = family.check_members(values, check_bounds=check_bounds, where="closed_loop_matrices")
    return _closed_loop(family, v, controller)


def _closed_loop(family: Family, values: np.ndarray, controller) -> np.ndarray:
    """:func:`closed_loop_matrices` of checked values."""
    blocks = _loop_blocks(family, values, controller)
    M = interconnection(family, blocks, controller)
    A = close_loops(*([getattr(b, x) for b in blocks] for x in "ABCD"), M)
    if A.shape[0] != values.shape[0]:  # no block varies: every member has the same loop
        A = np.repeat(A, values.shape[0], axis=0)
    return A


def batched_poles(
    family: Family,
    values: np.ndarray,
    *,
    controller: ct.StateSpace | None = None,
    check_bounds: bool = True,
) -> np.ndarray:
    """Closed-loop poles of members ``values``.

    Parameters
    ----------
    family : Family
        The family the members belong to.
    values : ndarray, shape (N, d)
        Uncertain-parameter values (columns in ``family.names`` order).
    controller : control.StateSpace, optional
        Compensator (inputs among ``x, c, y``; outputs among ``f, r_corr``).
    check_bounds : bool
        As for :func:`closed_loop_matrices`.

    Returns
    -------
    ndarray of complex, shape (N, n)
        Every member's closed-loop poles, rad/s, in no particular order (the numbers
        :func:`member_metrics` reduces: :func:`robust.analysis.small_eig.eigvals_stack`;
        one batch: for large ``N`` see :func:`member_metrics`, which works chunk by chunk).

    Raises
    ------
    ParameterError
        As :func:`closed_loop_matrices`.
    """
    return eigvals_stack(
        closed_loop_matrices(family, values, controller=controller, check_bounds=check_bounds)
    )


@dataclasses.dataclass(frozen=True)
class ValidationResult:
    """Family-wide closed-loop pole metrics.

    Attributes
    ----------
    samples : int
        Number of members validated.
    seed : int
        Seed of the sample set.
    method : str
        Sampling method.
    human : str or None
        Human variant (None for a user's uncertain system).
    k_psf : float or None
        Position scale factor (None for a user's uncertain system).
    fraction_stable : float
        Fraction of members whose poles all have real part below ``stability_threshold``.
    n_unstable : int
        Number of unstable members.
    max_real_pole : float
        Largest real part of any closed-loop pole of any member, 1/s.
    min_damping : float
        Smallest damping ratio ``-Re(p)/|p|`` of the poles with ``|Im(p)|/(2 pi)``
        in ``band_hz`` (``inf`` if no member has a pole in the band).
    worst : dict
        Parameters (name -> value) of the member with the largest real part.
    worst_index : int
        Row of that member in the sample set.
    stability_threshold : float
        Threshold on the real part used for ``fraction_stable``, 1/s.
    band_hz : (float, float)
        The band of ``min_damping``, Hz: the BDFT band by default for a family, every
        frequency ``(0, inf)`` for a user's uncertain system.
    nstates : int
        Closed-loop order.
    controller_states : int
        Order of the controller (0 without one).
    max_real : ndarray, shape (N,)
        Per-member largest real part (read-only).
    member_min_damping : ndarray, shape (N,)
        Per-member smallest damping ratio in the band (``inf`` if none; read-only).
    """

    samples: int
    seed: int
    method: str
    human: str | None
    k_psf: float | None
    fraction_stable: float
    n_unstable: int
    max_real_pole: float
    min_damping: float
    worst: dict
    worst_index: int
    stability_threshold: float
    band_hz: tuple[float, float]
    nstates: int
    controller_states: int
    max_real: np.ndarray = dataclasses.field(repr=False)
    member_min_damping: np.ndarray = dataclasses.field(repr=False)

    def to_json(self) -> dict:
        """The JSON object of ``bdft validate --json`` (per-member arrays left out)."""
        d = {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if f.name not in ("max_real", "member_min_damping")
        }
        d["band_hz"] = list(self.band_hz)
        return d


def _member_metrics(poles: np.ndarray, band_hz) -> tuple[np.ndarray, np.ndarray]:
    return poles.real.max(axis=1), damping_in_band(poles, band_hz)


def _check_options(where: str, chunk, band_hz, progress) -> tuple[int, tuple[float, float]]:
    """Validate ``chunk``, ``band_hz`` and ``progress`` of a batched call."""
    chunk = check_int(f"{where}: chunk", chunk, low=1)
    try:
        lo, hi = band_hz
    except (TypeError, ValueError):
        raise ParameterError(
            f"{where}: band_hz must be a pair (low, high) in Hz; got {band_hz!r}"
        ) from None
    lo = check_scalar(f"{where}: band_hz[0]", lo, FINITE)
    hi = math.inf if hi == math.inf else check_scalar(f"{where}: band_hz[1]", hi, FINITE)
    if not (0.0 <= lo < hi):
        raise ParameterError(
            f"{where}: band_hz must satisfy 0 <= low < high; got {band_hz!r} (high may be inf)"
        )
    check_callable("progress", progress, owner=where)
    return chunk, (lo, hi)


def _memory_chunk(family: Family, controller, chunk: int) -> int:
    """``chunk`` reduced so that one chunk's matrices stay within :data:`MAX_CHUNK_BYTES`."""
    n = 1 + 4 + 4 + (4 if family.human == "physical" else 2)
    if isinstance(controller, ct.StateSpace):
        n += int(controller.nstates)
    return max(1, min(chunk, MAX_CHUNK_BYTES // (40 * n * n)))


def _check_all(family: Family, values, check_bounds: bool, where: str) -> np.ndarray:
    """Check every member, :data:`CHECK_ROWS` rows per pass, before any pole is computed."""
    if not (isinstance(values, np.ndarray) and values.ndim == 2 and values.dtype.kind in "iuf"):
        return family.check_members(values, check_bounds=check_bounds, where=where)
    v = np.asarray(values, float)
    for start in range(0, max(1, v.shape[0]), CHECK_ROWS):
        family.check_members(
            v[start : start + CHECK_ROWS],
            check_bounds=check_bounds,
            row_offset=start,
            where=where,
        )
    return v


def member_metrics(
    family: Family,
    values: np.ndarray,
    *,
    controller: ct.StateSpace | None = None,
    chunk: int = DEFAULT_CHUNK,
    band_hz: tuple[float, float] = DAMPING_BAND_HZ,
    progress: Callable[[int], None] | None = None,
    check_bounds: bool = True,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Per-member largest real part and smallest in-band damping ratio, chunk by chunk.

    Every member is checked (:meth:`uncertainty.family.Family.check_members`) before
    any pole is computed.

    Parameters
    ----------
    family : Family
        The family the members belong to.
    values : ndarray, shape (N, d)
        Uncertain-parameter values (columns in ``family.names`` order).
    controller, chunk, band_hz, progress, check_bounds
        As for :func:`validate_family`.

    Returns
    -------
    max_real : ndarray, shape (N,)
        Largest real part of each member's closed-loop poles, 1/s.
    min_damping : ndarray, shape (N,)
        Smallest damping ratio of each member's poles in ``band_hz`` (``inf`` if none).
    nstates : int
        Closed-loop order.

    Raises
    ------
    ParameterError
        If a member is non-finite, non-physical or (with ``check_bounds``) outside the
        family's bounds (the message names the row and the parameter), ``chunk`` is not
        a positive integer, ``band_hz`` is not ``0 <= low < high`` or ``progress`` is not
        callable.
    """
    _check_family(family, "member_metrics")
    chunk, band_hz = _check_options("member_metrics", chunk, band_hz, progress)
    values = _check_all(family, values, check_bounds, "member_metrics")
    return _metrics(family, values, controller, chunk, band_hz, progress)


def _metrics(family, values, controller, chunk, band_hz, progress):
    """:func:`member_metrics` of checked values and options."""
    chunk = _memory_chunk(family, controller, chunk)
    N = values.shape[0]
    max_real = np.empty(N)
    min_damp = np.empty(N)
    nstates = 0
    for start in range(0, N, chunk):
        stop = min(N, start + chunk)
        Acl = _closed_loop(family, values[start:stop], controller)
        nstates = Acl.shape[-1]
        poles = eigvals_stack(Acl)
        del Acl
        max_real[start:stop], min_damp[start:stop] = _member_metrics(poles, band_hz)
        if progress is not None:
            progress(stop - start)
    return max_real, min_damp, int(nstates)


#: Members per task when validation runs in several threads or on a Dask cluster.
TASK_MEMBERS = 50_000


def _metrics_task(family, controller, chunk, band_hz, values):
    """One task of a parallel validation: the metrics of a slice of checked members."""
    return _metrics(family, values, controller, chunk, band_hz, None)


def _distributed_metrics(family, values, controller, chunk, band_hz, progress, jobs, scheduler):
    """:func:`_metrics` in tasks of :data:`TASK_MEMBERS` members on the chosen engine."""
    jobs = check_int("validate_family: jobs", jobs, low=1)
    N = values.shape[0]
    starts = list(range(0, N, TASK_MEMBERS))
    slices = [values[a : a + TASK_MEMBERS] for a in starts]
    sizes = [len(v) for v in slices]
    done = (lambda i: progress(sizes[i])) if progress is not None else None
    parts = map_tasks(
        functools.partial(_metrics_task, family, controller, chunk, band_hz),
        slices,
        jobs=jobs,
        scheduler=scheduler,
        progress=done,
        threads=True,
    )
    max_real = np.concatenate([p[0] for p in parts])
    min_damp = np.concatenate([p[1] for p in parts])
    return max_real, min_damp, parts[0][2]


def validate_family(
    family: Family | USS,
    samples: SampleSet,
    *,
    controller: ct.StateSpace | None = None,
    chunk: int = DEFAULT_CHUNK,
    band_hz: tuple[float, float] | None = None,
    stability_threshold: float = STABILITY_THRESHOLD,
    progress: Callable[[int], None] | None = None,
    check_bounds: bool = True,
    jobs: int = 1,
    scheduler: str | None = None,
) -> ValidationResult:
    """Closed-loop poles of every member of ``samples``, and the family metrics.

    Member values must be finite and physical and lie within the family's bounds
    (:meth:`uncertainty.family.Family.check_members`); every member is checked,
    vectorised, before any pole is computed, so a bad member costs no work.

    Parameters
    ----------
    family : Family or USS
        The family the members belong to, or an uncertain system
        (:func:`uncertainty.uss`; its members are the values of its uncertain reals).
    samples : SampleSet
        Members; its names must equal ``family.names`` (a system's: the names of
        ``system.parameters``, in any order).
    controller : control.StateSpace, optional
        Compensator (a family: inputs among ``x, c, y``, outputs among ``f, r_corr``; a
        system: in its feedback path, ``system.feedback(controller)``).
    chunk : int
        Members per batch (bounds memory: about ``chunk * n^2 * 40`` bytes; reduced to
        keep within :data:`MAX_CHUNK_BYTES`, which changes no result).
    band_hz : (float, float), optional
        Frequency band of the poles whose damping is reported, Hz (``high`` may be
        ``inf``). Default: the BDFT band (:data:`DAMPING_BAND_HZ`, 0.5-10 Hz) for a
        family, every frequency (``(0, inf)``) for an uncertain system.
    stability_threshold : float
        A member is stable when all its poles have real part below this, 1/s.
    progress : callable, optional
        Called with the number of members finished after each chunk.
    check_bounds : bool
        Require every member within the family's bounds (default). Pass False to
        validate members beyond them (a scaled box for robust margins); non-finite and
        non-physical values (a negative mass, frequency or damping ratio) are refused
        either way.
    jobs : int
        Threads of this process that validate tasks of :data:`TASK_MEMBERS` members side by
        side (the compiled loops release the GIL, so no worker process is needed); 1
        (default) validates in this thread.
    scheduler : str, optional
        A Dask scheduler's address (or ``$DASK_SCHEDULER_ADDRESS``): the members are
        validated on its workers in tasks of :data:`TASK_MEMBERS` (see
        :func:`robust.engine.map_tasks`). Every engine gives the same result, bit for
        bit: each member's poles are computed alone and the metrics are combined in order.

    Returns
    -------
    ValidationResult

    Raises
    ------
    ParameterError
        If ``samples`` is not a :class:`~uncertainty.sampling.SampleSet` whose names
        match the family's, a member is non-finite, non-physical or (with
        ``check_bounds``) outside the family's bounds (the message names the row and the
        parameter), ``chunk`` is not a positive integer, ``band_hz`` is not
        ``0 <= low < high`` or ``stability_threshold`` is not finite.
    ModelStructureError
        For an invalid controller, an ill-posed loop or non-finite poles.
    """
    if isinstance(family, USS):
        band_hz = EVERY_FREQUENCY_HZ if band_hz is None else band_hz
        return _validate_system(
            family, samples, controller, chunk, band_hz, stability_threshold, progress, check_bounds
        )  # (small systems: in this process)
    band_hz = DAMPING_BAND_HZ if band_hz is None else band_hz
    _check_family(family, "validate_family")
    if not isinstance(samples, SampleSet):
        raise ParameterError(
            f"validate_family: samples must be an uncertainty.SampleSet; "
            f"got {type(samples).__name__}"
        )
    if tuple(samples.names) != family.names:
        raise ParameterError(
            f"validate_family: sample names {list(samples.names)} do not match the family's "
            f"{list(family.names)}"
        )
    chunk, (lo, hi) = _check_options("validate_family", chunk, band_hz, progress)
    stability_threshold = check_scalar(
        "validate_family: stability_threshold", stability_threshold, FINITE
    )
    N = len(samples)
    if N == 0:
        raise ParameterError("validate_family: samples holds no members; got 0 rows")
    values = _check_all(family, samples.values, check_bounds, "validate_family")
    if jobs == 1 and scheduler_address(scheduler) is None:
        max_real, min_damp, nstates = _metrics(
            family, values, controller, chunk, (lo, hi), progress
        )
    else:
        max_real, min_damp, nstates = _distributed_metrics(
            family, values, controller, chunk, (lo, hi), progress, jobs, scheduler
        )
    if not np.all(np.isfinite(max_real)):
        raise ModelStructureError(
            "non-finite closed-loop poles for some members; check parameter ranges"
        )
    return _result(
        samples,
        max_real,
        min_damp,
        stability_threshold,
        (lo, hi),
        nstates,
        0 if controller is None else int(controller.nstates),
        family.human,
        family.k_psf,
    )


def _validate_system(
    system, samples, controller, chunk, band_hz, threshold, progress, check_bounds
):
    """:func:`validate_family` of an uncertain system (closed with ``controller``)."""
    where = "validate_family"
    if not isinstance(samples, SampleSet):
        raise ParameterError(
            f"{where}: samples must be an uncertainty.SampleSet; got {type(samples).__name__}"
        )
    names = tuple(system.parameters)
    if sorted(samples.names) != sorted(names):
        raise ParameterError(
            f"{where}: sample names {list(samples.names)} do not match the system's "
            f"parameters {list(names)}"
        )
    chunk, (lo, hi) = _check_options(where, chunk, band_hz, progress)
    threshold = check_scalar(f"{where}: stability_threshold", threshold, FINITE)
    # the columns in the system's order (a sample of the same parameters in another order,
    # e.g. of the transfer function the system realises, is the same members)
    values = np.asarray(samples.values, float)[:, [samples.names.index(n) for n in names]]
    N = values.shape[0]
    if N == 0:
        raise ParameterError(f"{where}: samples holds no members; got 0 rows")
    bad = ~np.isfinite(values)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ParameterError(f"{where}: member {i}: {names[j]} must be finite; got {values[i, j]}")
    if check_bounds:
        low = np.array([p.low for p in system.parameters.values()])
        high = np.array([p.high for p in system.parameters.values()])
        tol = BOUNDS_RTOL * np.maximum(np.abs(low), np.abs(high))
        out = (values < low - tol) | (values > high + tol)
        if out.any():
            i, j = np.argwhere(out)[0]
            raise ParameterError(
                f"{where}: member {i}: {names[j]} must lie in [{low[j]:g}, {high[j]:g}]; "
                f"got {values[i, j]!r}"
            )
    closed = system if controller is None else system.feedback(controller, sign=-1)
    if closed.nstates == 0:
        raise ModelStructureError(f"{where}: the system has no state (a static gain)")
    n = closed.nstates
    chunk = max(1, min(chunk, MAX_CHUNK_BYTES // (40 * n * n)))
    max_real, min_damp = np.empty(N), np.empty(N)
    for start in range(0, N, chunk):
        stop = min(N, start + chunk)
        poles = eigvals_stack(closed.state_matrices(values[start:stop]))
        max_real[start:stop], min_damp[start:stop] = _member_metrics(poles, (lo, hi))
        if progress is not None:
            progress(stop - start)
    if not np.all(np.isfinite(max_real)):
        raise ModelStructureError(f"{where}: non-finite closed-loop poles for some members")
    ctrl_states = 0 if controller is None else int(ct.ss(controller).nstates)
    return _result(samples, max_real, min_damp, threshold, (lo, hi), n, ctrl_states, None, None)


def _result(samples, max_real, min_damp, threshold, band, nstates, ctrl_states, human, k_psf):
    """The :class:`ValidationResult` of per-member metrics."""
    N = len(max_real)
    stable = max_real < threshold
    worst = int(np.argmax(max_real))
    for arr in (max_real, min_damp):
        arr.setflags(write=False)
    return ValidationResult(
        samples=N,
        seed=samples.seed,
        method=samples.method,
        human=human,
        k_psf=k_psf,
        fraction_stable=float(np.mean(stable)),
        n_unstable=int(N - np.count_nonzero(stable)),
        max_real_pole=float(max_real[worst]),
        min_damping=float(np.min(min_damp)),
        worst=samples.row(worst),
        worst_index=worst,
        stability_threshold=float(threshold),
        band_hz=band,
        nstates=int(nstates),
        controller_states=ctrl_states,
        max_real=max_real,
        member_min_damping=min_damp,
    )
