"""Layout writes: the triangles and placement of each realization, computed once and stored.

``import`` stores them with the realizations (same transaction), migration 0004 adds them to
databases made before that; everything that draws tags only reads them (see
:mod:`ottag_db.store.tags`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Connection, and_, insert, select
from sqlalchemy.orm import aliased

from ottag_db.core.layout import Layout, lay_out_and_place, layout_supported
from ottag_db.core.placement import mirrored_placements
from ottag_db.core.types import ProgressCallback
from ottag_db.store.db import Database
from ottag_db.store.models import LayoutRow, OrderType, Realization, coordinates_from_blobs, triangles_to_text

__all__ = [
    "LAYOUT_BATCH",
    "MIRROR_FROM_ORIGINAL_MIN_K",
    "BatchMap",
    "MissingLayout",
    "PendingLayouts",
    "add_missing_layouts",
    "ensure_layouts",
    "finish_layouts",
    "missing_layouts",
    "start_layouts",
    "store_layouts",
]

#: Realizations laid out per batch (bounds memory; progress is reported per batch).
LAYOUT_BATCH = 512

#: From this k on, a mirror image's layout is its original's, reflected (see
#: :func:`store_layouts`); below it, tags have been printed from separately searched ones.
MIRROR_FROM_ORIGINAL_MIN_K = 9

#: A ``map``-like callable: ``map_batches(function, batches)`` yields ``function(batch)`` for
#: each batch, in order (builtin ``map`` or ``ProcessPoolExecutor.map``).
_Searched = tuple[list[Layout], NDArray[np.float64], NDArray[np.float64]]
BatchMap = Callable[[Callable[[NDArray[np.float64]], _Searched], Iterable[NDArray[np.float64]]], Iterator[_Searched]]


@dataclass(frozen=True)
class MissingLayout:
    """A realization without a stored layout: its id, k, record index and coordinates blob;
    ``original`` is the coordinates blob of the record it mirrors (None unless a mirror image)."""

    realization_id: int
    k: int
    record_index: int
    coordinates: bytes
    original: bytes | None


def missing_layouts(
    conn: Connection, *, source_id: int | None = None, first: int = 0, stop: int | None = None
) -> list[MissingLayout]:
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
    list of MissingLayout
        Ordered by k, then record index, then id (so a record's realization comes before its
        mirror's); a mirror image carries its original's coordinates.
    """
    twin = aliased(Realization)
    q = (
        select(Realization.id, OrderType.k, Realization.record_index, Realization.coordinates, twin.coordinates)
        .join(OrderType, OrderType.id == Realization.order_type_id)
        .outerjoin(LayoutRow, LayoutRow.realization_id == Realization.id)
        .outerjoin(
            twin,
            and_(
                Realization.mirrored.is_(True),
                twin.source_id == Realization.source_id,
                twin.record_index == Realization.record_index,
                twin.mirrored.is_(False),
            ),
        )
        .where(LayoutRow.id.is_(None), Realization.record_index >= first)
        .order_by(OrderType.k, Realization.record_index, Realization.id)
    )
    if source_id is not None:
        q = q.where(Realization.source_id == source_id)
    if stop is not None:
        q = q.where(Realization.record_index < stop)
    return [
        MissingLayout(int(r), int(k), int(i), bytes(b), None if t is None else bytes(t))
        for r, k, i, b, t in conn.execute(q).all()
        if layout_supported(int(k))
    ]


def store_layouts(
    conn: Connection,
    rows: Sequence[MissingLayout],
    *,
    map_batches: BatchMap = map,
    on_batch: Callable[[int], None] | None = None,
) -> int:
    """Compute and insert the layout and placement of realizations of one k.

    Parameters
    ----------
    conn : Connection
        Connection inside the caller's transaction.
    rows : sequence of MissingLayout
        Realizations of one k (3, 5 … 9), as :func:`missing_layouts` lists them.
    map_batches : callable, optional
        ``map``-like: applies :func:`~ottag_db.core.layout.lay_out_and_place` to batches of
        :data:`LAYOUT_BATCH` sets and yields the results in order (builtin ``map``, or a
        process pool's ``map`` to use several cores; the results are the same).
    on_batch : callable, optional
        Called with the number of rows stored so far, after each batch is inserted.

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

    A mirror image of k ≥ :data:`MIRROR_FROM_ORIGINAL_MIN_K` gets its original's triangles and
    figures and the reflected placement (:func:`~ottag_db.core.placement.mirrored_placements`):
    its printed tag is the mirror image of the original's, and it costs no search. Below that
    k mirror images are searched on their own, as they always were: tags of k ≤ 8 have been
    printed from those layouts, and the two searches can end in different ties.
    """
    return finish_layouts(conn, start_layouts(rows, map_batches=map_batches), on_batch=on_batch)


@dataclass(frozen=True)
class PendingLayouts:
    """Layout searches started by :func:`start_layouts` and not yet stored: the ``rows``,
    whether each is a ``derived`` mirror, the ``slots`` of their searches and the ``results``
    of the searches (an iterator over batches, computed as it is read or already running)."""

    rows: Sequence[MissingLayout]
    derived: list[bool]
    slots: list[int]
    results: Iterator[_Searched]


def start_layouts(rows: Sequence[MissingLayout], *, map_batches: BatchMap = map) -> PendingLayouts:
    """Start the layout searches of realizations of one k (the first half of :func:`store_layouts`).

    With a process pool's ``map`` every batch is submitted here, so the pool works while the
    caller does other things (the import stores the previous chunk meanwhile).

    Parameters
    ----------
    rows : sequence of MissingLayout
        Realizations of one k (3, 5 … 9), as :func:`missing_layouts` lists them.
    map_batches : callable, optional
        See :func:`store_layouts`.

    Returns
    -------
    PendingLayouts
        What :func:`finish_layouts` stores.
    """
    if not rows:
        return PendingLayouts(rows, [], [], iter(()))
    k = rows[0].k
    # Each distinct input is searched once: a derived mirror shares its original's search.
    derived = [r.original is not None and k >= MIRROR_FROM_ORIGINAL_MIN_K for r in rows]
    keys = [r.original if d and r.original is not None else r.coordinates for r, d in zip(rows, derived, strict=True)]
    slot: dict[bytes, int] = {}
    for key in keys:
        slot.setdefault(key, len(slot))
    inputs = coordinates_from_blobs(list(slot), k).astype(np.float64)
    batches = [inputs[s : s + LAYOUT_BATCH] for s in range(0, len(inputs), LAYOUT_BATCH)]
    return PendingLayouts(rows, derived, [slot[key] for key in keys], iter(map_batches(lay_out_and_place, batches)))


def finish_layouts(conn: Connection, pending: PendingLayouts, *, on_batch: Callable[[int], None] | None = None) -> int:
    """Insert the layouts of :func:`start_layouts` as their batches come in (the second half of
    :func:`store_layouts`).

    Parameters
    ----------
    conn : Connection
        Connection inside the caller's transaction.
    pending : PendingLayouts
        The started searches.
    on_batch : callable, optional
        Called with the number of rows stored so far, after each batch is inserted.

    Returns
    -------
    int
        Number of layout rows inserted.
    """
    rows, derived, slots = pending.rows, pending.derived, pending.slots
    searched: list[Layout] = []
    searched_text: list[str] = []
    total = max(slots, default=-1) + 1
    searched_maps = np.empty((total, 2, 3))
    searched_printed = np.empty(total)
    row = 0
    for layouts, maps, printed in pending.results:
        searched_maps[len(searched) : len(searched) + len(layouts)] = maps
        searched_printed[len(searched) : len(searched) + len(layouts)] = printed
        searched.extend(layouts)
        searched_text.extend(triangles_to_text(lay.triangles) for lay in layouts)
        end = row
        while end < len(rows) and slots[end] < len(searched):
            end += 1
        _insert_layouts(
            conn,
            rows[row:end],
            derived[row:end],
            slots[row:end],
            _SearchResults(searched, searched_text, searched_maps, searched_printed),
        )
        row = end
        if on_batch is not None:
            on_batch(row)
    return len(rows)


@dataclass(frozen=True)
class _SearchResults:
    """The layout searches so far: layouts, their triangles column text, maps and printed MP."""

    layouts: list[Layout]
    triangles: list[str]
    maps: NDArray[np.float64]
    printed: NDArray[np.float64]


#: Columns of a layout row, in the order of the tuples :func:`_insert_layouts` builds.
_LAYOUT_COLUMNS = (
    "realization_id",
    "triangles",
    "triangle_count",
    "min_angle_deg",
    "min_side",
    "min_gap",
    "min_shared_gap_deg",
    "score",
    "placement",
    "printed_mp_unit",
)


def _insert_layouts(
    conn: Connection,
    rows: Sequence[MissingLayout],
    derived: Sequence[bool],
    slots: Sequence[int],
    searched: _SearchResults,
) -> None:
    """Insert the layout rows of ``rows`` from the searched results (``slots`` index them)."""
    if not rows:
        return
    maps = searched.maps[list(slots)]
    # A derived mirror prints its original's tag reflected: the same printed MP.
    printed = searched.printed[list(slots)].tolist()
    mirror = np.flatnonzero(derived)
    if mirror.size:
        # Reflection axis x = (x0 + x0') / 2 from the first point of the mirror and original.
        first_x = [
            int.from_bytes(rows[int(i)].coordinates[:2], "little")
            + int.from_bytes((rows[int(i)].original or b"")[:2], "little")
            for i in mirror
        ]
        maps[mirror] = mirrored_placements(maps[mirror], first_x)
    values = []
    for r, slot_index, m, pm in zip(rows, slots, maps, printed, strict=True):
        lay = searched.layouts[slot_index]
        values.append(
            (
                r.realization_id,
                searched.triangles[slot_index],
                len(lay.triangles),
                float(lay.min_angle_deg),
                float(lay.min_side),
                None if lay.min_gap is None else float(lay.min_gap),
                None if lay.min_shared_gap_deg is None else float(lay.min_shared_gap_deg),
                float(lay.score),
                _placement_json(m),
                pm,
            )
        )
    if conn.dialect.name == "sqlite":
        # SQLite fast path: positional rows, without the per-row parameter processing of Core.
        conn.exec_driver_sql(
            f"INSERT INTO layouts ({', '.join(_LAYOUT_COLUMNS)}) VALUES ({', '.join('?' * len(_LAYOUT_COLUMNS))})",
            values,
        )
    else:
        conn.execute(insert(LayoutRow.__table__), [dict(zip(_LAYOUT_COLUMNS, v, strict=True)) for v in values])  # type: ignore[arg-type]


def _placement_json(m: NDArray[np.float64]) -> str:
    """``json.dumps(m.tolist())`` of a finite ``(2, 3)`` map, without the encoder's overhead."""
    (a, b, c), (d, e, f) = m.tolist()
    return f"[[{a!r}, {b!r}, {c!r}], [{d!r}, {e!r}, {f!r}]]"


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
    for k in sorted({row.k for row in todo}):
        base = done

        def report(n: int, base: int = base) -> None:
            if progress is not None:
                progress(base + n, len(todo))

        done += store_layouts(conn, [row for row in todo if row.k == k], on_batch=report)
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
