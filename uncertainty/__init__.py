"""Uncertain parameters, sampling, parametric families and their batched validation.

Built on :mod:`robust` (the models); the designs, reports and the command line build on it.

Public API (import from here; module layout may change):

* uncertain parameters: :class:`UncertainParameter`, :data:`DISTRIBUTIONS`;
* families: :class:`Family`, :func:`default_family`, :data:`MODEL_PARAMETERS`,
  :data:`PHYSICAL_LIMITS` and :data:`BOUNDS_RTOL` (what a member's values must satisfy,
  :meth:`Family.check_members`);
* sampling: :func:`sample`, :class:`SampleSet`, :data:`METHODS`, :data:`MAX_SAMPLE_BYTES`
  and :func:`max_members` (the largest sample drawn at once);
* batched validation: :func:`validate_family`, :class:`ValidationResult`,
  :func:`closed_loop_matrices`, :func:`batched_poles`, :func:`member_metrics`,
  :data:`DAMPING_BAND_HZ` (the one default damping band, also the pole region's);
* files: :func:`load_controller`, :func:`load_component_fit`, :func:`family_nominals`,
  :func:`load_system` (a user's uncertain system from a Python file),
  :func:`match_controller` (a controller's signals paired with a user system's);
* uncertain reals and expressions: :func:`ureal`, :class:`UExpr`, :func:`umatrix`,
  :func:`evaluate_matrix`; uncertain state-space systems: :func:`uss`, :class:`USS`,
  :func:`interconnect` (by signal names); uncertain transfer functions: :func:`tf`
  (``tf("s")``, the Laplace variable), :class:`UTF`;
* synthesis for an uncertain system: :func:`augw` (the mixed-sensitivity generalized
  plant, an :class:`UncertainPlant`), :func:`hinfsyn_nominal` (its nominal member),
  :func:`hinfsyn_members` (sampled members, each certified);
* the family's loop as an uncertain system: :func:`family_uss`; the LFT form of an
  uncertain system: :func:`lft_form`, :class:`LFTForm`;
* structured singular value: :func:`mussv` (lower and upper bounds), :class:`MuBounds`;
* robust margins of a family or an uncertain system: :func:`robust_margin`,
  :class:`Region`, :class:`MarginResult`, :func:`margin_lower_bound`,
  :func:`margin_upper_bound`, :func:`worst_member`, :func:`scaled_bounds`;
* robust performance (a weighted closed-loop bound over the box, certified by mu):
  :func:`robust_performance`, :class:`PerformanceResult`, :func:`performance_system`,
  :func:`certify_performance`, :func:`worst_performance`;
* mu-synthesis of an uncertain generalized plant by D-K or D-G-K iteration, its peak mu
  certified at every frequency: :func:`musyn`, :class:`MusynResult`;
* sweeps: :func:`workspace_sweep`, :func:`frequency_damping_sweep`,
  :func:`structure_frequency_sweep`, :class:`SweepResult`.
"""

from robust.lazy import lazy_exports

__all__ = [
    "UExpr",
    "ureal",
    "umatrix",
    "evaluate_matrix",
    "USS",
    "uss",
    "interconnect",
    "UTF",
    "tf",
    "UncertainPlant",
    "augw",
    "hinfsyn_nominal",
    "hinfsyn_members",
    "family_uss",
    "LFTForm",
    "lft_form",
    "MuBounds",
    "mussv",
    "Region",
    "MarginResult",
    "robust_margin",
    "margin_lower_bound",
    "margin_upper_bound",
    "worst_member",
    "scaled_bounds",
    "PerformanceResult",
    "robust_performance",
    "performance_system",
    "certify_performance",
    "worst_performance",
    "MusynResult",
    "musyn",
    "DISTRIBUTIONS",
    "UncertainParameter",
    "HUMAN_VARIANTS",
    "MODEL_PARAMETERS",
    "RANGES",
    "Family",
    "default_family",
    "PHYSICAL_LIMITS",
    "BOUNDS_RTOL",
    "METHODS",
    "SampleSet",
    "sample",
    "MAX_SAMPLE_BYTES",
    "max_members",
    "DAMPING_BAND_HZ",
    "DEFAULT_CHUNK",
    "MAX_CHUNK_BYTES",
    "STABILITY_THRESHOLD",
    "ValidationResult",
    "batched_poles",
    "closed_loop_matrices",
    "validate_family",
    "member_metrics",
    "load_controller",
    "load_system",
    "match_controller",
    "load_component_fit",
    "family_nominals",
    "SWEEPS",
    "SweepResult",
    "workspace_sweep",
    "frequency_damping_sweep",
    "structure_frequency_sweep",
]

# the names above, each imported from its module on first use (robust.lazy)
__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "robust.constants": ("DAMPING_BAND_HZ",),
        "robust.analysis.region": ("Region",),
        "uncertainty.constants": (
            "DEFAULT_CHUNK",
            "RANGES",
        ),
        "uncertainty.batched": (
            "batched_poles",
            "closed_loop_matrices",
        ),
        "uncertainty.validation": (
            "MAX_CHUNK_BYTES",
            "STABILITY_THRESHOLD",
            "ValidationResult",
            "member_metrics",
            "validate_family",
        ),
        "uncertainty.family": (
            "BOUNDS_RTOL",
            "HUMAN_VARIANTS",
            "MODEL_PARAMETERS",
            "PHYSICAL_LIMITS",
            "Family",
        ),
        "uncertainty.family_ranges": ("default_family",),
        "uncertainty.dgk": (
            "MusynResult",
            "musyn",
        ),
        "uncertainty.files": (
            "family_nominals",
            "load_component_fit",
            "load_controller",
            "load_system",
            "match_controller",
        ),
        "uncertainty.lft": (
            "LFTForm",
            "lft_form",
        ),
        "uncertainty.loop": ("family_uss",),
        "uncertainty.margins": (
            "margin_lower_bound",
            "robust_margin",
        ),
        "uncertainty.mu": (
            "MuBounds",
            "mussv",
        ),
        "uncertainty.performance": (
            "PerformanceResult",
            "certify_performance",
            "performance_system",
            "robust_performance",
            "worst_performance",
        ),
        "uncertainty.parameters": (
            "DISTRIBUTIONS",
            "UncertainParameter",
        ),
        "uncertainty.region": ("MarginResult",),
        "uncertainty.sampling": (
            "MAX_SAMPLE_BYTES",
            "METHODS",
            "SampleSet",
            "max_members",
            "sample",
        ),
        "uncertainty.search": (
            "margin_upper_bound",
            "scaled_bounds",
            "worst_member",
        ),
        "uncertainty.sweeps": (
            "SWEEPS",
            "SweepResult",
            "frequency_damping_sweep",
            "structure_frequency_sweep",
            "workspace_sweep",
        ),
        "uncertainty.ureal": (
            "UExpr",
            "evaluate_matrix",
            "umatrix",
            "ureal",
        ),
        "uncertainty.uss": (
            "USS",
            "interconnect",
            "uss",
        ),
        "uncertainty.synthesis": (
            "UncertainPlant",
            "augw",
            "hinfsyn_members",
            "hinfsyn_nominal",
        ),
        "uncertainty.utf": (
            "UTF",
            "tf",
        ),
    },
)
