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
from sqlalchemy import func, select

from ottag_db.store.db import Database
from ottag_db.store.models import LayoutRow, OrderType, Realization, coordinates_from_blob, triangles_from_text

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
    return _record(
        (o.id, o.lambda_text, o.k, o.unique_min, o.chiral, o.mirror_lambda_text),
        (r.id, r.mp, r.coordinates, r.canonical_labeling),
        (lay.triangles, lay.placement, lay.printed_mp_unit, lay.score),
    )


def _record(
    order_type: tuple[int, str, int, bool, bool, str],
    realization: tuple[int, float, bytes, str],
    layout: tuple[str, str, float, float],
) -> TagRecord:
    """A :class:`TagRecord` from the stored columns (the one place that decodes them)."""
    ot_id, text, k, unique_min, chiral, mirror = order_type
    rid, mp, coordinates, labeling = realization
    triangles, placement, printed_mp_unit, score = layout
    return TagRecord(
        order_type_id=int(ot_id),
        lambda_text=text,
        k=int(k),
        mp=float(mp),
        unique_min=bool(unique_min),
        chiral=bool(chiral),
        mirror=mirror,
        realization_id=int(rid),
        points=coordinates_from_blob(coordinates),
        labeling=tuple(int(c) for c in labeling),
        triangles=triangles_from_text(triangles),
        placement=np.array(json.loads(placement), dtype=np.float64),
        printed_mp_unit=float(printed_mp_unit),
        layout_score=float(score),
    )


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
    # One query: every realization with a layout, ranked per order type by (MP desc, id);
    # rows, not ORM objects (a nine-point database has 316,809 order types).
    rank = (
        func.row_number()
        .over(partition_by=Realization.order_type_id, order_by=(Realization.mp.desc(), Realization.id))
        .label("rank")
    )
    ranked = (
        select(
            OrderType.id.label("ot_id"),
            OrderType.k,
            OrderType.lambda_text.label("lambda_text"),
            OrderType.unique_min,
            OrderType.chiral,
            OrderType.mirror_lambda_text.label("mirror_text"),
            Realization.id.label("rid"),
            Realization.mp,
            Realization.coordinates,
            Realization.canonical_labeling,
            LayoutRow.triangles,
            LayoutRow.placement,
            LayoutRow.printed_mp_unit,
            LayoutRow.score,
            rank,
        )
        .join(Realization, Realization.order_type_id == OrderType.id)
        .join(LayoutRow, LayoutRow.realization_id == Realization.id)
    )
    if ks:
        ranked = ranked.where(OrderType.k.in_(list(ks)))
    if matchable:
        ranked = ranked.where(OrderType.unique_min.is_(True))
    if lambdas:
        ranked = ranked.where(OrderType.lambda_text.in_(list(lambdas)))
    if ids:
        ranked = ranked.where(OrderType.id.in_(list(ids)))
    sub = ranked.subquery()
    q = select(sub).where(sub.c.rank == 1).order_by(sub.c.k, sub.c.lambda_text)
    if min_mp is not None:
        q = q.where(sub.c.mp >= min_mp)
    with db.engine.connect() as conn:
        rows = conn.execute(q).all()
    return [
        _record(
            (r.ot_id, r.lambda_text, r.k, r.unique_min, r.chiral, r.mirror_text),
            (r.rid, r.mp, r.coordinates, r.canonical_labeling),
            (r.triangles, r.placement, r.printed_mp_unit, r.score),
        )
        for r in rows
    ]
