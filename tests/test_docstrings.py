"""Every public function and class documents its parameters (numpydoc form).

Modelled on python-control's ``control/tests/docstrings_test.py``. The public API is
what the packages export: the ``__all__`` of :data:`PACKAGES` and of each of their
public (not underscore-prefixed) modules. For each exported object defined in this
project:

* a function (or other routine) must have a docstring whose numpydoc ``Parameters``
  section names every parameter of its signature;
* a class must have a docstring of its own whose ``Parameters`` section (for a
  dataclass, ``Parameters`` or ``Attributes``; an ``__init__`` docstring counts too)
  names every parameter of its constructor; a class whose constructor it inherits
  from a built-in class (the exceptions) or a :class:`typing.Protocol` has no
  parameters of its own to document;
* every public method (and property) of a public class that is defined in this
  project has at least a one-line docstring; a property may instead be an entry of
  its class's ``Attributes`` section (numpydoc lists properties there).

``self`` and ``cls`` are never required; ``*args`` / ``**kwargs`` are accepted when
the docstring mentions them (``*args`` or ``**kwargs`` anywhere in it, or ``args`` /
``kwargs`` in the Parameters section). An entry such as ``a, b : float`` documents both
``a`` and ``b``. Constants and other non-callables are skipped.

Each check is one test, parametrised by the qualified name of the object it checks
(``module.QualName`` where it is defined, ``module.Class.method`` for methods), so a
failure names its culprit. The parser below is deliberately small: numpydoc sections
are a title line underlined with dashes, and entries are the section's lines that
are not indented.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
import re
from collections.abc import Iterator
from types import ModuleType

import pytest

#: Packages whose ``__all__`` (and whose public modules' ``__all__``) are the public API.
PACKAGES = (
    "robust",
    "robust.analysis",
    "robust.synthesis",
    "robust.sysid",
    "uncertainty",
    "backhoe",
    "backhoe.model",
    "backhoe.analysis",
    "backhoe.synthesis",
    "backhoe.sysid",
    "backhoe.families",
    "designs",
    "reports",
)

#: Objects defined under these top-level packages are checked; re-exports of other
#: libraries' objects are not ours to document.
PROJECT_ROOTS = ("robust", "uncertainty", "backhoe", "designs", "reports", "bdft")

#: Sections whose entries document constructor parameters, per kind of object.
FUNCTION_SECTIONS = ("Parameters",)
CLASS_SECTIONS = ("Parameters",)
DATACLASS_SECTIONS = ("Parameters", "Attributes")

_UNDERLINE = re.compile(r"^\s*-{3,}\s*$")


# ----------------------------------------------------------------------------------
# numpydoc parsing
# ----------------------------------------------------------------------------------


def numpydoc_sections(docstring: str) -> dict[str, list[str]]:
    """Split a docstring into its numpydoc sections.

    Parameters
    ----------
    docstring : str
        The docstring, already cleaned (as :func:`inspect.getdoc` or
        :func:`inspect.cleandoc` return it: common indentation removed).

    Returns
    -------
    dict of str to list of str
        Section title (``"Parameters"``, ``"Attributes"``, ...) to the lines of the
        section's body, up to the next section title. Text before the first section
        is not returned. A title repeated in one docstring concatenates its bodies.
    """
    lines = docstring.splitlines()
    sections: dict[str, list[str]] = {}
    current: list[str] | None = None
    i = 0
    while i < len(lines):
        line = lines[i]
        title = line.strip()
        underlined = i + 1 < len(lines) and _UNDERLINE.match(lines[i + 1]) is not None
        if title and underlined and not _UNDERLINE.match(line):
            current = sections.setdefault(title, [])
            i += 2
            continue
        if current is not None:
            current.append(line)
        i += 1
    return sections


def documented_names(docstring: str, section_titles: tuple[str, ...]) -> set[str]:
    """Names documented by the entries of the given numpydoc sections.

    Parameters
    ----------
    docstring : str
        The cleaned docstring.
    section_titles : tuple of str
        The sections to read, e.g. ``("Parameters",)`` or
        ``("Parameters", "Attributes")``.

    Returns
    -------
    set of str
        Every name an entry line documents. An entry line is a non-blank line of the
        section with the section's least indentation, of the form ``name : type``,
        ``name`` or ``a, b : type`` (each of ``a`` and ``b`` counts); leading ``*``
        of ``*args`` / ``**kwargs`` is dropped.
    """
    sections = numpydoc_sections(docstring)
    names: set[str] = set()
    for title in section_titles:
        body = [line for line in sections.get(title, []) if line.strip()]
        if not body:
            continue
        indent = min(len(line) - len(line.lstrip()) for line in body)
        for line in body:
            if len(line) - len(line.lstrip()) != indent:
                continue
            head = line.strip().split(" : ", 1)[0].rstrip(":").strip()
            for name in head.split(","):
                name = name.strip().lstrip("*")
                if name.isidentifier():
                    names.add(name)
    return names


# ----------------------------------------------------------------------------------
# collecting the public API
# ----------------------------------------------------------------------------------


def _import(name: str, errors: dict[str, str]) -> ModuleType | None:
    try:
        return importlib.import_module(name)
    except Exception as exc:  # reported by test_public_module_imports
        errors[name] = f"{type(exc).__name__}: {exc}"
        return None


def public_modules() -> tuple[list[ModuleType], dict[str, str]]:
    """The packages of :data:`PACKAGES` and their public modules, imported.

    Returns
    -------
    modules : list of module
        Each package, followed by its modules whose names do not start with an
        underscore (subpackages listed in :data:`PACKAGES` appear once).
    errors : dict of str to str
        Module name to the exception its import raised; those modules (and, for a
        package, its submodules) are left out of ``modules``.
    """
    modules: dict[str, ModuleType] = {}
    errors: dict[str, str] = {}
    for package_name in PACKAGES:
        package = _import(package_name, errors)
        if package is None:
            continue
        modules.setdefault(package_name, package)
        for info in pkgutil.iter_modules(package.__path__, package_name + "."):
            if info.name.rsplit(".", 1)[1].startswith("_") or info.name in modules:
                continue
            module = _import(info.name, errors)
            if module is not None:
                modules[info.name] = module
    return list(modules.values()), errors


def is_project_object(obj: object) -> bool:
    """Whether ``obj`` is defined in one of this project's packages.

    Parameters
    ----------
    obj : object
        A function, class or other object with a ``__module__``.

    Returns
    -------
    bool
        True when the defining module's top-level package is in
        :data:`PROJECT_ROOTS`.
    """
    module = getattr(obj, "__module__", None) or ""
    return module.split(".", 1)[0] in PROJECT_ROOTS


def qualified_name(obj: object) -> str:
    """``module.QualName`` of a function or class, where it is defined."""
    return f"{obj.__module__}.{obj.__qualname__}"


def is_checked_callable(obj: object) -> bool:
    """Whether an exported object is a function or class (constants are skipped).

    Parameters
    ----------
    obj : object
        An object named in an ``__all__``.

    Returns
    -------
    bool
        True for classes and routines (functions, builtins, and wrappers such as
        :func:`functools.lru_cache` ones that carry ``__wrapped__``) defined in this
        project.
    """
    if not is_project_object(obj):
        return False
    if inspect.isclass(obj) or inspect.isroutine(obj):
        return True
    return callable(obj) and hasattr(obj, "__wrapped__")


def exported_objects(modules: list[ModuleType]) -> dict[str, object]:
    """Every public function and class, once, keyed by its qualified name.

    Parameters
    ----------
    modules : list of module
        The modules whose ``__all__`` is the public API (:func:`public_modules`).

    Returns
    -------
    dict of str to object
        Qualified name (:func:`qualified_name`) to the object, over the ``__all__``
        of every module, in order of first appearance.
    """
    found: dict[str, object] = {}
    for module in modules:
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name, None)
            if obj is None or not is_checked_callable(obj):
                continue
            found.setdefault(qualified_name(obj), obj)
    return found


def public_methods(cls: type) -> Iterator[tuple[str, tuple[type, object]]]:
    """The public methods and properties a class gets from this project's classes.

    Parameters
    ----------
    cls : type
        A public class.

    Yields
    ------
    name : str
        Qualified name ``module.DefiningClass.method`` (inherited methods are named
        after the class that defines them, so each is checked once).
    owner_and_member : (type, object)
        The defining class, and the function (unwrapped from a classmethod or
        staticmethod) or property stored in its ``__dict__``.
    """
    for name in dir(cls):
        if name.startswith("_"):
            continue
        for owner in cls.__mro__:
            if name in owner.__dict__:
                break
        else:
            continue
        if not is_project_object(owner):
            continue
        member = owner.__dict__[name]
        if isinstance(member, staticmethod | classmethod):
            member = member.__func__
        if inspect.isfunction(member) or isinstance(member, property):
            yield f"{qualified_name(owner)}.{name}", (owner, member)


MODULES, IMPORT_ERRORS = public_modules()
EXPORTED = exported_objects(MODULES)

FUNCTIONS = {name: obj for name, obj in EXPORTED.items() if not inspect.isclass(obj)}
CLASSES = {name: obj for name, obj in EXPORTED.items() if inspect.isclass(obj)}
# an inherited method appears once per subclass, always with the same key and value
METHODS = dict(item for cls in CLASSES.values() for item in public_methods(cls))


# ----------------------------------------------------------------------------------
# the checks
# ----------------------------------------------------------------------------------


def own_docstring(obj: object) -> str | None:
    """The docstring an object carries itself, cleaned.

    Parameters
    ----------
    obj : object
        A function or class.

    Returns
    -------
    str or None
        None when the object has no docstring of its own: a class inheriting one
        from a base class, or a dataclass whose ``__doc__`` is the signature
        :mod:`dataclasses` generates when the class has none.
    """
    if inspect.isclass(obj):
        doc = obj.__dict__.get("__doc__")
        if doc and dataclasses.is_dataclass(obj) and doc.startswith(obj.__name__ + "("):
            return None
    else:
        doc = getattr(obj, "__doc__", None)
    if not doc or not doc.strip():
        return None
    return inspect.cleandoc(doc)


def undocumented_parameters(
    signature: inspect.Signature, docstring: str, sections: tuple[str, ...]
) -> list[str]:
    """Parameters of a signature that the docstring does not document.

    Parameters
    ----------
    signature : inspect.Signature
        The signature of the function or constructor.
    docstring : str
        The cleaned docstring.
    sections : tuple of str
        The numpydoc sections whose entries count as documentation.

    Returns
    -------
    list of str
        The missing parameters in signature order, ``*args`` / ``**kwargs`` spelled
        with their stars.
    """
    documented = documented_names(docstring, sections)
    missing = []
    for name, parameter in signature.parameters.items():
        if name in ("self", "cls") or name in documented:
            continue
        if parameter.kind is inspect.Parameter.VAR_POSITIONAL:
            if f"*{name}" not in docstring:
                missing.append(f"*{name}")
        elif parameter.kind is inspect.Parameter.VAR_KEYWORD:
            if f"**{name}" not in docstring:
                missing.append(f"**{name}")
        else:
            missing.append(name)
    return missing


def has_own_constructor(cls: type) -> bool:
    """Whether a class's constructor parameters are its own to document.

    Parameters
    ----------
    cls : type
        A public class.

    Returns
    -------
    bool
        False for protocols and for classes whose ``__init__`` and ``__new__`` both
        come from Python's built-in classes (``object``, ``Exception``, ...).
    """
    if getattr(cls, "_is_protocol", False):
        return False
    for method in ("__init__", "__new__"):
        for owner in cls.__mro__:
            if method in owner.__dict__:
                if owner.__module__ != "builtins":
                    return True
                break
    return False


def test_public_api_is_not_empty():
    assert len(FUNCTIONS) > 50 and len(CLASSES) > 30 and len(METHODS) > 10


@pytest.mark.parametrize("name", [*PACKAGES, *sorted(set(IMPORT_ERRORS) - set(PACKAGES))])
def test_public_module_imports(name):
    assert name not in IMPORT_ERRORS, f"{name} does not import: {IMPORT_ERRORS[name]}"


@pytest.mark.parametrize("module", MODULES, ids=lambda module: module.__name__)
def test_public_module_declares_all(module):
    names = getattr(module, "__all__", None)
    assert names is not None, f"{module.__name__} has no __all__"
    missing = [name for name in names if not hasattr(module, name)]
    assert not missing, f"{module.__name__}.__all__ names undefined {missing}"


@pytest.mark.parametrize("name", list(FUNCTIONS))
def test_function_documents_parameters(name):
    function = FUNCTIONS[name]
    docstring = own_docstring(function)
    assert docstring, f"{name} has no docstring"
    signature = inspect.signature(function)
    missing = undocumented_parameters(signature, docstring, FUNCTION_SECTIONS)
    assert not missing, f"{name}: Parameters section misses {missing}"


@pytest.mark.parametrize("name", list(CLASSES))
def test_class_documents_parameters(name):
    cls = CLASSES[name]
    docstring = own_docstring(cls)
    assert docstring, f"{name} has no docstring of its own"
    if not has_own_constructor(cls):
        return
    sections = DATACLASS_SECTIONS if dataclasses.is_dataclass(cls) else CLASS_SECTIONS
    init = cls.__dict__.get("__init__")
    init_doc = own_docstring(init) if inspect.isfunction(init) else None
    if init_doc:
        docstring = docstring + "\n\n" + init_doc
    missing = undocumented_parameters(inspect.signature(cls), docstring, sections)
    assert not missing, f"{name}: {' or '.join(sections)} section misses {missing}"


@pytest.mark.parametrize("name", list(METHODS))
def test_method_has_docstring(name):
    owner, member = METHODS[name]
    doc = member.__doc__
    if doc and doc.strip():
        return
    attribute = name.rsplit(".", 1)[1]
    if isinstance(member, property):
        listed = documented_names(own_docstring(owner) or "", ("Attributes",))
        assert attribute in listed, (
            f"{name} (a property) has no docstring and is not in the Attributes section "
            f"of {owner.__qualname__}"
        )
        return
    raise AssertionError(f"{name} has no docstring")


# ----------------------------------------------------------------------------------
# the parser, on known inputs
# ----------------------------------------------------------------------------------

_SAMPLE = """Summary line.

Parameters
----------
a, b : float
    Two numbers, in metres.
    c : not an entry (indented)
*args
    Extra positionals.
**options : dict
    Keyword options.

Attributes
----------
x : int
    An attribute.

Returns
-------
y : float
    Not a parameter.
"""


def test_parser_reads_entries():
    assert documented_names(_SAMPLE, ("Parameters",)) == {"a", "b", "args", "options"}
    assert documented_names(_SAMPLE, ("Parameters", "Attributes")) == {
        "a",
        "b",
        "args",
        "options",
        "x",
    }
    assert documented_names(_SAMPLE, ("Other",)) == set()


def test_parser_flags_missing_parameters():
    def f(a, b, c, *args, d=1, **options):
        pass

    missing = undocumented_parameters(inspect.signature(f), _SAMPLE, ("Parameters",))
    assert missing == ["c", "d"]

    def g(self, *rest, **kw):
        pass

    # *rest and **kw are neither entries nor mentioned in the text
    assert undocumented_parameters(inspect.signature(g), _SAMPLE, ("Parameters",)) == [
        "*rest",
        "**kw",
    ]


def test_generated_dataclass_docstring_does_not_count():
    @dataclasses.dataclass
    class Undocumented:
        a: float

    @dataclasses.dataclass
    class Documented:
        """Documented.

        Attributes
        ----------
        a : float
            A length, m.
        """

        a: float

    assert own_docstring(Undocumented) is None
    assert documented_names(own_docstring(Documented), DATACLASS_SECTIONS) == {"a"}
    assert has_own_constructor(Documented)
    assert not has_own_constructor(ValueError)
