"""Report builders: the reproduction of the paper, the design comparison and the sweep pages.

Every page goes through one builder (:class:`reports.html.HtmlPage`, written
atomically by :func:`reports.html.write_report_dir`); figure code returns matplotlib
figures (:mod:`reports.figures`, :mod:`reports.sweeps`) and only the builders save
them. Builds on :mod:`robust`, :mod:`uncertainty` and :mod:`designs`; the command
line builds on it.
"""

from robust.lazy import lazy_exports

__all__ = [
    "FamilyCoverage",
    "add_coverage_section",
    "family_coverage",
    "HtmlPage",
    "ReproductionResult",
    "VariantResult",
    "fmt",
    "reproduce",
    "result_to_json",
    "run_all_designs",
    "sweep_figures",
    "verdict",
    "write_design_report",
    "write_report_dir",
    "write_reproduction_report",
    "write_sweep_report",
]

# the names above, each imported from its module on first use (robust.lazy)
__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "reports.coverage": (
            "FamilyCoverage",
            "add_coverage_section",
            "family_coverage",
        ),
        "reports.design_runs": ("run_all_designs",),
        "reports.designs": (
            "verdict",
            "write_design_report",
        ),
        "reports.html": (
            "HtmlPage",
            "fmt",
            "write_report_dir",
        ),
        "reports.reproduce": (
            "ReproductionResult",
            "VariantResult",
            "reproduce",
            "result_to_json",
            "write_reproduction_report",
        ),
        "reports.sweeps": (
            "sweep_figures",
            "write_sweep_report",
        ),
    },
)
