"""Named tag dictionaries: create (greedy, with a minimum flip distance), list, get and delete.

Files (JSON/CSV) are in :mod:`ottag_db.store.dictionary_files`, decoder lookups in
:mod:`ottag_db.store.lookups`, the flip graph in :mod:`ottag_db.store.flipgraph`.
"""

from __future__ import annotations

import dataclasses
import json
import re
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import delete, func, select
from sqlalchemy.orm import Session, selectinload

from ottag_db.core.types import ProgressCallback
from ottag_db.errors import DictionaryError, NotFoundError, UsageError
from ottag_db.store.db import Database
from ottag_db.store.flipgraph import ensure_flip_graph, flip_adjacency, within_flips
from ottag_db.store.models import Dictionary, DictionaryTag, LayoutRow, OrderType, Realization, Source
from ottag_db.store.queries import missing_ks_note
from ottag_db.store.tags import TagRecord, select_tags, tag_record

__all__ = [
    "DictionaryInfo",
    "DictionaryMember",
    "DictionaryOptions",
    "check_dictionary_name",
    "create_dictionary",
    "delete_dictionary",
    "dictionary_source_name",
    "dictionary_tag_records",
    "find_dictionary",
    "get_dictionary",
    "list_dictionaries",
]

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$")


@dataclass(frozen=True)
class DictionaryOptions:
    """How to build a dictionary.

    Candidates are the drawable order types (k = 3, 5 … 9) passing the filters (``min_mp`` in
    grid units); with ``include_mirrors=False`` only the member of each chiral pair with the
    smaller canonical λ is a candidate. Candidates are taken greedily in the order
    (MP descending, k, canonical λ) and kept when no kept member is fewer than
    ``min_flip_distance`` flips away (1 = no constraint; 2 = no two members are neighbours,
    so any single-triple misread lands outside the dictionary). ``polarity`` ``both`` gives
    each chosen order type two consecutive tags (normal, then inverted). ``max_size``
    bounds the number of tags.
    """

    ks: tuple[int, ...] = ()
    min_mp: float | None = None
    matchable: bool = False
    polarity: str = "normal"
    include_mirrors: bool = True
    min_flip_distance: int = 2
    max_size: int | None = None

    def as_json(self) -> dict[str, Any]:
        """The options as stored with the dictionary."""
        return {
            "k": list(self.ks),
            "min_mp": self.min_mp,
            "matchable": self.matchable,
            "polarity": self.polarity,
            "include_mirrors": self.include_mirrors,
            "min_flip_distance": self.min_flip_distance,
            "max_size": self.max_size,
        }


@dataclass(frozen=True)
class DictionaryMember:
    """Tag ``number`` of a dictionary (everything another implementation needs to draw it)."""

    number: int
    lambda_text: str
    k: int
    polarity: str
    order_type_id: int
    universal_number: int | None
    points: list[list[int]]
    triangles: list[list[int]]
    mp: float
    unique_min: bool
    realization_id: int | None = None

    def as_json(self) -> dict[str, Any]:
        """One object of the ``tags`` array of ``dictionary export --format json``."""
        return {
            "number": self.number,
            "lambda": self.lambda_text,
            "k": self.k,
            "polarity": self.polarity,
            "universal_number": self.universal_number,
            "points": self.points,
            "triangles": self.triangles,
            "mp": self.mp,
            "unique_min": self.unique_min,
        }


@dataclass(frozen=True)
class DictionaryInfo:
    """A stored dictionary with its members in number order."""

    name: str
    min_flip_distance: int
    parameters: dict[str, Any]
    created_at: datetime
    members: list[DictionaryMember]

    def counts(self) -> dict[int, int]:
        """Tags per k."""
        out: dict[int, int] = {}
        for m in self.members:
            out[m.k] = out.get(m.k, 0) + 1
        return dict(sorted(out.items()))


def check_dictionary_name(name: str) -> None:
    """Refuse a dictionary name that is not 1–100 letters, digits, ``_``, ``.``, ``-``.

    Parameters
    ----------
    name : str
        The proposed name (must start with a letter or digit).

    Raises
    ------
    UsageError
        The name has other characters or is too long.
    """
    if not _NAME.match(name):
        raise UsageError(f"dictionary name {name!r}: use letters, digits, '_', '.', '-' (up to 100 characters)")


def create_dictionary(
    db: Database, name: str, options: DictionaryOptions, *, progress: ProgressCallback | None = None
) -> DictionaryInfo:
    """Build and store a dictionary (see :class:`DictionaryOptions` for the documented choice).

    Parameters
    ----------
    db : Database
        An open database; with ``min_flip_distance`` ≥ 2 every k involved must be complete.
    name : str
        New dictionary name (see :func:`check_dictionary_name`).
    options : DictionaryOptions
        Filters, polarity, minimum flip distance and size bound.
    progress : ProgressCallback, optional
        Progress of computing the flip graph, when it is not stored yet.

    Returns
    -------
    DictionaryInfo
        The stored dictionary with its members in number order.

    Raises
    ------
    UsageError
        Bad name or options.
    DictionaryError
        The name exists, nothing matches, or a k is incomplete.
    """
    check_dictionary_name(name)
    if options.polarity not in ("normal", "inverted", "both"):
        raise UsageError(f"polarity must be normal, inverted or both, got {options.polarity!r}")
    if options.min_flip_distance < 1:
        raise UsageError("--min-flip-distance must be at least 1")
    if options.max_size is not None and options.max_size < 1:
        raise UsageError("--max-size must be at least 1")
    with db.session() as s:
        if s.execute(select(Dictionary.id).where(Dictionary.name == name)).first() is not None:
            raise DictionaryError(f"a dictionary named {name!r} exists already; delete it first or choose another name")
    candidates = select_tags(db, ks=options.ks, min_mp=options.min_mp, matchable=options.matchable)
    if not options.include_mirrors:
        candidates = [t for t in candidates if not t.chiral or t.lambda_text < t.mirror]
    if not candidates:
        raise DictionaryError(
            f"no order type matches the filters; nothing to put in the dictionary{missing_ks_note(db, options.ks)}"
        )
    ks = sorted({t.k for t in candidates})
    radius = options.min_flip_distance - 1
    if radius > 0:
        ensure_flip_graph(db, ks, progress=progress)
    candidates.sort(key=lambda t: (-t.mp, t.k, t.lambda_text))
    polarities = ["normal", "inverted"] if options.polarity == "both" else [options.polarity]
    chosen: list[TagRecord] = []
    adj = flip_adjacency(db, ks) if radius > 0 else {}
    with db.session() as s:
        blocked: set[int] = set()
        for t in candidates:
            if options.max_size is not None and len(chosen) * len(polarities) + len(polarities) > options.max_size:
                break
            if t.order_type_id in blocked:
                continue
            chosen.append(t)
            if radius > 0:
                blocked |= within_flips(adj, t.order_type_id, radius)
        if not chosen:
            raise DictionaryError(f"--max-size {options.max_size} is too small for --polarity {options.polarity}")
        d = Dictionary(
            name=name,
            min_flip_distance=options.min_flip_distance,
            parameters=json.dumps(options.as_json(), sort_keys=True),
            created_at=datetime.now(),
        )
        s.add(d)
        s.flush()
        number = 0
        for t in chosen:
            for p in polarities:
                s.add(
                    DictionaryTag(
                        dictionary_id=d.id,
                        number=number,
                        order_type_id=t.order_type_id,
                        polarity=p,
                        realization_id=t.realization_id,
                    )
                )
                number += 1
    return get_dictionary(db, name)


def list_dictionaries(db: Database) -> list[tuple[str, int, int, datetime]]:
    """Every stored dictionary, by name.

    Parameters
    ----------
    db : Database
        An open database.

    Returns
    -------
    list of (str, int, int, datetime)
        ``(name, min_flip_distance, number of tags, created_at)``.
    """
    with db.session() as s:
        rows = s.execute(
            select(
                Dictionary.name, Dictionary.min_flip_distance, func.count(DictionaryTag.number), Dictionary.created_at
            )
            .outerjoin(DictionaryTag, DictionaryTag.dictionary_id == Dictionary.id)
            .group_by(Dictionary.id)
            .order_by(Dictionary.name)
        ).all()
    return [(str(a), int(b), int(c), d) for a, b, c, d in rows]


def find_dictionary(session: Session, name: str) -> Dictionary:
    """The stored dictionary called ``name``.

    Parameters
    ----------
    session : Session
        An open session of the database.
    name : str
        Dictionary name.

    Returns
    -------
    Dictionary
        Its ORM row (members in ``tags``).

    Raises
    ------
    NotFoundError
        No dictionary of that name; the message points at ``ottag-db dictionary list``.
    """
    d = session.execute(select(Dictionary).where(Dictionary.name == name)).scalar_one_or_none()
    if d is None:
        raise NotFoundError(f"no dictionary named {name!r} (see `ottag-db dictionary list`)")
    return d


def dictionary_source_name(name: str) -> str:
    """The ``sources.file_name`` of the geometry ``dictionary import`` stored for dictionary ``name``.

    Parameters
    ----------
    name : str
        Dictionary name.

    Returns
    -------
    str
        ``"dictionary:NAME"``; that source goes when the dictionary is deleted.
    """
    return f"dictionary:{name}"


def dictionary_tag_records(db: Database, name: str) -> tuple[DictionaryInfo, list[TagRecord]]:
    """A stored dictionary and, per member (number order), the tag it is printed from.

    A member's tag is the realization the dictionary names (chosen by ``dictionary create``,
    stored by ``dictionary import``) with its stored layout and placement; a member of a
    dictionary made before database revision 0005 gets its order type's best realization.

    Parameters
    ----------
    db : Database
        An open database (only read).
    name : str
        Dictionary name.

    Returns
    -------
    (DictionaryInfo, list of TagRecord)
        The dictionary (members with the points and triangles of those tags) and the tags,
        one per member, with ``TagRecord.tag`` set to the member number.

    Raises
    ------
    NotFoundError
        No dictionary of that name.
    """
    with db.session() as s:
        d = find_dictionary(s, name)
        rows = [(m.number, m.order_type_id, m.polarity, m.realization_id) for m in d.tags]
        info_head = (d.name, d.min_flip_distance, json.loads(d.parameters), d.created_at)
        numbers = dict(
            s.execute(select(OrderType.id, OrderType.number).where(OrderType.id.in_([r[1] for r in rows]))).all()
        )
        pinned_ids = sorted({r[3] for r in rows if r[3] is not None})
        pinned = {
            r.id: tag_record(r.order_type, r)
            for r in s.execute(
                select(Realization)
                .join(LayoutRow, LayoutRow.realization_id == Realization.id)
                .where(Realization.id.in_(pinned_ids))
                .options(selectinload(Realization.layout), selectinload(Realization.order_type))
            ).scalars()
        }
    loose = sorted({r[1] for r in rows if r[3] is None or r[3] not in pinned})
    best = {t.order_type_id: t for t in select_tags(db, ids=loose)} if loose else {}
    members = []
    records = []
    for number, ot_id, polarity, rid in rows:
        t = pinned[rid] if rid is not None and rid in pinned else best[ot_id]
        records.append(dataclasses.replace(t, tag=number))
        members.append(
            DictionaryMember(
                number=number,
                lambda_text=t.lambda_text,
                k=t.k,
                polarity=polarity,
                order_type_id=ot_id,
                universal_number=numbers.get(ot_id),
                points=t.points.tolist(),
                triangles=[list(tri) for tri in t.triangles],
                mp=t.mp,
                unique_min=t.unique_min,
                realization_id=t.realization_id,
            )
        )
    info = DictionaryInfo(
        name=info_head[0],
        min_flip_distance=info_head[1],
        parameters=info_head[2],
        created_at=info_head[3],
        members=members,
    )
    return info, records


def get_dictionary(db: Database, name: str) -> DictionaryInfo:
    """A stored dictionary with every member (points and triangles of its tag realization).

    Parameters
    ----------
    db : Database
        An open database (only read).
    name : str
        Dictionary name.

    Returns
    -------
    DictionaryInfo
        Name, parameters and members in number order (see :func:`dictionary_tag_records`
        for which realization a member has).

    Raises
    ------
    NotFoundError
        No dictionary of that name.
    """
    return dictionary_tag_records(db, name)[0]


def delete_dictionary(db: Database, name: str) -> int:
    """Delete a dictionary and its members (and the geometry ``dictionary import`` stored for it).

    Parameters
    ----------
    db : Database
        An open database.
    name : str
        Dictionary name.

    Returns
    -------
    int
        How many tags it had.

    Raises
    ------
    NotFoundError
        No dictionary of that name.
    """
    with db.session() as s:
        d = find_dictionary(s, name)
        n = len(d.tags)
        s.delete(d)  # members go with it (delete-orphan cascade)
        s.flush()
        # The geometry `dictionary import` stored goes too (realizations and layouts cascade).
        s.execute(delete(Source).where(Source.file_name == dictionary_source_name(name)))
    return n
