"""Layout writes: the triangles and placement of each realization, computed once and stored.

``import`` stores them with the realizations (same transaction), migration 0004 adds them to
databases made before that; everything that draws tags only reads them (see
:mod:`ottag_db.store.tags`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence

import numpy as np
from sqlalchemy import Connection, insert, select

from ottag_db.core.geometry import maximal_perturbations
from ottag_db.core.layout import compute_layouts, layout_supported
from ottag_db.core.placement import apply_placements, tag_placements
from ottag_db.core.types import ProgressCallback
from ottag_db.store.db import Database
from ottag_db.store.models import LayoutRow, OrderType, Realization, coordinates_from_blob

__all__ = ["LAYOUT_BATCH", "add_missing_layouts", "ensure_layouts", "missing_layouts", "store_layouts"]

#: Realizations laid out per batch (bounds memory; progress is reported per batch).
LAYOUT_BATCH = 512


def missing_layouts(
    conn: Connection, *, source_id: int | None = None, first: int = 0, stop: int | None = None
) -> list[tuple[int, int, int, bytes]]:
    """Realizations that can be drawn (k = 3, 5 … 9) and have no stored layout yet.

    Parameters
    ----------
    conn : Connection
        Connection inside the caller's transaction.
    source_id : int, optional
        Only realizations of this source file.
    first, stop : int
        Only records with ``first <= record_index < stop`` (``stop`` None: no upper bound).

    Returns
    -------
    list of (int, int, int, bytes)
        ``(realization id, k, record index, coordinates blob)``, ordered by k, then record
        index, then id (so a record's realization comes before its mirror's).
    """
    q = (
        select(Realization.id, OrderType.k, Realization.record_index, Realization.coordinates)
        .join(OrderType, OrderType.id == Realization.order_type_id)
        .outerjoin(LayoutRow, LayoutRow.realization_id == Realization.id)
        .where(LayoutRow.id.is_(None), Realization.record_index >= first)
        .order_by(OrderType.k, Realization.record_index, Realization.id)
    )
    if source_id is not None:
        q = q.where(Realization.source_id == source_id)
    if stop is not None:
        q = q.where(Realization.record_index < stop)
    return [(int(r), int(k), int(i), bytes(b)) for r, k, i, b in conn.execute(q).all() if layout_supported(int(k))]


def store_layouts(conn: Connection, rows: Sequence[tuple[int, bytes]]) -> int:
    """Compute and insert the layout and placement of realizations of one k.

    Parameters
    ----------
    conn : Connection
        Connection inside the caller's transaction.
    rows : sequence of (int, bytes)
        ``(realization id, coordinates blob)``, every set with the same k (3, 5 … 9).

    Returns
    -------
    int
        Number of layout rows inserted.

    Notes
    -----
    ``placement`` is stored as the JSON of the exact ``(2, 3)`` map of
    :func:`ottag_db.core.placement.tag_placements` (file coordinates → data-area units),
    which is the same map whatever batch a set is placed in, so a sheet drawn from the
    stored map equals one placed afresh. ``printed_mp_unit`` is the MP of the placed points.
    """
    if not rows:
        return 0
    pts = np.stack([coordinates_from_blob(blob) for _, blob in rows]).astype(np.float64)
    layouts = compute_layouts(pts)
    maps = tag_placements(pts)
    placed = apply_placements(maps, pts)
    printed = maximal_perturbations(placed)
    values = [
        {
            "realization_id": rid,
            "triangles": ";".join(",".join(str(i) for i in t) for t in lay.triangles),
            "triangle_count": len(lay.triangles),
            "min_angle_deg": float(lay.min_angle_deg),
            "min_side": float(lay.min_side),
            "min_gap": None if lay.min_gap is None else float(lay.min_gap),
            "min_shared_gap_deg": None if lay.min_shared_gap_deg is None else float(lay.min_shared_gap_deg),
            "score": float(lay.score),
            "placement": json.dumps(m.tolist()),
            "printed_mp_unit": float(pm),
        }
        for (rid, _), lay, m, pm in zip(rows, layouts, maps, printed, strict=True)
    ]
    conn.execute(insert(LayoutRow.__table__), values)  # type: ignore[arg-type]
    return len(values)


def add_missing_layouts(conn: Connection, *, progress: ProgressCallback | None = None) -> int:
    """Store the layout and placement of every drawable realization that has none.

    Parameters
    ----------
    conn : Connection
        Connection inside the caller's transaction (an import or a migration).
    progress : ProgressCallback, optional
        ``progress(done, total)`` in realizations, after every batch of :data:`LAYOUT_BATCH`.

    Returns
    -------
    int
        Number of layouts added (0 when every drawable realization has one).
    """
    todo = missing_layouts(conn)
    done = 0
    for k in sorted({row[1] for row in todo}):
        rows = [(rid, blob) for rid, kk, _, blob in todo if kk == k]
        for start in range(0, len(rows), LAYOUT_BATCH):
            done += store_layouts(conn, rows[start : start + LAYOUT_BATCH])
            if progress is not None:
                progress(done, len(todo))
    return done


def ensure_layouts(db: Database, *, progress: ProgressCallback | None = None) -> int:
    """Store the missing layouts of a database in one transaction (a write, for repairs and tools).

    ``import`` and migration 0004 already store every layout, so on a database made by this
    tool this finds nothing to do.

    Parameters
    ----------
    db : Database
        An open database.
    progress : ProgressCallback, optional
        See :func:`add_missing_layouts`.

    Returns
    -------
    int
        Number of layouts added.
    """
    with db.engine.begin() as conn:
        return add_missing_layouts(conn, progress=progress)
