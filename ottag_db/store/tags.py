"""Tag reads: each order type's best realization with its stored layout and placement.

Only reads: layouts and placements are written by ``import`` / migration 0004
(:mod:`ottag_db.store.layouts`), so export works on a read-only database.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session, selectinload

from ottag_db.store.db import Database
from ottag_db.store.models import LayoutRow, OrderType, Realization

__all__ = ["TagRecord", "select_tags", "tag_record"]


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


def tag_record(o: OrderType, r: Realization) -> TagRecord:
    """The printable tag of realization ``r`` of order type ``o``.

    Parameters
    ----------
    o : OrderType
        The order type (ORM row).
    r : Realization
        One of its realizations, with its stored layout loaded (``r.layout`` not None).

    Returns
    -------
    TagRecord
        Points in file order, the stored triangles and placement, MP in grid units.
    """
    lay = r.layout
    if lay is None:  # every realization of a drawable k gets a layout at import
        raise ValueError(f"realization {r.id} has no stored layout")
    return TagRecord(
        order_type_id=o.id,
        lambda_text=o.lambda_text,
        k=o.k,
        mp=float(r.mp),
        unique_min=bool(o.unique_min),
        chiral=bool(o.chiral),
        mirror=o.mirror_lambda_text,
        realization_id=r.id,
        points=r.points(),
        labeling=r.labeling(),
        triangles=tuple(lay.triangle_list()),
        placement=np.array(json.loads(lay.placement), dtype=np.float64),
        printed_mp_unit=float(lay.printed_mp_unit),
        layout_score=float(lay.score),
    )


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
    """Tags matching the filters, ordered by k then canonical λ (deterministic); only reads.

    Parameters
    ----------
    db : Database
        An open database (may be read-only).
    ks : sequence of int
        Only these point counts (empty: all).
    min_mp : float, optional
        Only tags whose realization has MP ≥ ``min_mp``, grid units (as the paper's Table 7).
    matchable : bool
        Only order types with a unique minimal ordering.
    lambdas : sequence of str
        Only these canonical IDs (text form ``k:digits``).
    ids : sequence of int
        Only these order-type database ids.

    Returns
    -------
    list of TagRecord
        Each order type's best realization (largest MP, then smallest id) that has a stored
        layout; k = 4 order types have none and are skipped.
    """
    with db.session() as s:
        q = select(OrderType).order_by(OrderType.k, OrderType.lambda_text)
        if ks:
            q = q.where(OrderType.k.in_(list(ks)))
        if matchable:
            q = q.where(OrderType.unique_min.is_(True))
        if lambdas:
            q = q.where(OrderType.lambda_text.in_(list(lambdas)))
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
            out.append(tag_record(o, r))
    return out
