"""Reports: figures (library code returns matplotlib figures) and HTML pages."""

from reports.html import HtmlPage, write_report_dir
from reports.reproduce import ReproductionResult, reproduce, write_reproduction_report

__all__ = [
    "HtmlPage",
    "write_report_dir",
    "ReproductionResult",
    "reproduce",
    "write_reproduction_report",
]
