"""Universal numbers, the stored flip graph and named tag dictionaries with a minimum flip distance."""

from __future__ import annotations

import csv
import io
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from ottag_db.core.canonical import lambda_text, parse_lambda_text
from ottag_db.core.flips import flip_neighbours
from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.core.types import ProgressCallback
from ottag_db.errors import DictionaryError, NotFoundError, UsageError
from ottag_db.store.db import Database
from ottag_db.store.models import (
    Dictionary,
    DictionaryTag,
    FlipEdgeRow,
    FlipGraphStatus,
    OrderType,
    Realization,
    coordinates_from_blob,
)
from ottag_db.store.numbering import COMPLETE_COUNTS, assign_numbers
from ottag_db.store.tags import TagRecord, load_lookup, select_tags

__all__ = [
    "COMPLETE_COUNTS",
    "DictionaryInfo",
    "DictionaryMember",
    "DictionaryOptions",
    "assign_numbers",
    "create_dictionary",
    "delete_dictionary",
    "dictionary_lookup",
    "ensure_flip_graph",
    "export_dictionary",
    "get_dictionary",
    "import_dictionary",
    "list_dictionaries",
    "neighbour_members",
    "neighbours",
]

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$")


def _require_complete(s: Session, k: int) -> None:
    n = s.execute(select(func.count()).select_from(OrderType).where(OrderType.k == k)).scalar_one()
    if COMPLETE_COUNTS.get(k) != n:
        raise DictionaryError(
            f"the flip graph of k = {k} needs every order type of {k} points "
            f"({COMPLETE_COUNTS.get(k, '?')} with mirrors; the database has {n}): run `ottag-db import` "
            "(bundled data) or import the reference files with --with-mirrors"
        )


def ensure_flip_graph(db: Database, ks: Sequence[int], *, progress: ProgressCallback | None = None) -> dict[int, int]:
    """Compute and store the flip graph of each complete k in ``ks`` not computed yet.

    Every order type's best realization (canonical order) is flipped triple by triple;
    edges are confirmed by orientations (:func:`ottag_db.core.flips.flip_neighbours`).
    Returns ``{k: edges}`` for the ks now stored. Raises :class:`DictionaryError` when a k
    is incomplete.
    """
    out: dict[int, int] = {}
    with db.session() as s:
        for k in sorted(set(ks)):
            status = s.get(FlipGraphStatus, k)
            if status is not None:
                out[k] = status.edges
                continue
            _require_complete(s, k)
            rows = s.execute(
                select(
                    OrderType.id, OrderType.canonical_lambda, Realization.coordinates, Realization.canonical_labeling
                )
                .join(Realization, Realization.order_type_id == OrderType.id)
                .where(OrderType.k == k)
                .order_by(OrderType.canonical_lambda, Realization.mp.desc(), Realization.id)
            ).all()
            first: dict[int, tuple[str, bytes, str]] = {}
            for ot_id, text, blob, labeling in rows:
                first.setdefault(ot_id, (text, blob, labeling))
            ot_ids = list(first)
            texts = [first[i][0] for i in ot_ids]
            pts = np.stack([coordinates_from_blob(first[i][1])[[int(c) for c in first[i][2]]] for i in ot_ids]).astype(
                np.float64
            )
            edges = flip_neighbours(pts, texts, progress=progress) if k >= 4 else []
            unique = {(ot_ids[e.source], ot_ids[e.target], ",".join(map(str, e.triple))) for e in edges}
            if unique:
                s.execute(
                    FlipEdgeRow.__table__.insert(),  # type: ignore[attr-defined]
                    [{"source_id": a, "target_id": b, "triple": t} for a, b, t in sorted(unique)],
                )
            s.add(FlipGraphStatus(k=k, order_types=len(ot_ids), edges=len(unique), computed_at=datetime.now()))
            out[k] = len(unique)
    return out


def neighbours(db: Database, ident: str | int) -> list[tuple[str, str]]:
    """Flip neighbours ``(lambda, triple)`` of one order type (the flip graph must be stored)."""
    with db.session() as s:
        ot = _order_type(s, ident)
        ensure = s.get(FlipGraphStatus, ot.k)
        if ensure is None:
            raise DictionaryError(f"the flip graph of k = {ot.k} is not computed yet: create a dictionary first")
        rows = s.execute(
            select(OrderType.canonical_lambda, FlipEdgeRow.triple)
            .join(FlipEdgeRow, FlipEdgeRow.target_id == OrderType.id)
            .where(FlipEdgeRow.source_id == ot.id)
            .order_by(OrderType.canonical_lambda, FlipEdgeRow.triple)
        ).all()
    return [(str(a), str(b)) for a, b in rows]


def _order_type(s: Session, ident: str | int) -> OrderType:
    if isinstance(ident, int) or str(ident).isdigit():
        ot = s.get(OrderType, int(ident))
    else:
        mat = parse_lambda_text(str(ident))
        ot = s.execute(
            select(OrderType).where(OrderType.k == mat.shape[0], OrderType.canonical_lambda == lambda_text(mat))
        ).scalar_one_or_none()
    if ot is None:
        raise NotFoundError(f"order type {ident} is not in the database")
    return ot


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


def _check_name(name: str) -> None:
    if not _NAME.match(name):
        raise UsageError(f"dictionary name {name!r}: use letters, digits, '_', '.', '-' (up to 100 characters)")


def _adjacency(s: Session, ks: Sequence[int]) -> dict[int, set[int]]:
    adj: dict[int, set[int]] = {}
    rows = s.execute(
        select(FlipEdgeRow.source_id, FlipEdgeRow.target_id)
        .join(OrderType, OrderType.id == FlipEdgeRow.source_id)
        .where(OrderType.k.in_(list(ks)))
    ).all()
    for a, b in rows:
        if a != b:
            adj.setdefault(int(a), set()).add(int(b))
            adj.setdefault(int(b), set()).add(int(a))
    return adj


def _within(adj: dict[int, set[int]], start: int, radius: int) -> set[int]:
    seen = {start}
    frontier = {start}
    for _ in range(radius):
        frontier = {n for f in frontier for n in adj.get(f, ())} - seen
        seen |= frontier
    return seen


def create_dictionary(
    db: Database, name: str, options: DictionaryOptions, *, progress: ProgressCallback | None = None
) -> DictionaryInfo:
    """Build and store a dictionary (see :class:`DictionaryOptions` for the documented choice)."""
    _check_name(name)
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
    with db.session() as s:
        adj = _adjacency(s, ks) if radius > 0 else {}
        blocked: set[int] = set()
        for t in candidates:
            if options.max_size is not None and len(chosen) * len(polarities) + len(polarities) > options.max_size:
                break
            if t.order_type_id in blocked:
                continue
            chosen.append(t)
            if radius > 0:
                blocked |= _within(adj, t.order_type_id, radius)
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
    """``(name, min_flip_distance, tags, created_at)`` of every dictionary, by name."""
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


def get_dictionary(db: Database, name: str) -> DictionaryInfo:
    """A stored dictionary with every member (points and triangles of its tag realization)."""
    with db.session() as s:
        d = s.execute(select(Dictionary).where(Dictionary.name == name)).scalar_one_or_none()
        if d is None:
            raise NotFoundError(f"no dictionary named {name!r} (see `ottag-db dictionary list`)")
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
    """Delete a dictionary; returns how many tags it had."""
    with db.session() as s:
        d = s.execute(select(Dictionary).where(Dictionary.name == name)).scalar_one_or_none()
        if d is None:
            raise NotFoundError(f"no dictionary named {name!r}")
        n = len(d.tags)
        s.delete(d)  # members go with it (delete-orphan cascade)
    return n


def export_dictionary(db: Database, name: str, fmt: str = "json") -> str:
    """The dictionary as JSON (``name``, ``min_flip_distance``, ``parameters``, ``tags``) or CSV."""
    info = get_dictionary(db, name)
    if fmt == "json":
        return json.dumps(
            {
                "format": "ottag-dictionary/1",
                "name": info.name,
                "min_flip_distance": info.min_flip_distance,
                "parameters": info.parameters,
                "orientation": "screen coordinates (x right, y down); p left of pi->pj when "
                "(xj-xi)(yp-yi)-(yj-yi)(xp-xi) < 0",
                "tags": [m.as_json() for m in info.members],
            },
            indent=1,
        )
    if fmt == "csv":
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["number", "lambda", "k", "polarity", "universal_number", "points", "triangles", "mp", "unique_min"])
        for m in info.members:
            w.writerow(
                [
                    m.number,
                    m.lambda_text,
                    m.k,
                    m.polarity,
                    "" if m.universal_number is None else m.universal_number,
                    " ".join(f"{x},{y}" for x, y in m.points),
                    " ".join(",".join(str(i) for i in t) for t in m.triangles),
                    f"{m.mp:.6f}",
                    int(m.unique_min),
                ]
            )
        return buf.getvalue()
    raise UsageError(f"format must be json or csv, got {fmt!r}")


def import_dictionary(db: Database, text: str, *, source: str = "<input>", name: str | None = None) -> DictionaryInfo:
    """Store a dictionary from its JSON export; every member's order type must be in the database."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DictionaryError(f"{source}: not JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})") from exc
    if not isinstance(data, dict) or "tags" not in data or "name" not in data:
        raise DictionaryError(f"{source}: not an ottag dictionary export (needs 'name' and 'tags')")
    dict_name = name or str(data["name"])
    _check_name(dict_name)
    tags = data["tags"]
    if not isinstance(tags, list) or not tags:
        raise DictionaryError(f"{source}: 'tags' must be a non-empty list")
    with db.session() as s:
        if s.execute(select(Dictionary.id).where(Dictionary.name == dict_name)).first() is not None:
            raise DictionaryError(f"a dictionary named {dict_name!r} exists already; delete it or pass --name")
        d = Dictionary(
            name=dict_name,
            min_flip_distance=int(data.get("min_flip_distance", 1)),
            parameters=json.dumps(data.get("parameters", {}), sort_keys=True),
            created_at=datetime.now(),
        )
        s.add(d)
        s.flush()
        seen: set[int] = set()
        for i, tag in enumerate(tags):
            try:
                number = int(tag["number"])
                polarity = str(tag.get("polarity", "normal"))
                mat = parse_lambda_text(str(tag["lambda"]))
            except (KeyError, TypeError, ValueError) as exc:
                raise DictionaryError(f"{source}: tag {i}: needs 'number', 'lambda' and 'polarity' ({exc})") from exc
            if polarity not in ("normal", "inverted"):
                raise DictionaryError(f"{source}: tag {i}: polarity must be normal or inverted")
            if number in seen:
                raise DictionaryError(f"{source}: tag {i}: number {number} appears twice")
            seen.add(number)
            text_id = lambda_text(mat)
            ot_id = s.execute(
                select(OrderType.id).where(OrderType.k == mat.shape[0], OrderType.canonical_lambda == text_id)
            ).scalar_one_or_none()
            if ot_id is None:
                raise DictionaryError(
                    f"{source}: tag {number}: order type {text_id} is not in the database; "
                    "import the bundled data first"
                )
            s.add(DictionaryTag(dictionary_id=d.id, number=number, order_type_id=ot_id, polarity=polarity))
    return get_dictionary(db, dict_name)


def dictionary_lookup(db: Database, name: str | None) -> MemoryLookup:
    """Decoder lookup: the whole database, or only one dictionary's members (with tag numbers).

    A member's ``LookupEntry.extra["tags"]`` maps polarity → tag number; ``tag`` is the number
    of its first polarity.
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
    """
    with db.session() as s:
        d = s.execute(select(Dictionary).where(Dictionary.name == name)).scalar_one_or_none()
        if d is None:
            raise NotFoundError(f"no dictionary named {name!r}")
        rows = s.execute(
            select(OrderType.canonical_lambda, func.min(DictionaryTag.number))
            .join(FlipEdgeRow, FlipEdgeRow.source_id == OrderType.id)
            .join(DictionaryTag, DictionaryTag.order_type_id == FlipEdgeRow.target_id)
            .where(DictionaryTag.dictionary_id == d.id, FlipEdgeRow.source_id != FlipEdgeRow.target_id)
            .group_by(OrderType.canonical_lambda)
        ).all()
    return {str(t): int(n) for t, n in rows}
