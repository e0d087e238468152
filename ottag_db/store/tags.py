"""Tags stored in the database: layouts and placements per realization, tag selection, decoder lookup."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session, selectinload

from ottag_db.core.geometry import maximal_perturbations
from ottag_db.core.layout import compute_layouts, layout_supported
from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.core.placement import tag_placements
from ottag_db.core.types import ProgressCallback
from ottag_db.errors import NotFoundError
from ottag_db.store.db import Database
from ottag_db.store.models import LayoutRow, OrderType, Realization, coordinates_from_blob

__all__ = ["TagRecord", "ensure_layouts", "load_lookup", "select_tags"]


@dataclass(frozen=True)
class TagRecord:
    """One printable tag: an order type with its best realization, layout and placement.

    ``points`` are file coordinates in file order; ``labeling[l]`` is the file index of the
    point with canonical label ``l``; ``placement`` the ``(2, 3)`` affine map to data-area
    unit coordinates; ``mp`` in grid units; ``printed_mp_unit`` in data-area sides.
    """

    order_type_id: int
    lambda_text: str
    k: int
    mp: float
    unique_min: bool
    chiral: bool
    mirror: str
    realization_id: int
    points: NDArray[np.int64]
    labeling: tuple[int, ...]
    triangles: tuple[tuple[int, int, int], ...]
    placement: NDArray[np.float64]
    printed_mp_unit: float
    layout_score: float
    tag: int | None = None


def ensure_layouts(db: Database, *, progress: ProgressCallback | None = None, chunk: int = 512) -> int:
    """Compute and store the layout and placement of every realization that has none.

    Only k = 3 and 5 … 8 get layouts (k = 4 cannot be drawn, see :mod:`ottag_db.core.layout`).
    Returns the number of layouts added. Runs in one transaction.
    """
    with db.session() as s:
        missing = s.execute(
            select(Realization.id, Realization.coordinates, OrderType.k)
            .join(OrderType, OrderType.id == Realization.order_type_id)
            .outerjoin(LayoutRow, LayoutRow.realization_id == Realization.id)
            .where(LayoutRow.id.is_(None))
            .order_by(OrderType.k, Realization.id)
        ).all()
        todo = [(rid, blob, k) for rid, blob, k in missing if layout_supported(k)]
        done = 0
        for k in sorted({k for _, _, k in todo}):
            rows = [(rid, blob) for rid, blob, kk in todo if kk == k]
            for start in range(0, len(rows), chunk):
                part = rows[start : start + chunk]
                pts = np.stack([coordinates_from_blob(b) for _, b in part]).astype(np.float64)
                layouts = compute_layouts(pts)
                maps = tag_placements(pts)
                placed = np.einsum("bxy,bky->bkx", maps[:, :, :2], pts) + maps[:, None, :, 2]
                printed = maximal_perturbations(placed)
                for (rid, _), lay, m, pm in zip(part, layouts, maps, printed, strict=True):
                    s.add(
                        LayoutRow(
                            realization_id=rid,
                            triangles=";".join(",".join(str(i) for i in t) for t in lay.triangles),
                            triangle_count=len(lay.triangles),
                            min_angle_deg=float(lay.min_angle_deg),
                            min_side=float(lay.min_side),
                            min_gap=None if lay.min_gap is None else float(lay.min_gap),
                            min_shared_gap_deg=None
                            if lay.min_shared_gap_deg is None
                            else float(lay.min_shared_gap_deg),
                            score=float(lay.score),
                            placement=json.dumps(np.round(m, 12).tolist()),
                            printed_mp_unit=float(pm),
                        )
                    )
                s.flush()
                done += len(part)
                if progress is not None:
                    progress(done, len(todo))
    return done


def _best_realizations(s: Session, order_type_ids: Sequence[int]) -> dict[int, Realization]:
    best: dict[int, Realization] = {}
    for start in range(0, len(order_type_ids), 5000):
        part = list(order_type_ids[start : start + 5000])
        rows = (
            s.execute(
                select(Realization)
                .join(LayoutRow, LayoutRow.realization_id == Realization.id)
                .where(Realization.order_type_id.in_(part))
                .options(selectinload(Realization.layout))
                .order_by(Realization.order_type_id, Realization.mp.desc(), Realization.id)
            )
            .scalars()
            .all()
        )
        for r in rows:
            best.setdefault(r.order_type_id, r)
    return best


def select_tags(
    db: Database,
    *,
    ks: Sequence[int] = (),
    min_mp: float | None = None,
    matchable: bool = False,
    lambdas: Sequence[str] = (),
    ids: Sequence[int] = (),
) -> list[TagRecord]:
    """Tags matching the filters, ordered by k then canonical λ (deterministic).

    ``min_mp`` is in grid units (as Table 7), on the tag's realization. k = 4 order types
    are skipped (no layout). Layouts missing in the database are computed first.
    """
    ensure_layouts(db)
    with db.session() as s:
        q = select(OrderType).order_by(OrderType.k, OrderType.canonical_lambda)
        if ks:
            q = q.where(OrderType.k.in_(list(ks)))
        if matchable:
            q = q.where(OrderType.unique_min.is_(True))
        if lambdas:
            q = q.where(OrderType.canonical_lambda.in_(list(lambdas)))
        if ids:
            q = q.where(OrderType.id.in_(list(ids)))
        ots = s.execute(q).scalars().all()
        best = _best_realizations(s, [o.id for o in ots])
        out: list[TagRecord] = []
        for o in ots:
            r = best.get(o.id)
            if r is None or r.layout is None:
                continue
            if min_mp is not None and r.mp < min_mp:
                continue
            lay = r.layout
            out.append(
                TagRecord(
                    order_type_id=o.id,
                    lambda_text=o.canonical_lambda,
                    k=o.k,
                    mp=float(r.mp),
                    unique_min=bool(o.unique_min),
                    chiral=bool(o.chiral),
                    mirror=o.mirror_lambda,
                    realization_id=r.id,
                    points=r.points(),
                    labeling=r.labeling(),
                    triangles=tuple(lay.triangle_list()),
                    placement=np.array(json.loads(lay.placement), dtype=np.float64),
                    printed_mp_unit=float(lay.printed_mp_unit),
                    layout_score=float(lay.score),
                )
            )
    return out


def load_lookup(db: Database, *, ks: Sequence[int] = ()) -> MemoryLookup:
    """All order types (optionally only some k) with every realization, for the decoder.

    Realization points are given in canonical label order, as :class:`LookupEntry` requires.
    """
    with db.session() as s:
        q = select(OrderType.id, OrderType.k, OrderType.canonical_lambda, OrderType.unique_min)
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
