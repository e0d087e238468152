"""Tests of ottag_db.store.flipgraph: the stored graph equals the one flipped from every order type."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from sqlalchemy import select

from ottag_db.core.flips import flip_edges
from ottag_db.store.db import open_database
from ottag_db.store.flipgraph import ensure_flip_graph
from ottag_db.store.models import FlipEdgeRow, FlipGraphStatus, OrderType, Realization, coordinates_from_blob


def test_mirror_symmetry_gives_the_directly_flipped_graph(bundled_db_path: Path, tmp_path: Path) -> None:
    """Only one order type per reflection pair is flipped; the rest comes from symmetry."""
    path = tmp_path / "g.sqlite"
    shutil.copy(bundled_db_path, path)
    db = open_database(path)
    try:
        counts = ensure_flip_graph(db, [6, 7, 8])
        with db.session() as s:
            for k in (6, 7, 8):
                rows = s.execute(
                    select(
                        OrderType.id,
                        OrderType.lambda_text,
                        OrderType.unique_min,
                        Realization.coordinates,
                        Realization.canonical_labeling,
                    )
                    .join(Realization, Realization.order_type_id == OrderType.id)
                    .where(OrderType.k == k)
                    .order_by(OrderType.lambda_text, Realization.mp.desc(), Realization.id)
                ).all()
                first = {}
                for r in rows:
                    first.setdefault(r[0], r)
                ids = list(first)
                pts = np.stack([coordinates_from_blob(first[i][3])[[int(c) for c in first[i][4]]] for i in ids])
                e = flip_edges(pts.astype(float), [first[i][1] for i in ids])
                direct = {
                    (ids[a], ids[b], ",".join(map(str, t)))
                    for a, b, t in zip(e.source.tolist(), e.target.tolist(), e.triple.tolist(), strict=True)
                }
                stored: set[tuple[int, int, str]] = set(
                    s.execute(
                        select(FlipEdgeRow.source_id, FlipEdgeRow.target_id, FlipEdgeRow.triple)
                        .join(OrderType, OrderType.id == FlipEdgeRow.source_id)
                        .where(OrderType.k == k)
                    ).all()
                )
                assert {(a, b) for a, b, _ in stored} == {(a, b) for a, b, _ in direct}, k
                # A unique minimum fixes the labels, so the triple is the same whichever way found.
                unique = {i for i in ids if first[i][2]}
                assert {x for x in stored if x[0] in unique} == {x for x in direct if x[0] in unique}, k
                assert counts[k] == len(stored) == s.get(FlipGraphStatus, k).edges
    finally:
        db.close()
