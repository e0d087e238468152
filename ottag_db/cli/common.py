"""What every command shares: error display, the ``--db``/``--quiet`` options, opening the
database, notes and progress bars on stderr.

Only click and ``ottag_db.errors`` are imported at module level; the database layer
(SQLAlchemy, Alembic) is imported when a command opens a database.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, TypeVar

import click

from ottag_db.errors import OttagError

if TYPE_CHECKING:
    from ottag_db.store.db import Database

__all__ = [
    "TAG_SIZE_HELP",
    "CliError",
    "CliUsageError",
    "Group",
    "Progress",
    "StageProgress",
    "db_options",
    "note",
    "open_db",
    "quiet_option",
    "root_options",
]

F = TypeVar("F", bound=Callable[..., Any])

#: Shared help of ``--tag-size`` (export, decode).
TAG_SIZE_HELP = (
    "Side of the black data area (the square you measure with a ruler and give to the pose "
    "estimator), with a unit: mm, cm or in"
)


class CliError(click.ClickException):
    """A library error shown as ``error: message`` on stderr, exit code 1."""

    def show(self, file: Any = None) -> None:
        click.echo(f"error: {self.format_message()}", err=True)


class CliUsageError(CliError):
    """A bad option value caught by the library: exit code 2 like click's own usage errors."""

    exit_code = 2


class Group(click.Group):
    """Turns the library's typed errors into one-line messages with the right exit code."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except OttagError as exc:
            if exc.exit_code == 2:
                raise CliUsageError(str(exc)) from exc
            raise CliError(str(exc)) from exc
        except Exception as exc:
            # A database failure that escaped the command's own handling (see open_db).
            if "sqlalchemy" not in sys.modules:
                raise
            from ottag_db.store.db import as_database_error, is_database_failure

            if not is_database_failure(exc):
                raise
            raise CliError(str(as_database_error(exc, ctx.find_root().params.get("db_target")))) from exc


def _root_value(ctx: click.Context, name: str) -> Any:
    root = ctx.find_root()
    return None if root is ctx else root.params.get(name)


def _inherit_db(ctx: click.Context, _param: click.Parameter, value: str | None) -> str | None:
    return value if value is not None else _root_value(ctx, "db_target")


def _inherit_quiet(ctx: click.Context, _param: click.Parameter, value: bool) -> bool:
    return bool(value or _root_value(ctx, "quiet"))


_DB_HELP = "Database file [env OTTAG_DB; default ./ottag.sqlite]; also accepted before the command."


def root_options(func: F) -> F:
    """``--db`` (env ``OTTAG_DB``) and ``--quiet`` on the top-level group, before the command name.

    Every command's own ``--db``/``--quiet`` falls back to these, so ``ottag-db --db X stats``
    and ``ottag-db stats --db X`` are the same.
    """
    func = click.option("--db", "db_target", envvar="OTTAG_DB", default=None, metavar="PATH", help=_DB_HELP)(func)
    return click.option("--quiet", "-q", is_flag=True, help="No progress bars or notes on stderr.")(func)


def db_options(func: F) -> F:
    """Add ``--db PATH`` (else the top-level ``--db``, else env ``OTTAG_DB``), passed as ``db_target``."""
    func = click.option(
        "--db", "db_target", default=None, metavar="PATH", callback=_inherit_db, expose_value=True, help=_DB_HELP
    )(func)
    return func


def quiet_option(func: F) -> F:
    """Add ``--quiet``/``-q`` (also accepted before the command), passed to the command as ``quiet``."""
    return click.option(
        "--quiet", "-q", is_flag=True, callback=_inherit_quiet, help="No progress bars or notes on stderr."
    )(func)


def note(msg: str, quiet: bool = False) -> None:
    """Print a message for the user on stderr unless ``quiet``."""
    if not quiet:
        click.echo(msg, err=True)


@contextmanager
def open_db(target: str | None, quiet: bool = False, *, create: bool = False) -> Iterator[Database]:
    """Open (and migrate) the database for one command; say so on stderr when it was migrated.

    SQLite failures inside the ``with`` block (a corrupt page, a read-only file, a lock held
    too long) become one-line :class:`~ottag_db.errors.DatabaseError` messages naming the file.

    Parameters
    ----------
    target : str or None
        Database file (``--db``); None for ``$OTTAG_DB`` or the default.
    quiet : bool
        No note about a migration.
    create : bool
        Create a missing database (import, ``db upgrade``); read commands refuse it instead,
        naming the command that creates one.

    Returns
    -------
    Iterator[Database]
        The open database, closed when the ``with`` block ends.
    """
    from ottag_db.store.db import as_database_error, head_revision, is_database_failure, open_database

    db = open_database(target, create=create)
    if db.backup is not None:
        note(f"migrated {db.path} to revision {head_revision()} (backup: {db.backup})", quiet)
    try:
        yield db
    except Exception as exc:
        if is_database_failure(exc):
            raise as_database_error(exc, db.path or db.url) from exc
        raise
    finally:
        db.close()


class Progress:
    """A click progress bar on stderr driven by ``(done, total)`` callbacks (``show_pos``: also
    ``done/total``, e.g. pages)."""

    def __init__(self, label: str, quiet: bool, *, show_pos: bool = False):
        self.label = label
        self.quiet = quiet
        self.show_pos = show_pos
        self._bar: Any = None
        self._done = 0

    def __call__(self, done: int, total: int) -> None:
        if self.quiet:
            return
        if self._bar is None:
            self._bar = click.progressbar(length=total, label=self.label, file=sys.stderr, show_pos=self.show_pos)
            self._bar.__enter__()
        self._bar.update(done - self._done)
        self._done = done

    def close(self) -> None:
        """End the bar (a new one starts with the next callback)."""
        if self._bar is not None:
            self._bar.__exit__(None, None, None)
            self._bar = None
            self._done = 0


class StageProgress:
    """Progress bars for ``progress(stage, done, total)`` callbacks: one bar per stage."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.stage: str | None = None
        self.bar: Progress | None = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage != self.stage:
            self.close()
            self.stage = stage
            self.bar = Progress(stage, self.quiet)
        assert self.bar is not None
        self.bar(done, total)

    def close(self) -> None:
        """End the current stage's bar."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None
