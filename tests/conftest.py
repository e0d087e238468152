"""Shared fixtures: the reference files from $OTTAG_AICHHOLZER_DIR and a database built from them."""

from __future__ import annotations

import os
import sqlite3
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ottag_db.db import Database, open_database
from ottag_db.importer import import_point_file
from ottag_db.pointfile import read_point_file

FIG4 = [[206, 159], [214, 127], [176, 49], [42, 144], [47, 175], [129, 178], [149, 206]]
FIG8 = [[0, 0], [69, 255], [149, 116], [138, 72], [255, 69]]
TABLE9 = [
    [0, 5, 4, 3, 2, 1, 0],
    [0, 0, 2, 5, 4, 3, 1],
    [1, 3, 0, 4, 3, 2, 2],
    [2, 0, 1, 0, 5, 4, 3],
    [3, 1, 2, 0, 0, 5, 4],
    [4, 2, 3, 1, 0, 0, 5],
    [5, 4, 3, 2, 1, 0, 0],
]


def _otdb() -> Path | None:
    value = os.environ.get("OTTAG_AICHHOLZER_DIR")
    return Path(value) if value else None


@pytest.fixture(scope="session")
def otdb_dir() -> Path:
    """Folder with Aichholzer's otypes03.b08 … otypes08.b08 (skips when not configured)."""
    d = _otdb()
    if d is None or not (d / "otypes08.b08").exists():
        pytest.skip("set OTTAG_AICHHOLZER_DIR to the folder with otypes03.b08 … otypes08.b08")
    return d


@pytest.fixture(scope="session")
def reference_sets(otdb_dir: Path) -> dict[int, np.ndarray]:
    """Reference point sets per k (3 … 8) as (records, k, 2) int64 arrays."""
    return {k: read_point_file(otdb_dir / f"otypes{k:02d}.b08") for k in range(3, 9)}


def build_reference_db(path: Path, otdb: Path, *, with_mirrors: bool) -> Path:
    """Import otypes03 … otypes08 into a new database at ``path``."""
    db = open_database(path)
    try:
        for k in range(3, 9):
            import_point_file(db, otdb / f"otypes{k:02d}.b08", with_mirrors=with_mirrors)
    finally:
        db.close()
    return path


def dump_database(path: Path) -> list[str]:
    """The SQL dump of a SQLite file: equal dumps mean an unchanged database."""
    con = sqlite3.connect(path)
    try:
        return list(con.iterdump())
    finally:
        con.close()


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
