"""What the decoder tests draw and look up: the tags of a database, read the project's way.

The scenes themselves are drawn by :mod:`ottag_db.printing.scenes`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ottag_db.core.lookup import MemoryLookup
from ottag_db.printing.scenes import DrawableTag, drawable_from_file_order
from ottag_db.store.db import open_database
from ottag_db.store.lookups import load_lookup
from ottag_db.store.tags import select_tags

__all__ = ["DECODER_KS", "scene_data"]

#: Point counts the decoder tests use (k = 3 and 4 tags are not drawn: see ottag_db.core.layout).
DECODER_KS = (5, 6, 7, 8)


def scene_data(db_path: Path, ks: Sequence[int] = DECODER_KS) -> tuple[MemoryLookup, list[DrawableTag]]:
    """The decoder lookup of a database and its tags as drawn (stored layout and placement).

    Parameters
    ----------
    db_path : Path
        An ottag database file (only read).
    ks : sequence of int
        Point counts to load.

    Returns
    -------
    lookup : MemoryLookup
        Every order type of those k with its realizations (``load_lookup``).
    tags : list of DrawableTag
        Every order type's tag as ``export`` draws it, points in canonical label order.
    """
    db = open_database(db_path)
    try:
        lookup = load_lookup(db, ks=ks)
        tags = [
            drawable_from_file_order(t.lambda_text, t.points, t.labeling, t.triangles, t.placement, t.printed_mp_unit)
            for t in select_tags(db, ks=ks)
        ]
    finally:
        db.close()
    return lookup, tags
