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

* :class:`robust.model.loop.BDFTLoop` turns each junction into a static
  python-control system and closes the loop with :func:`connect`;
* the force-feedback generalized plant (:mod:`robust.synthesis.forcefb`) takes
  the loop's blocks, junctions included, and adds its weights;
* the batched family assembly (:mod:`uncertainty.batched`) expands every block
  input through the junctions (:func:`expand`) into one constant interconnection
  matrix.

The controller's force output is called ``f_ctrl`` inside the loop (``f`` is the
total force on the hand); :data:`CONTROLLER_FORCE` names it.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence

import control as ct
import numpy as np

from robust.errors import ModelStructureError

__all__ = [
    "Junction",
    "figure5_junctions",
    "expand",
    "interconnection_matrix",
    "connect",
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
        (junction sign times loop-scale factor, :class:`robust.model.loop.LoopCalibration`).
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


def connect(
    blocks: list,
    *,
    inputs: list[str],
    outputs: list[str],
    name: str,
    ignore_inputs: Iterable[str] = (),
) -> ct.StateSpace:
    """Interconnect named blocks by signal names; unused or unknown signals are errors.

    python-control's :func:`control.interconnect` only warns when a block input is
    left unconnected (it is then silently zero) or a block output is unused; here
    both are :class:`robust.errors.ModelStructureError`, so a misspelt signal name
    cannot drop a path of the loop. A block input that is meant to be zero must be
    named in ``ignore_inputs``.

    Parameters
    ----------
    blocks : list of control.StateSpace
        Named blocks with named signals.
    inputs, outputs : list of str
        External inputs and outputs of the interconnection (signal names).
    name : str
        Name of the result.
    ignore_inputs : iterable of str
        Block inputs deliberately left unconnected (held at zero).

    Returns
    -------
    control.StateSpace
    """
    ignore = list(ignore_inputs)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            sys = ct.interconnect(
                blocks,
                inputs=list(inputs),
                outputs=list(outputs),
                name=name,
                check_unused=True,
                ignore_inputs=ignore or None,
                ignore_outputs=_unused_outputs_allowed(blocks, outputs),
            )
        except ValueError as exc:
            raise ModelStructureError(f"{name}: cannot connect the blocks by name: {exc}") from None
    for w in caught:
        msg = str(w.message)
        if "Unused" in msg:
            raise ModelStructureError(
                f"{name}: {msg}; connect every block input (or name it in ignore_inputs)"
            )
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return sys


def _unused_outputs_allowed(blocks, outputs) -> list[str]:
    """Block outputs that may stay unread: the loop's measurable signals.

    Every block output is a signal a caller may or may not ask for (``e``, ``h``,
    ``r_corr``...); an unread output drops no path, unlike an unconnected input.
    """
    consumed = {s for b in blocks for s in b.input_labels}
    return [
        s for b in blocks for s in b.output_labels if s not in outputs and s not in consumed
    ] or None


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
