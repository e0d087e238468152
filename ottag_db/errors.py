"""Typed errors raised by ottag_db; the CLI turns them into messages and exit codes."""

from __future__ import annotations

__all__ = [
    "BoardError",
    "CalibrationError",
    "ClusterError",
    "DatabaseError",
    "DecodeError",
    "DictionaryError",
    "ExportError",
    "GeneralPositionError",
    "LambdaFormatError",
    "NotFoundError",
    "OttagError",
    "PointFileError",
    "UsageError",
]


class OttagError(Exception):
    """Base class of every error this package raises on purpose."""

    exit_code = 1


class UsageError(OttagError):
    """The caller asked for something that cannot be done as asked (bad option value)."""

    exit_code = 2


class GeneralPositionError(OttagError):
    """A point set has a repeated point or a collinear triple.

    ``record`` is the index of the offending set in its batch or file, ``points`` the
    indices (within the set) of the repeated pair or collinear triple.
    """

    def __init__(self, message: str, *, record: int | None = None, points: tuple[int, ...] = ()):
        super().__init__(message)
        self.record = record
        self.points = points


class PointFileError(OttagError):
    """A point-set file cannot be read, is empty, truncated, or of an unknown layout."""


class DatabaseError(OttagError):
    """The database file is corrupt, not an ottag database, or cannot be migrated."""


class LambdaFormatError(UsageError):
    """A text ID is not of the form ``k:digits`` with k*k digits."""


class NotFoundError(OttagError):
    """The requested order type, dictionary or realization is not in the database."""


class ExportError(OttagError):
    """A tag sheet or rendering cannot be produced as requested."""


class DecodeError(OttagError):
    """An image cannot be read or decoded."""


class DictionaryError(OttagError):
    """A tag dictionary cannot be created, imported or used as asked."""


class BoardError(OttagError):
    """A calibration-board file is missing, of another format, or inconsistent."""


class CalibrationError(OttagError):
    """A camera cannot be calibrated from the given board and images (too few or degenerate views)."""


class ClusterError(OttagError):
    """A Dask scheduler cannot be reached (``generate --scheduler``)."""
