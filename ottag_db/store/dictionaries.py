"""Named tag dictionaries: create (greedy, with a minimum flip distance), list, get and delete.

Files (JSON/CSV) are in :mod:`ottag_db.store.dictionary_files`, decoder lookups in
:mod:`ottag_db.store.lookups`, the flip graph in :mod:`ottag_db.store.flipgraph`.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from ottag_db.core.types import ProgressCallback
from ottag_db.errors import DictionaryError, NotFoundError, UsageError
from ottag_db.store.db import Database
from ottag_db.store.flipgraph import ensure_flip_graph, flip_adjacency, within_flips
from ottag_db.store.models import Dictionary, DictionaryTag, OrderType
from ottag_db.store.tags import TagRecord, select_tags

__all__ = [
    "DictionaryInfo",
    "DictionaryMember",
    "DictionaryOptions",
    "check_dictionary_name",
    "create_dictionary",
    "delete_dictionary",
    "find_dictionary",
    "get_dictionary",
    "list_dictionaries",
]

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$")


@dataclass(frozen=True)
class DictionaryOptions:
    """How to build a dictionary.

    Candidates are the drawable order types (k = 3, 5 … 8) passing the filters (``min_mp`` in
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
        raise DictionaryError("no order type matches the filters; nothing to put in the dictionary")
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
                s.add(DictionaryTag(dictionary_id=d.id, number=number, order_type_id=t.order_type_id, polarity=p))
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
        Name, parameters and members in number order.

    Raises
    ------
    NotFoundError
        No dictionary of that name.
    """
    with db.session() as s:
        d = find_dictionary(s, name)
        rows = [(m.number, m.order_type_id, m.polarity) for m in d.tags]
        info_head = (d.name, d.min_flip_distance, json.loads(d.parameters), d.created_at)
        numbers = dict(
            s.execute(select(OrderType.id, OrderType.number).where(OrderType.id.in_([r[1] for r in rows]))).all()
        )
    tags = {t.order_type_id: t for t in select_tags(db, ids=sorted({r[1] for r in rows}))}
    members = []
    for number, ot_id, polarity in rows:
        t = tags[ot_id]
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
            )
        )
    return DictionaryInfo(
        name=info_head[0],
        min_flip_distance=info_head[1],
        parameters=info_head[2],
        created_at=info_head[3],
        members=members,
    )


def delete_dictionary(db: Database, name: str) -> int:
    """Delete a dictionary and its members.

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
    return n
