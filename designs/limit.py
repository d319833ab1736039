"""The achievable-limit map: what fraction of operators can any compensator protect?

For each member of a seeded sample of the default family, and for each set of actuators
and sensors, :func:`member_limit` finds the compensator that knows that member exactly
and meets the specification's bounds on the intended-motion response (the deviation from
the BDFT-free response, :mod:`designs.response`), its noise and reference-effort limits,
with the least RMS handle force and every closed-loop pole in the specification's region
by construction (:mod:`robust.synthesis.youla`: Youla/Q-parametrisation, Boyd & Barratt
1991). The frequency-wise bounds are imposed on a design grid (0-1000 Hz) and the
controller found is realised, closed around the member and re-checked independently of the
optimisation: its eigenvalues against the region, the deviation's bounds at *every*
frequency (:func:`designs.response.deviation_bound_checks`), the exact RMS force, noise and
reference effort (Lyapunov, with the remnant and the sensor noise) and the peak force of a
simulated realistic intended motion. Where the exact check finds a bound exceeded between
the grid's frequencies, those frequencies join the grid and the problem is solved again
(cutting planes, :data:`CUT_ROUNDS`). The member's *required force multiple* is the
smallest multiple of the Omni's force limits (peak and continuous together) within which
that controller meets the whole specification.

Sets
----
Actuators (:data:`ACTUATOR_SETS`): the handle force ``f`` (today's handle-force designs),
the cylinder-reference shaping ``r_corr`` (no force), both. Sensors
(:data:`SENSOR_SETS`): ``full`` (every state of the loop, noiseless: full information, the
most any compensator could know), ``handle`` (the handle position through the Omni's
encoder, quantisation noise of :data:`ENCODER_MM`) and ``handle+cab`` (plus a cab
accelerometer with noise :data:`ACCEL_NOISE_RMS`); with measured signals the compensator
is an observer-based output feedback with its own Youla parameter.

What the map bounds
-------------------
* A member counted as covered at force multiple ``s`` has a verified controller: the map's
  coverage is a *lower bound* on what compensators of that set, knowing the member, can
  cover.
* Where no controller of the basis meets the bounds and the effort limits at any force,
  the smallest uniform relaxation ``rho`` of all of them that the basis can meet is
  reported, with the constraint furthest from its limit there as ``binding``; where force
  binds, the required multiple. Both are *upper bounds* of the exact limit (a richer basis
  can only lower them; :func:`basis_check` measures by how much), computed for the basis.
  A member whose controller fails the re-check is ``"undecided"``, one whose solver failed
  ``"solver failed"``: every uncovered member is counted under exactly one name.
* Knowing the member exactly is more than any one compensator for a family knows: a
  robust design, or a scheduled bank with identification errors, cannot beat the map of
  its set, up to the basis' approximation.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from joblib import delayed

from designs.constants import (
    ACTUATOR_SETS,
    ALL_SETS,
    DEFAULT_SETS,
    FORCE_SCALES,
    LIMIT_SAMPLES,
    SENSOR_SETS,
)
from designs.limit_member import BASIS_POLES, member_controller, member_limit
from designs.limit_plant import ACCEL_NOISE_RMS, ENCODER_MM, sensor_noise
from designs.limit_plant import _gain as _gain
from designs.limit_plant import _member_plant as _member_plant
from designs.limit_plant import _observer as _observer
from designs.limit_plant import _schur_response as _schur_response
from designs.limit_sets import design_set, limit_coverage_of, set_contains, split_set
from designs.limit_solve import FORCE_FLOOR_N, SetLimit
from designs.limit_tasks import _member_task, _run
from designs.specification import Specification
from robust.checks import check_int
from robust.errors import ParameterError
from uncertainty import sample
from uncertainty.search import worst_member

__all__ = [
    "ALL_SETS",
    "DEFAULT_SETS",
    "SENSOR_SETS",
    "split_set",
    "set_contains",
    "sensor_noise",
    "FORCE_FLOOR_N",
    "FORCE_SCALES",
    "LIMIT_SAMPLES",
    "ACTUATOR_SETS",
    "BASIS_POLES",
    "SetLimit",
    "member_limit",
    "member_controller",
    "limit_map",
    "LimitMap",
    "basis_check",
    "design_set",
    "limit_coverage_of",
]

# ACTUATOR_SETS and SENSOR_SETS (name -> the loop's actuator signals, the measured signals),
# and the map's defaults ALL_SETS, DEFAULT_SETS, FORCE_SCALES and LIMIT_SAMPLES, are defined
# in designs.constants (the command line reads them without NumPy)


@dataclasses.dataclass(frozen=True)
class LimitMap:
    """The limit map: per member and set, what the best verified controller needs.

    Parameters
    ----------
    names : tuple of str
        Parameter names (``family.names``).
    values : numpy.ndarray (N, d)
        The members: the Latin hypercube first, then the critical members.
    labels : tuple of str
        Per member, ``"lhs"`` or the critical member's label (``"nominal"``,
        ``"open-loop worst"``).
    sets : tuple of str
        Sets ``"actuators/sensors"`` (:data:`ALL_SETS`).
    limits : tuple of tuple of SetLimit
        ``limits[i][j]``: member ``i``, set ``j``.
    force_scales : tuple of float
        Multiples of the device's force limits reported.
    samples, seed : int
        Latin-hypercube size and seed.
    basis_poles : tuple of float
        Lags of the basis, rad/s.
    specification : dict
        The specification (:meth:`Specification.to_json`).
    noise : dict
        Sensor noise: encoder resolution, mm, and accelerometer RMS.
    """

    names: tuple
    values: np.ndarray
    labels: tuple
    sets: tuple
    limits: tuple
    force_scales: tuple
    samples: int
    seed: int
    basis_poles: tuple
    specification: dict
    noise: dict

    def lhs_index(self) -> np.ndarray:
        """Boolean mask of the Latin-hypercube members (the critical members excluded)."""
        return np.array([lab == "lhs" for lab in self.labels])

    def own_required(self, name: str) -> np.ndarray:
        """Required force multiple per member from the set's own problem (``inf``: none found).

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        """
        j = self.sets.index(name)
        return np.array(
            [row[j].required_force if row[j].verified else math.inf for row in self.limits]
        )

    def required(self, name: str) -> np.ndarray:
        """Required force multiple per member for one set, the best of the sets it contains.

        A controller of a smaller set is a controller of ``name`` (an unused actuator held
        at zero, an unused sensor ignored; full information knows every measured signal
        without noise), so each member's requirement is the least over the map's sets
        contained in ``name`` (:func:`set_contains`) of their verified requirements.

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        """
        own = [self.own_required(x) for x in self.sets if set_contains(name, x)]
        return np.min(np.vstack(own), axis=0)

    def lower(self, name: str) -> np.ndarray:
        """Lower bound of the force multiple any compensator of the set needs, per member.

        The frequency-wise relaxation of the set's actuators (:mod:`designs.relaxation`;
        it holds for every sensor set and for the sets it contains): with a force actuator
        its ``force_lower``; a reference correction alone needs no force, or is ``inf``
        where its effort bound exceeds the limits (no force makes it feasible).

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        """
        j = self.sets.index(name)
        a, _ = split_set(name)
        if "f" in ACTUATOR_SETS[a]:
            return np.array([row[j].force_lower for row in self.limits])
        return np.array([0.0 if row[j].reference_lower <= 1.0 else math.inf for row in self.limits])

    def coverage(self, name: str, force_scale: float) -> float:
        """Fraction of the Latin hypercube covered by one set at ``force_scale``.

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        force_scale : float
            Multiple of the device's force limits.
        """
        req = self.required(name)[self.lhs_index()]
        return float(np.mean(req <= force_scale))

    def binding(self, name: str, force_scale: float) -> dict:
        """Per constraint, the Latin-hypercube members it keeps uncovered at ``force_scale``.

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        force_scale : float
            Multiple of the device's force limits.
        """
        j = self.sets.index(name)
        req = self.required(name)
        out = {}
        for row, lhs, r in zip(self.limits, self.lhs_index(), req):
            if not lhs or r <= force_scale:
                continue
            key = row[j].binding or "unverified"
            out[key] = out.get(key, 0) + 1
        return out

    def scale_for(self, name: str, fraction: float = 0.95) -> float:
        """Smallest force multiple covering ``fraction`` of the Latin hypercube (``inf``: none).

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        fraction : float
            Coverage wanted, in (0, 1].
        """
        return _quantile(self.required(name)[self.lhs_index()], fraction)

    def bracket_for(self, name: str, fraction: float = 0.95) -> dict:
        """``{"lower", "upper"}`` of the force multiple covering ``fraction`` of the Latin
        hypercube: the upper from verified controllers (:meth:`scale_for`), the lower from
        the relaxation's bounds (:meth:`lower`: a member no compensator covers below its
        bound, so the fraction with bounds below ``s`` bounds the coverage at ``s``).

        Parameters
        ----------
        name : str
            A set of :attr:`sets`.
        fraction : float
            Coverage wanted, in (0, 1].
        """
        low = _quantile(self.lower(name)[self.lhs_index()], fraction)
        return {"lower": low, "upper": self.scale_for(name, fraction)}

    def sets_json(self) -> list:
        """Per set and force multiple: name, force_scale, coverage, samples, seed, binding."""
        out = []
        lhs = self.lhs_index()
        for name in self.sets:
            a, s_ = split_set(name)
            for sc in self.force_scales:
                cov = self.coverage(name, sc)
                out.append(
                    {
                        "name": name,
                        "actuators": list(ACTUATOR_SETS[a]),
                        "sensors": s_,
                        "force_scale": sc,
                        "coverage": cov,
                        "coverage_own": float(np.mean(self.own_required(name)[lhs] <= sc)),
                        "covered": int(round(cov * self.samples)),
                        "samples": self.samples,
                        "seed": self.seed,
                        "binding": self.binding(name, sc),
                        # members that no compensator of the set covers at this multiple
                        "proven_uncovered": int(np.sum(self.lower(name)[lhs] > sc)),
                    }
                )
        return out

    def to_json(self) -> dict:
        """The ``bdft limit --json`` object (without the basis check and the page's path)."""
        crit = []
        for i, lab in enumerate(self.labels):
            if lab == "lhs":
                continue
            crit.append(
                {
                    "label": lab,
                    "parameters": dict(zip(self.names, map(float, self.values[i]))),
                    "limits": [dataclasses.asdict(x) for x in self.limits[i]],
                }
            )
        gaps = [
            abs(x.gap) for row in self.limits for x in row if x.verified and math.isfinite(x.gap)
        ]
        return {
            "sets": self.sets_json(),
            "force_for_95": {name: self.bracket_for(name, 0.95) for name in self.sets},
            "critical": crit,
            "samples": self.samples,
            "seed": self.seed,
            "method": "lhs",
            "basis_poles": list(self.basis_poles),
            "noise": dict(self.noise),
            "solver_gap": {
                "median": float(np.median(gaps)) if gaps else math.nan,
                "max": float(np.max(gaps)) if gaps else math.nan,
            },
            "specification": self.specification,
        }


def _quantile(values: np.ndarray, fraction: float) -> float:
    """The smallest value at or below which ``fraction`` of ``values`` lie."""
    v = np.sort(np.asarray(values, float))
    k = int(math.ceil(fraction * v.size)) - 1
    return float(v[max(k, 0)])


def limit_map(
    family,
    spec: Specification | None = None,
    *,
    samples: int = LIMIT_SAMPLES,
    seed: int = 0,
    sets=DEFAULT_SETS,
    force_scales=FORCE_SCALES,
    critical: bool = True,
    basis_poles=BASIS_POLES,
    duration_s: float = 20.0,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
    scheduler: str | None = None,
) -> LimitMap:
    """The limit map of ``family`` (module notes): every member's limit for every set.

    Parameters
    ----------
    family : backhoe.Family
        A family with the physical human.
    spec : Specification, optional
        The specification (default :class:`Specification` ``()``).
    samples : int
        Latin-hypercube members (>= 1).
    seed : int
        Seed of the Latin hypercube (and, ``seed + i``, of member ``i``'s simulation).
    sets : sequence of str
        Sets ``"actuators/sensors"`` of :data:`ALL_SETS`.
    force_scales : sequence of float
        Multiples of the device's force limits reported.
    critical : bool
        Add the nominal member and the open loop's worst member of the box for the
        specification's pole region (:func:`uncertainty.search.worst_member`).
    basis_poles : sequence of float
        The lag basis, rad/s.
    duration_s : float
        Peak-force simulation length, s.
    n_jobs : int
        Parallel processes.
    progress : callable, optional
        ``progress(done, total)`` members.
    scheduler : str, optional
        A Dask scheduler's address (or ``$DASK_SCHEDULER_ADDRESS``): the members run on
        its workers; the same map.

    Returns
    -------
    LimitMap
    """
    spec = Specification() if spec is None else spec
    samples = check_int("samples", samples, low=1, owner="limit_map")
    n_jobs = check_int("n_jobs", n_jobs, low=1, owner="limit_map")
    sets = tuple(dict.fromkeys(sets))
    if not sets:
        raise ParameterError("limit_map: sets must name at least one set; got none")
    for name in sets:
        split_set(name)
    scales = tuple(float(x) for x in force_scales)
    if not scales or any(not (math.isfinite(x) and x > 0) for x in scales):
        raise ParameterError(
            f"limit_map: force_scales must be positive numbers; got {force_scales!r}"
        )
    rows = list(sample(family.parameters, samples, method="lhs", seed=seed).values)
    labels = ["lhs"] * samples
    if critical:
        rows.append(family.nominal_values())
        labels.append("nominal")
        _, worst = worst_member(family, 1.0, region=spec.region(), seed=seed)
        rows.append(worst)
        labels.append("open-loop worst")
    values = np.asarray(rows, float)
    poles = tuple(float(x) for x in basis_poles)
    tasks = [
        delayed(_member_task)(family, values[i], sets, spec, seed + i, poles, duration_s)
        for i in range(len(values))
    ]
    results = _run(tasks, n_jobs, progress, scheduler=scheduler)
    return LimitMap(
        names=tuple(family.names),
        values=values,
        labels=tuple(labels),
        sets=sets,
        limits=tuple(results),
        force_scales=scales,
        samples=samples,
        seed=seed,
        basis_poles=poles,
        specification=spec.to_json(),
        noise={"encoder_mm": ENCODER_MM, "accel_rms": ACCEL_NOISE_RMS},
    )


def basis_check(
    family,
    lm: LimitMap,
    *,
    members: int = 8,
    sets=None,
    spec: Specification | None = None,
    n_jobs: int = 1,
    scheduler: str | None = None,
) -> dict:
    """How much a richer basis lowers the map's limits: the first members with twice the lags.

    The basis is an inner approximation (module notes): a richer one can only lower a
    member's required force multiple (up to the solver's accuracy). The first ``members``
    members of the Latin hypercube are re-run with the map's lags and their geometric
    midpoints (a basis that contains the map's), so the decrease measures how far the map
    is from the limit of an infinite basis.

    Parameters
    ----------
    family : backhoe.Family
        The map's family.
    lm : LimitMap
        The map.
    members : int
        Members re-run (>= 1).
    sets : sequence of str, optional
        Sets re-run (default: the map's sets with a force actuator).
    spec : Specification, optional
        The map's specification.
    n_jobs : int
        Parallel processes.
    scheduler : str, optional
        A Dask scheduler's address (see :func:`limit_map`).

    Returns
    -------
    dict
        Per set: ``members``, ``poles`` (before, after), the required force multiples
        before and after, and the median and largest relative decrease among members
        finite in both.
    """
    spec = Specification() if spec is None else spec
    members = check_int("members", members, low=1, owner="basis_check")
    if sets is None:
        sets = tuple(x for x in lm.sets if "f" in ACTUATOR_SETS[split_set(x)[0]])
    sets = tuple(sets)
    a = np.asarray(lm.basis_poles)
    mids = np.sqrt(a[:-1] * a[1:])
    rich = tuple(float(x) for x in np.sort(np.concatenate([a, mids])))
    idx = np.flatnonzero(lm.lhs_index())[:members]
    tasks = [
        delayed(_member_task)(family, lm.values[i], sets, spec, lm.seed + int(i), rich, 20.0)
        for i in idx
    ]
    runner = _run(tasks, n_jobs, scheduler=scheduler)
    out = {}
    for j, name in enumerate(sets):
        k = lm.sets.index(name)
        before = np.array(
            [lm.limits[i][k].required_force if lm.limits[i][k].verified else math.inf for i in idx]
        )
        after = np.array([r[j].required_force if r[j].verified else math.inf for r in runner])
        ok = np.isfinite(before) & np.isfinite(after) & (before > 1e-3)
        dec = 1.0 - after[ok] / before[ok]
        out[name] = {
            "members": int(idx.size),
            "poles": [len(lm.basis_poles), len(rich)],
            "required_before": before.tolist(),
            "required_after": after.tolist(),
            "median_decrease": float(np.median(dec)) if dec.size else math.nan,
            "largest_decrease": float(np.max(dec)) if dec.size else math.nan,
        }
    return out
