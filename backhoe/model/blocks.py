"""The machine's and the operator's dynamic blocks, each written once over any arithmetic.

A block is a function of its parameters and an :class:`Algebra` (how matrices are made in
one kind of arithmetic): plain numbers, batches of members as numpy arrays
(:data:`NUMPY`), intervals, uncertain reals. The batched matrices of many members
(:mod:`backhoe.families.batched`), the certified interval enclosures and the uncertain system
(:mod:`backhoe.families.loop`), the hydraulic simulation (:mod:`backhoe.analysis.saturation`) and
the physical human of the python-control member (:mod:`backhoe.model.physical`) take their
matrices from here; adding a parameter to a block is an edit here.

The python-control member's valve/cylinder, structure, PI and literal human are still
realised from the paper's transfer functions (SLICOT's ``td04ad``,
:mod:`backhoe.model.components`), a second realisation of the same equations: the tests
check that both give the same responses and poles. The shipped designs are synthesised on
the python-control member and their syntheses depend on the state coordinates (state
weights, LMI conditioning): realised from these blocks instead, the robust LMI design
reached another rung of its ladder and limit-cycles at the nominal member under the device
limits, and the multi-model design's worst member lost its 1 kHz damping. Moving them
waits for design verdicts that do not hinge on rounding.

The parameters are named ``<block>.<field>`` (:func:`parameter_name`): the families, the
value sets and the reports address them by these names, and only this module spells them.

Blocks (the paper's Figure 5; equations of Humphreys, Book & Huggins, "Modeling of
biodynamic feedthrough in backhoe operation"):

* :func:`valve_block`, Eqn 3, valve command ``e`` -> cylinder position ``y``, in cascade
  form with physical states (spool position and rate, cylinder speed, cylinder position,
  scaled):
  ``K_VC p1 / (s (s + p1)) * wn^2 / (s^2 + 2 zeta wn s + wn^2)``;
* :func:`structure_block`, Eqn 4, cylinder position ``y`` -> cab displacement ``v`` and
  acceleration ``c = s^2 v``: ``K_s s^2 prod_i (2 z_i w_i s + w_i^2) / (s^2 + 2 z_i w_i s +
  w_i^2)``, two cascaded sections;
* :func:`literal_human_block`, Eqn 5 times ``s^2`` (driven by the cab displacement ``v``, so
  its double integrator is the structure's ``s^2`` cancelled): ``K_H (s + z1)^2 / (s + p1)^2``;
* :func:`physical_human_block`, the seated two-mass chain (:mod:`backhoe.model.physical`)
  with inputs ``c`` and the handle force ``f``, from its entries as
  :func:`human_entries_modal` (the families' parametrisation: masses, natural frequencies
  and damping ratios) or :func:`human_entries_physical` (masses, stiffnesses and dampings)
  write them;
* :func:`pi_block`, the cylinder position loop's PI controller (fixed numbers).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping

import numpy as np

__all__ = [
    "Algebra",
    "NUMPY",
    "as_batch",
    "BLOCK_FIELDS",
    "STRUCTURE_FIELDS",
    "VALVE_FIELDS",
    "LITERAL_HUMAN_FIELDS",
    "PHYSICAL_HUMAN_FIELDS",
    "parameter_name",
    "block_of",
    "field_of",
    "block_values",
    "valve_block",
    "structure_block",
    "literal_human_block",
    "human_entries_modal",
    "human_entries_physical",
    "physical_human_block",
    "pi_block",
]

TWO_PI = 2.0 * math.pi

#: The structure's parameters (Eqn 4): gain, damping ratios and natural frequencies (Hz).
STRUCTURE_FIELDS = ("k_s", "zeta1", "zeta2", "f1_hz", "f2_hz")
#: The valve/cylinder's parameters (Eqn 3): gain, real pole (rad/s), valve frequency (Hz)
#: and damping ratio.
VALVE_FIELDS = ("k_vc", "p1", "wn_hz", "zeta")
#: The literal human's parameters (Eqn 5): gain, double zero and double pole (rad/s).
LITERAL_HUMAN_FIELDS = ("k_h", "z1", "p1")
#: The physical human's parameters as the families vary them (biodynamics' modal form).
PHYSICAL_HUMAN_FIELDS = (
    "body_mass",
    "m_arm",
    "f_arm_hz",
    "zeta_arm",
    "f_trunk_hz",
    "zeta_trunk",
    "h_gain",
    "c_unit",
)
#: The physical human's derived quantities a member also reports (masses, stiffnesses and
#: dampings of the chain).
PHYSICAL_HUMAN_DERIVED = ("m_trunk", "k_trunk", "c_trunk", "k_arm", "c_arm")

#: The prefix each block's parameters carry.
_PREFIX = {"structure": "struct", "valve": "valve", "human": "human"}

#: Every block's parameter fields (the physical human's modal and derived ones together).
BLOCK_FIELDS = {
    "structure": STRUCTURE_FIELDS,
    "valve": VALVE_FIELDS,
    "human": tuple(
        dict.fromkeys(LITERAL_HUMAN_FIELDS + PHYSICAL_HUMAN_FIELDS + PHYSICAL_HUMAN_DERIVED)
    ),
}


def parameter_name(block: str, field: str) -> str:
    """The name of ``block``'s parameter ``field`` (``"struct.k_s"``, ``"human.m_arm"``).

    Parameters
    ----------
    block : str
        ``"structure"``, ``"valve"`` or ``"human"``.
    field : str
        A field of the block (:data:`BLOCK_FIELDS`).

    Raises
    ------
    KeyError
        For an unknown block or field; the message names it and what exists.
    """
    if block not in BLOCK_FIELDS:
        raise KeyError(f"unknown block {block!r}; expected one of {sorted(BLOCK_FIELDS)}")
    if field not in BLOCK_FIELDS[block]:
        raise KeyError(
            f"unknown {block} parameter {field!r}; expected one of {BLOCK_FIELDS[block]}"
        )
    return f"{_PREFIX[block]}.{field}"


def block_of(name: str) -> str | None:
    """The block a parameter name belongs to, or None for a name of no block.

    Parameters
    ----------
    name : str
        A parameter name (:func:`parameter_name`).
    """
    head = name.split(".", 1)[0]
    for block, prefix in _PREFIX.items():
        if head == prefix:
            return block
    return None


def field_of(name: str) -> str:
    """The field of a parameter name (``"struct.k_s"`` -> ``"k_s"``).

    Parameters
    ----------
    name : str
        A parameter name (:func:`parameter_name`).
    """
    return name.split(".", 1)[1] if "." in name else name


def block_values(values: Mapping, block: str, fields=None) -> dict:
    """``{field: value}`` of ``block``'s parameters found in ``values`` (keyed by name).

    Parameters
    ----------
    values : mapping
        Values keyed by parameter names.
    block : str
        The block.
    fields : sequence of str, optional
        The fields wanted (all of the block's by default); a missing one is left out.
    """
    out = {}
    for f in BLOCK_FIELDS[block] if fields is None else fields:
        name = parameter_name(block, f)
        if name in values:
            out[f] = values[name]
    return out


@dataclasses.dataclass(frozen=True)
class Algebra:
    """How a block's matrices are made in one kind of arithmetic.

    Parameters
    ----------
    matrix : callable
        Rows of entries (numbers and the algebra's scalars) to a matrix.
    blockdiag : callable
        A list of matrices to their block diagonal.
    vstack : callable
        A list of matrices stacked vertically.
    constant : callable
        A numeric array to a constant matrix.
    square : callable
        ``x**2`` of a scalar (tight for intervals).
    reciprocal : callable
        ``1 / x`` of a scalar.
    nonzero : callable
        The structural pattern of a matrix (bool array: entries that may be nonzero).
    """

    matrix: Callable
    blockdiag: Callable
    vstack: Callable
    constant: Callable
    square: Callable
    reciprocal: Callable
    nonzero: Callable


def _batch(entries) -> int:
    return max((np.shape(e)[0] if np.ndim(e) else 1) for e in entries)


def _np_matrix(rows) -> np.ndarray:
    entries = [e for row in rows for e in row]
    out = np.zeros((_batch(entries), len(rows), len(rows[0])))
    for i, row in enumerate(rows):
        for j, e in enumerate(row):
            out[:, i, j] = e
    return out


def _np_blockdiag(mats) -> np.ndarray:
    n = max(m.shape[0] for m in mats)
    out = np.zeros((n, sum(m.shape[1] for m in mats), sum(m.shape[2] for m in mats)))
    r = c = 0
    for m in mats:
        out[:, r : r + m.shape[1], c : c + m.shape[2]] = m
        r, c = r + m.shape[1], c + m.shape[2]
    return out


def _np_vstack(mats) -> np.ndarray:
    n = max(m.shape[0] for m in mats)
    return np.concatenate([np.broadcast_to(m, (n, *m.shape[1:])) for m in mats], axis=1)


def as_batch(mats, n: int | None = None) -> tuple:
    """:data:`NUMPY` matrices as writable arrays of ``n`` members each (a constant one
    repeated; ``n`` the largest batch among them when None).

    Parameters
    ----------
    mats : sequence of ndarray
        Matrices of shape (N_i, rows, columns), N_i 1 or ``n``.
    n : int, optional
        The batch size.
    """
    n = max(m.shape[0] for m in mats) if n is None else n
    return tuple(np.array(np.broadcast_to(m, (n, *m.shape[1:])), float) for m in mats)


#: Batches of members: a scalar is a number or an array of shape (N,), a matrix an array of
#: shape (N, rows, columns) (N = 1 for numbers).
NUMPY = Algebra(
    matrix=_np_matrix,
    blockdiag=_np_blockdiag,
    vstack=_np_vstack,
    constant=lambda a: np.asarray(a, float)[None],
    square=lambda x: x * x,
    reciprocal=lambda x: 1.0 / x,
    nonzero=lambda m: np.any(np.asarray(m) != 0, axis=0),
)


def _get(p: Mapping, block: str, field: str):
    return p[parameter_name(block, field)]


def valve_block(p: Mapping, alg: Algebra) -> tuple:
    """The valve/cylinder (Eqn 3, ``e -> y``): ``A, B, C, D`` in cascade form.

    States, each of the size of the command at steady state: the spool position ``q``
    (``wn^2 / (s^2 + 2 zeta wn s + wn^2)`` of the command) and its rate over ``wn``, the
    cylinder speed over ``K_VC`` (``p1 / (s + p1)`` of the spool), and the cylinder position
    ``y`` (the integral of the speed). Nothing in the block reads the position, so a stroke
    limit can set it without making the other states inconsistent. The scaling keeps every
    entry of the order of ``wn``, ``p1`` or ``K_VC`` (a state weight of one means the same
    on every state).

    Parameters
    ----------
    p : mapping
        Every ``valve`` parameter (:data:`VALVE_FIELDS`) by name, in the algebra's scalars.
    alg : Algebra
        The arithmetic.
    """
    wn = TWO_PI * _get(p, "valve", "wn_hz")
    p1 = _get(p, "valve", "p1")
    A = alg.matrix(
        [
            [0.0, wn, 0.0, 0.0],
            [-wn, -(2.0 * _get(p, "valve", "zeta") * wn), 0.0, 0.0],
            [p1, 0.0, -p1, 0.0],
            [0.0, 0.0, _get(p, "valve", "k_vc"), 0.0],
        ]
    )
    B = alg.matrix([[0.0], [wn], [0.0], [0.0]])
    C = alg.constant(np.array([[0.0, 0.0, 0.0, 1.0]]))
    D = alg.constant(np.zeros((1, 1)))
    return A, B, C, D


def _section(z, w, alg: Algebra):
    """``(2 z w s + w^2) / (s^2 + 2 z w s + w^2)`` with states ``w^2 x`` and ``w x'``: ``A``
    and ``2 z`` (the output is the first state plus ``2 z`` times the second; the input
    enters the second state with gain ``w``)."""
    z2 = 2.0 * z
    return alg.matrix([[0.0, w], [-w, -(z2 * w)]]), z2


def structure_block(p: Mapping, alg: Algebra) -> tuple:
    """The structure (Eqn 4): ``y -> (v, c)``, ``A, B, C, D``.

    Two cascaded sections ``(2 z_i w_i s + w_i^2) / (s^2 + 2 z_i w_i s + w_i^2)`` give the
    cab displacement ``v = K_s * sections(y)``; the acceleration is ``c = s^2 v`` (the
    second output, biproper). 4 states, each section's scaled (``w^2 x`` and ``w x'``) so
    that the entries are of the order of the natural frequencies.

    Parameters
    ----------
    p : mapping
        Every ``structure`` parameter (:data:`STRUCTURE_FIELDS`) by name, in the algebra's
        scalars (or numbers).
    alg : Algebra
        The arithmetic.
    """
    z1, w1 = _get(p, "structure", "zeta1"), TWO_PI * _get(p, "structure", "f1_hz")
    z2, w2 = _get(p, "structure", "zeta2"), TWO_PI * _get(p, "structure", "f2_hz")
    k = _get(p, "structure", "k_s")
    A1, d1 = _section(z1, w1, alg)
    A2, d2 = _section(z2, w2, alg)
    # cascade: section 1 driven by y, section 2 driven by section 1's output
    A = alg.blockdiag([A1, A2]) + alg.matrix(
        [[0.0] * 4, [0.0] * 4, [0.0] * 4, [w2, d1 * w2, 0.0, 0.0]]
    )
    B = alg.matrix([[0.0], [w1], [0.0], [0.0]])
    Cv = alg.matrix([[0.0, 0.0, k, k * d2]])
    CA = Cv @ A
    C = alg.vstack([Cv, CA @ A])
    D = alg.vstack([alg.constant(np.zeros((1, 1))), CA @ B])
    return A, B, C, D


def literal_human_block(p: Mapping, alg: Algebra) -> tuple:
    """Eqn 5 times ``s^2`` (``v -> h``): ``K_H (s + z1)^2 / (s + p1)^2``, ``A, B, C, D``.

    Parameters
    ----------
    p : mapping
        ``human.k_h``, ``human.z1``, ``human.p1`` in the algebra's scalars.
    alg : Algebra
        The arithmetic.
    """
    k, z1, p1 = (_get(p, "human", f) for f in LITERAL_HUMAN_FIELDS)
    A = alg.matrix([[0.0, 1.0], [-alg.square(p1), -2.0 * p1]])
    B = alg.constant(np.array([[0.0], [1.0]]))
    C = alg.matrix([[k * (alg.square(z1) - alg.square(p1)), k * (2.0 * (z1 - p1))]])
    D = alg.matrix([[k]])
    return A, B, C, D


def human_entries_modal(p: Mapping, trunk_share: float, alg: Algebra) -> dict:
    """The chain's matrix entries (:func:`physical_human_block`) from the modal parameters.

    Written in the per-unit-mass rates ``r = m_arm / m_trunk``, ``w_t^2 = k_trunk / (m_trunk
    + m_arm)``, ``2 zeta_t w_t = c_trunk / (m_trunk + m_arm)``, ``w_a^2 = k_arm / m_arm``,
    ``2 zeta_a w_a = c_arm / m_arm``, each parameter appearing as few times as it can (tight
    interval enclosures).

    Parameters
    ----------
    p : mapping
        ``human.body_mass``, ``human.m_arm``, ``human.f_trunk_hz``, ``human.zeta_trunk``,
        ``human.f_arm_hz``, ``human.zeta_arm``, ``human.h_gain``, ``human.c_unit`` by name.
    trunk_share : float
        The upper body's mass per unit body mass.
    alg : Algebra
        The arithmetic.
    """
    m_t = trunk_share * _get(p, "human", "body_mass")
    m_a = _get(p, "human", "m_arm")
    r = m_a * alg.reciprocal(m_t)
    wt = TWO_PI * _get(p, "human", "f_trunk_hz")
    wa = TWO_PI * _get(p, "human", "f_arm_hz")
    wt2, wa2 = alg.square(wt), alg.square(wa)
    st = 2.0 * _get(p, "human", "zeta_trunk") * wt
    sa = 2.0 * _get(p, "human", "zeta_arm") * wa
    one_r = 1.0 + r
    cu = _get(p, "human", "c_unit")
    return {
        "a20": -(one_r * wt2) - r * wa2,
        "a21": r * wa2,
        "a22": -(one_r * st) - r * sa,
        "a23": r * sa,
        "a30": wa2,
        "a31": -wa2,
        "a32": sa,
        "a33": -sa,
        "b20": -cu,
        "b30": -cu,
        "b31": alg.reciprocal(m_a),
        "c01": _get(p, "human", "h_gain"),
    }


def human_entries_physical(m_trunk, m_arm, k_trunk, c_trunk, k_arm, c_arm, h_gain, c_unit) -> dict:
    """The chain's matrix entries (:func:`physical_human_block`) from masses, stiffnesses and
    dampings (the equations of :mod:`backhoe.model.physical` divided by the masses).

    Parameters
    ----------
    m_trunk, m_arm : float or ndarray
        Upper-body and arm-endpoint masses, kg.
    k_trunk, c_trunk, k_arm, c_arm : float or ndarray
        Seat-trunk and trunk-arm stiffnesses (N/m) and dampings (N s/m).
    h_gain, c_unit : float or ndarray
        Output and input unit gains (:mod:`backhoe.model.physical`).
    """
    mt, ma, kt, ct, ka, ca = m_trunk, m_arm, k_trunk, c_trunk, k_arm, c_arm
    return {
        "a20": -(kt + ka) / mt,
        "a21": ka / mt,
        "a22": -(ct + ca) / mt,
        "a23": ca / mt,
        "a30": ka / ma,
        "a31": -ka / ma,
        "a32": ca / ma,
        "a33": -ca / ma,
        "b20": -c_unit,
        "b30": -c_unit,
        "b31": 1.0 / ma,
        "c01": h_gain,
    }


def physical_human_block(e: Mapping, alg: Algebra) -> tuple:
    """The seated two-mass chain (``c, f -> h``): ``A, B, C, D``.

    States ``[z_trunk, z_arm, z_trunk', z_arm']`` relative to the seat; inputs the seat
    acceleration and the handle force; output the hand motion.

    Parameters
    ----------
    e : mapping
        The entries, :func:`human_entries_modal` or :func:`human_entries_physical`.
    alg : Algebra
        The arithmetic.
    """
    A = alg.matrix(
        [
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [e["a20"], e["a21"], e["a22"], e["a23"]],
            [e["a30"], e["a31"], e["a32"], e["a33"]],
        ]
    )
    B = alg.matrix([[0.0, 0.0], [0.0, 0.0], [e["b20"], 0.0], [e["b30"], e["b31"]]])
    C = alg.matrix([[0.0, e["c01"], 0.0, 0.0]])
    D = alg.constant(np.zeros((1, 2)))
    return A, B, C, D


def pi_block(kp: float, ki: float) -> tuple:
    """The cylinder loop's PI controller (``err -> e``), ``e = kp err + ki integral(err)``:
    ``A, B, C, D`` (one integrator state; none when ``ki`` is 0), numpy arrays.

    Parameters
    ----------
    kp, ki : float
        Proportional and integral gains.
    """
    if ki > 0.0:
        return tuple(np.array(m, float) for m in ([[0.0]], [[1.0]], [[ki]], [[kp]]))
    return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[float(kp)]])
