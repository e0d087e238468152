"""The one way from a database or a dictionary file to a configured detector (the store → decode seam)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from ottag_db.decode import DEFAULT_PARAMS, Detector, DetectorParams
from ottag_db.errors import UsageError

if TYPE_CHECKING:
    from ottag_db.store.db import Database
    from ottag_db.store.dictionary_files import DictionaryDocument

__all__ = ["Detector", "DetectorParams", "open_detector"]


def open_detector(
    db: str | os.PathLike[str] | Database | None = None,
    *,
    dictionary: str | None = None,
    dictionary_file: str | os.PathLike[str] | DictionaryDocument | None = None,
    params: DetectorParams | None = None,
) -> Detector:
    """A detector whose lookup is read once from a database, one of its dictionaries, or a dictionary file.

    The database or file is read here only; :meth:`Detector.detect` never touches it. The lookup
    carries each tag's stored (or the file's) points and layout, against which every reading is
    verified.

    Parameters
    ----------
    db : str, PathLike, Database or None
        Database file or ``sqlite:///`` URL as ``--db`` (None: ``$OTTAG_DB`` or
        ``./ottag.sqlite``), or a database already open (it stays open). A missing file is
        refused, not created: ``ottag-db import`` creates one.
    dictionary : str or None
        Name of a dictionary in the database: only its members decode, and ``Detection.tag``
        is the member's number. None: every stored order type.
    dictionary_file : str, PathLike, DictionaryDocument or None
        A dictionary export (``ottag-dictionary/1`` JSON, as ``dictionary export`` writes it),
        or one already read by :func:`ottag_db.app.dictionary_io.load_dictionary_file`: only
        its tags decode, verified against its points, and no database is opened. Excludes
        ``db`` and ``dictionary``.
    params : DetectorParams or None
        Detector settings (None: the defaults).

    Returns
    -------
    Detector
        Ready to decode frames (``detect``, ``detect_with_rejections``).

    Raises
    ------
    UsageError
        ``dictionary_file`` given together with ``db`` or ``dictionary``.
    DatabaseError
        The database file is missing, corrupt or not an ottag database.
    NotFoundError
        The database has no dictionary ``dictionary``.
    DictionaryError
        The dictionary file cannot be read or a tag in it is bad (the message names it).
    """
    settings = DEFAULT_PARAMS if params is None else params
    if dictionary_file is not None:
        if db is not None or dictionary is not None:
            raise UsageError("a dictionary file is decoded alone: give dictionary_file without db or dictionary")
        from ottag_db.app.dictionary_io import load_dictionary_file

        document = (
            load_dictionary_file(Path(dictionary_file))
            if isinstance(dictionary_file, str | os.PathLike)
            else dictionary_file
        )
        return Detector(document.lookup(), settings)
    # the store (SQLAlchemy) is imported only when a database is opened
    from ottag_db.store.db import Database, open_database
    from ottag_db.store.lookups import dictionary_lookup

    if isinstance(db, Database):
        return Detector(dictionary_lookup(db, dictionary), settings)
    opened = open_database(db, create=False)
    try:
        lookup = dictionary_lookup(opened, dictionary)
    finally:
        opened.close()
    return Detector(lookup, settings)
