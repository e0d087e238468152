"""Output paths of the renderers: refuse one that cannot be written before any drawing is done."""

from __future__ import annotations

import os
from pathlib import Path

from ottag_db.errors import ExportError

__all__ = ["check_writable"]


def check_writable(path: Path) -> None:
    """Raise unless a file can be written at ``path`` (its folder exists and is writable).

    Parameters
    ----------
    path : Path
        The output file (PDF, PNG or SVG); it may exist already.

    Raises
    ------
    ExportError
        ``path`` is a directory, its folder does not exist, or writing is not permitted.
    """
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ExportError(f"{path}: is a directory; give a file name")
    if not parent.exists():
        raise ExportError(f"{path}: the folder {parent} does not exist")
    if not os.access(parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise ExportError(f"{path}: cannot write there (permission denied)")
