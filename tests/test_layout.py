"""The layout's rules, checked on the source: layers (import-linter, in CI), private names and
function-local imports.

* No module imports a private name (a leading underscore, in the name or in the module
  path) from another package.
* Project modules are imported at module level; a function-local import is allowed only
  for an optional heavy dependency (none of the project's own packages), and in the command
  line (:data:`LAZY_IMPORTS`), whose modules import the numerical layers in the functions
  that run a command, so that building the parser and its ``--help`` need none of them
  (``tests/test_cli_startup.py``).
"""

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ("robust", "uncertainty", "backhoe", "designs", "reports", "bdft")
#: Packages whose modules import project modules inside functions (the command line: its
#: parsers and ``--help`` are built without the numerical layers).
LAZY_IMPORTS = ("bdft",)


def _modules():
    for pkg in PACKAGES:
        yield from sorted((ROOT / pkg).rglob("*.py"))


def _module_name(path: pathlib.Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _package_of(module: str) -> str:
    """The package a module belongs to: ``backhoe.model.loop`` -> ``backhoe.model``."""
    return module.rsplit(".", 1)[0] if "." in module else module


def _imports(tree):
    """(node, imported module, [names], function-local) for every project import."""
    local_nodes = set()
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for node in ast.walk(fn):
                if isinstance(node, (ast.Import, ast.ImportFrom)):
                    local_nodes.add(id(node))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node, node.module, [a.name for a in node.names], id(node) in local_nodes
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield node, a.name, [], id(node) in local_nodes


MODULES = list(_modules())
EAGER = [p for p in MODULES if _module_name(p).split(".")[0] not in LAZY_IMPORTS]


def test_the_layout_has_every_package():
    names = {_module_name(p) for p in MODULES}
    for pkg in PACKAGES:
        assert pkg in names


@pytest.mark.parametrize("path", MODULES, ids=[_module_name(p) for p in MODULES])
def test_no_private_names_across_packages(path):
    me = _module_name(path)
    tree = ast.parse(path.read_text(), filename=str(path))
    bad = []
    for node, module, names, _ in _imports(tree):
        if module.split(".")[0] not in PACKAGES:
            continue
        other_pkg = (
            _package_of(module) if not (ROOT / module.replace(".", "/")).is_dir() else module
        )
        mine = _package_of(me) if not path.name == "__init__.py" else me
        if other_pkg == mine:
            continue
        private_path = any(part.startswith("_") for part in module.split("."))
        private_names = [n for n in names if n.startswith("_") and n != "__version__"]
        if private_path or private_names:
            bad.append(f"line {node.lineno}: from {module} import {', '.join(names)}")
    assert not bad, f"{me} imports private names of another package: {bad}"


@pytest.mark.parametrize("path", EAGER, ids=[_module_name(p) for p in EAGER])
def test_project_modules_are_imported_at_module_level(path):
    tree = ast.parse(path.read_text(), filename=str(path))
    local = [
        f"line {node.lineno}: {module}"
        for node, module, _, is_local in _imports(tree)
        if is_local and module.split(".")[0] in PACKAGES
    ]
    assert not local, f"{_module_name(path)} imports project modules inside functions: {local}"
