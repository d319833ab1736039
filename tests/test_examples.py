"""The docstring examples of the uncertain-system API run and print what they show."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "uncertainty.ureal",
    "uncertainty.uss",
    "uncertainty.utf",
    "uncertainty.synthesis",
    "uncertainty.margins",
    "uncertainty.mu",
    "uncertainty.lft",
    "backhoe.families.files",
    "backhoe.families.loop",
]


@pytest.mark.parametrize("name", MODULES, ids=[n.rsplit(".", 1)[1] for n in MODULES])
def test_docstring_examples(name):
    # (the package's names ureal and uss are the functions; the modules come from here)
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
