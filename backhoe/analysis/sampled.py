"""Continuous against discrete closed loops: does the 1 kHz controller behave like the design?

The continuous design is validated on the family; the target runs its Tustin
equivalent at the servo rate. :func:`sampled_data_check` closes each member's
loop both ways and compares them:

* continuous: the member's Figure 5 loop with the continuous controller;
* discrete: the same plant (the loop with the controller's signals cut open)
  sampled by zero-order hold at the controller's sample time, the DAC holding the
  handle force (or reference correction) between samples, closed with the
  discrete controller.

Reported per member: the largest real part of the continuous closed-loop poles,
that of the discrete poles mapped back by ``s = ln(z) / T``, and the largest
deviation of the intended-motion-to-cylinder response ``u -> y`` between the two
over 0.05-10 Hz, in dB. The sampled-data loop is exact at the sampling instants
for a held input (Franklin, Powell & Workman, *Digital Control of Dynamic
Systems*, 3rd ed., 1998, Sec. 4.3).
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np

from backhoe.analysis.loops import loop_poles
from backhoe.model.loop import BDFTLoop
from backhoe.model.wiring import connect
from robust.analysis.realization import minimal_realization
from robust.analysis.stability import poles_stable
from robust.checks import check_int, check_state_space
from robust.errors import ModelStructureError, ParameterError

__all__ = ["SampledDataCheck", "sampled_data_check", "open_plant", "CHECK_BAND_HZ"]

CHECK_BAND_HZ = (0.05, 10.0)


@dataclasses.dataclass(frozen=True)
class SampledDataCheck:
    """Continuous vs discrete closed loop of one member (see the module notes).

    Parameters
    ----------
    max_real_continuous : float
        Largest real part of the continuous closed-loop poles, rad/s.
    max_real_discrete : float
        Largest real part of the discrete poles mapped by ``s = ln(z) / T``, rad/s.
    max_response_deviation_db : float
        Largest deviation of ``|u -> y|`` between the two loops over the check band, dB,
        to 0.001 dB (its last digits depend on the CPU's BLAS kernel near notches).
    stable_continuous, stable_discrete : bool
        Stability of each loop (:mod:`robust.analysis.stability`).
    """

    max_real_continuous: float  # rad/s
    max_real_discrete: float  # rad/s, discrete poles mapped by s = ln(z)/T
    max_response_deviation_db: float
    stable_continuous: bool
    stable_discrete: bool

    @property
    def agree(self) -> bool:
        """Both loops stable or both unstable."""
        return self.stable_continuous == self.stable_discrete

    def to_json(self) -> dict:
        """The fields and :attr:`agree` as a JSON-able dict."""
        return dict(dataclasses.asdict(self), agree=self.agree)


def open_plant(loop, K):
    """The member's loop with the controller removed.

    Inputs ``u`` and K's outputs, outputs ``y`` and K's inputs (``y`` once when K
    measures it); a human force port that K does not drive is held at zero.

    Parameters
    ----------
    loop : backhoe.model.loop.BDFTLoop
        One family member.
    K : control.StateSpace
        The controller whose signals are cut open (loop convention).

    Raises
    ------
    ParameterError
        If ``loop`` is not a :class:`~backhoe.model.loop.BDFTLoop`.
    ModelStructureError
        If ``K`` is not a :class:`control.StateSpace`.
    """
    if not isinstance(loop, BDFTLoop):
        raise ParameterError(f"open_plant: loop must be a BDFTLoop; got {type(loop).__name__}")
    if not isinstance(K, ct.StateSpace):
        raise ModelStructureError(
            f"open_plant: K must be a control.StateSpace; got {type(K).__name__}"
        )
    outs = list(K.output_labels)
    blocks = loop.blocks(bdft=True, reference_correction="r_corr" in outs)
    ignore = ["f"] if loop.human.has_force_port and "f" not in outs else []
    # y is listed once: a controller that measures the cylinder position reads that output
    return connect(
        blocks,
        inputs=["u", *outs],
        outputs=["y", *[s for s in K.input_labels if s != "y"]],
        name="open_plant",
        ignore_inputs=ignore,
    )


def sampled_data_check(loop, K, Kd, *, n_freq: int = 200) -> SampledDataCheck:
    """Compare the continuous loop (``K``) with the sampled-data loop (ZOH plant, ``Kd``).

    Parameters
    ----------
    loop : backhoe.model.loop.BDFTLoop
        One family member.
    K : control.StateSpace
        Continuous controller (loop convention: inputs among ``x, c, y``, outputs among
        ``f, r_corr``).
    Kd : control.StateSpace
        Its discrete equivalent, same signal names, ``dt > 0``.
    n_freq : int
        Frequencies of the response comparison over :data:`CHECK_BAND_HZ`, >= 2.

    Raises
    ------
    ModelStructureError
        If ``K`` or ``Kd`` is not a :class:`control.StateSpace` with finite matrices
        (named), ``Kd`` is not discrete-time with a sample time, or their signals differ.
    ParameterError
        If ``loop`` is not a :class:`~backhoe.model.loop.BDFTLoop` or ``n_freq`` is not an
        integer >= 2.
    """
    if not isinstance(loop, BDFTLoop):
        raise ParameterError(
            f"sampled_data_check: loop must be a BDFTLoop; got {type(loop).__name__}"
        )
    for name, sys in (("K", K), ("Kd", Kd)):
        if not isinstance(sys, ct.StateSpace):
            raise ModelStructureError(
                f"sampled_data_check: {name} must be a control.StateSpace; got {type(sys).__name__}"
            )
        check_state_space(f"sampled_data_check: {name}", sys)
    n_freq = check_int("sampled_data_check: n_freq", n_freq, low=2)
    if not (Kd.isdtime(strict=True) and Kd.dt > 0):
        raise ModelStructureError(
            f"Kd must be a discrete-time controller with a sample time; got dt={Kd.dt}"
        )
    if list(K.input_labels) != list(Kd.input_labels) or list(K.output_labels) != list(
        Kd.output_labels
    ):
        raise ModelStructureError(
            f"K and Kd must have the same signals; got {K.input_labels}->{K.output_labels} and "
            f"{Kd.input_labels}->{Kd.output_labels}"
        )
    T = float(Kd.dt)
    poles_c = loop_poles(loop, controller=K)
    G = open_plant(loop, K)
    Gd = ct.sample_system(G, T, method="zoh")
    Gd = ct.ss(
        Gd.A,
        Gd.B,
        Gd.C,
        Gd.D,
        T,
        inputs=G.input_labels,
        outputs=G.output_labels,
        name="open_plant_d",
    )
    cl_d = connect([Gd, Kd], inputs=["u"], outputs=["y"], name="sampled_loop")
    z = np.linalg.eigvals(np.asarray(cl_d.A, float))
    s_d = np.log(z.astype(complex)) / T
    max_re_d = float(np.max(s_d.real)) if s_d.size else -np.inf
    cl_c = loop.system(bdft=True, controller=K, outputs=["y"])
    f = np.geomspace(*CHECK_BAND_HZ, n_freq)
    w = 2 * np.pi * f
    Hc = _siso_response(cl_c, w, "u", "y")
    Hd = _siso_response(cl_d, w, "u", "y")
    # reported to 0.001 dB: near the response's notches its last digits depend on the
    # rounding of the BLAS kernel (2e-5 dB between the Haswell and Sandybridge kernels)
    dev = round(float(np.max(np.abs(20 * np.log10(np.abs(Hd) / np.abs(Hc))))), 3)
    return SampledDataCheck(
        max_real_continuous=float(poles_c.max_real),
        max_real_discrete=max_re_d,
        max_response_deviation_db=dev,
        stable_continuous=bool(poles_c.stable),
        stable_discrete=poles_stable(s_d),
    )


def _siso_response(sys, w, inp, out):
    i = list(sys.input_labels).index(inp)
    o = list(sys.output_labels).index(out)
    # on a minimal realisation: a cancelled, lightly damped mode (an exact cancellation
    # controller leaves one) makes the resolvent of the full loop ill-conditioned
    m = minimal_realization(sys.A, sys.B[:, [i]], sys.C[[o], :], sys.D[[o]][:, [i]])
    resp = ct.frequency_response(ct.ss(m.A, m.B, m.C, m.D, sys.dt), w)
    return np.asarray(resp.complex).reshape(-1)
