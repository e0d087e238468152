"""The stored flip graph: order types one triple-flip apart, computed once per complete k."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from ottag_db.core.canonical import canonicalize_lambdas, mirror_lambdas
from ottag_db.core.flips import flip_edges
from ottag_db.core.geometry import lambda_matrices
from ottag_db.core.types import COMPLETE_COUNTS, ProgressCallback
from ottag_db.errors import DictionaryError, NotFoundError
from ottag_db.store.db import Database
from ottag_db.store.models import FlipEdgeRow, FlipGraphStatus, OrderType, Realization, coordinates_from_blob
from ottag_db.store.queries import find_order_type

__all__ = ["ensure_flip_graph", "flip_adjacency", "neighbours", "within_flips"]

# Edge rows per INSERT batch (k = 9 stores about 4 million).
_INSERT_BATCH = 200_000
# Text of a triple coded 100 a + 10 b + c (labels 0 … 9), as stored: "a,b,c".
_TRIPLE_TEXT = {100 * a + 10 * b + c: f"{a},{b},{c}" for a in range(10) for b in range(10) for c in range(10)}


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
    edges are confirmed by orientations (:func:`ottag_db.core.flips.flip_edges`). Only one
    order type per reflection pair is flipped: the mirror image of an edge ``A → B`` is the
    edge ``mirror(A) → mirror(B)`` (the flipped triple renamed into the mirror's canonical
    labels), so the other half comes from symmetry. Every edge is stored in both directions
    with its triple (k = 9: about 4 million rows; see the README). This writes (once per k);
    dictionary creation calls it.

    Parameters
    ----------
    db : Database
        An open database holding every order type of each k in ``ks``.
    ks : sequence of int
        Point counts.
    progress : ProgressCallback, optional
        Passed on to :func:`ottag_db.core.flips.flip_edges` ((order type, triple) pairs).

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
            edges = _edge_arrays(pts, texts, progress) if k >= 4 else np.zeros((0, 3), dtype=np.int64)
            ids = np.asarray(ot_ids, dtype=np.int64)
            conn = s.connection()
            for start in range(0, edges.shape[0], _INSERT_BATCH):
                part = edges[start : start + _INSERT_BATCH]
                values = [
                    (a, b, _TRIPLE_TEXT[c])
                    for a, b, c in zip(
                        ids[part[:, 0]].tolist(), ids[part[:, 1]].tolist(), part[:, 2].tolist(), strict=True
                    )
                ]
                if conn.dialect.name == "sqlite":
                    conn.exec_driver_sql(
                        "INSERT INTO flip_edges (source_id, target_id, triple) VALUES (?, ?, ?)", values
                    )
                else:
                    s.execute(
                        FlipEdgeRow.__table__.insert(),  # type: ignore[attr-defined]
                        [{"source_id": a, "target_id": b, "triple": t} for a, b, t in values],
                    )
            s.add(FlipGraphStatus(k=k, order_types=len(ot_ids), edges=int(edges.shape[0]), computed_at=datetime.now()))
            out[k] = int(edges.shape[0])
    return out


def _edge_arrays(pts: NDArray[np.float64], texts: list[str], progress: ProgressCallback | None) -> NDArray[np.int64]:
    """``(E, 3)`` rows ``(source index, target index, triple code)`` of every edge among ``texts``.

    Flips one order type per reflection pair and adds the mirror image of each edge; the
    triple ``(a, b, c)`` is coded ``100 a + 10 b + c`` (see ``_TRIPLE_TEXT``). Rows are unique
    and sorted (arrays, not Python tuples: k = 9 has about 4 million edges).
    """
    index_of = {t: i for i, t in enumerate(texts)}
    # In chunks: the orientations of all 316,809 nine-point sets at once would take 1.8 GB.
    lam = np.concatenate([lambda_matrices(pts[i : i + 16384]) for i in range(0, pts.shape[0], 16384)])
    mirror = canonicalize_lambdas(mirror_lambdas(lam))
    mirror_texts = mirror.texts()
    mirror_index = np.array([index_of.get(t, -1) for t in mirror_texts], dtype=np.int64)
    # One per reflection pair (the smaller ID), or every type whose mirror is missing.
    own = np.array([m < 0 or t <= mt for t, mt, m in zip(texts, mirror_texts, mirror_index, strict=True)])
    edges = flip_edges(pts, texts, index_of, sources=np.flatnonzero(own), progress=progress)
    code = np.array([100, 10, 1], dtype=np.int64)
    rows = [np.stack([edges.source, edges.target, edges.triple @ code], axis=1)]
    # The mirror image of A → B: label l of A is label inverse[A, l] of mirror(A).
    ok = (mirror_index[edges.source] >= 0) & (mirror_index[edges.target] >= 0)
    src, tgt, tri = edges.source[ok], edges.target[ok], edges.triple[ok]
    inverse = np.argsort(mirror.labelings, axis=1)
    renamed = np.sort(np.take_along_axis(inverse[src], tri, axis=1), axis=1)
    rows.append(np.stack([mirror_index[src], mirror_index[tgt], renamed @ code], axis=1))
    out: NDArray[np.int64] = np.unique(np.concatenate(rows), axis=0)
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
