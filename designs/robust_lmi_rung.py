"""One rung of the robust LMI ladder: the settings, and the rounds at one family scale.

:class:`RobustOptions` holds every setting of the margin maximisation
(:func:`designs.robust_lmi_ladder.maximise_margin`), :class:`ScaleLevel` what one scale
tried gave. ``_try_scale`` runs the rounds at one scale (step 3 of :mod:`designs.robust_lmi`):
the design members, the start into the pole region, the P-K LMI synthesis, the worst-member
search of the scaled box and the specification's check on :data:`LADDER_CONSTRAINTS`. Kept
apart from the ladder that climbs the scales (:mod:`designs.robust_lmi_ladder`) and from the
cache and the worker that try rungs beside it (:mod:`designs.robust_lmi_ahead`).
"""

from __future__ import annotations

import dataclasses
import math
import time

import control as ct
import numpy as np

from backhoe.synthesis.forcefb import synthesis_member
from designs.spec import Specification, check_specification
from robust.checks import POSITIVE, Spec, check_int, validate_fields
from robust.errors import BDFTError, InfeasibleError, ParameterError
from robust.synthesis.pk import pksyn_multi
from robust.synthesis.tuning import minimax_start, tune_members
from uncertainty.search import scaled_bounds, worst_member

__all__ = ["RobustOptions", "ScaleLevel"]

#: Ways of bringing a round's controller into the region (:class:`RobustOptions`).
START_METHODS = ("minimax-bfgs", "minimax", "bfgs")

#: Scales tried upwards (the box about the nominal; 1 = the whole family).
LADDER = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0)


@dataclasses.dataclass(frozen=True)
class RobustOptions:
    """Settings of the margin maximisation (every one changes the result; all are reported).

    Parameters
    ----------
    controls : tuple of str
        Controller outputs (``("f",)`` handle force, ``("r_corr",)`` cylinder reference).
    measurements : tuple of str
        Controller inputs, among ``x``, ``c``, ``y``.
    order : int
        Controller order.
    budget_fraction : float
        Fraction of the continuous-force limit the RMS force of the design members may use.
    crest_factor : float
        Assumed peak-to-RMS ratio of the force under the realistic motion.
    tracking_bound : float
        Bound of the weighted tracking channel on the design members (below 1 leaves
        room for the members between them).
    ladder : tuple of float
        Scales tried upwards.
    bisection : int
        Bisection steps between the last scale reached and the first failed.
    rounds : int
        Design-member rounds per scale (four: with three, whether a rung was reached hung
        on the BLAS kernel's rounding; see ``start``).
    give_up : int
        A scale is abandoned before its last round once the largest utilisation of the
        ladder's constraints on the checked members has grown in this many rounds in a
        row, to above 1 (0: every round is run). Each round adds the members that failed,
        and a scale whose rounds keep failing by more is a failed one. Measured on the
        three LMI designs and the force trade-off's four points (41 scales, 8 failed): four
        failed scales are abandoned a round early (``hinf-robust-lmi``'s 0.1 and 0.075,
        the same 0.1 at the device's force, the half-force point's 0), and no scale that
        was reached had grown so. A reached scale's controller is the ladder's result, so
        the designs' controllers are unchanged.
    pk_iterations : int
        P-K steps per round.
    start : str
        How each round's controller is brought into the region before the LMI synthesis.
        ``"minimax"``: :func:`robust.synthesis.tuning.minimax_start` alone, sequential
        linear programs into the region, then on the largest utilisation of the budgets
        with the region kept (measured on the default family,
        ``benchmarks/bench_robust_lmi.py --ladder``: scale 0.05 reached in 136 s).
        ``"minimax-bfgs"`` (default): the same linear programs, but where the budgets'
        minimax leaves the region (the budgets cannot all be met) the nonsmooth tuning
        :func:`robust.synthesis.tuning.tune_members` takes over. ``"bfgs"``: the nonsmooth
        tuning in every round. With either start the ladder's path depends on rounding:
        the linear programs' trust-region steps, the SDP solver's answers and the rounds'
        design members are decisions that a last-digit change of the data can flip, and a
        rung is reached or not by a few tenths of a rad/s of region violation in its last
        round. Measured (``minimax-bfgs``, scale reached; the README has the table): with
        three rounds per scale 0.075, 0.05 and 0.035 on the SkylakeX, Haswell and
        Sandybridge BLAS kernels; with four (``rounds``' default) 0.075 on all three.
        The ``bdft`` command fixes the kernels (:mod:`bdft.kernels`), so from the command
        line the path is the same on every x86-64 CPU with AVX2 and FMA.
    tune_iterations : int
        Iterations of the start (linear programs; BFGS iterations per run).
    tune_restarts : int
        BFGS runs per phase of the nonsmooth tuning.
    worst_samples : int
        Latin-hypercube members of the worst-member search per round.
    spec_samples : int
        Seeded members of the scaled box the specification is checked on per round.
    margin_boxes : int
        Sub-boxes of the region certificate per scale.
    seed : int
        Seed of every sample (written into the result).
    """

    controls: tuple = ("f",)
    measurements: tuple = ("x", "c")
    order: int = 4
    budget_fraction: float = 0.95
    crest_factor: float = 4.2
    tracking_bound: float = 0.95
    ladder: tuple = LADDER
    bisection: int = 1
    rounds: int = 4
    give_up: int = 2
    pk_iterations: int = 4
    start: str = "minimax-bfgs"
    tune_iterations: int = 100
    tune_restarts: int = 2
    worst_samples: int = 200
    spec_samples: int = 12
    margin_boxes: int = 60
    seed: int = 0

    def __post_init__(self):
        validate_fields(
            self,
            {
                "budget_fraction": Spec(0.0, 1.0, True, False),
                "crest_factor": POSITIVE,
                "tracking_bound": POSITIVE,
            },
        )
        for name, low in (
            ("order", 1),
            ("bisection", 0),
            ("rounds", 1),
            ("give_up", 0),
            ("pk_iterations", 0),
            ("tune_iterations", 0),
            ("tune_restarts", 1),
            ("worst_samples", 10),
            ("spec_samples", 0),
            ("margin_boxes", 1),
            ("seed", 0),
        ):
            check_int(name, getattr(self, name), low=low, owner="RobustOptions")
        ladder = tuple(float(k) for k in self.ladder)
        if not ladder or any(not (0 < k <= 8) for k in ladder) or list(ladder) != sorted(ladder):
            raise ParameterError(
                f"RobustOptions.ladder must be increasing scales in (0, 8]; got {self.ladder}"
            )
        object.__setattr__(self, "ladder", ladder)
        if self.start not in START_METHODS:
            raise ParameterError(
                f"RobustOptions.start must be one of {START_METHODS}; got {self.start!r}"
            )

    def force_budget(self, spec: Specification) -> float:
        """The RMS force the synthesis allows, N."""
        return min(
            self.budget_fraction * spec.continuous_force_n, spec.peak_force_n / self.crest_factor
        )


@dataclasses.dataclass(frozen=True)
class ScaleLevel:
    """One scale tried.

    Parameters
    ----------
    scale : float
        The box scale.
    reached : bool
        Whether a controller met the checks on members at this scale: no member of the
        scaled box found outside the region, the specification on the design members and
        the seeded samples.
    members : int
        Design members at the end.
    worst_violation : float
        Largest region violation found in the scaled box, rad/s.
    certified : bool
        Whether, in addition, the region was certified over the whole scaled box.
    binding : str
        The binding constraint among :data:`LADDER_CONSTRAINTS` on the checked members.
    utilisation : float
        Its utilisation (above 1: violated).
    reason : str
        Why the scale was not reached (empty if it was).
    seconds : float
        Time spent at this scale (its certification, run after the ladder, aside).
    starts : dict
        Rounds started by each method (``minimax``: the linear programs; ``bfgs``: the
        nonsmooth tuning, run when the linear programs end outside the region).
    """

    scale: float
    reached: bool
    members: int
    worst_violation: float
    certified: bool
    binding: str
    utilisation: float
    reason: str
    seconds: float
    starts: dict = dataclasses.field(default_factory=dict)


def _loop_controller(K, options: RobustOptions, name: str) -> ct.StateSpace:
    return ct.ss(
        K.A,
        K.B,
        K.C,
        K.D,
        inputs=list(options.measurements),
        outputs=list(options.controls),
        name=name,
    )


#: The constraints of the specification a rung of the ladder must meet on its members: the
#: pole region, the device's forces and the tracking of the operator's band, which the
#: synthesis designs for. The feedthrough's reduction, the noise and the reference effort are
#: beyond what the P-K iteration targets: the specification's check reports them for the
#: design (its binding constraint and coverage), they do not stop the ladder.
LADDER_CONSTRAINTS = ("decay rate", "damping", "peak force", "continuous force", "tracking")


def _given_up(utilisations, rounds: int) -> bool:
    """Whether the last of ``utilisations`` is above 1 and each of the last ``rounds``
    exceeds the one before (``rounds`` 0: never)."""
    u = list(utilisations)
    if rounds <= 0 or len(u) <= rounds or u[-1] <= 1.0:
        return False
    return all(u[-i] > u[-i - 1] for i in range(1, rounds + 1))


def _binding(check):
    """The constraint of :data:`LADDER_CONSTRAINTS` with the largest utilisation."""
    return max(
        (c for c in check.constraints if c.name in LADDER_CONSTRAINTS),
        key=lambda c: c.utilisation,
    )


def _accepted(check) -> bool:
    """Whether a rung's check meets :data:`LADDER_CONSTRAINTS`."""
    return all(c.holds for c in check.constraints if c.name in LADDER_CONSTRAINTS)


#: The synthesis' own feedthrough target on its design grid: no growth of the peak over the
#: structure band. The specification asks for a 6 dB reduction at every frequency of the band
#: (``Specification.feedthrough_reduction_db``); with that target the ladder reaches no rung
#: (its first, 0.005 of the box, is infeasible: measured), so the designs keep this one and
#: the specification's check reports how far they fall short.
DESIGN_AMPLIFICATION_DB = 0.0


def _members(family, rows, options: RobustOptions, spec: Specification, limits):
    out = []
    for i, r in enumerate(rows):
        out.append(
            synthesis_member(
                family.member(r, check_bounds=False),
                controls=options.controls,
                measurements=options.measurements,
                limits=limits,
                intent_fraction=spec.intent_fraction,
                intent_bandwidth_hz=spec.intent_bandwidth_hz,
                tracking_error=spec.tracking_error,
                feedthrough_band_hz=spec.feedthrough_band_hz,
                max_amplification_db=DESIGN_AMPLIFICATION_DB,
                label=f"member {i}",
            )
        )
    return out


def _spec_rows(family, k: float, n: int, seed: int) -> np.ndarray:
    lo, hi = scaled_bounds(family, k)
    U = np.random.default_rng(seed).random((n, lo.size))
    return lo + U * (hi - lo)


def _try_scale(family, k, K, rows, spec, options, limits, progress):
    """Rounds of design members and synthesis at scale ``k``; returns the outcome."""
    # one region: the synthesis enforces its damping at every frequency (conservatively),
    # the checks of the scaled box in its band
    region = spec.region()
    budget = options.force_budget(spec)
    h2 = budget if "f" in options.controls else None
    rows = [np.asarray(r, float) for r in rows]
    t0 = time.perf_counter()
    outcome = {"reached": False, "reason": "", "K": K, "pk": None}
    check = None
    worst_v = math.nan
    starts = {"minimax": 0, "bfgs": 0}
    grown = []  # the largest utilisation of the ladder's constraints, round by round
    for rnd in range(options.rounds):
        members = _members(family, rows, options, spec, limits)
        common = dict(tracking_bound=options.tracking_bound, h2_bound=h2, margin=0.05)
        tuned = None
        if options.start != "bfgs":
            tuned = minimax_start(
                members,
                K,
                region,
                max_iter=options.tune_iterations,
                keep_region=options.start == "minimax",
                **common,
            )
            starts["minimax"] += 1
        if tuned is None or tuned.violation >= 0:
            # the nonsmooth tuning may find another basin (its path depends on rounding)
            tuned = tune_members(
                members,
                K,
                region,
                max_iter=options.tune_iterations,
                restarts=options.tune_restarts,
                **common,
            )
            starts["bfgs"] += 1
        if tuned.violation >= 0:
            outcome["reason"] = (
                f"no controller found with every design member's poles in the region "
                f"(violation {tuned.violation:.3g} rad/s)"
            )
            break
        try:
            # the region LMIs are solved for the one synthesis kept (_maximise)
            pk = pksyn_multi(
                members,
                tuned.K,
                region,
                h2_bound=h2 * 1.05 if h2 else None,
                max_iter=options.pk_iterations,
                region_certificates=False,
            )
        except (InfeasibleError, BDFTError) as exc:
            outcome["reason"] = f"LMI synthesis failed: {exc}"
            break
        K = pk.K
        KL = _loop_controller(K, options, "K")
        worst_v, row = worst_member(
            family,
            k,
            controller=KL,
            region=region,
            samples=options.worst_samples,
            seed=options.seed + rnd,
        )
        srows = _spec_rows(family, k, options.spec_samples, options.seed + 1000 + rnd)
        checked = np.vstack([rows, srows]) if len(srows) else np.asarray(rows)
        check = check_specification(
            [family.member(r, check_bounds=False) for r in checked],
            KL,
            spec,
            seed=options.seed,
            simulate_peak=3,
        )
        if progress:
            progress(
                f"scale {k:.3g}, round {rnd + 1}: {len(rows)} design members, worst region "
                f"violation {worst_v:.3g} rad/s, specification's binding {check.binding}"
            )
        outcome.update(K=K, pk=pk, check=check, members=members)
        if worst_v < 0 and _accepted(check):
            break
        grown.append(_binding(check).utilisation)
        if rnd + 1 < options.rounds and _given_up(grown, options.give_up):
            outcome["reason"] = (
                f"abandoned after round {rnd + 1} of {options.rounds}: the largest utilisation "
                f"of the ladder's constraints grew in {options.give_up} rounds in a row, to "
                f"{grown[-1]:.3g} (worst region violation {worst_v:.3g} rad/s)"
            )
            break
        # new design members: the worst one of the search, and the sampled member that
        # binds the specification (unless it is a design member already)
        n_design = len(rows)
        if worst_v >= 0:
            rows.append(row)
        if not _accepted(check):
            bad = _binding(check)
            if bad.worst_member >= n_design:
                rows.append(checked[bad.worst_member])
    else:
        outcome["reason"] = outcome["reason"] or (
            f"after {options.rounds} rounds of design members: worst region violation "
            f"{worst_v:.3g} rad/s, the ladder's constraints "
            f"{'hold' if check and _accepted(check) else 'fail'}"
        )
    if check is not None and worst_v < 0 and _accepted(check):
        # whether the region holds over the whole scaled box: _maximise certifies the
        # rungs reached once the ladder is done (the path never depends on it)
        outcome["reached"] = True
    # the ladder's binding constraint: the largest utilisation among those it requires
    bad = _binding(check) if check else None
    level = ScaleLevel(
        scale=float(k),
        reached=outcome["reached"],
        members=len(rows),
        worst_violation=float(worst_v),
        certified=False,  # filled in by _certify_rungs
        binding=bad.name if bad else "",
        utilisation=float(bad.utilisation) if bad else math.inf,
        reason="" if outcome["reached"] else outcome["reason"],
        seconds=time.perf_counter() - t0,
        starts=starts,
    )
    return level, outcome, rows
