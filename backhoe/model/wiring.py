"""The wiring of the paper's Figure 5 loop: one table that every assembly consumes.

::

              handle x = u + h_cmd                     cylinder loop
     u ──►(+)──────────► K_PSF ──r──►(+)──err──► PI ──e──► valve/cyl ──┬── y
           ▲                          ▲ ▲-                             │
           │                    r_corr┘ └──────────────────────────────┤
           │                                                           ▼
           └── h_cmd = sigma*kappa*h ◄── h ── human ◄── c ── structure ◄┘
                                               ▲
                                    f = f_ctrl + f_ext (force on the hand)

The dynamic blocks (PI, valve/cylinder, structure, human, controller) carry their
own signal names. Everything else in the loop is a static *junction*, a weighted
sum of named signals; :func:`figure5_junctions` is the single table of them.
Three assemblies consume it:

* :class:`backhoe.model.loop.BDFTLoop` turns each junction into a static
  python-control system and closes the loop with :func:`connect`;
* the force-feedback generalized plant (:mod:`backhoe.synthesis.forcefb`) takes
  the loop's blocks, junctions included, and adds its weights;
* the batched family assembly (:mod:`backhoe.families.batched`) expands every block
  input through the junctions (:func:`expand`) into one constant interconnection
  matrix.

The controller's force output is called ``f_ctrl`` inside the loop (``f`` is the
total force on the hand); :data:`CONTROLLER_FORCE` names it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence

import control as ct
import numpy as np

from robust.errors import ModelStructureError
from uncertainty.closeloops import algebraic_cycle

__all__ = [
    "Junction",
    "figure5_junctions",
    "expand",
    "interconnection_matrix",
    "connect",
    "algebraic_cycle",
    "MAX_LOOP_CONDITION",
    "renamed",
    "CONTROLLER_FORCE",
    "EXOGENOUS",
]

#: Name of the controller's force output inside the loop (the hand force is ``f``).
CONTROLLER_FORCE = "f_ctrl"
#: Exogenous inputs of the loop: intended handle motion and an external force on the hand.
EXOGENOUS = ("u", "f_ext")


@dataclasses.dataclass(frozen=True)
class Junction:
    """A static junction: ``output = sum(gain * signal for signal, gain in terms)``.

    Parameters
    ----------
    name : str
        Block name (``"handle"``, ``"cyl_err"``, ...).
    output : str
        Name of the signal it defines.
    terms : tuple of (str, float)
        The summed signals and their gains.
    """

    name: str
    output: str
    terms: tuple[tuple[str, float], ...]

    def __post_init__(self):
        for sig, gain in self.terms:
            if not math.isfinite(gain):
                raise ModelStructureError(
                    f"junction {self.name!r}: gain of {sig!r} must be finite; got {gain!r}"
                )

    @property
    def inputs(self) -> tuple[str, ...]:
        """The summed signals' names."""
        return tuple(s for s, _ in self.terms)

    def system(self) -> ct.StateSpace:
        """The junction as a static python-control system (no states)."""
        D = np.array([[g for _, g in self.terms]], dtype=float)
        return ct.ss(
            np.zeros((0, 0)),
            np.zeros((0, D.shape[1])),
            np.zeros((1, 0)),
            D,
            inputs=list(self.inputs),
            outputs=[self.output],
            name=self.name,
        )


def figure5_junctions(
    *,
    k_psf: float,
    handle_gain: float,
    bdft: bool = True,
    reference_correction: bool = False,
    force_terms: Iterable[str] = (),
) -> tuple[Junction, ...]:
    """The static junctions of the Figure 5 loop.

    Parameters
    ----------
    k_psf : float
        Position scale factor ``K_PSF`` (cylinder reference per handle unit).
    handle_gain : float
        ``sigma * kappa``: handle units per unit of the human's output ``h``
        (junction sign times loop-scale factor, :class:`backhoe.model.loop.LoopCalibration`).
    bdft : bool
        With the feedthrough path (``x = u + h_cmd``); without it ``x = u``.
    reference_correction : bool
        Add a controller's correction ``r_corr`` to the cylinder reference.
    force_terms : iterable of str
        Signals summed into the hand force ``f`` (``"f_ext"`` and/or
        :data:`CONTROLLER_FORCE`); empty: no junction, ``f`` is left to the caller.

    Returns
    -------
    tuple of Junction
        ``loop_scale`` (``h_cmd``, with ``bdft``), ``handle`` (``x``), ``reference``
        (``r``), ``cyl_err`` (``err``) and, with ``force_terms``, ``hand_force`` (``f``).
    """
    err_terms = [("r", 1.0)] + ([("r_corr", 1.0)] if reference_correction else []) + [("y", -1.0)]
    out = []
    if bdft:
        out.append(Junction("loop_scale", "h_cmd", (("h", float(handle_gain)),)))
        out.append(Junction("handle", "x", (("u", 1.0), ("h_cmd", 1.0))))
    else:
        out.append(Junction("handle", "x", (("u", 1.0),)))
    out.append(Junction("reference", "r", (("x", float(k_psf)),)))
    out.append(Junction("cyl_err", "err", tuple(err_terms)))
    force_terms = tuple(force_terms)
    if force_terms:
        if not bdft:
            raise ModelStructureError(
                "the hand force exists only in the loop with BDFT (bdft=True)"
            )
        out.append(Junction("hand_force", "f", tuple((s, 1.0) for s in force_terms)))
    return tuple(out)


def expand(
    signal: str, junctions: Iterable[Junction], *, zero: Iterable[str] = EXOGENOUS
) -> dict[str, float]:
    """A signal as a linear combination of block outputs, through the junctions.

    Junction outputs are substituted recursively; signals in ``zero`` (exogenous
    inputs) contribute nothing; any other signal is a block output and stands for
    itself.

    Parameters
    ----------
    signal : str
        The signal to expand (typically a dynamic block's input).
    junctions : iterable of Junction
        The junction table (:func:`figure5_junctions`).
    zero : iterable of str
        Signals set to zero (default: the loop's exogenous inputs).

    Returns
    -------
    dict
        ``{block output: coefficient}``.

    Raises
    ------
    ModelStructureError
        If the junctions form an algebraic cycle.
    """
    table = {j.output: j for j in junctions}
    zeros = set(zero)

    def walk(sig, gain, seen, acc):
        if sig in zeros:
            return
        j = table.get(sig)
        if j is None:
            acc[sig] = acc.get(sig, 0.0) + gain
            return
        if sig in seen:
            raise ModelStructureError(f"the junctions form an algebraic cycle through {sig!r}")
        for src, g in j.terms:
            walk(src, gain * g, seen | {sig}, acc)

    acc: dict[str, float] = {}
    walk(signal, 1.0, frozenset(), acc)
    return acc


#: Largest condition number of ``I - D K`` (the blocks' direct feedthrough around the
#: wiring; rows and columns scaled to unit largest entry) that :func:`connect` solves; above
#: it the algebraic loop is refused (measured: at most 4.6 on the BDFT family's loops, 3e16
#: on a loop whose gain is unity up to rounding).
MAX_LOOP_CONDITION = 1e12


def connect(
    blocks: list,
    *,
    inputs: list[str],
    outputs: list[str],
    name: str,
    ignore_inputs: Iterable[str] = (),
) -> ct.StateSpace:
    """Interconnect named blocks by signal names; unused or unknown signals are errors.

    Every block input is connected to the block output of the same name, to the external
    input of that name (both, summed, if both exist), or held at zero when it is named in
    ``ignore_inputs``; any other block input is a :class:`robust.errors.ModelStructureError`
    (python-control's :func:`control.interconnect` only warns and leaves it at zero), so a
    misspelt signal name cannot drop a path of the loop. A block output may stay unread.

    The matrices are computed exactly: with the blocks stacked (``x' = A x + B v``,
    ``z = C x + D v``, ``v`` every block input, ``z`` every block output) and the wiring
    ``v = K z + E w`` (``w`` the external inputs), the block outputs are
    ``z = (I - D K)^-1 (C x + D E w)``, which closes the loop. (python-control's
    :func:`control.interconnect` builds the same system as a nonlinear one and
    linearises it by finite differences, about ten times slower and exact only to
    rounding of the difference quotients.) The states keep the blocks' order, labelled
    ``<block>_<state>`` as python-control labels them.

    Parameters
    ----------
    blocks : list of control.StateSpace or control.TransferFunction
        Named blocks with named signals, on one timebase.
    inputs, outputs : list of str
        External inputs and outputs of the interconnection (signal names; an output is
        a block output).
    name : str
        Name of the result.
    ignore_inputs : iterable of str
        Block inputs deliberately left unconnected (held at zero): a signal name (every
        block input of that name) or ``"<block>.<signal>"`` (that block's).

    Returns
    -------
    control.StateSpace

    Raises
    ------
    ModelStructureError
        For an unconnected block input (``Unused input``), an external input or output
        that no block has, two blocks driving one signal, a repeated block name, external
        input or output, blocks on different timebases, or an algebraic loop without a
        solution (``I - D K``, scaled, with a condition number above
        :data:`MAX_LOOP_CONDITION`;
        a loop through static gains that has a solution is solved, where
        :func:`control.interconnect` refuses every algebraic loop). The message names the
        signal or block.
    """
    ignore = set(ignore_inputs)
    systems = [_as_state_space(name, b) for b in blocks]
    dt = _common_timebase(name, systems)
    for what, names in (
        ("block name", [b.name for b in systems]),
        ("external input", list(inputs)),
        ("output", list(outputs)),
    ):
        twice = sorted({x for x in names if names.count(x) > 1})
        if twice:
            raise ModelStructureError(
                f"{name}: cannot connect the blocks by name: repeated {what}(s) {twice}"
            )
    out_index: dict[str, int] = {}
    z_names = [s for b in systems for s in b.output_labels]
    for k, sig in enumerate(z_names):
        if sig in out_index:
            raise ModelStructureError(
                f"{name}: cannot connect the blocks by name: two blocks drive signal {sig!r}"
            )
        out_index[sig] = k
    v_names = [s for b in systems for s in b.input_labels]
    known = set(v_names)
    for sig in inputs:
        if sig not in known:
            raise ModelStructureError(
                f"{name}: cannot connect the blocks by name: no block has the input {sig!r} "
                f"(block inputs: {sorted(known)})"
            )
    for sig in outputs:
        if sig not in out_index:
            raise ModelStructureError(
                f"{name}: cannot connect the blocks by name: no block has the output {sig!r} "
                f"(block outputs: {sorted(out_index)})"
            )
    ext = {sig: k for k, sig in enumerate(inputs)}
    K = np.zeros((len(v_names), len(z_names)))
    E = np.zeros((len(v_names), len(inputs)))
    unused = []
    owners = [b.name for b in systems for _ in b.input_labels]
    for i, (sig, owner) in enumerate(zip(v_names, owners)):
        if sig in out_index:
            K[i, out_index[sig]] = 1.0
        if sig in ext:
            E[i, ext[sig]] = 1.0
        held = sig in ignore or f"{owner}.{sig}" in ignore
        if sig not in out_index and sig not in ext and not held:
            unused.append(f"{owner}.{sig}")
    if unused:
        raise ModelStructureError(
            f"{name}: Unused input(s) in the interconnection: {sorted(set(unused))}; "
            "connect every block input (or name it in ignore_inputs)"
        )
    A, B, C, D = _stacked(systems)
    M = np.eye(len(z_names)) - D @ K
    # an algebraic loop of unit gain (or one off unity by rounding) has no solution; without
    # a cycle through the feedthroughs there is no algebraic loop (I - D K is unipotent)
    cond = _equilibrated_condition(M) if _feedthrough_cycle(D, K) else 1.0
    if cond > MAX_LOOP_CONDITION:
        raise ModelStructureError(
            f"{name}: the blocks' direct feedthrough forms an algebraic loop without a "
            f"solution (I - D K is singular or nearly so: condition number {cond:.3g} "
            f"after row and column scaling > {MAX_LOOP_CONDITION:.0e})"
        )
    sol = np.linalg.solve(M, np.hstack([C, D @ E]))  # z = sol @ [x; w]
    n = A.shape[0]
    Zx, Zw = sol[:, :n], sol[:, n:]
    S = np.zeros((len(outputs), len(z_names)))
    for r, sig in enumerate(outputs):
        S[r, out_index[sig]] = 1.0
    BK = B @ K
    states = [f"{b.name}_{lab}" for b in systems for lab in b.state_labels]
    return ct.ss(
        A + BK @ Zx,
        B @ E + BK @ Zw,
        S @ Zx,
        S @ Zw,
        dt,
        inputs=list(inputs),
        outputs=list(outputs),
        states=states,
        name=name,
    )


#: :func:`_feedthrough_cycle`'s answers by pattern (the members of a family share theirs)
_CYCLES: dict[tuple, bool] = {}


def _feedthrough_cycle(D: np.ndarray, K: np.ndarray) -> bool:
    """:func:`algebraic_cycle` of the pattern of ``D K`` (block output to block output through
    a direct feedthrough and a wire), kept per pattern."""
    P = (D != 0).astype(float) @ (K != 0).astype(float) > 0
    key = (P.shape, np.packbits(P).tobytes())
    found = _CYCLES.get(key)
    if found is None:
        if len(_CYCLES) >= 256:
            _CYCLES.clear()
        found = _CYCLES[key] = algebraic_cycle(P)
    return found


def _equilibrated_condition(M: np.ndarray) -> float:
    """2-norm condition number of ``M`` with its rows, then its columns, scaled to unit
    largest entry: free of the signals' units (the loop's gains span decades, so the raw
    condition number of a well-posed loop reached 5e10), infinite for a singular ``M``."""
    if not M.size:
        return 1.0
    r = np.max(np.abs(M), axis=1)
    if not np.all(r > 0):
        return math.inf
    M1 = M / r[:, None]
    c = np.max(np.abs(M1), axis=0)
    if not np.all(c > 0):
        return math.inf
    return float(np.linalg.cond(M1 / c[None, :]))


def _as_state_space(name: str, block) -> ct.StateSpace:
    """A block as a named state-space system (a transfer function converted)."""
    if isinstance(block, ct.StateSpace):
        return block
    if isinstance(block, ct.TransferFunction):
        return ct.ss(block, name=block.name)
    raise ModelStructureError(
        f"{name}: cannot connect the blocks by name: each block must be a linear "
        f"control.StateSpace or TransferFunction; got {type(block).__name__}"
    )


def _common_timebase(name: str, systems) -> float | None:
    """The blocks' timebase: static blocks (``None``) take the others'; two others clash."""
    dts = {b.dt for b in systems if b.dt is not None}
    if len(dts) > 1:
        raise ModelStructureError(
            f"{name}: cannot connect the blocks by name: blocks on different timebases "
            f"{sorted(dts, key=float)}"
        )
    return dts.pop() if dts else None


def _stacked(systems) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Block-diagonal ``A, B, C, D`` of the blocks, in their order."""
    mats = [[np.asarray(m, float) for m in (b.A, b.B, b.C, b.D)] for b in systems]
    ns = [a.shape[0] for a, _, _, _ in mats]
    ms = [b.ninputs for b in systems]
    ps = [b.noutputs for b in systems]
    A = np.zeros((sum(ns), sum(ns)))
    B = np.zeros((sum(ns), sum(ms)))
    C = np.zeros((sum(ps), sum(ns)))
    D = np.zeros((sum(ps), sum(ms)))
    i = j = k = 0
    for (a, b, c, d), n, m, p in zip(mats, ns, ms, ps):
        A[i : i + n, i : i + n] = a
        B[i : i + n, j : j + m] = b.reshape(n, m)
        C[k : k + p, i : i + n] = c.reshape(p, n)
        D[k : k + p, j : j + m] = d
        i, j, k = i + n, j + m, k + p
    return A, B, C, D


def renamed(
    sys: ct.StateSpace,
    mapping: Mapping[str, str],
    *,
    name: str | None = None,
) -> ct.StateSpace:
    """A copy of ``sys`` with input and output signals renamed by ``mapping``.

    Signals not in ``mapping`` keep their names (python-control's ``update_names``
    on a copy; ``sys`` itself is not changed).

    Parameters
    ----------
    sys : control.StateSpace
        The system (a controller, typically).
    mapping : mapping of str to str
        Old signal name -> new signal name, for inputs and outputs alike.
    name : str, optional
        New system name (default: unchanged).
    """
    out = ct.ss(sys.A, sys.B, sys.C, sys.D, sys.dt)
    out.update_names(
        inputs=[mapping.get(s, s) for s in sys.input_labels],
        outputs=[mapping.get(s, s) for s in sys.output_labels],
        name=name or sys.name,
    )
    return out


def interconnection_matrix(
    inputs: Sequence[str],
    outputs: Sequence[str],
    junctions: Iterable[Junction],
    *,
    zero: Iterable[str] = EXOGENOUS,
) -> np.ndarray:
    """Constant ``M`` with ``u = M y``: every block input from the block outputs.

    Each block input is expanded through the junctions (:func:`expand`) with the
    signals in ``zero`` held at zero.

    Parameters
    ----------
    inputs : sequence of str
        The dynamic blocks' inputs, stacked in block order (length ``m``).
    outputs : sequence of str
        The dynamic blocks' outputs, stacked in block order (length ``p``).
    junctions : iterable of Junction
        The junction table (:func:`figure5_junctions`).
    zero : iterable of str
        Signals set to zero (default: the loop's exogenous inputs).

    Returns
    -------
    ndarray, shape (m, p)

    Raises
    ------
    ModelStructureError
        If a block input needs a signal that no block provides.
    """
    outs = list(outputs)
    col = {s: j for j, s in enumerate(outs)}
    table = tuple(junctions)
    M = np.zeros((len(inputs), len(outs)))
    for i, s in enumerate(inputs):
        for src, coef in expand(s, table, zero=zero).items():
            if src not in col:
                raise ModelStructureError(
                    f"block input {s!r} needs the signal {src!r}, which no block provides "
                    f"(block outputs: {outs})"
                )
            M[i, col[src]] += coef
    return M
