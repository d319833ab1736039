"""The docstring examples of the uncertain-system API run and print what they show."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["ureal", "uss", "utf", "synthesis", "files", "loop", "margins", "mu", "lft"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    # (the package's names ureal and uss are the functions; the modules come from here)
    module = importlib.import_module(f"uncertainty.{name}")
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
