"""Decoder lookups built from the database: every order type, or one dictionary's members."""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import func, select

from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.errors import NotFoundError
from ottag_db.store.db import Database
from ottag_db.store.dictionaries import find_dictionary
from ottag_db.store.models import (
    DictionaryTag,
    FlipEdgeRow,
    LayoutRow,
    OrderType,
    Realization,
    coordinates_from_blob,
)

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
        canonical label order (row ``l`` = point with label ``l``), as the decoder needs,
        with their stored layouts (triangles in canonical labels).

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
        layouts: dict[int, list[_Layout]] = {}
        placements: dict[int, list[_Placement]] = {}
        rq = (
            select(
                Realization.order_type_id,
                Realization.coordinates,
                Realization.canonical_labeling,
                LayoutRow.triangles,
                LayoutRow.placement,
            )
            .outerjoin(LayoutRow, LayoutRow.realization_id == Realization.id)
            .order_by(Realization.order_type_id, Realization.mp.desc(), Realization.id)
        )
        if ks:
            rq = rq.join(OrderType, OrderType.id == Realization.order_type_id).where(OrderType.k.in_(list(ks)))
        for ot_id, blob, labeling, triangles, placement in s.execute(rq):
            reals.setdefault(ot_id, []).append(_canonical_points(blob, labeling))
            layouts.setdefault(ot_id, []).append(_canonical_layout(triangles, labeling))
            placements.setdefault(ot_id, []).append(_placement(placement))
    entries = [
        LookupEntry(
            lambda_text=text,
            k=k,
            order_type_id=ot_id,
            unique_min=bool(uniq),
            realizations=tuple(reals.get(ot_id, [])),
            layouts=_known(layouts.get(ot_id, [])),
            placements=_known_placements(placements.get(ot_id, [])),
        )
        for ot_id, k, text, uniq in ots
    ]
    return MemoryLookup(entries)


@dataclass(frozen=True)
class MemberGeometry:
    """What the decoder needs of one dictionary member: its tag number and polarity, its order
    type and the realizations it is verified against (``(k, 2)`` float64, rows in canonical
    label order, grid units, screen convention) with, when known, the triangles printed for
    each (``layouts[r]`` for ``realizations[r]``, triples of canonical labels; empty when
    unknown) and the placement each was printed with (``placements[r]``: ``(2, 3)`` grid →
    data-area units, None when unknown; empty when none is known)."""

    number: int
    polarity: str
    lambda_text: str
    k: int
    order_type_id: int
    unique_min: bool
    realizations: tuple[NDArray[np.float64], ...]
    layouts: tuple[tuple[tuple[int, int, int], ...], ...] = ()
    placements: tuple[NDArray[np.float64] | None, ...] = ()


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
        lays: dict[bytes, _Layout] = {}
        places: dict[bytes, _Placement] = {}
        for m in group:
            for i, r in enumerate(m.realizations):
                key = np.ascontiguousarray(r, dtype=np.float64).tobytes()
                reals.setdefault(key, r)
                lays.setdefault(key, m.layouts[i] if i < len(m.layouts) else ())
                places.setdefault(key, m.placements[i] if i < len(m.placements) else None)
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
                layouts=_known([lays[key] for key in reals]),
                placements=_known_placements([places[key] for key in reals]),
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
        by_id: dict[int, tuple[NDArray[np.float64], _Layout, _Placement]] = {}
        by_type: dict[int, list[tuple[NDArray[np.float64], _Layout, _Placement]]] = {}
        rq = select(
            Realization.id,
            Realization.order_type_id,
            Realization.coordinates,
            Realization.canonical_labeling,
            LayoutRow.triangles,
            LayoutRow.placement,
        ).outerjoin(LayoutRow, LayoutRow.realization_id == Realization.id)
        for part in _chunks(sorted(pinned)):
            for rid, _ot, blob, labeling, tris, plc in s.execute(rq.where(Realization.id.in_(part))):
                by_id[int(rid)] = (
                    _canonical_points(blob, labeling),
                    _canonical_layout(tris, labeling),
                    _placement(plc),
                )
        for part in _chunks(sorted(loose)):
            q = rq.where(Realization.order_type_id.in_(part)).order_by(Realization.mp.desc(), Realization.id)
            for _rid, ot, blob, labeling, tris, plc in s.execute(q):
                by_type.setdefault(int(ot), []).append(
                    (_canonical_points(blob, labeling), _canonical_layout(tris, labeling), _placement(plc))
                )
    members = []
    for number, polarity, pinned_id, ot_id, k, text, uniq in rows:
        geoms = [by_id[int(pinned_id)]] if pinned_id is not None else by_type.get(int(ot_id), [])
        members.append(
            MemberGeometry(
                number=int(number),
                polarity=str(polarity),
                lambda_text=str(text),
                k=int(k),
                order_type_id=int(ot_id),
                unique_min=bool(uniq),
                realizations=tuple(g[0] for g in geoms),
                layouts=_known([g[1] for g in geoms]),
                placements=_known_placements([g[2] for g in geoms]),
            )
        )
    return member_lookup(name, members)


def _chunks(ids: Sequence[int], size: int = 5000) -> Iterator[Sequence[int]]:
    for start in range(0, len(ids), size):
        yield ids[start : start + size]


_Layout = tuple[tuple[int, int, int], ...]


def _canonical_layout(triangles: str | None, labeling: str) -> _Layout:
    """Stored triangles (``"a,b,c;d,e,f"``, file indices) as triples of canonical labels; ``()``
    for a realization without a stored layout."""
    if not triangles:
        return ()
    label_of = {int(c): label for label, c in enumerate(labeling)}
    out = []
    for tri in triangles.split(";"):
        a, b, c = (label_of[int(v)] for v in tri.split(","))
        out.append((a, b, c))
    return tuple(out)


def _known(layouts: Sequence[_Layout]) -> tuple[_Layout, ...]:
    """The layouts of an entry's realizations, or ``()`` when none is known."""
    return tuple(layouts) if any(layouts) else ()


_Placement = NDArray[np.float64] | None


def _placement(text: str | None) -> _Placement:
    """A stored placement (JSON of the ``(2, 3)`` map grid → data-area units) as an array;
    None for a realization without a stored layout. Rows of the realization are reordered to
    canonical labels, but a point keeps its coordinates, so the map applies unchanged."""
    if not text:
        return None
    m = np.asarray(json.loads(text), dtype=np.float64)
    return m if m.shape == (2, 3) and np.isfinite(m).all() else None


def _known_placements(placements: Sequence[_Placement]) -> tuple[_Placement, ...]:
    """The placements of an entry's realizations, or ``()`` when none is known."""
    return tuple(placements) if any(p is not None for p in placements) else ()


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
