"""Import point-set files into the database: one transaction per file, streamed in chunks.

Each chunk's realizations are stored with their layouts and placements
(:mod:`ottag_db.store.layouts`), so reads never have to compute them.
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Connection, func, insert, select, update
from sqlalchemy.dialects import postgresql

from ottag_db.core.canonical import canonicalize_lambdas, mirror_lambdas
from ottag_db.core.geometry import analyse_point_sets, check_general_position
from ottag_db.core.layout import layout_supported
from ottag_db.core.types import ProgressCallback
from ottag_db.errors import GeneralPositionError, PointFileError
from ottag_db.files.pointfile import PointFileInfo, file_sha256, inspect_point_file, iter_point_chunks
from ottag_db.store.db import Database
from ottag_db.store.layouts import BatchMap, PendingLayouts, finish_layouts, missing_layouts, start_layouts
from ottag_db.store.models import OrderType, Realization, Source, coordinates_to_blobs, labelings_to_texts
from ottag_db.store.numbering import assign_numbers

__all__ = ["ImportReport", "import_point_file", "import_point_files", "is_imported"]

_HINT = "is --points right?"

# Records per chunk: an n = 10 chunk needs about 16384 × 450 float64 of orientations (60 MB).
_CHUNK_RECORDS = 16384
_IN_BATCH = 5000


@dataclass(frozen=True)
class ImportReport:
    """What one file's import did. ``skipped`` is True when it was already imported."""

    path: Path
    n: int
    records: int
    new_order_types: int
    new_realizations: int
    skipped: bool
    seconds: float
    mirrors: bool


@dataclass(frozen=True)
class _ChunkData:
    texts: list[str]
    mirror_texts: list[str]
    minimal: NDArray[np.int64]
    hulls: NDArray[np.int64]
    labelings: list[str]
    mirror_labelings: list[str]
    mp: NDArray[np.float64]

    def mirrored(self) -> _ChunkData:
        """The same data for the reflected sets: IDs and labelings swap, MP and hull stay."""
        return _ChunkData(
            texts=self.mirror_texts,
            mirror_texts=self.texts,
            minimal=self.minimal,
            hulls=self.hulls,
            labelings=self.mirror_labelings,
            mirror_labelings=self.labelings,
            mp=self.mp,
        )


def _analyse(points: NDArray[np.int64], first: int) -> _ChunkData:
    analysis = analyse_point_sets(points)
    if not analysis.general_position.all():
        bad = int(np.flatnonzero(~analysis.general_position)[0])
        check_general_position(points[bad : bad + 1], record_offset=first + bad)
    lam = analysis.lambdas
    batch = canonicalize_lambdas(lam)
    # Reflection swaps left and right: the mirror's λ follows from λ without new geometry,
    # and the reflected set keeps the point indices, so its labeling comes out directly.
    mirror = canonicalize_lambdas(mirror_lambdas(lam))
    return _ChunkData(
        texts=batch.texts(),
        mirror_texts=mirror.texts(),
        minimal=batch.minimal_orderings,
        hulls=batch.hull_sizes,
        labelings=labelings_to_texts(batch.labelings),
        mirror_labelings=labelings_to_texts(mirror.labelings),
        mp=analysis.mp,
    )


def _reflect(points: NDArray[np.int64], max_coordinate: int) -> NDArray[np.int64]:
    out = points.copy()
    out[..., 0] = max_coordinate - out[..., 0]
    return out


# SQL column names (bulk inserts go by column, not by ORM attribute: see models.OrderType).
_OT_COLUMNS = ("k", "canonical_lambda", "unique_min", "minimal_orderings", "hull_size", "mirror_lambda", "chiral")
_R_COLUMNS = ("order_type_id", "source_id", "record_index", "mirrored", "coordinates", "mp", "canonical_labeling")


def _upsert_order_types(conn: Connection, k: int, data: _ChunkData) -> dict[str, int]:
    """Insert the chunk's new order types (others may exist from earlier files) and map ID → row id."""
    rows: dict[str, tuple[object, ...]] = {}
    for i, text in enumerate(data.texts):
        if text not in rows:
            mirror = data.mirror_texts[i]
            rows[text] = (
                k,
                text,
                bool(data.minimal[i] == 1),
                int(data.minimal[i]),
                int(data.hulls[i]),
                mirror,
                mirror != text,
            )
    if conn.dialect.name == "sqlite":
        return _upsert_sqlite(conn, k, rows)
    return _upsert_generic(conn, k, rows)


def _upsert_sqlite(conn: Connection, k: int, rows: dict[str, tuple[object, ...]]) -> dict[str, int]:
    """SQLite fast path: one INSERT OR IGNORE and one join through a temporary key table."""
    cols = ", ".join(_OT_COLUMNS)
    conn.exec_driver_sql(
        f"INSERT OR IGNORE INTO order_types ({cols}) VALUES ({', '.join('?' * len(_OT_COLUMNS))})",
        list(rows.values()),
    )
    conn.exec_driver_sql("CREATE TEMP TABLE IF NOT EXISTS ottag_chunk_keys (lam TEXT PRIMARY KEY)")
    conn.exec_driver_sql("DELETE FROM ottag_chunk_keys")
    conn.exec_driver_sql("INSERT INTO ottag_chunk_keys (lam) VALUES (?)", [(t,) for t in rows])
    found = conn.exec_driver_sql(
        "SELECT o.canonical_lambda, o.id FROM ottag_chunk_keys c "
        "JOIN order_types o ON o.k = ? AND o.canonical_lambda = c.lam",
        (k,),
    ).all()
    return {t: int(i) for t, i in found}


def _upsert_generic(conn: Connection, k: int, rows: dict[str, tuple[object, ...]]) -> dict[str, int]:
    """Any other database: look the IDs up, insert the missing ones by column name, look up again."""
    table: Any = OrderType.__table__
    stmt: Any = insert(table)
    if conn.dialect.name == "postgresql":
        stmt = postgresql.insert(table).on_conflict_do_nothing()
    keys = list(rows)
    ids: dict[str, int] = {}
    for s in range(0, len(keys), _IN_BATCH):
        part = keys[s : s + _IN_BATCH]
        query = select(OrderType.lambda_text, OrderType.id).where(OrderType.k == k, OrderType.lambda_text.in_(part))
        ids.update({t: i for t, i in conn.execute(query).all()})
        missing = [dict(zip(_OT_COLUMNS, rows[t], strict=True)) for t in part if t not in ids]
        if missing:
            conn.execute(stmt, missing)
            ids.update({t: i for t, i in conn.execute(query).all()})
    return ids


def _insert_realizations(
    conn: Connection,
    source_id: int,
    first: int,
    points: NDArray[np.int64],
    data: _ChunkData,
    ids: dict[str, int],
    mirrored: bool,
    keep: NDArray[np.bool_] | None = None,
) -> int:
    blobs = coordinates_to_blobs(points)
    idx = range(points.shape[0]) if keep is None else np.flatnonzero(keep).tolist()
    mp = data.mp.tolist()
    rows = [(ids[data.texts[i]], source_id, first + i, mirrored, blobs[i], mp[i], data.labelings[i]) for i in idx]
    if not rows:
        return 0
    if conn.dialect.name == "sqlite":
        conn.exec_driver_sql(
            f"INSERT INTO realizations ({', '.join(_R_COLUMNS)}) VALUES ({', '.join('?' * len(_R_COLUMNS))})", rows
        )
    else:
        conn.execute(insert(Realization.__table__), [dict(zip(_R_COLUMNS, r, strict=True)) for r in rows])  # type: ignore[arg-type]
    return len(rows)


def import_point_file(
    db: Database,
    path: str | os.PathLike[str],
    *,
    n: int | None = None,
    with_mirrors: bool = False,
    progress: ProgressCallback | None = None,
    display_name: str | None = None,
    allow_duplicates: bool = False,
    jobs: int = 1,
) -> ImportReport:
    """Import one ``.b08``/``.b16`` file in a single transaction.

    Every record is checked for general position, canonicalized and stored as a
    realization of its order type (order types are shared across files), together with its
    triangle layout and tag placement (k = 3, 5 … 8; see :mod:`ottag_db.store.layouts`).
    With ``with_mirrors`` the mirror image (x → max − x) of every chiral record is stored
    too, as a realization of the mirror order type. Importing a file whose SHA-256 is
    already recorded (with the same or fewer mirrors) is a no-op reported with
    ``skipped=True``. Any error rolls the whole file back (realizations, layouts and the
    source row alike) and raises a typed error naming the file and record.

    Parameters
    ----------
    db : Database
        An open, migrated database.
    path : str or PathLike
        The point-set file.
    n : int, optional
        Points per record; None reads it from the name ``otypesNN``.
    with_mirrors : bool
        Also store the mirror image of every chiral record.
    progress : ProgressCallback, optional
        ``progress(done, total)`` in records of the file: a record is done once its
        realizations and their layouts are stored (reported per chunk and per layout batch).
    display_name : str, optional
        Name stored for the source and used in messages (default: the file name).
    allow_duplicates : bool
        Accept two records of the same order type (refused by default: Aichholzer's files
        hold each order type once, so a repeat usually means a wrong ``--points``).
    jobs : int
        Processes that compute layouts, placements and canonical IDs (above 1, a pool of
        spawned worker processes beside this one, which does the SQL; the next chunk's IDs
        are computed while this one's layouts are stored); the stored rows are the same.

    Returns
    -------
    ImportReport
        Records read, new order types and realizations, seconds, and whether it was skipped.

    Raises
    ------
    PointFileError
        Unreadable file, bad size, a record not in general position or (unless
        ``allow_duplicates``) two records of the same order type.
    DatabaseError
        The database is read-only, corrupt or locked (raised by the caller's error handling).
    """
    start = time.perf_counter()
    info = inspect_point_file(path, n)
    name = display_name or info.path.name
    digest = file_sha256(info.path)
    max_coordinate = (1 << info.bits) - 1
    with db.write() as conn:
        src = conn.execute(select(Source).where(Source.sha256 == digest)).first()
        if src is not None and src.n != info.n:
            raise PointFileError(
                f"{name}: this content was imported as {src.n}-point records ({src.file_name}); {_HINT} "
                f"(`ottag-db sources remove {src.file_name}` first to import it as {info.n}-point records)"
            )
        if src is not None and (src.mirrors_included or not with_mirrors):
            return ImportReport(info.path, info.n, info.records, 0, 0, True, time.perf_counter() - start, with_mirrors)
        before = conn.execute(select(func.count()).select_from(OrderType)).scalar_one()
        only_mirrors = src is not None
        if src is None:
            inserted = conn.execute(
                insert(Source).values(
                    file_name=name,
                    sha256=digest,
                    n=info.n,
                    coordinate_bits=info.bits,
                    records=info.records,
                    mirrors_included=with_mirrors,
                    imported_at=datetime.now(),
                )
            ).inserted_primary_key
            assert inserted is not None
            source_id = inserted[0]
        else:
            source_id = src.id
            conn.execute(update(Source).where(Source.id == source_id).values(mirrors_included=True))
        added = 0
        try:
            with _layout_workers(jobs if layout_supported(info.n) or info.records > _CHUNK_RECORDS else 1) as pool:
                added = _import_chunks(
                    conn, info, int(source_id), with_mirrors, only_mirrors, max_coordinate, progress, pool
                )
        except GeneralPositionError as exc:
            record = exc.record if exc.record is not None else 0
            raise PointFileError(
                f"{name}: record {record} (byte offset {record * info.record_size}): "
                f"{str(exc).split(': ', 1)[-1]}; every point set must be in general position — "
                f"{_HINT if not info.official else 'fix or drop that record'}"
            ) from exc
        if not allow_duplicates and not only_mirrors:
            _check_distinct(conn, int(source_id), name, info)
        after = conn.execute(select(func.count()).select_from(OrderType)).scalar_one()
        assign_numbers(conn)
    return ImportReport(
        info.path, info.n, info.records, int(after - before), added, False, time.perf_counter() - start, with_mirrors
    )


def _check_distinct(conn: Connection, source_id: int, name: str, info: PointFileInfo) -> None:
    """Refuse a file with two records of one order type, naming the first repeat."""
    row = conn.exec_driver_sql(
        "SELECT record_index, first FROM (SELECT record_index, "
        "MIN(record_index) OVER (PARTITION BY order_type_id) AS first FROM realizations "
        "WHERE source_id = ? AND mirrored = 0) WHERE record_index > first ORDER BY record_index LIMIT 1",
        (source_id,),
    ).first()
    if row is not None:
        later, first = int(row[0]), int(row[1])
        raise PointFileError(
            f"{name}: records {first} and {later} have the same order type ({info.n} points per record); "
            f"a point-set file holds each order type once — {_HINT} (--allow-duplicates imports it anyway)"
        )


def is_imported(db: Database, path: str | os.PathLike[str]) -> bool:
    """Whether a file with this content (SHA-256) is recorded as a source.

    Parameters
    ----------
    db : Database
        An open database (only read).
    path : str or PathLike
        The point-set file.

    Returns
    -------
    bool
        True once the file's import has been committed.
    """
    digest = file_sha256(path)
    with db.engine.connect() as conn:
        return conn.execute(select(Source.id).where(Source.sha256 == digest)).first() is not None


def _import_chunks(
    conn: Connection,
    info: PointFileInfo,
    source_id: int,
    with_mirrors: bool,
    only_mirrors: bool,
    max_coordinate: int,
    progress: ProgressCallback | None,
    pool: Executor | None,
) -> int:
    """Store the file's chunks; with a ``pool``, each chunk's analysis (canonical IDs) and layout
    searches run there while this process stores the chunk before it."""
    added = 0
    drawable = layout_supported(info.n)
    map_batches: BatchMap = pool.map if pool is not None else map
    chunks = iter_point_chunks(info, _CHUNK_RECORDS)
    current = next(chunks, None)
    analysis = _start_analysis(pool, current)
    pending: _ChunkLayouts | None = None
    while current is not None:
        first, points = current
        data = analysis()
        current = next(chunks, None)
        if not only_mirrors:
            ids = _upsert_order_types(conn, info.n, data)
            added += _insert_realizations(conn, source_id, first, points, data, ids, mirrored=False)
        if with_mirrors:
            chiral = np.array([m != t for m, t in zip(data.mirror_texts, data.texts, strict=True)], dtype=bool)
            if chiral.any():
                mirrored_points = _reflect(points, max_coordinate)
                mdata = data.mirrored()
                ids = _upsert_order_types(conn, info.n, mdata)
                added += _insert_realizations(
                    conn, source_id, first, mirrored_points, mdata, ids, mirrored=True, keep=chiral
                )
        # Queued before this chunk's layout batches, so a worker analyses the next chunk
        # while the others lay out this one.
        analysis = _start_analysis(pool, current)
        stop = first + points.shape[0]
        # This chunk's searches start now; the previous chunk's are stored while they run, so
        # the pool is not idle while this process writes a chunk's realizations.
        started = _start_chunk_layouts(conn, source_id, first, stop, map_batches) if drawable else None
        if pending is not None:
            _finish_chunk_layouts(conn, pending, info.records, progress)
        pending = started
        if pending is None and progress is not None:
            progress(stop, info.records)
    if pending is not None:
        _finish_chunk_layouts(conn, pending, info.records, progress)
    return added


def _start_analysis(pool: Executor | None, chunk: tuple[int, NDArray[np.int64]] | None) -> Callable[[], _ChunkData]:
    """The analysis of ``chunk`` (record offset, points): submitted to ``pool``, or computed
    when called without one; the returned callable gives the result (raising its error)."""
    if chunk is None:
        return _no_chunk
    first, points = chunk
    if pool is None:
        return lambda: _analyse(points, first)
    return pool.submit(_analyse, points, first).result


def _no_chunk() -> _ChunkData:
    raise AssertionError("no chunk left to analyse")


@dataclass(frozen=True)
class _ChunkLayouts:
    """A chunk's started layout searches and the record index its records stop at."""

    layouts: PendingLayouts
    stop: int


def _start_chunk_layouts(
    conn: Connection, source_id: int, first: int, stop: int, map_batches: BatchMap
) -> _ChunkLayouts:
    """Start the layout searches of the chunk's new realizations (records ``first … stop − 1``)."""
    todo = missing_layouts(conn, source_id=source_id, first=first, stop=stop)
    return _ChunkLayouts(start_layouts(todo, map_batches=map_batches), stop)


def _finish_chunk_layouts(
    conn: Connection, chunk: _ChunkLayouts, records: int, progress: ProgressCallback | None
) -> None:
    """Store a chunk's layouts; progress counts the records finished."""
    todo = chunk.layouts.rows

    def report(done: int) -> None:
        # The last record of a batch may still have its mirror in the next one.
        if progress is not None and done:
            progress(todo[done - 1].record_index, records)

    finish_layouts(conn, chunk.layouts, on_batch=report)
    if progress is not None:
        progress(chunk.stop, records)


@contextmanager
def _layout_workers(jobs: int) -> Iterator[Executor | None]:
    """A pool of ``jobs`` processes for layouts and analyses, or None (``jobs = 1``: this process)."""
    if jobs <= 1:
        yield None
        return
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    # Spawned workers import numpy and ottag_db.core only; they ignore Ctrl-C, which the
    # import handles (rolls the file back) in this process.
    with ProcessPoolExecutor(jobs, mp_context=get_context("spawn"), initializer=_ignore_interrupts) as pool:
        try:
            yield pool
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise


def _ignore_interrupts() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def import_point_files(
    db: Database,
    paths: Sequence[str | os.PathLike[str]],
    *,
    n: int | None = None,
    with_mirrors: bool = False,
    progress: ProgressCallback | None = None,
    jobs: int = 1,
) -> list[ImportReport]:
    """Import several files, each in its own transaction; stops at the first failing file.

    Parameters
    ----------
    db : Database
        An open, migrated database.
    paths : sequence of str or PathLike
        The point-set files, imported in this order.
    n : int, optional
        Points per record of every file; None reads each from its name.
    with_mirrors : bool
        Also store mirror images (see :func:`import_point_file`).
    progress : ProgressCallback, optional
        Called per file as in :func:`import_point_file`.
    jobs : int
        Layout processes per file (see :func:`import_point_file`).

    Returns
    -------
    list of ImportReport
        One report per file.
    """
    return [import_point_file(db, p, n=n, with_mirrors=with_mirrors, progress=progress, jobs=jobs) for p in paths]
