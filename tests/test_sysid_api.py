"""The public APIs of robust.sysid and backhoe.sysid document themselves.

Every public name has a docstring naming its arguments.
"""

import inspect

import pytest

from backhoe import sysid as machine_sysid
from robust import sysid

PUBLIC = [
    (mod, n)
    for mod in (sysid, machine_sysid)
    for n in mod.__all__
    if inspect.isfunction(getattr(mod, n)) or inspect.isclass(getattr(mod, n))
]


@pytest.mark.parametrize("mod,name", PUBLIC, ids=[f"{m.__name__}.{n}" for m, n in PUBLIC])
def test_public_name_documents_its_arguments(mod, name):
    obj = getattr(mod, name)
    doc = inspect.getdoc(obj)
    assert doc, f"{name} has no docstring"
    if inspect.isfunction(obj):
        for p in inspect.signature(obj).parameters.values():
            if p.kind is p.VAR_KEYWORD:
                assert f"**{p.name}" in doc, f"{name} does not document **{p.name}"
            else:
                assert p.name in doc, f"{name} does not document its argument {p.name!r}"


def test_all_names_exist():
    missing = [n for n in sysid.__all__ if not hasattr(sysid, n)]
    assert not missing
