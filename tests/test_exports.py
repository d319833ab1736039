"""The packages' public names load on first use (:mod:`robust.lazy`) and all still resolve.

``robust``, ``uncertainty``, ``backhoe``, ``designs`` and ``reports`` list their public names in
``__all__`` and import each from its module when it is first asked for, so that their
light modules (the errors, the constants the command line's options need) import without
the numerical stack. Checked here: every ``__all__`` name resolves through ``from PACKAGE
import NAME`` and attribute access, to the object its module defines; ``dir`` lists them;
an unknown name is an :class:`AttributeError`; a submodule named like a public name does
not hide the name; and, in a fresh process, the light modules import no numerical library.
"""

import importlib
import inspect
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The packages whose public names are lazy.
LAZY = ("robust", "uncertainty", "backhoe", "designs", "reports")
#: Modules importable without the numerical stack (what the command line's parsers use).
LIGHT = (
    "robust",
    "robust.errors",
    "robust.version",
    "robust.engine",
    "robust.lazy",
    "uncertainty",
    "uncertainty.constants",
    "backhoe",
    "backhoe.constants",
    "designs",
    "designs.constants",
    "reports",
)
HEAVY = ("numpy", "scipy", "control", "cvxpy", "matplotlib", "pandas", "dask", "joblib", "numba")

NAMES = [(pkg, name) for pkg in LAZY for name in importlib.import_module(pkg).__all__]


@pytest.mark.parametrize("pkg,name", NAMES, ids=[f"{p}.{n}" for p, n in NAMES])
def test_every_public_name_resolves(pkg, name):
    namespace: dict = {}
    exec(f"from {pkg} import {name}", namespace)
    package = importlib.import_module(pkg)
    assert namespace[name] is getattr(package, name)
    assert name in dir(package)


@pytest.mark.parametrize("pkg", LAZY)
def test_public_names_come_from_their_modules(pkg):
    package = importlib.import_module(pkg)
    assert len(set(package.__all__)) == len(package.__all__), "a name listed twice"
    for name in package.__all__:
        value = getattr(package, name)
        if inspect.isfunction(value) or inspect.isclass(value):
            # a function or class is the one its defining module holds
            assert value.__module__.split(".")[0] in LAZY, f"{pkg}.{name}"
            assert getattr(importlib.import_module(value.__module__), value.__name__) is value


@pytest.mark.parametrize("pkg", LAZY)
def test_an_unknown_name_is_an_attribute_error(pkg):
    package = importlib.import_module(pkg)
    with pytest.raises(AttributeError, match="no_such_name"):
        package.no_such_name  # noqa: B018
    assert not hasattr(package, "no_such_name")
    with pytest.raises(ImportError):
        exec(f"from {pkg} import no_such_name", {})


@pytest.mark.parametrize(
    "pkg,name", [("uncertainty", "uss"), ("uncertainty", "ureal"), ("reports", "reproduce")]
)
def test_a_submodule_does_not_hide_the_public_name_of_its_name(pkg, name):
    submodule = importlib.import_module(f"{pkg}.{name}")
    package = importlib.import_module(pkg)
    value = getattr(package, name)
    assert callable(value) and not isinstance(value, type(sys))
    assert value is getattr(submodule, name)


def test_light_modules_import_no_numerical_library():
    code = (
        "import importlib, json, sys\n"
        f"for m in {LIGHT!r}:\n"
        "    importlib.import_module(m)\n"
        f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == []
