"""The public API of robust.sysid documents itself.

Every public name has a docstring naming its arguments.
"""

import inspect

import pytest

from robust import sysid

PUBLIC = [
    n
    for n in sysid.__all__
    if inspect.isfunction(getattr(sysid, n)) or inspect.isclass(getattr(sysid, n))
]


@pytest.mark.parametrize("name", PUBLIC, ids=PUBLIC)
def test_public_name_documents_its_arguments(name):
    obj = getattr(sysid, name)
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
