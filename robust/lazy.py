"""A package's public names, imported on first use (PEP 562).

The packages ``robust``, ``uncertainty``, ``designs`` and ``reports`` export their public
API from their ``__init__`` (``from robust import BDFTLoop``), but importing every module
behind it would load NumPy, SciPy, python-control and CVXPY whenever any of their modules
is imported, even a light one (``import robust.errors`` runs ``robust/__init__.py``
first). So each ``__init__`` lists its names once, by the module that defines them, and
hands the list to :func:`lazy_exports`: the package's module ``__getattr__`` imports a
name's module when the name is first asked for (``from package import name``,
``package.name``, :func:`getattr`) and keeps the value in the package's namespace, and its
``__dir__`` lists the names not yet imported too. The command line's ``--help`` and its
argument errors are answered this way without the numerical stack
(``tests/test_cli_startup.py``).

A submodule named like one of the package's public names (``uncertainty.uss``, the
module, and ``uncertainty.uss``, the function it defines) would hide that name once
imported, since the import system binds a loaded submodule in its package; a lazy package
keeps the public name, as the package did when its ``__init__`` imported every name.

This module imports only the standard library: every package's ``__init__`` uses it.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable, Iterable, Mapping

__all__ = ["lazy_exports"]

#: Package name -> its public names and the module that defines each.
_EXPORTS: dict[str, dict[str, str]] = {}


class _LazyPackage(types.ModuleType):
    """A package made lazy by :func:`lazy_exports` (keeps its public names from submodules)."""

    def __setattr__(self, name: str, value) -> None:
        if (
            isinstance(value, types.ModuleType)
            and name in _EXPORTS.get(self.__name__, ())
            and value.__name__ == f"{self.__name__}.{name}"
        ):
            return  # a submodule of a public name's name: the public name is kept
        super().__setattr__(name, value)


def lazy_exports(
    package: str, modules: Mapping[str, Iterable[str]]
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of a package whose names load on first use.

    Call it from the package's ``__init__`` and bind what it returns::

        __getattr__, __dir__ = lazy_exports(__name__, {"robust.errors": ("BDFTError",)})

    Parameters
    ----------
    package : str
        The package's name (its ``__init__``'s ``__name__``; it must be in
        :data:`sys.modules`, as it is while its ``__init__`` runs).
    modules : mapping of str to iterable of str
        Module (its full name) -> the public names it defines, as the ``__init__``'s
        ``from MODULE import NAME, ...`` statements would list them.

    Returns
    -------
    (callable, callable)
        ``__getattr__(name)``: the value of ``name`` from its module, imported then and
        kept in the package's namespace (a later access does not call it); raises
        :class:`AttributeError` for a name that is not listed. ``__dir__()``: the
        package's namespace and every listed name, sorted.

    Raises
    ------
    ValueError
        If a name is listed under two modules.
    """
    module = sys.modules[package]
    where: dict[str, str] = {}
    for source, names in modules.items():
        for name in names:
            if where.setdefault(name, source) != source:
                raise ValueError(f"{package}: {name!r} is listed under {where[name]} and {source}")
    _EXPORTS[package] = where

    def __getattr__(name: str):
        try:
            source = where[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(source), name)
        module.__dict__[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*module.__dict__, *where})

    module.__class__ = _LazyPackage
    return __getattr__, __dir__
