"""Tests of ottag_db.store.db: opening, migrating, backups, pragmas and corrupt files."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import pytest
from alembic import command
from sqlalchemy import text
from sqlalchemy.exc import OperationalError

from ottag_db.errors import DatabaseError
from ottag_db.store.db import (
    _alembic_config,
    as_database_error,
    busy_timeout_seconds,
    check_integrity,
    head_revision,
    open_database,
    resolve_database_url,
)


def test_new_database_is_at_head_with_wal_and_foreign_keys(tmp_path: Path) -> None:
    path = tmp_path / "new.sqlite"
    db = open_database(path)
    try:
        assert db.current_revision() == head_revision()
        with db.engine.connect() as conn:
            assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
            assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
            names = {r[0] for r in conn.execute(text("SELECT name FROM sqlite_master WHERE type='table'"))}
        assert {"sources", "order_types", "realizations", "alembic_version"} <= names
        assert db.backup is None
    finally:
        db.close()


def test_constraints_are_named(tmp_path: Path) -> None:
    db = open_database(tmp_path / "n.sqlite")
    db.close()
    sql = " ".join(
        r[0]
        for r in sqlite3.connect(tmp_path / "n.sqlite").execute("SELECT sql FROM sqlite_master WHERE sql IS NOT NULL")
    )
    for name in [
        "pk_sources",
        "uq_sources_sha256",
        "uq_order_types_k_canonical_lambda",
        "fk_realizations_order_type_id_order_types",
    ]:
        assert name in sql


def test_url_and_env_resolution(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _, path = resolve_database_url(f"sqlite:///{tmp_path}/u.sqlite")
    assert path == (tmp_path / "u.sqlite").resolve()
    monkeypatch.setenv("OTTAG_DB", str(tmp_path / "env.sqlite"))
    assert resolve_database_url(None)[1] == (tmp_path / "env.sqlite").resolve()
    monkeypatch.delenv("OTTAG_DB")
    monkeypatch.chdir(tmp_path)
    assert resolve_database_url(None)[1] == (tmp_path / "ottag.sqlite").resolve()
    db = open_database(f"sqlite:///{tmp_path}/u.sqlite")
    assert db.current_revision() == head_revision()
    db.close()


def test_corrupt_file_is_refused_and_untouched(tmp_path: Path) -> None:
    path = tmp_path / "corrupt.sqlite"
    path.write_bytes(b"this is not a database" * 50)
    before = path.read_bytes()
    with pytest.raises(DatabaseError, match="not an SQLite database"):
        open_database(path)
    assert path.read_bytes() == before


def test_foreign_database_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "other.sqlite"
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE customers (id INTEGER)")
    con.commit()
    con.close()
    with pytest.raises(DatabaseError, match="not an ottag database"):
        open_database(path)


def test_older_revision_is_backed_up_then_migrated(tmp_path: Path) -> None:
    head = head_revision()
    if head == "0001":
        pytest.skip("only one revision so far")
    path = tmp_path / "old.sqlite"
    db = open_database(path, migrate=False)
    cfg = _alembic_config()
    with db.engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, "0001")
    db.close()
    db = open_database(path)
    try:
        assert db.current_revision() == head
        assert db.backup is not None and db.backup.exists()
        con = sqlite3.connect(db.backup)
        assert con.execute("SELECT version_num FROM alembic_version").fetchone()[0] == "0001"
        con.close()
    finally:
        db.close()


def test_migration_0004_stores_missing_layouts(bundled_db_path: Path, tmp_path: Path) -> None:
    """A database of revision 0003 without layouts gets them on opening (after a backup)."""
    path = tmp_path / "old.sqlite"
    shutil.copyfile(bundled_db_path, path)
    con = sqlite3.connect(path)
    stored = con.execute("SELECT realization_id, triangles, placement FROM layouts ORDER BY realization_id").fetchall()
    con.execute("DELETE FROM layouts WHERE realization_id % 40 = 0")  # some of every k
    con.execute("UPDATE alembic_version SET version_num = '0003'")
    con.commit()
    assert con.execute("SELECT count(*) FROM layouts").fetchone()[0] < len(stored)
    con.close()
    db = open_database(path)
    try:
        assert db.current_revision() == head_revision()
        assert db.backup is not None and db.backup.exists()
    finally:
        db.close()
    con = sqlite3.connect(path)
    again = con.execute("SELECT realization_id, triangles, placement FROM layouts ORDER BY realization_id").fetchall()
    con.close()
    assert again == stored  # the same layouts and placements as the import stored


def test_read_only_uri_resolves_to_the_file_and_opens_without_writing(bundled_db_path: Path, tmp_path: Path) -> None:
    path = tmp_path / "ro.sqlite"
    shutil.copyfile(bundled_db_path, path)
    url = f"sqlite:///file:{path}?mode=ro&uri=true"
    assert resolve_database_url(url) == (url, path.resolve())
    before = path.read_bytes()
    db = open_database(url)
    try:
        assert db.current_revision() == head_revision()
        with pytest.raises(OperationalError, match="readonly"), db.engine.begin() as conn:
            conn.exec_driver_sql("DELETE FROM layouts")
    finally:
        db.close()
    assert path.read_bytes() == before


def test_server_urls_are_refused_with_a_clear_message(tmp_path: Path) -> None:
    with pytest.raises(DatabaseError, match=r"only SQLite databases are supported \(got postgresql\)"):
        open_database("postgresql://user:secret@localhost/ottag")
    with pytest.raises(DatabaseError) as err:
        open_database("postgresql://user:secret@localhost/ottag")
    assert "secret" not in str(err.value)


def test_a_missing_file_is_refused_unless_created(tmp_path: Path) -> None:
    path = tmp_path / "missing.sqlite"
    with pytest.raises(DatabaseError, match=r"no database here; create one with `ottag-db import --db"):
        open_database(path, create=False)
    assert not path.exists()
    open_database(path).close()
    open_database(path, create=False).close()


def test_database_failures_are_explained(tmp_path: Path) -> None:
    cases = {
        "database disk image is malformed": "corrupt",
        "attempt to write a readonly database": "cannot write",
        "unable to open database file": "folder",
        "database is locked": "locked by another process",
    }
    for message, expected in cases.items():
        err = as_database_error(sqlite3.OperationalError(message), tmp_path / "x.sqlite")
        assert expected in str(err) and str(tmp_path / "x.sqlite") in str(err) and "\n" not in str(err)


def test_busy_timeout_comes_from_the_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OTTAG_DB_TIMEOUT", "2.5")
    assert busy_timeout_seconds() == 2.5
    db = open_database(tmp_path / "t.sqlite")
    try:
        with db.engine.connect() as conn:
            assert conn.exec_driver_sql("PRAGMA busy_timeout").scalar() == 2500
    finally:
        db.close()
    monkeypatch.setenv("OTTAG_DB_TIMEOUT", "soon")
    assert busy_timeout_seconds() == 60.0


def test_check_integrity_on_an_intact_database(tmp_path: Path) -> None:
    db = open_database(tmp_path / "ok.sqlite")
    try:
        assert check_integrity(db) == []
    finally:
        db.close()


def test_concurrent_first_use_from_threads(tmp_path: Path) -> None:
    from concurrent.futures import ThreadPoolExecutor

    path = tmp_path / "race.sqlite"

    def open_close(_: int) -> str | None:
        db = open_database(path)
        try:
            return db.current_revision()
        finally:
            db.close()

    with ThreadPoolExecutor(4) as pool:
        assert set(pool.map(open_close, range(4))) == {head_revision()}
