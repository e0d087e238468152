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


def db_options(func: F) -> F:
    """Add ``--db PATH|URL`` (env ``OTTAG_DB``), passed to the command as ``db_target``."""
    func = click.option(
        "--db",
        "db_target",
        envvar="OTTAG_DB",
        default=None,
        metavar="PATH|URL",
        help="Database file or SQLAlchemy URL [env OTTAG_DB; default ./ottag.sqlite].",
    )(func)
    return func


def quiet_option(func: F) -> F:
    """Add ``--quiet``/``-q``, passed to the command as ``quiet``."""
    return click.option("--quiet", "-q", is_flag=True, help="No progress bars or notes on stderr.")(func)


def note(msg: str, quiet: bool = False) -> None:
    """Print a message for the user on stderr unless ``quiet``."""
    if not quiet:
        click.echo(msg, err=True)


@contextmanager
def open_db(target: str | None, quiet: bool = False) -> Iterator[Database]:
    """Open (and migrate) the database for one command; say so on stderr when it was migrated.

    Parameters
    ----------
    target : str or None
        Database file or SQLAlchemy URL (``--db``); None for the default.
    quiet : bool
        No note about a migration.

    Returns
    -------
    Iterator[Database]
        The open database, closed when the ``with`` block ends.
    """
    from ottag_db.store.db import head_revision, open_database

    db = open_database(target)
    if db.backup is not None:
        note(f"migrated {db.path} to revision {head_revision()} (backup: {db.backup})", quiet)
    try:
        yield db
    finally:
        db.close()


class Progress:
    """A click progress bar on stderr driven by ``(done, total)`` callbacks."""

    def __init__(self, label: str, quiet: bool):
        self.label = label
        self.quiet = quiet
        self._bar: Any = None
        self._done = 0

    def __call__(self, done: int, total: int) -> None:
        if self.quiet:
            return
        if self._bar is None:
            self._bar = click.progressbar(length=total, label=self.label, file=sys.stderr)
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
