"""A detector whose lookup comes from a database (the store → decode seam)."""

from __future__ import annotations

from ottag_db.decode import DEFAULT_PARAMS, Detector, DetectorParams

__all__ = ["Detector", "DetectorParams", "detector_from_database"]


def detector_from_database(
    target: str | None = None, dictionary: str | None = None, params: DetectorParams = DEFAULT_PARAMS
) -> Detector:
    """A detector whose lookup is loaded once from a database (or one named dictionary).

    The database is read here only; :meth:`Detector.detect` never touches it. The lookup
    carries each realization's stored layout, which soft decoding checks (a corrected reading
    must show the triangles its tag is printed with).

    Parameters
    ----------
    target : str or None
        Database path or URL as ``--db`` (None: ``$OTTAG_DB`` or ``./ottag.sqlite``).
    dictionary : str or None
        A dictionary name: only its members decode, and ``Detection.tag`` is the member's
        number for the detected polarity; a member only held in the other polarity is
        rejected with reason ``"polarity_not_in_dictionary"``. None: every order type.
    params : DetectorParams
        Detector settings.

    Returns
    -------
    Detector
        Ready to decode frames.
    """
    # the store (SQLAlchemy) is imported only by the commands that open a database
    from ottag_db.store.db import open_database
    from ottag_db.store.lookups import dictionary_lookup

    db = open_database(target)
    try:
        lookup = dictionary_lookup(db, dictionary)
    finally:
        db.close()
    return Detector(lookup, params)
