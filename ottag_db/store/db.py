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
    "as_database_error",
    "busy_timeout_seconds",
    "check_integrity",
    "head_revision",
    "is_database_failure",
    "open_database",
    "resolve_database_url",
    "upgrade",
]

#: Used when neither ``--db`` nor ``$OTTAG_DB`` names a database.
DEFAULT_DB_PATH = "ottag.sqlite"

_SQLITE_MAGIC = b"SQLite format 3\x00"

#: Seconds a command waits for another process's write lock (``$OTTAG_DB_TIMEOUT`` overrides).
DEFAULT_BUSY_TIMEOUT_S = 60.0


def busy_timeout_seconds() -> float:
    """How long a connection waits for a lock held by another process.

    Returns
    -------
    float
        Seconds: ``$OTTAG_DB_TIMEOUT`` when set to a non-negative number, else 60.
    """
    raw = os.environ.get("OTTAG_DB_TIMEOUT")
    try:
        value = float(raw) if raw else DEFAULT_BUSY_TIMEOUT_S
    except ValueError:
        return DEFAULT_BUSY_TIMEOUT_S
    return value if value >= 0 and value == value else DEFAULT_BUSY_TIMEOUT_S


def is_database_failure(exc: BaseException) -> bool:
    """True for an error raised by SQLite or SQLAlchemy (not by our own code).

    Parameters
    ----------
    exc : BaseException
        Any exception.

    Returns
    -------
    bool
        Whether :func:`as_database_error` should explain it.
    """
    return isinstance(exc, (SQLAlchemyError, sqlite3.Error))


def as_database_error(exc: BaseException, where: str | os.PathLike[str] | None) -> DatabaseError:
    """One line naming the database and what to do, for an SQLite/SQLAlchemy failure.

    Parameters
    ----------
    exc : BaseException
        The driver's or SQLAlchemy's error.
    where : str or PathLike or None
        The database file (or URL) to name in the message.

    Returns
    -------
    DatabaseError
        Malformed (corrupt pages), read-only, locked/busy, full disk, or a generic failure.
    """
    orig = getattr(exc, "orig", None) or exc
    text = str(orig.args[0]) if getattr(orig, "args", None) else str(orig)
    low = text.lower()
    name = str(where) if where is not None else "the database"
    if "malformed" in low or "not a database" in low or "disk i/o error" in low:
        return DatabaseError(
            f"{name}: the database file is corrupt ({text}); restore it from a backup or build a new "
            "one with `ottag-db import --db NEW_FILE` (`ottag-db db check` reports the damage)"
        )
    if "readonly" in low or "read-only" in low:
        return DatabaseError(
            f"{name}: cannot write to the database ({text}); SQLite needs write permission on the file "
            "and its folder (for the journal): fix the permissions or choose another file with --db"
        )
    if "unable to open database" in low:
        return DatabaseError(
            f"{name}: cannot open the database ({text}); SQLite needs write permission on the file and its "
            "folder (for the WAL journal, even to read): fix the permissions or copy the file to a writable folder"
        )
    if "locked" in low or "busy" in low:
        return DatabaseError(
            f"{name}: the database is locked by another process ({text}, waited "
            f"{busy_timeout_seconds():g} s); wait for it to finish and try again, or raise $OTTAG_DB_TIMEOUT"
        )
    if "full" in low:
        return DatabaseError(f"{name}: {text}; free disk space and try again")
    return DatabaseError(f"{name}: cannot use this database: {text}")


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
    def write(self) -> Iterator[Connection]:
        """A connection in one write transaction, committed on success, rolled back on any error.

        On SQLite the transaction starts with ``BEGIN IMMEDIATE``: it takes the write lock at
        once (waiting up to :func:`busy_timeout_seconds` for another writer), so what it
        reads cannot be changed by another process before it commits.
        """
        with self.engine.begin() as conn:
            if self.engine.dialect.name == "sqlite":
                conn.exec_driver_sql("BEGIN IMMEDIATE")
            yield conn

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
    cur.execute(f"PRAGMA busy_timeout={int(busy_timeout_seconds() * 1000)}")
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


def open_database(
    target: str | os.PathLike[str] | None = None, *, migrate: bool = True, create: bool = True
) -> Database:
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
        Upgrade to the newest revision (False only for tools and tests). Concurrent first use
        is safe: creating and migrating happen under an exclusive lock on the file.
    create : bool
        Create a missing database file; False refuses it, naming the command that creates one.

    Returns
    -------
    Database
        The open database; ``backup`` names the copy taken before migrating, if any.

    Raises
    ------
    DatabaseError
        A corrupt or foreign file, a missing folder or file (with ``create=False``), a
        server URL (only SQLite is supported), or a schema newer than this tool.
    """
    url, path = resolve_database_url(target)
    backend = make_url(url).get_backend_name()
    if backend != "sqlite":
        raise DatabaseError(
            f"{make_url(url).render_as_string(hide_password=True)}: only SQLite databases are supported "
            f"(got {backend}); pass --db with a file path"
        )
    if path is not None:
        _check_sqlite_file(path)
        if not path.parent.exists():
            raise DatabaseError(f"{path}: the folder {path.parent} does not exist")
        if not create and (not path.exists() or path.stat().st_size == 0):
            raise DatabaseError(
                f"{path}: no database here; create one with `ottag-db import --db {path}` "
                "(the bundled order types) or pass --db with an existing file"
            )
    existed = path is not None and path.exists() and path.stat().st_size > 0
    try:
        engine = create_engine(url)
    except (SQLAlchemyError, ImportError) as exc:
        raise DatabaseError(f"cannot open database {url}: {exc}") from exc
    if engine.dialect.name == "sqlite":
        event.listen(engine, "connect", _on_connect)
    db = Database(url=url, engine=engine, sessions=sessionmaker(engine, expire_on_commit=False), path=path)
    try:
        if path is not None and not _read_only(url) and (not existed or (migrate and not _at_head(db))):
            # First use or an upgrade: one process at a time creates, sets WAL and migrates.
            with _file_lock(path):
                _prepare(db, url, path, migrate)
        else:
            _prepare(db, url, path, migrate)
    except DatabaseError:
        engine.dispose()
        raise
    except (DBAPIError, SQLAlchemyError, sqlite3.Error) as exc:
        engine.dispose()
        raise as_database_error(exc, path or url) from exc
    except OSError as exc:
        engine.dispose()
        raise DatabaseError(f"{path or url}: {exc.strerror or exc}; check the file's permissions") from exc
    return db


def _prepare(db: Database, url: str, path: Path | None, migrate: bool) -> None:
    existed = path is not None and path.exists() and path.stat().st_size > 0
    if path is not None:
        with db.engine.connect() as conn:
            # Only change the mode when needed: setting it writes, which a read-only file refuses.
            if conn.exec_driver_sql("PRAGMA journal_mode").scalar() != "wal" and not _read_only(url):
                conn.exec_driver_sql("PRAGMA journal_mode=WAL")
    if migrate:
        _migrate(db, existed)


def _at_head(db: Database) -> bool:
    with db.engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision() == head_revision()


@contextmanager
def _file_lock(path: Path) -> Iterator[None]:
    """An exclusive advisory lock (``flock``) on the database file itself, created if missing.

    SQLite's own locks are POSIX record locks, which ``flock`` does not interact with on
    Linux, so this serializes only the callers of :func:`open_database` that create or migrate.
    Where ``fcntl`` is unavailable (Windows) no lock is taken.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def check_integrity(db: Database) -> list[str]:
    """SQLite's ``PRAGMA integrity_check`` and ``foreign_key_check`` on the database.

    Parameters
    ----------
    db : Database
        An open database (only read).

    Returns
    -------
    list of str
        The problems found; empty when the database is intact.
    """
    with db.engine.connect() as conn:
        rows = [str(r[0]) for r in conn.exec_driver_sql("PRAGMA integrity_check").all()]
        problems = [] if rows == ["ok"] else rows
        for table, rowid, parent, _fk in conn.exec_driver_sql("PRAGMA foreign_key_check").all():
            problems.append(f"{table} row {rowid}: refers to a missing {parent} row")
    return problems


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
    # db.write() opens the transaction with an explicit BEGIN: Python's sqlite3 driver starts none
    # before DDL, so without it every CREATE TABLE commits on its own and a process killed
    # mid-migration leaves a half-built schema behind.
    with db.write() as conn:
        _run_upgrade(cfg, conn, revision)


def _run_upgrade(cfg: Config, conn: Connection, revision: str) -> None:
    cfg.attributes["connection"] = conn
    command.upgrade(cfg, revision)
