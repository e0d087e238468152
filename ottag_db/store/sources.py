"""Imported sources (point files): list them, and remove one with everything only it provided."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import Connection, delete, distinct, exists, func, or_, select, update

from ottag_db.errors import DictionaryError, NotFoundError
from ottag_db.store.db import Database
from ottag_db.store.models import Dictionary, DictionaryTag, FlipGraphStatus, OrderType, Realization, Source
from ottag_db.store.numbering import assign_numbers

__all__ = ["RemovedSource", "SourceSummary", "list_sources", "remove_source"]


@dataclass(frozen=True)
class SourceSummary:
    """One imported file: its name, SHA-256, points per record, records and what it provided.

    ``realizations`` counts the stored realizations (mirrors included), ``order_types`` the
    distinct order types they realize.
    """

    id: int
    name: str
    sha256: str
    n: int
    coordinate_bits: int
    records: int
    mirrors_included: bool
    imported_at: datetime
    realizations: int
    order_types: int

    def as_json(self) -> dict[str, object]:
        """The summary as a JSON-ready dict (``imported_at`` in ISO 8601)."""
        return {
            "id": self.id,
            "name": self.name,
            "sha256": self.sha256,
            "n": self.n,
            "coordinate_bits": self.coordinate_bits,
            "records": self.records,
            "mirrors_included": self.mirrors_included,
            "imported_at": self.imported_at.isoformat(timespec="seconds"),
            "realizations": self.realizations,
            "order_types": self.order_types,
        }


@dataclass(frozen=True)
class RemovedSource:
    """What :func:`remove_source` deleted: the source, its realizations (with their layouts)
    and the order types no other source realizes."""

    source: SourceSummary
    realizations: int
    order_types: int


def list_sources(db: Database) -> list[SourceSummary]:
    """Every imported source, in import order.

    Parameters
    ----------
    db : Database
        An open database (only read).

    Returns
    -------
    list of SourceSummary
        One per imported file.
    """
    with db.engine.connect() as conn:
        return _summaries(conn, None)


def _summaries(conn: Connection, source_id: int | None) -> list[SourceSummary]:
    counts = (
        select(
            Realization.source_id,
            func.count().label("realizations"),
            func.count(distinct(Realization.order_type_id)).label("order_types"),
        )
        .group_by(Realization.source_id)
        .subquery()
    )
    query = (
        select(Source, counts.c.realizations, counts.c.order_types)
        .outerjoin(counts, counts.c.source_id == Source.id)
        .order_by(Source.id)
    )
    if source_id is not None:
        query = query.where(Source.id == source_id)
    out = []
    for row in conn.execute(query).all():
        out.append(
            SourceSummary(
                id=int(row.id),
                name=row.file_name,
                sha256=row.sha256,
                n=int(row.n),
                coordinate_bits=int(row.coordinate_bits),
                records=int(row.records),
                mirrors_included=bool(row.mirrors_included),
                imported_at=row.imported_at,
                realizations=int(row.realizations or 0),
                order_types=int(row.order_types or 0),
            )
        )
    return out


def _find(conn: Connection, name_or_id: str) -> int:
    by_name = conn.execute(select(Source.id).where(Source.file_name == name_or_id)).scalars().all()
    if len(by_name) == 1:
        return int(by_name[0])
    if len(by_name) > 1:
        ids = ", ".join(str(i) for i in by_name)
        raise NotFoundError(f"{len(by_name)} sources are named {name_or_id!r} (ids {ids}); remove one by its id")
    if name_or_id.isdigit():
        found = conn.execute(select(Source.id).where(Source.id == int(name_or_id))).scalar()
        if found is not None:
            return int(found)
    raise NotFoundError(f"no source {name_or_id!r} in the database; `ottag-db sources` lists them")


def remove_source(db: Database, name_or_id: str) -> RemovedSource:
    """Remove an imported source in one transaction.

    Deletes the source, its realizations with their layouts, and the order types left
    without any realization (with their flip-graph edges); numbers are reassigned (a k that
    is no longer complete loses its numbers) and the flip graph of an affected k is marked
    as not computed. A source whose removal would take order types or realizations out of
    a dictionary is refused.

    Parameters
    ----------
    db : Database
        An open database.
    name_or_id : str
        The source's file name (as ``ottag-db sources`` lists it) or its database id.

    Returns
    -------
    RemovedSource
        The removed source and the counts of deleted realizations and order types.

    Raises
    ------
    NotFoundError
        No such source (or an ambiguous name).
    DictionaryError
        A dictionary uses what the removal would delete; delete that dictionary first.
    """
    with db.write() as conn:
        source_id = _find(conn, name_or_id)
        summary = _summaries(conn, source_id)[0]
        other = select(Realization.id).where(
            Realization.order_type_id == OrderType.id, Realization.source_id != source_id
        )
        mine = select(Realization.id).where(
            Realization.order_type_id == OrderType.id, Realization.source_id == source_id
        )
        orphans = select(OrderType.id).where(exists(mine), ~exists(other))
        orphan_ids = [int(i) for i in conn.execute(orphans).scalars().all()]
        ours = select(Realization.id).where(Realization.source_id == source_id)
        used = conn.execute(
            select(Dictionary.name)
            .distinct()
            .join(DictionaryTag, DictionaryTag.dictionary_id == Dictionary.id)
            .where(or_(DictionaryTag.order_type_id.in_(orphans), DictionaryTag.realization_id.in_(ours)))
            .order_by(Dictionary.name)
        ).scalars()
        names = list(used)
        if names:
            raise DictionaryError(
                f"{summary.name}: dictionar{'y' if len(names) == 1 else 'ies'} {', '.join(names)} use(s) its "
                "tags; delete them first (`ottag-db dictionary delete NAME`)"
            )
        ks = {
            int(k) for k in conn.execute(select(OrderType.k).distinct().where(OrderType.id.in_(orphan_ids))).scalars()
        }
        realizations = conn.execute(delete(Realization).where(Realization.source_id == source_id)).rowcount
        for start in range(0, len(orphan_ids), 5000):
            conn.execute(delete(OrderType).where(OrderType.id.in_(orphan_ids[start : start + 5000])))
        conn.execute(delete(Source).where(Source.id == source_id))
        if ks:
            conn.execute(delete(FlipGraphStatus).where(FlipGraphStatus.k.in_(ks)))
            conn.execute(update(OrderType).where(OrderType.k.in_(ks)).values(number=None))
        assign_numbers(conn)
    return RemovedSource(summary, int(realizations or 0), len(orphan_ids))
