"""H-infinity synthesis for an uncertain system: its weighted generalized plant, and
controllers for the nominal member and for sampled members.

:func:`augw` is python-control's ``augw`` for an uncertain plant (a ``uss``, an
uncertain transfer function or a python-control system), joined by signal names
(:func:`uncertainty.interconnect`): the mixed-sensitivity plant whose closed loop with
``u = K v`` maps ``w`` to ``z1 = W1 S w``, ``z2 = W2 K S w`` and ``z3 = W3 T w``
(``S = (I + G K)^-1``, ``T = G K S``)::

          w ----->(+)---- v --------------------------------+--> v (measured)
                   ^ -                                       |
                   |                                         +--> [ W1 ] --> z1
                  yg
                   |
          u ---+-->[ G ]-- yg --> [ W3 ] --> z3
               |
               +--> [ W2 ] --> z2

:class:`UncertainPlant` is that plant: a ``uss`` with named partitions ``w, u, z, y``
(the uncertain counterpart of :class:`robust.synthesis.GeneralizedPlant`), whose members
(:meth:`UncertainPlant.at`, :meth:`UncertainPlant.nominal`,
:meth:`UncertainPlant.members`) are generalized plants the synthesis of :mod:`robust`
takes. :func:`hinfsyn_nominal` designs for the nominal member
(:func:`robust.synthesis.hinfsyn_lmi`), :func:`hinfsyn_members` one controller for a set
of members with a certificate for each (:func:`robust.synthesis.hinfsyn_multi`, on
members of :func:`uncertainty.sample`). Both controllers are ``u = K v`` with
``v = w - y_G``: closed around the plant alone that is ``G.feedback(K)``, the convention
of :func:`uncertainty.robust_margin`, which then tells how much of the box the design
holds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from robust.errors import ModelStructureError, ParameterError
from robust.synthesis import (
    GeneralizedPlant,
    HinfResult,
    MultiHinfResult,
    hinfsyn_lmi,
    hinfsyn_multi,
)
from uncertainty.sampling import SampleSet, sample
from uncertainty.uss import USS, interconnect, uss

__all__ = ["UncertainPlant", "augw", "hinfsyn_nominal", "hinfsyn_members"]


def _names(base: str, n: int) -> list:
    return [base] if n == 1 else [f"{base}[{i}]" for i in range(n)]


@dataclasses.dataclass(frozen=True)
class UncertainPlant:
    """An uncertain generalized plant: a ``uss`` with named partitions w, u, z, y.

    Parameters
    ----------
    sys : USS
        The plant; its signal names are partitioned by the names below.
    w, u, z, y : tuple of str
        Exogenous inputs, controls, performance outputs and measurements: every input of
        ``sys`` in one of ``w, u`` and every output in one of ``z, y``
        (:meth:`robust.synthesis.GeneralizedPlant.from_system` checks them).

    Attributes
    ----------
    parameters : dict
        The uncertain reals of ``sys``, in order (what :func:`uncertainty.sample` draws).
    """

    sys: USS
    w: tuple
    u: tuple
    z: tuple
    y: tuple

    def __post_init__(self):
        if not isinstance(self.sys, USS):
            raise ModelStructureError(
                f"UncertainPlant: sys must be a uss; got {type(self.sys).__name__}"
            )
        for part in ("w", "u", "z", "y"):
            object.__setattr__(self, part, tuple(getattr(self, part)))
        self.nominal()  # the partition checked once, by GeneralizedPlant's own rules

    @property
    def parameters(self) -> dict:
        """Name -> uncertain parameter of every uncertain real of the plant."""
        return self.sys.parameters

    def at(self, values: Mapping) -> GeneralizedPlant:
        """The member at ``values`` (name -> number; others nominal), a generalized plant."""
        return GeneralizedPlant.from_system(
            self.sys.at(values), w=self.w, u=self.u, z=self.z, y=self.y
        )

    def nominal(self) -> GeneralizedPlant:
        """The nominal member, a :class:`robust.synthesis.GeneralizedPlant`."""
        return self.at({})

    def members(self, samples: SampleSet) -> list:
        """The generalized plants of the members of ``samples`` (rows of parameter values).

        Parameters
        ----------
        samples : SampleSet
            Members drawn by :func:`uncertainty.sample` from this plant (or its system,
            or the transfer function it was built from): its names must be the plant's
            parameters, in any order.
        """
        if not isinstance(samples, SampleSet):
            raise ParameterError(
                f"UncertainPlant.members: samples must be an uncertainty.SampleSet; "
                f"got {type(samples).__name__}"
            )
        if sorted(samples.names) != sorted(self.parameters):
            raise ParameterError(
                f"UncertainPlant.members: sample names {list(samples.names)} must be the "
                f"plant's parameters {list(self.parameters)} (draw them with "
                "uncertainty.sample(plant, n))"
            )
        return [self.at(samples.row(i)) for i in range(len(samples))]

    def ordered(self) -> USS:
        """The plant's system with its inputs ordered ``[w; u]`` and outputs ``[z; y]``
        (control.hinfsyn's partition, what :func:`uncertainty.musyn` takes)."""
        cols = [self.sys.inputs.index(n) for n in (*self.w, *self.u)]
        rows = [self.sys.outputs.index(n) for n in (*self.z, *self.y)]
        A, B, C, D = self.sys.A, self.sys.B, self.sys.C, self.sys.D
        return USS(
            A,
            B[:, cols],
            C[rows, :],
            D[np.ix_(rows, cols)],
            inputs=[*self.w, *self.u],
            outputs=[*self.z, *self.y],
        )

    def closed_loop(self, K) -> USS:
        """The uncertain closed loop from w to z with ``u = K y`` (the lower LFT).

        Parameters
        ----------
        K : control.StateSpace, control.TransferFunction or USS
            Controller from the ``y`` signals to the ``u`` signals (positive feedback, as
            :func:`robust.synthesis.hinfsyn_lmi` returns it).
        """
        Ku = uss(K)
        if (Ku.ninputs, Ku.noutputs) != (len(self.y), len(self.u)):
            raise ModelStructureError(
                f"UncertainPlant.closed_loop: K must map the {len(self.y)} measurements to the "
                f"{len(self.u)} controls; got {Ku.ninputs} -> {Ku.noutputs}"
            )
        Ku = uss(Ku, inputs=list(self.y), outputs=list(self.u))
        return interconnect([self.sys, Ku], inputs=list(self.w), outputs=list(self.z))


def _weight(W, n: int, name: str, inputs: list, outputs: list) -> list:
    """The weight ``name`` on ``n`` channels: one block (n x n) or one per channel."""
    if W is None:
        return []
    try:
        Wu = uss(W)
    except (ParameterError, ModelStructureError) as exc:
        raise type(exc)(f"augw: {name}: {exc}") from None
    if (Wu.ninputs, Wu.noutputs) == (n, n):
        return [uss(Wu, inputs=inputs, outputs=outputs)]
    if (Wu.ninputs, Wu.noutputs) == (1, 1):
        return [uss(Wu, inputs=[i], outputs=[o]) for i, o in zip(inputs, outputs)]
    raise ModelStructureError(
        f"augw: {name} must have one input and one output (applied to each of the {n} "
        f"channels) or be {n} x {n}; got {Wu.ninputs} inputs and {Wu.noutputs} outputs"
    )


def augw(G, w1=None, w2=None, w3=None) -> UncertainPlant:
    """The mixed-sensitivity generalized plant of an uncertain plant (python-control's ``augw``).

    Parameters
    ----------
    G : USS, UTF, control.StateSpace or control.TransferFunction
        The plant, ``ny`` outputs and ``nu`` inputs (an uncertain transfer function is
        realised by :meth:`uncertainty.UTF.to_uss`; it must be proper).
    w1, w2, w3 : system or number, optional
        Weights on ``S`` (``ny`` channels), on ``K S`` (``nu``) and on ``T`` (``ny``): a
        python-control system, an uncertain transfer function, a ``uss``, a number or an
        uncertain expression, of one input and one output (applied to each channel) or
        square of the channels' size; proper. None leaves that output out; at least one
        is needed.

    Returns
    -------
    UncertainPlant
        Inputs ``w`` (``ny``) and ``u`` (``nu``); outputs ``z1`` (with ``w1``), ``z2``
        (with ``w2``), ``z3`` (with ``w3``) and the measured error ``v = w - G u``. The
        names carry an index ``[i]`` when there are several channels.

    Raises
    ------
    robust.errors.ModelStructureError
        If no weight is given, a weight's size fits neither form, or ``G`` or a weight is
        improper or discrete-time.
    robust.errors.ParameterError
        If ``G`` or a weight is not a system, a number or an uncertain expression.

    Examples
    --------
    A damped mass on a spring with an uncertain stiffness, weighted for tracking below
    1 rad/s and for control effort:

    >>> import control as ct
    >>> from uncertainty import augw, tf, ureal
    >>> k = ureal("k", 4.0, 3.0, 5.0)
    >>> s = tf("s")
    >>> P = augw(k / (s**2 + 0.8 * s + k), w1=ct.tf([0.5, 1.0], [1.0, 0.01]), w2=0.1)
    >>> P.w, P.u, P.z, P.y
    (('w',), ('u',), ('z1', 'z2'), ('v',))
    >>> P.nominal().nx  # two of the plant, one of the weight
    3
    """
    if w1 is None and w2 is None and w3 is None:
        raise ModelStructureError(
            "augw: give at least one weight (w1 on S, w2 on K S, w3 on T); got none"
        )
    try:
        Gu = uss(G)
    except (ParameterError, ModelStructureError) as exc:
        raise type(exc)(f"augw: G: {exc}") from None
    ny, nu = Gu.noutputs, Gu.ninputs
    w, u, v, yg = _names("w", ny), _names("u", nu), _names("v", ny), _names("yg", ny)
    z1, z2, z3 = _names("z1", ny), _names("z2", nu), _names("z3", ny)
    error = uss([], [], [], np.hstack([np.eye(ny), -np.eye(ny)]), inputs=w + yg, outputs=v)
    blocks = [uss(Gu, inputs=u, outputs=yg), error]
    blocks += _weight(w1, ny, "w1", v, z1)
    blocks += _weight(w2, nu, "w2", u, z2)
    blocks += _weight(w3, ny, "w3", yg, z3)
    z = (z1 if w1 is not None else []) + (z2 if w2 is not None else [])
    z += z3 if w3 is not None else []
    P = interconnect(blocks, inputs=w + u, outputs=z + v)
    return UncertainPlant(P, tuple(w), tuple(u), tuple(z), tuple(v))


def _plant(plant, where: str) -> UncertainPlant:
    if not isinstance(plant, UncertainPlant):
        raise ParameterError(
            f"{where}: plant must be an uncertain generalized plant (uncertainty.augw or "
            f"uncertainty.UncertainPlant); got {type(plant).__name__}"
        )
    return plant


def hinfsyn_nominal(plant: UncertainPlant, **options) -> HinfResult:
    """An H-infinity controller for the nominal member of an uncertain plant.

    :func:`robust.synthesis.hinfsyn_lmi` on :meth:`UncertainPlant.nominal`; nothing is
    claimed for the other members (check them with :func:`uncertainty.robust_margin` or
    design for members with :func:`hinfsyn_members`).

    Parameters
    ----------
    plant : UncertainPlant
        The uncertain generalized plant (:func:`augw`).
    **options
        Keyword options of :func:`robust.synthesis.hinfsyn_lmi` (``backoff``,
        ``gamma_max``, ``solvers``...).

    Returns
    -------
    robust.synthesis.HinfResult
        ``K`` (``u = K v``), the verified nominal closed-loop norm ``gamma`` and the
        certificate of the LMI optimum.

    Examples
    --------
    >>> import control as ct
    >>> from uncertainty import augw, hinfsyn_nominal, tf, ureal
    >>> k = ureal("k", 4.0, 3.0, 5.0)
    >>> s = tf("s")
    >>> P = augw(k / (s**2 + 0.8 * s + k), w1=ct.tf([0.5, 1.0], [1.0, 0.01]), w2=0.1)
    >>> res = hinfsyn_nominal(P)
    >>> bool(res.gamma < 1.0), res.K.ninputs, res.K.noutputs
    (True, 1, 1)
    """
    return hinfsyn_lmi(_plant(plant, "hinfsyn_nominal").nominal(), **options)


def hinfsyn_members(
    plant: UncertainPlant,
    samples: SampleSet | int = 8,
    *,
    seed: int = 0,
    method: str = "lhs",
    nominal: bool = True,
    **options,
) -> MultiHinfResult:
    """One H-infinity controller for sampled members of an uncertain plant, each certified.

    :func:`robust.synthesis.hinfsyn_multi` on the members' generalized plants: every
    member listed gets a Lyapunov certificate of stability and of its weighted
    closed-loop norm below ``gamma_bound``; nothing is claimed between the members
    (check the box with :func:`uncertainty.robust_margin`).

    Parameters
    ----------
    plant : UncertainPlant
        The uncertain generalized plant (:func:`augw`).
    samples : SampleSet or int
        The members (drawn from the plant's parameters, in order), or how many to draw
        with :func:`uncertainty.sample` (``method``, ``seed``).
    seed : int
        Seed of the draw (when ``samples`` is a number).
    method : str
        Sampling method of the draw (``"lhs"``, ``"mc"``, ``"grid"``, ``"vertices"``).
    nominal : bool
        Add the nominal member first (default True).
    **options
        Keyword options of :func:`robust.synthesis.hinfsyn_multi` (``max_iter``,
        ``rtol``, ``K0``...).

    Returns
    -------
    robust.synthesis.MultiHinfResult
        ``K`` and ``gammas``, the members' verified norms: the nominal's first (with
        ``nominal``), then the samples' rows in order.

    Examples
    --------
    >>> import control as ct
    >>> from uncertainty import augw, hinfsyn_members, tf, ureal
    >>> k = ureal("k", 4.0, 3.0, 5.0)
    >>> s = tf("s")
    >>> P = augw(k / (s**2 + 0.8 * s + k), w1=ct.tf([0.5, 1.0], [1.0, 0.01]), w2=0.1)
    >>> res = hinfsyn_members(P, 3, seed=1, max_iter=2)
    >>> len(res.gammas), bool(res.gamma <= res.gamma_bound * (1 + 1e-6))
    (4, True)
    """
    plant = _plant(plant, "hinfsyn_members")
    if not isinstance(nominal, (bool, np.bool_)):
        raise ParameterError(f"hinfsyn_members: nominal must be True or False; got {nominal!r}")
    if not isinstance(samples, SampleSet):
        samples = sample(plant, samples, method=method, seed=seed)
    members = ([plant.nominal()] if nominal else []) + plant.members(samples)
    return hinfsyn_multi(members, **options)
