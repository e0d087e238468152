"""Importing point files: which files with which options (the bundled data when none are
named), and the totals over several files.

The import itself is :func:`ottag_db.store.importer.import_point_file`, one transaction per
file; a caller runs the plan's jobs in order and reports on each.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from ottag_db.errors import UsageError
from ottag_db.files.bundled import bundled_point_files

if TYPE_CHECKING:
    from ottag_db.store.importer import ImportReport

__all__ = [
    "ImportInterrupted",
    "ImportJob",
    "ImportPlan",
    "ImportTotals",
    "import_totals",
    "interrupts_raise",
    "plan_import",
]


class ImportInterrupted(BaseException):
    """SIGINT or SIGTERM arrived during an import; ``signum`` says which.

    A BaseException like :class:`KeyboardInterrupt`, so no ``except Exception`` swallows it;
    the open transaction rolls back as it propagates.
    """

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        """The shell convention for death by this signal: 128 + signal number (130, 143)."""
        return 128 + self.signum


@contextmanager
def interrupts_raise() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise :class:`ImportInterrupted`.

    Outside the main thread (where handlers cannot be installed) nothing changes. The
    previous handlers are restored on exit.
    """

    def handler(signum: int, _frame: FrameType | None) -> None:
        raise ImportInterrupted(signum)

    previous: dict[signal.Signals, object] = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, handler)
    except ValueError:  # not the main thread
        pass
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)  # type: ignore[arg-type]


@dataclass(frozen=True)
class ImportJob:
    """One file to import: ``points`` per record, or None to read it from the name ``otypesNN``."""

    path: Path
    points: int | None


@dataclass(frozen=True)
class ImportPlan:
    """The files to import, in order, and whether to store the mirror of every chiral record."""

    jobs: tuple[ImportJob, ...]
    with_mirrors: bool


@dataclass(frozen=True)
class ImportTotals:
    """Sums over the reports of several imported files."""

    records: int
    new_order_types: int
    new_realizations: int


def plan_import(
    files: Sequence[Path],
    points: int | None = None,
    with_mirrors: bool | None = None,
    ks: Sequence[int] = (),
    *,
    data_folder: Path | None = None,
) -> ImportPlan:
    """What ``ottag-db import`` imports for the given files and options.

    Parameters
    ----------
    files : sequence of Path
        Point files (.b08/.b16); empty for the bundled data.
    points : int or None
        Points per record of every named file; None reads it from each file's name. Ignored for
        the bundled data, whose point counts are known.
    with_mirrors : bool or None
        Store the mirror image of every chiral record; None for the default: on for the
        bundled data (so it holds every order type, as the CLI promises), off for named files.
    ks : sequence of int
        Bundled files to import, by point count (``--k``; e.g. ``(9,)`` for the 158,817
        nine-point records, which the default leaves out); empty for the default bundled files
        (every order type of 3 … 8 points, one per reflection pair). Only with no ``files``.
    data_folder : Path, optional
        Where the bundled files are (default: the installed data folder).

    Returns
    -------
    ImportPlan
        The jobs in order and the mirror setting that applies to all of them.

    Raises
    ------
    UsageError
        ``files`` and ``ks`` together (``--k`` selects bundled files).
    PointFileError
        A k in ``ks`` has no bundled file.
    """
    if files and ks:
        raise UsageError("--k selects bundled files by point count; name point files or use --k, not both")
    if files:
        return ImportPlan(tuple(ImportJob(Path(p), points) for p in files), bool(with_mirrors))
    chosen = bundled_point_files(tuple(ks) if ks else None, folder=data_folder)
    jobs = tuple(ImportJob(p, k) for p, k in chosen)
    return ImportPlan(jobs, True if with_mirrors is None else with_mirrors)


def import_totals(reports: Sequence[ImportReport]) -> ImportTotals:
    """Records read and order types/realizations added over several imports.

    Parameters
    ----------
    reports : sequence of ImportReport
        One report per imported file (skipped files count with their zeros).

    Returns
    -------
    ImportTotals
        The sums.
    """
    return ImportTotals(
        records=sum(r.records for r in reports),
        new_order_types=sum(r.new_order_types for r in reports),
        new_realizations=sum(r.new_realizations for r in reports),
    )
