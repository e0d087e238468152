"""The package map holds: imports go one way between sub-packages, and no module grows too long.

The allowed directions are the ones drawn in ``docs/architecture.md``. Every ``import`` and
``from … import`` statement counts, also those inside functions and ``TYPE_CHECKING`` blocks:
a lazy import is still a dependency.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ottag_db"

#: Sub-package → the sub-packages its modules may import (itself and ``errors`` always).
ALLOWED: dict[str, frozenset[str]] = {
    "errors": frozenset(),
    "core": frozenset(),
    "files": frozenset({"core"}),
    "store": frozenset({"core", "files"}),
    "decode": frozenset({"core"}),
    "printing": frozenset({"core"}),
    "generation": frozenset({"core", "files"}),
    "app": frozenset({"core", "files", "store", "decode", "printing", "generation"}),
    "cli": frozenset({"app", "store", "files", "core"}),
    # The package root only re-exports (lazily) and __main__ only starts the CLI.
    "__init__": frozenset({"core", "files", "store", "decode", "printing", "generation", "app"}),
    "__main__": frozenset({"cli"}),
}

#: Third-party packages a sub-package must not import (heavy, or outside its concern).
FORBIDDEN_THIRD_PARTY: dict[str, frozenset[str]] = {
    "core": frozenset({"cv2", "scipy", "sqlalchemy", "alembic", "reportlab", "click", "numba"}),
    "files": frozenset({"cv2", "scipy", "sqlalchemy", "alembic", "reportlab", "click", "numba"}),
    "decode": frozenset({"sqlalchemy", "alembic", "reportlab", "click", "numba"}),
    "printing": frozenset({"sqlalchemy", "alembic", "click", "numba"}),
    "generation": frozenset({"cv2", "sqlalchemy", "alembic", "reportlab", "click"}),
    "store": frozenset({"cv2", "reportlab", "click", "numba"}),
    "app": frozenset({"click", "numba"}),
}

MAX_MODULE_LINES = 500

#: The compiled kernels (``native/ottag_native``, Cython; a top-level package so that the tests
#: in the checkout import it from where ``pip install .`` built it) serve the decoder's stages.
NATIVE = PACKAGE.parent / "native" / "ottag_native"
NATIVE_USERS = frozenset({"decode"})


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def _layer(path: Path) -> str:
    rel = path.relative_to(PACKAGE)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path) -> list[tuple[int, str]]:
    """``(line, absolute module name)`` of every import in one module of the package."""
    package = _module_name(path) if path.name == "__init__.py" else _module_name(path).rpartition(".")[0]
    return _imports_in(path.read_text(encoding="utf-8"), package)


def _imports_in(source: str, package: str) -> list[tuple[int, str]]:
    """``(line, absolute module name)`` of every import in ``source``, a module of ``package``
    (relative imports resolved against it)."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            if module == "ottag_db":
                # ``from ottag_db import core`` names a sub-package; ``from ottag_db import
                # __version__`` names an attribute of the (lazy) package root.
                found.extend(
                    (node.lineno, f"ottag_db.{alias.name}" if _is_submodule(alias.name) else module)
                    for alias in node.names
                )
            else:
                found.append((node.lineno, module))
    return found


def _is_submodule(name: str) -> bool:
    return (PACKAGE / name / "__init__.py").exists() or (PACKAGE / f"{name}.py").exists()


def _target_layer(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "ottag_db" or len(parts) < 2:
        return None
    return parts[1]


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_go_one_way(path: Path) -> None:
    layer = _layer(path)
    assert layer in ALLOWED, f"{path}: sub-package {layer!r} is not on the map (docs/architecture.md)"
    allowed = ALLOWED[layer] | {layer, "errors"}
    wrong = [
        f"{path.relative_to(PACKAGE.parent)}:{line} imports {module}"
        for line, module in _imports(path)
        if (target := _target_layer(module)) is not None and target not in allowed
    ]
    assert not wrong, f"{layer} may import only {sorted(allowed)}:\n" + "\n".join(wrong)


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_heavy_or_foreign_third_party_imports(path: Path) -> None:
    forbidden = FORBIDDEN_THIRD_PARTY.get(_layer(path), frozenset())
    wrong = [f"line {line}: {module}" for line, module in _imports(path) if module.split(".")[0] in forbidden]
    assert not wrong, f"{path.relative_to(PACKAGE.parent)} imports {wrong}"


def test_modules_stay_short() -> None:
    long = {
        str(p.relative_to(PACKAGE.parent)): n
        for p in _modules()
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_every_sub_package_is_on_the_map() -> None:
    subpackages = {p.parent.name for p in PACKAGE.glob("*/__init__.py")}
    assert subpackages <= set(ALLOWED), sorted(subpackages - set(ALLOWED))


def test_the_checker_sees_a_violation() -> None:
    # The walk must resolve relative and lazy imports, or the tests above prove nothing.
    src = "def f():\n    from ..store.db import open_database\n    import ottag_db.cli\n    from . import geometry\n"
    src += "    from ottag_db import __version__, decode\n"
    targets = [_target_layer(m) for _, m in _imports_in(src, "ottag_db.core")]
    assert targets == ["store", "cli", "core", None, "decode"]


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_only_the_decoder_uses_the_compiled_kernels(path: Path) -> None:
    if _layer(path) in NATIVE_USERS:
        return
    wrong = [f"line {line}: {module}" for line, module in _imports(path) if module.split(".")[0] == "ottag_native"]
    assert not wrong, f"{path.relative_to(PACKAGE.parent)} imports the compiled kernels: {wrong}"


def test_the_compiled_kernels_import_nothing_of_ours() -> None:
    sources = sorted(p for p in NATIVE.iterdir() if p.suffix in (".py", ".pyi", ".pyx"))
    assert any(p.suffix == ".pyx" for p in sources)
    ours = re.compile(r"^\s*(from|c?import)\s+ottag_db\b", re.MULTILINE)
    wrong = [str(p.relative_to(PACKAGE.parent)) for p in sources if ours.search(p.read_text(encoding="utf-8"))]
    assert not wrong, f"the kernels are leaves (numbers in, numbers out): {wrong}"
