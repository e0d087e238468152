"""The stored flip graph: order types one triple-flip apart, computed once per complete k."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from ottag_db.core.flips import flip_neighbours
from ottag_db.core.types import COMPLETE_COUNTS, ProgressCallback
from ottag_db.errors import DictionaryError, NotFoundError
from ottag_db.store.db import Database
from ottag_db.store.models import FlipEdgeRow, FlipGraphStatus, OrderType, Realization, coordinates_from_blob
from ottag_db.store.queries import find_order_type

__all__ = ["ensure_flip_graph", "flip_adjacency", "neighbours", "within_flips"]


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
    This writes (once per k); dictionary creation calls it.

    Parameters
    ----------
    db : Database
        An open database holding every order type of each k in ``ks``.
    ks : sequence of int
        Point counts.
    progress : ProgressCallback, optional
        Passed on to :func:`ottag_db.core.flips.flip_neighbours`.

    Returns
    -------
    dict of int to int
        ``{k: number of stored edges}`` for every k in ``ks``.

    Raises
    ------
    DictionaryError
        A k is incomplete (the graph needs every order type of k points).
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
                select(OrderType.id, OrderType.lambda_text, Realization.coordinates, Realization.canonical_labeling)
                .join(Realization, Realization.order_type_id == OrderType.id)
                .where(OrderType.k == k)
                .order_by(OrderType.lambda_text, Realization.mp.desc(), Realization.id)
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
    """Flip neighbours of one order type (the flip graph of its k must be stored).

    Parameters
    ----------
    db : Database
        An open database.
    ident : str or int
        Database id or ID text (see :func:`ottag_db.store.queries.find_order_type`).

    Returns
    -------
    list of (str, str)
        ``(canonical λ of the neighbour, flipped triple "a,b,c" in canonical labels)``,
        sorted.

    Raises
    ------
    NotFoundError
        Unknown order type.
    DictionaryError
        The flip graph of its k is not stored yet.
    """
    with db.session() as s:
        ot = find_order_type(s, ident)
        if ot is None:
            raise NotFoundError(f"order type {ident} is not in the database")
        if s.get(FlipGraphStatus, ot.k) is None:
            raise DictionaryError(f"the flip graph of k = {ot.k} is not computed yet: create a dictionary first")
        rows = s.execute(
            select(OrderType.lambda_text, FlipEdgeRow.triple)
            .join(FlipEdgeRow, FlipEdgeRow.target_id == OrderType.id)
            .where(FlipEdgeRow.source_id == ot.id)
            .order_by(OrderType.lambda_text, FlipEdgeRow.triple)
        ).all()
    return [(str(a), str(b)) for a, b in rows]


def flip_adjacency(db: Database, ks: Sequence[int]) -> dict[int, set[int]]:
    """The stored flip graph of some k as an undirected adjacency (self-loops dropped).

    Parameters
    ----------
    db : Database
        An open database.
    ks : sequence of int
        Point counts whose edges to load.

    Returns
    -------
    dict of int to set of int
        Order-type database id → ids one flip away.
    """
    adj: dict[int, set[int]] = {}
    with db.session() as s:
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


def within_flips(adj: dict[int, set[int]], start: int, radius: int) -> set[int]:
    """Order types at most ``radius`` flips from ``start`` (breadth-first over ``adj``).

    Parameters
    ----------
    adj : dict of int to set of int
        Adjacency from :func:`flip_adjacency`.
    start : int
        Order-type database id.
    radius : int
        Number of flips (0: only ``start``).

    Returns
    -------
    set of int
        Ids within the radius, ``start`` included.
    """
    seen = {start}
    frontier = {start}
    for _ in range(radius):
        frontier = {n for f in frontier for n in adj.get(f, ())} - seen
        seen |= frontier
    return seen
