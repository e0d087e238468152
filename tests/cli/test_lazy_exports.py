"""The package root resolves its public names lazily (PEP 562) and they all still resolve.

A name whose target module moved fails here with the name; ``_EXPORTS`` and the
``TYPE_CHECKING`` imports (what mypy sees) must name the same module for every name.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

import ottag_db

INIT = Path(ottag_db.__file__)


@pytest.mark.parametrize("name", ottag_db.__all__)
def test_every_public_name_resolves(name: str) -> None:
    value = getattr(ottag_db, name)
    if name != "__version__":
        assert value is getattr(importlib.import_module(ottag_db._EXPORTS[name]), name)


def test_all_is_the_lazy_map() -> None:
    assert sorted(ottag_db.__all__) == sorted([*ottag_db._EXPORTS, "__version__"])


def test_type_checking_imports_match_the_lazy_map() -> None:
    tree = ast.parse(INIT.read_text(encoding="utf-8"))
    block = next(n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test) == "TYPE_CHECKING")
    seen = {alias.name: node.module for node in block.body if isinstance(node, ast.ImportFrom) for alias in node.names}
    assert seen == ottag_db._EXPORTS


def test_dir_lists_public_names() -> None:
    assert set(ottag_db.__all__) <= set(dir(ottag_db))


def test_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = ottag_db.no_such_name  # type: ignore[attr-defined]
    assert not hasattr(ottag_db, "_private")


def test_from_import_works() -> None:
    from ottag_db import OttagError, canonical_form

    assert issubclass(OttagError, Exception) and callable(canonical_form)
