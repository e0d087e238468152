"""Open the ottag database: one entry point that backs up, migrates to head and configures SQLite."""

from __future__ import annotations

import os
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine, create_engine, event, inspect
from sqlalchemy.engine import make_url
from sqlalchemy.exc import DBAPIError, SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

from ottag_db.errors import DatabaseError
from ottag_db.files.resources import migrations_dir

__all__ = [
    "DEFAULT_DB_PATH",
    "Database",
    "head_revision",
    "open_database",
    "resolve_database_url",
    "upgrade",
]

#: Used when neither ``--db`` nor ``$OTTAG_DB`` names a database.
DEFAULT_DB_PATH = "ottag.sqlite"

_SQLITE_MAGIC = b"SQLite format 3\x00"


@dataclass
class Database:
    """An open, migrated database: an engine plus a session factory.

    ``backup`` is the path of the copy taken before migrating an older file, if any.
    """

    url: str
    engine: Engine
    sessions: sessionmaker[Session]
    path: Path | None
    backup: Path | None = None

    @contextmanager
    def session(self) -> Iterator[Session]:
        """A session in one transaction: committed on success, rolled back on any error."""
        with self.sessions.begin() as s:
            yield s

    def current_revision(self) -> str | None:
        """Alembic revision the database is at."""
        with self.engine.connect() as conn:
            return MigrationContext.configure(conn).get_current_revision()

    def close(self) -> None:
        """Dispose of the engine's connections."""
        self.engine.dispose()

    def __enter__(self) -> Database:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def resolve_database_url(target: str | os.PathLike[str] | None = None) -> tuple[str, Path | None]:
    """Turn ``--db`` / ``$OTTAG_DB`` / the default into a SQLAlchemy URL and a file path (if any).

    Parameters
    ----------
    target : str or PathLike, optional
        A value containing ``://`` is taken as a SQLAlchemy URL (an SQLite URI such as
        ``sqlite:///file:/path/db.sqlite?mode=ro&uri=true`` opens the file read-only);
        anything else is a file path. None means ``$OTTAG_DB`` or ``./ottag.sqlite``.

    Returns
    -------
    tuple of (str, Path or None)
        The URL, and the resolved database file for SQLite files (None otherwise).
    """
    raw = str(target) if target is not None else os.environ.get("OTTAG_DB") or DEFAULT_DB_PATH
    if "://" in raw:
        url = make_url(raw)
        database = url.database
        if url.get_backend_name() == "sqlite" and database and database != ":memory:":
            if url.query.get("uri") == "true" and database.startswith("file:"):
                database = database.removeprefix("file:")
            return raw, Path(database).resolve()
        return raw, None
    path = Path(raw).expanduser().resolve()
    return f"sqlite:///{path}", path


def _alembic_config() -> Config:
    cfg = Config()
    cfg.set_main_option("script_location", str(migrations_dir()))
    return cfg


def head_revision() -> str:
    """Newest revision of the bundled migrations.

    Returns
    -------
    str
        The Alembic revision id, e.g. ``"0004"``.
    """
    head = ScriptDirectory.from_config(_alembic_config()).get_current_head()
    if head is None:  # pragma: no cover - the package always ships migrations
        raise DatabaseError("no migrations found in the installed package")
    return head


def _on_connect(dbapi_conn: Any, _record: Any) -> None:
    cur = dbapi_conn.cursor()
    cur.execute("PRAGMA foreign_keys=ON")
    cur.execute("PRAGMA busy_timeout=10000")
    cur.close()


def _check_sqlite_file(path: Path) -> None:
    if path.is_dir():
        raise DatabaseError(f"{path}: is a directory; pass --db with a file path")
    if not path.exists() or path.stat().st_size == 0:
        return
    with path.open("rb") as fh:
        head = fh.read(len(_SQLITE_MAGIC))
    if head != _SQLITE_MAGIC:
        raise DatabaseError(
            f"{path}: not an SQLite database (corrupt or another kind of file); "
            "move it away or choose another file with --db"
        )


def _backup_sqlite(path: Path, revision: str | None) -> Path:
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    dest = path.with_name(f"{path.name}.bak-{revision or 'unversioned'}-{stamp}")
    src = sqlite3.connect(str(path))
    try:
        dst = sqlite3.connect(str(dest))
        try:
            src.backup(dst)
        finally:
            dst.close()
    finally:
        src.close()
    return dest


def open_database(target: str | os.PathLike[str] | None = None, *, migrate: bool = True) -> Database:
    """Open (creating if needed) the database and migrate it to the newest schema.

    An existing file at an older revision is copied to ``<name>.bak-<revision>-<timestamp>``
    first. SQLite connections get ``PRAGMA foreign_keys=ON`` and a writable file is put in
    WAL mode. A database at the newest revision is not written to by opening it, so it can
    be opened read-only (``sqlite:///file:…?mode=ro&uri=true``) for reading and exporting.

    Parameters
    ----------
    target : str or PathLike, optional
        File path or SQLAlchemy URL (see :func:`resolve_database_url`).
    migrate : bool
        Upgrade to the newest revision (False only for tools and tests).

    Returns
    -------
    Database
        The open database; ``backup`` names the copy taken before migrating, if any.

    Raises
    ------
    DatabaseError
        A corrupt or foreign file, a missing folder, or a schema newer than this tool.
    """
    url, path = resolve_database_url(target)
    if path is not None:
        _check_sqlite_file(path)
        if not path.parent.exists():
            raise DatabaseError(f"{path}: the folder {path.parent} does not exist")
    existed = path is not None and path.exists() and path.stat().st_size > 0
    try:
        engine = create_engine(url)
    except (SQLAlchemyError, ImportError) as exc:
        raise DatabaseError(f"cannot open database {url}: {exc}") from exc
    if engine.dialect.name == "sqlite":
        event.listen(engine, "connect", _on_connect)
    db = Database(url=url, engine=engine, sessions=sessionmaker(engine, expire_on_commit=False), path=path)
    try:
        if engine.dialect.name == "sqlite" and path is not None:
            with engine.connect() as conn:
                # Only change the mode when needed: setting it writes, which a read-only file refuses.
                if conn.exec_driver_sql("PRAGMA journal_mode").scalar() != "wal" and not _read_only(url):
                    conn.exec_driver_sql("PRAGMA journal_mode=WAL")
        if migrate:
            _migrate(db, existed)
    except DatabaseError:
        engine.dispose()
        raise
    except (DBAPIError, SQLAlchemyError) as exc:
        engine.dispose()
        raise DatabaseError(f"{path or url}: cannot use this database: {exc.args[0] if exc.args else exc}") from exc
    return db


def _read_only(url: str) -> bool:
    """True for an SQLite URI opened with ``mode=ro``."""
    return make_url(url).query.get("mode") == "ro"


def _migrate(db: Database, existed: bool) -> None:
    head = head_revision()
    script = ScriptDirectory.from_config(_alembic_config())
    with db.engine.connect() as conn:
        current = MigrationContext.configure(conn).get_current_revision()
        tables = set(inspect(conn).get_table_names())
    if current == head:
        return
    if current is not None:
        try:
            script.get_revision(current)
        except Exception as exc:
            raise DatabaseError(
                f"{db.path or db.url}: schema revision {current} is newer than this ottag-db; upgrade ottag-db"
            ) from exc
    elif tables:
        raise DatabaseError(
            f"{db.path or db.url}: holds tables ({', '.join(sorted(tables))}) but is not an ottag database; "
            "choose another file with --db"
        )
    if existed and db.path is not None and current is not None:
        db.backup = _backup_sqlite(db.path, current)
    upgrade(db)


def upgrade(db: Database, revision: str = "head") -> None:
    """Run the Alembic upgrade to ``revision`` on the database's own connection (one transaction).

    Parameters
    ----------
    db : Database
        An open database.
    revision : str
        Target revision (default the newest).
    """
    cfg = _alembic_config()
    with db.engine.begin() as conn:
        _run_upgrade(cfg, conn, revision)


def _run_upgrade(cfg: Config, conn: Connection, revision: str) -> None:
    cfg.attributes["connection"] = conn
    command.upgrade(cfg, revision)
