"""The workbench's version (written into reports and artifacts)."""

__all__ = ["__version__"]

__version__ = "0.1.0"
