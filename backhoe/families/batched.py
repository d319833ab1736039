"""Closed-loop state matrices and poles of every member of a family, assembled in batches.

Each block of the Figure 5 loop is realised as arrays ``A, B, C, D`` with a
leading member axis (a fixed block has axis length 1 and broadcasts), the block
outputs are wired to the block inputs by one constant matrix ``M`` built from the
signal names, and the loop is closed for all members at once::

    x' = A x + B u,   y = C x + D u,   u = M y
    =>  A_cl = A + B M (I - D M)^{-1} C

by the compiled loops of :func:`uncertainty.closeloops.close_loops` (the series of
``(D M)^k`` when the feedthroughs form no algebraic cycle, as in the family's loop; LAPACK's
solve otherwise). No python-control object is built per member. The eigenvalues of the stack
are taken by the compiled loop of :func:`robust.analysis.small_eig.eigvals_stack` (LAPACK's
to rounding); the validation of a family (:mod:`backhoe.families.validation`) takes them chunk by
chunk, so memory stays bounded.

Realisations: every block but the controller is :mod:`backhoe.model.blocks`' one
definition, evaluated over numpy batches (:data:`backhoe.model.blocks.NUMPY`):

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
* physical human: :func:`backhoe.model.physical.physical_human_matrices` (the chain's
  masses, stiffnesses and dampings into :func:`backhoe.model.blocks.physical_human_block`);
* controller: the given continuous state-space compensator, inputs among
  ``x, c, y`` and outputs among ``f, r_corr`` (the convention of
  :mod:`backhoe.model.loop`).

Bad members: every public function here checks the member values once, vectorised,
before any matrix is built (:meth:`backhoe.families.family.Family.check_members`, a small part of
a validation's time): NaN, inf and non-physical values (a non-positive mass, gain, natural
frequency or damping ratio) and, by default, values outside the family's bounds raise
:class:`~robust.errors.ParameterError` naming the member row and the parameter.
``check_bounds=False`` admits members beyond the bounds (a scaled box for robust margins)
while still refusing non-physical ones.

Static relations (intended motion ``u = 0`` and external hand force ``f_ext = 0``,
which do not affect poles), from the junction table of
:func:`backhoe.model.wiring.figure5_junctions`: ``x = sigma kappa h``,
``err = K_PSF x + r_corr - y``, ``f = f_controller``.
"""

from __future__ import annotations

import dataclasses
import functools

import control as ct
import numpy as np

from backhoe.families.family import Family
from backhoe.model.blocks import (
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
from backhoe.model.loop import CONTROLLER_INPUTS, CONTROLLER_OUTPUTS
from backhoe.model.physical import physical_human_matrices
from backhoe.model.wiring import CONTROLLER_FORCE, figure5_junctions, interconnection_matrix
from robust.analysis.small_eig import eigvals_stack
from robust.errors import ModelStructureError, ParameterError
from uncertainty.closeloops import close_loops
from uncertainty.constants import DEFAULT_CHUNK as DEFAULT_CHUNK

__all__ = [
    "DEFAULT_CHUNK",
    "Block",
    "valve_blocks",
    "loop_blocks",
    "closed_loop_matrices",
    "interconnection",
    "loop_junctions",
    "batched_poles",
]

# DEFAULT_CHUNK (members per chunk of the validation, backhoe.families.validation) is defined in
# uncertainty.constants and re-exported here for its old path

#: Members per task when validation runs in several threads or on a Dask cluster.
TASK_MEMBERS = 50_000


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
    """A :class:`Block` of matrices from :mod:`backhoe.model.blocks` (``NUMPY`` algebra),
    each broadcast to the batch of ``n`` members (the batch of its varied entries when
    ``n`` is None)."""
    return Block(name, *as_batch(mats, n), tuple(inputs), tuple(outputs))


def structure_blocks(k_s, zeta1, zeta2, f1_hz, f2_hz) -> Block:
    """Structure (Eqn 4) for arrays of parameters: input ``y``, outputs ``v`` and ``c``.

    ``v = c / s^2`` is the cab displacement, ``c`` the cab acceleration; 4 states
    (:func:`backhoe.model.blocks.structure_block`).

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
    :func:`backhoe.model.blocks.valve_block` (4 states).

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
    :func:`backhoe.model.blocks.literal_human_block`).

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
            f"{where}: family must be a backhoe.Family; got {type(family).__name__}"
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
        (:meth:`backhoe.families.family.Family.check_members`).

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


def _junction_args(family: Family, controller) -> tuple:
    """What the family's junction table depends on (:func:`loop_junctions`' arguments)."""
    ctrl_outs = () if controller is None else tuple(controller.output_labels)
    force = ("f_ext", CONTROLLER_FORCE) if "f" in ctrl_outs else ("f_ext",)
    cal = family.calibration
    return (
        float(family.k_psf),
        float(cal.handle_sign * cal.loop_scale),
        "r_corr" in ctrl_outs,
        force if family.human == "physical" else (),
    )


def loop_junctions(family: Family, controller=None) -> tuple:
    """The family's Figure 5 junction table (:func:`backhoe.model.wiring.figure5_junctions`).

    Parameters
    ----------
    family : Family
        The family (its position scale factor, calibration and human variant).
    controller : control.StateSpace, optional
        The compensator (its outputs decide the junctions).

    Returns
    -------
    tuple of backhoe.model.wiring.Junction
    """
    k_psf, handle_gain, correction, force_terms = _junction_args(family, controller)
    return figure5_junctions(
        k_psf=k_psf,
        handle_gain=handle_gain,
        reference_correction=correction,
        force_terms=force_terms,
    )


def interconnection(family: Family, blocks: list[Block], controller=None) -> np.ndarray:
    """Constant ``M`` with ``u = M y`` (block inputs from block outputs) of the family's loop.

    Every block input is expanded through the Figure 5 junction table
    (:func:`loop_junctions`, the same table :class:`backhoe.model.loop.BDFTLoop` is built
    from) with the exogenous inputs ``u`` and ``f_ext`` at zero
    (:func:`backhoe.model.wiring.interconnection_matrix`).

    Parameters
    ----------
    family : Family
        The family (its position scale factor, calibration and human variant).
    blocks : list of Block
        The loop's blocks, as :func:`loop_blocks` returns them.
    controller : control.StateSpace, optional
        The compensator among the blocks (its outputs decide the junctions).
    """
    return _interconnection(  # (a copy: the cached matrix stays as it was)
        *_junction_args(family, controller),
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
