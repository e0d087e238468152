"""Decoder lookups built from the database: every order type, or one dictionary's members."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import func, select

from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.errors import NotFoundError
from ottag_db.store.db import Database
from ottag_db.store.dictionaries import find_dictionary, get_dictionary
from ottag_db.store.models import DictionaryTag, FlipEdgeRow, OrderType, Realization, coordinates_from_blob

__all__ = ["dictionary_lookup", "load_lookup", "neighbour_members"]


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
            pts = coordinates_from_blob(blob)[[int(c) for c in labeling]].astype(np.float64)
            reals.setdefault(ot_id, []).append(pts)
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


def dictionary_lookup(db: Database, name: str | None) -> MemoryLookup:
    """Decoder lookup: the whole database, or only one dictionary's members (with tag numbers).

    Parameters
    ----------
    db : Database
        An open database (only read).
    name : str or None
        Dictionary name; None gives :func:`load_lookup` of the whole database.

    Returns
    -------
    MemoryLookup
        Entries of the members. A member's ``LookupEntry.extra["tags"]`` maps polarity →
        tag number; ``tag`` is its lowest tag number.

    Raises
    ------
    NotFoundError
        No dictionary of that name.
    """
    if name is None:
        return load_lookup(db)
    info = get_dictionary(db, name)
    full = load_lookup(db, ks=sorted({m.k for m in info.members}))
    entries: dict[str, LookupEntry] = {}
    per_pol: dict[str, dict[str, int]] = {}
    for m in info.members:
        per_pol.setdefault(m.lambda_text, {})[m.polarity] = m.number
    for text, pols in per_pol.items():
        base = full.get(text)
        if base is None:  # pragma: no cover - members reference stored order types
            continue
        entries[text] = LookupEntry(
            lambda_text=base.lambda_text,
            k=base.k,
            order_type_id=base.order_type_id,
            unique_min=base.unique_min,
            realizations=base.realizations,
            tag=min(pols.values()),
            extra={"tags": dict(pols), "dictionary": name},
        )
    return MemoryLookup(entries.values())


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
