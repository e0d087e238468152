"""Shared fixtures: the bundled order-type data and, as an extra layer, Aichholzer's reference files.

Every test that can run on the bundled data does (its IDs equal the reference files'): use
``bundled_sets`` / ``bundled_db_path``. The reference files are read from
``$OTTAG_AICHHOLZER_DIR`` by ``otdb_dir`` / ``reference_sets`` / ``reference_db_path`` /
``mirrors_db_path``, which skip when it is not set.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ottag_db.files.bundled import bundled_point_files
from ottag_db.files.pointfile import read_point_file
from ottag_db.store.db import Database, open_database
from ottag_db.store.importer import import_point_file
from tests.support.sources import POINT_SET_SOURCES, aichholzer_dir


@pytest.fixture(scope="session")
def otdb_dir() -> Path:
    """Folder with Aichholzer's otypes03.b08 … otypes08.b08 (skips when not configured)."""
    d = aichholzer_dir()
    if d is None or not (d / "otypes08.b08").exists():
        pytest.skip("set OTTAG_AICHHOLZER_DIR to the folder with otypes03.b08 … otypes08.b08")
    return d


@pytest.fixture(scope="session")
def reference_sets(otdb_dir: Path) -> dict[int, np.ndarray]:
    """Reference point sets per k (3 … 8) as (records, k, 2) int64 arrays."""
    return {k: read_point_file(otdb_dir / f"otypes{k:02d}.b08") for k in range(3, 9)}


@pytest.fixture(scope="session")
def bundled_sets() -> dict[int, np.ndarray]:
    """Bundled point sets per k (3 … 8), one per reflection pair, as (records, k, 2) int64 arrays.

    The same order types (and so the same IDs) as the reference files, other coordinates.
    """
    return {k: read_point_file(path) for path, k in bundled_point_files()}


@pytest.fixture(scope="session")
def bundled_db_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A database file with the bundled data imported as ``ottag-db import`` does (mirrors
    included: every order type of 3 … 8 points). Copy before mutating."""
    path = tmp_path_factory.mktemp("bundleddb") / "bundled.sqlite"
    db = open_database(path)
    try:
        for file, _k in bundled_point_files():
            import_point_file(db, file, with_mirrors=True)
    finally:
        db.close()
    return path


@pytest.fixture(params=POINT_SET_SOURCES)
def point_sets(request: pytest.FixtureRequest) -> dict[int, np.ndarray]:
    """Point sets per k (3 … 8) of one source (``bundled_sets`` or ``reference_sets``),
    ``(records, k, 2)`` int64, one per reflection pair: the same order types (the same IDs),
    other coordinates."""
    sets: dict[int, np.ndarray] = request.getfixturevalue(f"{request.param}_sets")
    return sets


def build_reference_db(path: Path, otdb: Path, *, with_mirrors: bool) -> Path:
    """Import otypes03 … otypes08 into a new database at ``path``."""
    db = open_database(path)
    try:
        for k in range(3, 9):
            import_point_file(db, otdb / f"otypes{k:02d}.b08", with_mirrors=with_mirrors)
    finally:
        db.close()
    return path


@pytest.fixture(scope="session")
def reference_db_path(otdb_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A database file with all reference files imported (no mirrors). Copy before mutating."""
    return build_reference_db(tmp_path_factory.mktemp("refdb") / "reference.sqlite", otdb_dir, with_mirrors=False)


@pytest.fixture(scope="session")
def mirrors_db_path(otdb_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A database file with all reference files imported with their mirrors. Copy before mutating."""
    return build_reference_db(tmp_path_factory.mktemp("mirrordb") / "mirrors.sqlite", otdb_dir, with_mirrors=True)


@pytest.fixture
def db(tmp_path: Path) -> Iterator[Database]:
    """A fresh, empty, migrated database in tmp_path."""
    d = open_database(tmp_path / "fresh.sqlite")
    yield d
    d.close()


@pytest.fixture
def runner() -> CliRunner:
    """Click test runner that keeps stdout and stderr apart."""
    return CliRunner()
