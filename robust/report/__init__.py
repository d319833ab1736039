"""Reports: figures (library code returns matplotlib figures) and HTML pages."""

from .html import HtmlPage, write_report_dir
from .reproduce import ReproductionResult, reproduce, write_reproduction_report

__all__ = ["HtmlPage", "write_report_dir", "ReproductionResult", "reproduce", "write_reproduction_report"]
