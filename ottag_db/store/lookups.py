"""Decoder lookups built from the database: every order type, or one dictionary's members."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import func, select

from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.errors import NotFoundError
from ottag_db.store.db import Database
from ottag_db.store.dictionaries import find_dictionary
from ottag_db.store.models import DictionaryTag, FlipEdgeRow, OrderType, Realization, coordinates_from_blob

__all__ = ["MemberGeometry", "dictionary_lookup", "load_lookup", "member_lookup", "neighbour_members"]


def load_lookup(db: Database, *, ks: Sequence[int] = ()) -> MemoryLookup:
    """All order types (optionally only some k) with every realization, for the decoder.

    Parameters
    ----------
    db : Database
        An open database (only read).
    ks : sequence of int
        Only these point counts (empty: all).

    Returns
    -------
    MemoryLookup
        One :class:`LookupEntry` per order type; its realizations (best MP first) in
        canonical label order (row ``l`` = point with label ``l``), as the decoder needs.

    Raises
    ------
    NotFoundError
        The database holds no order types.
    """
    with db.session() as s:
        q = select(OrderType.id, OrderType.k, OrderType.lambda_text, OrderType.unique_min)
        if ks:
            q = q.where(OrderType.k.in_(list(ks)))
        ots = s.execute(q).all()
        if not ots:
            raise NotFoundError("the database holds no order types: run `ottag-db import` first")
        reals: dict[int, list[NDArray[np.float64]]] = {}
        rq = select(Realization.order_type_id, Realization.coordinates, Realization.canonical_labeling).order_by(
            Realization.order_type_id, Realization.mp.desc(), Realization.id
        )
        if ks:
            rq = rq.join(OrderType, OrderType.id == Realization.order_type_id).where(OrderType.k.in_(list(ks)))
        for ot_id, blob, labeling in s.execute(rq):
            reals.setdefault(ot_id, []).append(_canonical_points(blob, labeling))
    entries = [
        LookupEntry(
            lambda_text=text,
            k=k,
            order_type_id=ot_id,
            unique_min=bool(uniq),
            realizations=tuple(reals.get(ot_id, [])),
        )
        for ot_id, k, text, uniq in ots
    ]
    return MemoryLookup(entries)


@dataclass(frozen=True)
class MemberGeometry:
    """What the decoder needs of one dictionary member: its tag number and polarity, its order
    type and the realizations it is verified against (``(k, 2)`` float64, rows in canonical
    label order, grid units, screen convention)."""

    number: int
    polarity: str
    lambda_text: str
    k: int
    order_type_id: int
    unique_min: bool
    realizations: tuple[NDArray[np.float64], ...]


def member_lookup(name: str, members: Iterable[MemberGeometry]) -> MemoryLookup:
    """Decoder lookup of a dictionary's members (from a database or straight from a file).

    Parameters
    ----------
    name : str
        Dictionary name (reported in ``LookupEntry.extra["dictionary"]``).
    members : iterable of MemberGeometry
        The members; two members of one order type (normal and inverted) share an entry.

    Returns
    -------
    MemoryLookup
        One entry per order type: ``tag`` is its lowest member number,
        ``extra["tags"]`` maps polarity → tag number, ``realizations`` are the members'
        geometries (identical ones once).
    """
    grouped: dict[str, list[MemberGeometry]] = {}
    for m in members:
        grouped.setdefault(m.lambda_text, []).append(m)
    entries = []
    for text, group in grouped.items():
        reals: dict[bytes, NDArray[np.float64]] = {}
        for m in group:
            for r in m.realizations:
                reals.setdefault(np.ascontiguousarray(r, dtype=np.float64).tobytes(), r)
        first = group[0]
        entries.append(
            LookupEntry(
                lambda_text=text,
                k=first.k,
                order_type_id=first.order_type_id,
                unique_min=first.unique_min,
                realizations=tuple(reals.values()),
                tag=min(m.number for m in group),
                extra={"tags": {m.polarity: m.number for m in group}, "dictionary": name},
            )
        )
    return MemoryLookup(entries)


def dictionary_lookup(db: Database, name: str | None) -> MemoryLookup:
    """Decoder lookup: the whole database, or only one dictionary's members (with tag numbers).

    A member verifies against exactly its own geometry (the realization ``dictionary create``
    chose or ``dictionary import`` stored); a member of a dictionary made before database
    revision 0005, which names no realization, against every realization of its order type.

    Parameters
    ----------
    db : Database
        An open database (only read).
    name : str or None
        Dictionary name; None gives :func:`load_lookup` of the whole database.

    Returns
    -------
    MemoryLookup
        Entries of the members (see :func:`member_lookup`). A member's
        ``LookupEntry.extra["tags"]`` maps polarity → tag number; ``tag`` is its lowest tag
        number.

    Raises
    ------
    NotFoundError
        No dictionary of that name.
    """
    if name is None:
        return load_lookup(db)
    with db.session() as s:
        d = find_dictionary(s, name)
        rows = s.execute(
            select(
                DictionaryTag.number,
                DictionaryTag.polarity,
                DictionaryTag.realization_id,
                OrderType.id,
                OrderType.k,
                OrderType.lambda_text,
                OrderType.unique_min,
            )
            .join(OrderType, OrderType.id == DictionaryTag.order_type_id)
            .where(DictionaryTag.dictionary_id == d.id)
            .order_by(DictionaryTag.number)
        ).all()
        pinned = {int(r[2]) for r in rows if r[2] is not None}
        loose = {int(r[3]) for r in rows if r[2] is None}
        by_id: dict[int, NDArray[np.float64]] = {}
        by_type: dict[int, list[NDArray[np.float64]]] = {}
        rq = select(Realization.id, Realization.order_type_id, Realization.coordinates, Realization.canonical_labeling)
        for part in _chunks(sorted(pinned)):
            for rid, _ot, blob, labeling in s.execute(rq.where(Realization.id.in_(part))):
                by_id[int(rid)] = _canonical_points(blob, labeling)
        for part in _chunks(sorted(loose)):
            q = rq.where(Realization.order_type_id.in_(part)).order_by(Realization.mp.desc(), Realization.id)
            for _rid, ot, blob, labeling in s.execute(q):
                by_type.setdefault(int(ot), []).append(_canonical_points(blob, labeling))
    members = [
        MemberGeometry(
            number=int(number),
            polarity=str(polarity),
            lambda_text=str(text),
            k=int(k),
            order_type_id=int(ot_id),
            unique_min=bool(uniq),
            realizations=(by_id[int(rid)],) if rid is not None else tuple(by_type.get(int(ot_id), [])),
        )
        for number, polarity, rid, ot_id, k, text, uniq in rows
    ]
    return member_lookup(name, members)


def _chunks(ids: Sequence[int], size: int = 5000) -> Iterator[Sequence[int]]:
    for start in range(0, len(ids), size):
        yield ids[start : start + size]


def _canonical_points(blob: bytes, labeling: str) -> NDArray[np.float64]:
    """A stored realization's points in canonical label order (row ``l`` = label ``l``)."""
    return coordinates_from_blob(blob)[[int(c) for c in labeling]].astype(np.float64)


def neighbour_members(db: Database, name: str) -> dict[str, int]:
    """For every order type one flip away from a member: canonical λ → lowest member number.

    Loaded once so a decoder can say which member a rejected reading was one flip from.

    Parameters
    ----------
    db : Database
        An open database with the flip graph of the dictionary's k stored.
    name : str
        Dictionary name.

    Returns
    -------
    dict of str to int
        Canonical λ text → lowest number of a member one flip away.

    Raises
    ------
    NotFoundError
        No dictionary of that name.
    """
    with db.session() as s:
        d = find_dictionary(s, name)
        rows = s.execute(
            select(OrderType.lambda_text, func.min(DictionaryTag.number))
            .join(FlipEdgeRow, FlipEdgeRow.source_id == OrderType.id)
            .join(DictionaryTag, DictionaryTag.order_type_id == FlipEdgeRow.target_id)
            .where(DictionaryTag.dictionary_id == d.id, FlipEdgeRow.source_id != FlipEdgeRow.target_id)
            .group_by(OrderType.lambda_text)
        ).all()
    return {str(t): int(n) for t, n in rows}
