"""Uncertain systems: uncertain reals, sampling, validation, LFTs, mu, robust margins and
performance, mu-synthesis.

Generic over any uncertain system, built on :mod:`robust` (the numerical core); nothing
here knows the backhoe. A machine's parametric family plugs in by registering its own
loop with :func:`margin_loop` and its batched members with :func:`validate_family`
(single dispatch on the type; :mod:`backhoe` registers the BDFT family), so the margin
and validation functions take it as they take an uncertain system. The machine
(:mod:`backhoe`), the designs, the reports and the command line build on it.

Public API (import from here; module layout may change):

* uncertain parameters: :class:`UncertainParameter`, :data:`DISTRIBUTIONS`,
  :data:`BOUNDS_RTOL` (the tolerance of a member's bounds check);
* sampling: :func:`sample`, :class:`SampleSet`, :data:`METHODS`, :data:`MAX_SAMPLE_BYTES`
  and :func:`max_members` (the largest sample drawn at once);
* batched validation: :func:`validate_family`, :class:`ValidationResult`;
* uncertain reals and expressions: :func:`ureal`, :class:`UExpr`, :func:`umatrix`,
  :func:`evaluate_matrix`; uncertain state-space systems: :func:`uss`, :class:`USS`,
  :func:`interconnect` (by signal names); uncertain transfer functions: :func:`tf`
  (``tf("s")``, the Laplace variable), :class:`UTF`;
* synthesis for an uncertain system: :func:`augw` (the mixed-sensitivity generalized
  plant, an :class:`UncertainPlant`), :func:`hinfsyn_nominal` (its nominal member),
  :func:`hinfsyn_members` (sampled members, each certified);
* the LFT form of an uncertain system: :func:`lft_form`, :class:`LFTForm`;
* structured singular value: :func:`mussv` (lower and upper bounds), :class:`MuBounds`;
* robust margins of an uncertain system or a registered family: :func:`robust_margin`,
  :class:`Region`, :class:`MarginResult`, :func:`margin_lower_bound`,
  :func:`margin_upper_bound`, :func:`worst_member`, :func:`scaled_bounds`,
  :func:`margin_loop` (what the margin sees, by type);
* robust performance (a weighted closed-loop bound over the box, certified by mu):
  :func:`robust_performance`, :class:`PerformanceResult`, :func:`performance_system`,
  :func:`certify_performance`, :func:`worst_performance`;
* mu-synthesis of an uncertain generalized plant by D-K or D-G-K iteration, its peak mu
  certified at every frequency: :func:`musyn`, :class:`MusynResult`; that certificate for
  any controller: :func:`certified_mu_peak`.
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
    "LFTForm",
    "lft_form",
    "MuBounds",
    "mussv",
    "Region",
    "MarginResult",
    "robust_margin",
    "margin_loop",
    "validate_family",
    "ValidationResult",
    "STABILITY_THRESHOLD",
    "MAX_CHUNK_BYTES",
    "DEFAULT_CHUNK",
    "BOUNDS_RTOL",
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
    "certified_mu_peak",
    "DISTRIBUTIONS",
    "UncertainParameter",
    "METHODS",
    "SampleSet",
    "sample",
    "MAX_SAMPLE_BYTES",
    "max_members",
]

# the names above, each imported from its module on first use (robust.lazy)
__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "robust.analysis.region": ("Region",),
        "uncertainty.dgk": (
            "MusynResult",
            "certified_mu_peak",
            "musyn",
        ),
        "uncertainty.enclosure": ("margin_loop",),
        "uncertainty.validation": (
            "MAX_CHUNK_BYTES",
            "STABILITY_THRESHOLD",
            "ValidationResult",
            "validate_family",
        ),
        "uncertainty.constants": ("DEFAULT_CHUNK",),
        "uncertainty.lft": (
            "LFTForm",
            "lft_form",
        ),
        "uncertainty.margins": (
            "margin_lower_bound",
            "robust_margin",
        ),
        "uncertainty.mu": (
            "MuBounds",
            "mussv",
        ),
        "uncertainty.parameters": (
            "BOUNDS_RTOL",
            "DISTRIBUTIONS",
            "UncertainParameter",
        ),
        "uncertainty.performance": (
            "PerformanceResult",
            "certify_performance",
            "performance_system",
            "robust_performance",
            "worst_performance",
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
        "uncertainty.synthesis": (
            "UncertainPlant",
            "augw",
            "hinfsyn_members",
            "hinfsyn_nominal",
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
        "uncertainty.utf": (
            "UTF",
            "tf",
        ),
    },
)
