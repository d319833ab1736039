"""Calibration of what the paper leaves out: PI gains, handle-junction sign, loop scale.

The paper prints the three identified blocks but not the PI gains of the cylinder
loop, the units between blocks, or the sign at the handle junction (BRIEF
section 4). :func:`calibrate` searches them for values under which the model
reproduces the paper's claims C1-C3, by a rule stated in full here so that the
result is reproducible and nothing is tuned by hand:

1. **Candidates.** PI gains on a grid (``kp`` x ``ki/kp``) and both junction signs.
   A PI is admissible when its inner (cylinder) loop is stable with classical
   margins: gain margin >= ``min_gain_margin_db`` and phase margin >=
   ``min_phase_margin_deg``.
2. **Root locus in the loop gain.** With the loop-scale factor ``kappa`` and
   ``K_PSF`` the BDFT loop depends only on ``g = kappa*K_PSF`` (and the sign).
   For each candidate the number of closed-loop right-half-plane poles is traced
   along ``g``; ``g1`` is where the loop first loses stability and ``g2`` where it
   first has more than two unstable poles.
3. **Claims as constraints.** C1 needs exactly two unstable poles at the nominal
   ``K_PSF = 0.1097`` and C2/C3 stability at ``K_PSF <= 0.055``: a pair of complex
   poles must cross at ``g1`` and ``0.055*kappa < g1 < 0.1097*kappa < g2``.
   ``kappa`` is set to centre ``g1`` between the two (geometric mean), which makes
   the log-margin
   ``m = min(ln(g1/(0.055 kappa)), ln(0.1097 kappa/g1), ln(g2/(0.1097 kappa)))``
   as large as the claims allow; ``kappa`` is then rounded to three significant
   digits.
4. **Selection.** Among candidates whose margin ``m`` is within 1 % of the best,
   the one with the highest inner-loop crossover frequency (the fastest, hence
   best-tracking, cylinder loop the margins admit) is chosen.

The calibration found by the default call is what
:data:`backhoe.model.loop.DEFAULT_CALIBRATION` holds; a test re-runs the search.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from backhoe.model.components import (
    K_PSF_NOMINAL,
    PIParams,
    pi_controller,
    structure,
    valve_cylinder,
)
from backhoe.model.human import HumanModel, LiteralHuman
from backhoe.model.loop import BDFTLoop, LoopCalibration
from backhoe.model.wiring import connect
from robust.analysis.realization import minimal_realization
from robust.analysis.stability import poles_stable, unstable_mask
from robust.checks import (
    NONNEGATIVE,
    POSITIVE,
    Spec,
    check_callable,
    check_int,
    check_scalar,
    check_sign,
    check_vector,
)
from robust.errors import InfeasibleError, ParameterError

__all__ = [
    "CalibrationCandidate",
    "CalibrationResult",
    "calibrate",
    "open_bdft_path",
    "K_PSF_STABLE",
]

#: The paper's workspace-doubled scale factor (claim C2).
K_PSF_STABLE = 0.055


@dataclasses.dataclass(frozen=True)
class CalibrationCandidate:
    """One row of the calibration search (one PI and one junction sign).

    Parameters
    ----------
    kp : float
        Proportional gain of the PI tried (valve command per unit position error).
    ki : float
        Integral gain tried, 1/s (``kp`` times a ratio of the grid).
    handle_sign : int
        Junction sign ``sigma`` tried, +1 or -1.
    inner_stable : bool
        Whether the cylinder position loop closed by this PI is stable.
    gain_margin_db : float
        Gain margin of the cylinder loop, dB (inf when the phase never crosses
        -180 degrees).
    phase_margin_deg : float
        Phase margin of the cylinder loop, degrees.
    crossover_hz : float
        Gain-crossover frequency of the cylinder loop, Hz.
    admissible : bool
        Whether the cylinder loop is stable with at least the required margins.
    g1 : float
        Loop gain ``kappa*K_PSF`` at which the BDFT loop first loses stability;
        inf if it never does on the traced grid, nan if the cylinder loop is
        unstable.
    g2 : float
        Loop gain above ``g1`` at which more than two closed-loop poles are
        unstable; inf if none on the grid, nan if the cylinder loop is unstable.
    pair_crossing : bool
        Whether stability is lost at ``g1`` by one complex pair (claim C1 needs
        exactly two unstable poles).
    crossing_hz : float
        Frequency of the unstable pair just above ``g1``, Hz (nan if none).
    kappa : float
        Loop scale that centres ``g1`` between ``0.055 kappa`` and ``0.1097 kappa``,
        rounded to 3 significant digits; nan if the candidate is unusable.
    margin : float
        Log-margin ``m`` of claims C1-C3 at that ``kappa`` (positive when they
        hold; -inf if they cannot).
    """

    kp: float
    ki: float
    handle_sign: int
    inner_stable: bool
    gain_margin_db: float
    phase_margin_deg: float
    crossover_hz: float
    admissible: bool
    g1: float  # loop gain kappa*K_PSF at the first loss of stability (inf if none)
    g2: float  # loop gain at which more than two poles are unstable (inf if none)
    pair_crossing: bool  # whether stability is lost by a complex pair (C1 needs two poles)
    crossing_hz: float  # frequency of the pair at g1
    kappa: float  # loop scale centring g1 (rounded to 3 significant digits); nan if unusable
    margin: float  # log-margin m of the claims at that kappa (-inf if they fail)

    @property
    def reproduces_c1_c3(self) -> bool:
        """Admissible, loses stability by a complex pair, and has a positive margin."""
        return self.admissible and self.pair_crossing and self.margin > 0


@dataclasses.dataclass(frozen=True)
class CalibrationResult:
    """Outcome of :func:`calibrate`: the chosen calibration and every candidate.

    Parameters
    ----------
    calibration : LoopCalibration
        PI gains, loop scale ``kappa`` and junction sign of the chosen candidate,
        ready for :class:`backhoe.model.loop.BDFTLoop`.
    chosen : CalibrationCandidate
        The selected row of the search.
    candidates : tuple of CalibrationCandidate
        Every candidate searched, in grid order (``kp``, then ``ki/kp``, then sign).
    settings : dict
        The search settings (grids, required margins, gain grid, human variant and
        the two ``K_PSF`` values), JSON-ready, for reproducing the search.
    """

    calibration: LoopCalibration
    chosen: CalibrationCandidate
    candidates: tuple[CalibrationCandidate, ...]
    settings: dict

    def table(self) -> list[dict]:
        """Every candidate as a dict of its fields plus ``reproduces_c1_c3``."""
        return [
            dataclasses.asdict(c) | {"reproduces_c1_c3": c.reproduces_c1_c3}
            for c in self.candidates
        ]


def open_bdft_path(human: HumanModel, pi: PIParams, loop: BDFTLoop | None = None):
    """Minimal ``(A, B, C, D)`` of the path from handle position ``x`` to hand motion ``h``.

    ``K_PSF = 1`` and no loop-scale: closing it with ``x = u + sign*g*h`` gives the
    Figure 5 loop with ``g = kappa*K_PSF``.

    Parameters
    ----------
    human : HumanModel
        Human variant at the end of the path (its input ``c``; a force port, if
        any, is left unconnected).
    pi : PIParams
        Gains of the cylinder position loop, closed inside the path.
    loop : BDFTLoop, optional
        Loop whose valve/cylinder and structure parameters are used (its human is
        replaced by ``human``; its calibration is ignored); ``BDFTLoop(human=human)``
        when omitted.

    Returns
    -------
    A, B, C, D : numpy.ndarray
        Minimal realisation (:func:`robust.analysis.realization.minimal_realization`)
        of the SISO path ``x -> h``; shapes (n, n), (n, 1), (1, n), (1, 1).

    Raises
    ------
    ParameterError
        If ``human``, ``pi`` or ``loop`` is not of its type.
    """
    if not isinstance(human, HumanModel):
        raise ParameterError(
            f"open_bdft_path: human must implement HumanModel; got {type(human).__name__}"
        )
    if not isinstance(pi, PIParams):
        raise ParameterError(f"open_bdft_path: pi must be PIParams; got {type(pi).__name__}")
    if loop is not None and not isinstance(loop, BDFTLoop):
        raise ParameterError(
            f"open_bdft_path: loop must be a BDFTLoop or None; got {type(loop).__name__}"
        )
    base = loop or BDFTLoop(human=human)
    base = base.replace(human=human)
    blocks = [
        ct.summing_junction(inputs=["x", "-y"], output="err", name="cyl_err"),
        pi_controller(pi),
        valve_cylinder(base.valve),
    ]
    blocks += [structure(base.struct), human.system()]
    sys = connect(
        blocks,
        inputs=["x"],
        outputs=["h"],
        name="open_bdft_path",
        ignore_inputs=["f"] if human.has_force_port else (),
    )
    m = minimal_realization(sys.A, sys.B, sys.C, sys.D)
    return m.A, m.B, m.C, m.D


def _closed_poles(path, signed_gain: float) -> np.ndarray:
    A, B, C, D = path
    feedthrough = 1.0 - signed_gain * D[0, 0]
    return np.linalg.eigvals(A + signed_gain * B @ C / feedthrough)


def _n_unstable(path, signed_gain: float) -> int:
    return int(np.count_nonzero(unstable_mask(_closed_poles(path, signed_gain))))


def _refine(path, sign: int, lo: float, hi: float, pred, rtol: float = 1e-7) -> float:
    """Bisect in log space for the gain where ``pred(count)`` turns true."""
    while hi / lo - 1.0 > rtol:
        mid = math.sqrt(lo * hi)
        if pred(_n_unstable(path, sign * mid)):
            hi = mid
        else:
            lo = mid
    return math.sqrt(lo * hi)


def _round_sig(x: float, digits: int = 3) -> float:
    if not math.isfinite(x) or x == 0:
        return x
    return float(f"{x:.{digits - 1}e}")


def _candidate(human, kp, ki, sign, settings) -> CalibrationCandidate:
    pi = PIParams(kp=kp, ki=ki)
    inner_open = pi_controller(pi) * valve_cylinder()
    inner_poles = ct.feedback(inner_open, 1).poles()
    inner_stable = poles_stable(inner_poles)
    gm, pm, _, _, wpc, wgc = _margins(inner_open)
    gm_db = 20 * math.log10(gm) if math.isfinite(gm) and gm > 0 else math.inf
    admissible = (
        inner_stable
        and gm_db >= settings["min_gain_margin_db"]
        and pm >= settings["min_phase_margin_deg"]
    )
    nan = float("nan")
    base = dict(
        kp=kp,
        ki=ki,
        handle_sign=sign,
        inner_stable=inner_stable,
        gain_margin_db=gm_db,
        phase_margin_deg=pm,
        crossover_hz=wgc / (2 * math.pi),
        admissible=admissible,
    )
    if not inner_stable:
        return CalibrationCandidate(
            **base,
            g1=nan,
            g2=nan,
            pair_crossing=False,
            crossing_hz=nan,
            kappa=nan,
            margin=-math.inf,
        )
    path = open_bdft_path(human, pi)
    grid = np.geomspace(settings["g_min"], settings["g_max"], settings["g_points"])
    counts = np.array([_n_unstable(path, sign * g) for g in grid])
    g1 = g2 = math.inf
    pair = False
    crossing_hz = nan
    first = np.flatnonzero(counts > 0)
    if first.size and first[0] > 0:
        i = first[0]
        g1 = _refine(path, sign, grid[i - 1], grid[i], lambda n: n > 0)
        just_after = _closed_poles(path, sign * g1 * (1 + 1e-4))
        unstable = just_after[unstable_mask(just_after)]
        pair = unstable.size == 2 and bool(np.all(np.abs(unstable.imag) > 0))
        crossing_hz = float(np.abs(unstable.imag).max() / (2 * math.pi)) if unstable.size else nan
        more = np.flatnonzero(counts > 2)
        more = more[more > i]
        if more.size:
            j = more[0]
            g2 = _refine(path, sign, grid[j - 1], grid[j], lambda n: n > 2)
    kappa = nan
    margin = -math.inf
    if math.isfinite(g1) and pair:
        kappa = _round_sig(g1 / math.sqrt(K_PSF_STABLE * K_PSF_NOMINAL))
        margin = min(
            math.log(g1 / (K_PSF_STABLE * kappa)),
            math.log(K_PSF_NOMINAL * kappa / g1),
            math.log(g2 / (K_PSF_NOMINAL * kappa)) if math.isfinite(g2) else math.inf,
        )
    return CalibrationCandidate(
        **base,
        g1=g1,
        g2=g2,
        pair_crossing=pair,
        crossing_hz=crossing_hz,
        kappa=kappa,
        margin=margin,
    )


def _margins(L):
    gm, pm, sm, wpc, wgc, wms = ct.stability_margins(L)
    return float(gm), float(pm), float(sm), float(wms), float(wpc), float(wgc)


DEFAULT_KP = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.6, 0.7, 0.8)
DEFAULT_KI_RATIO = (0.0, 0.1, 0.25, 0.5, 1.0, 2.0)


def _check_search(
    human, kp_grid, ki_ratio_grid, signs, gm_db, pm_deg, g_min, g_max, g_points, progress
) -> None:
    """Refuse bad options of :func:`calibrate` up front, naming the option."""
    if human is not None and not isinstance(human, HumanModel):
        raise ParameterError(
            f"calibrate: human must implement HumanModel or be None; got {type(human).__name__}"
        )
    check_vector("calibrate: kp_grid", kp_grid, POSITIVE)
    check_vector("calibrate: ki_ratio_grid", ki_ratio_grid, NONNEGATIVE)
    if isinstance(signs, (str, bytes)) or not hasattr(signs, "__len__") or len(signs) == 0:
        raise ParameterError(
            f"calibrate: signs must be a non-empty sequence of junction signs +1/-1; got {signs!r}"
        )
    for i, sign in enumerate(signs):
        check_sign(f"calibrate: junction sign signs[{i}]", sign)
    check_scalar("calibrate: min_gain_margin_db", gm_db, NONNEGATIVE)
    check_scalar(
        "calibrate: min_phase_margin_deg", pm_deg, Spec(low=0.0, high=180.0, high_open=True)
    )
    lo = check_scalar("calibrate: g_min", g_min, POSITIVE)
    hi = check_scalar("calibrate: g_max", g_max, POSITIVE)
    if not lo < hi:
        raise ParameterError(f"calibrate: g_min must be below g_max; got {g_min=}, {g_max=}")
    check_int("calibrate: g_points", g_points, low=2)
    check_callable("calibrate: progress", progress)


def calibrate(
    human: HumanModel | None = None,
    *,
    kp_grid=DEFAULT_KP,
    ki_ratio_grid=DEFAULT_KI_RATIO,
    signs=(1, -1),
    min_gain_margin_db: float = 6.0,
    min_phase_margin_deg: float = 45.0,
    g_min: float = 1e-8,
    g_max: float = 1e-1,
    g_points: int = 141,
    progress=None,
) -> CalibrationResult:
    """Search PI gains, junction sign and loop scale that reproduce claims C1-C3.

    Parameters
    ----------
    human : HumanModel, optional
        Human variant the loop is calibrated with (default: the paper's Eqn 5).
    kp_grid, ki_ratio_grid : sequence of float
        Proportional gains and integral-to-proportional ratios (1/s) searched.
    signs : sequence of int
        Junction signs searched.
    min_gain_margin_db, min_phase_margin_deg : float
        Classical margins the cylinder loop must keep to be admissible.
    g_min, g_max, g_points : float, float, int
        Log grid of the loop gain ``kappa*K_PSF`` traced for each candidate.
    progress : callable, optional
        Called with ``(done, total)`` after each candidate.

    Returns
    -------
    CalibrationResult
        The chosen calibration, the chosen candidate, every candidate and the
        settings.

    Raises
    ------
    ParameterError
        Before any search, naming the option: a junction sign other than +1 or -1, an
        empty grid or a grid entry that is not finite and positive (``kp_grid``) or
        non-negative (``ki_ratio_grid``), a margin that is not finite and >= 0 (a phase
        margin of 180 degrees or more), ``g_min``/``g_max`` not ``0 < g_min < g_max``,
        ``g_points`` not an integer >= 2, ``progress`` not callable, ``human`` not a
        :class:`~backhoe.model.human.HumanModel`.
    InfeasibleError
        If no candidate reproduces C1-C3; the message gives the best margin found.
    """
    _check_search(
        human,
        kp_grid,
        ki_ratio_grid,
        signs,
        min_gain_margin_db,
        min_phase_margin_deg,
        g_min,
        g_max,
        g_points,
        progress,
    )
    human = human or LiteralHuman()
    settings = dict(
        kp_grid=list(kp_grid),
        ki_ratio_grid=list(ki_ratio_grid),
        signs=list(signs),
        min_gain_margin_db=min_gain_margin_db,
        min_phase_margin_deg=min_phase_margin_deg,
        g_min=g_min,
        g_max=g_max,
        g_points=g_points,
        human=human.variant,
        k_psf_nominal=K_PSF_NOMINAL,
        k_psf_stable=K_PSF_STABLE,
    )
    cands = []
    total = len(kp_grid) * len(ki_ratio_grid) * len(signs)
    for kp in kp_grid:
        for ratio in ki_ratio_grid:
            for sign in signs:
                cands.append(_candidate(human, float(kp), float(kp * ratio), int(sign), settings))
                if progress is not None:
                    progress(len(cands), total)
    good = [c for c in cands if c.reproduces_c1_c3]
    if not good:
        best = max((c.margin for c in cands), default=-math.inf)
        raise InfeasibleError(
            f"calibration: no PI gains x junction sign in the grid reproduce C1-C3 with the "
            f"{human.variant!r} human (best claim margin {best:.3g}); widen kp_grid/ki_ratio_grid "
            "or relax min_gain_margin_db/min_phase_margin_deg"
        )
    best_margin = max(c.margin for c in good)
    near = [c for c in good if c.margin >= best_margin - 0.01 * abs(best_margin)]
    chosen = max(near, key=lambda c: (c.crossover_hz, -c.kp, -c.ki))
    cal = LoopCalibration(
        kp=chosen.kp,
        ki=chosen.ki,
        loop_scale=chosen.kappa,
        handle_sign=chosen.handle_sign,
        source=f"backhoe.analysis.calibration.calibrate(human={human.variant!r}) default search",
    )
    return CalibrationResult(
        calibration=cal, chosen=chosen, candidates=tuple(cands), settings=settings
    )
