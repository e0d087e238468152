"""Statistics of the stored order types per k: the paper's Tables 2, 3 and 7 (reads only)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sqlalchemy import func, select

from ottag_db.core.types import COMPLETE_COUNTS, MP_THRESHOLDS
from ottag_db.store.db import Database
from ottag_db.store.models import OrderType, Realization

__all__ = ["KStats", "best_mp_query", "database_stats"]


@dataclass(frozen=True)
class KStats:
    """Counts for one k: order types (Table 2), unique minimum (Table 3), MP ≥ v (Table 7).

    ``mp_at_least[v]`` counts order types whose best realization has MP ≥ v. The
    ``*_up_to_reflection`` counts take a chiral pair once (as Aichholzer's files and the
    paper's tables do): a chiral order type whose mirror is also stored counts only when its
    canonical λ is the smaller of the two. ``complete`` is True when the database holds every
    order type of k points (:data:`~ottag_db.core.types.COMPLETE_COUNTS`, both chiralities),
    so the counts are those of all order types of k points, not of a subset.
    """

    k: int
    order_types: int
    unique_min: int
    chiral: int
    mp_at_least: dict[float, int]
    up_to_reflection: int = 0
    unique_min_up_to_reflection: int = 0
    mp_at_least_up_to_reflection: dict[float, int] = field(default_factory=dict)
    complete: bool = False


def best_mp_query() -> Any:
    """``SELECT order_type_id, max(mp) AS mp, count() AS n FROM realizations GROUP BY order_type_id``.

    Returns
    -------
    Select
        Per order type: the MP of its best realization (grid units) and its realization count.
    """
    return select(Realization.order_type_id, func.max(Realization.mp).label("mp"), func.count().label("n")).group_by(
        Realization.order_type_id
    )


def database_stats(db: Database, thresholds: Sequence[float] = MP_THRESHOLDS) -> list[KStats]:
    """Per k: order types, unique-minimum ones, chiral ones and MP ≥ v counts (best realization).

    Parameters
    ----------
    db : Database
        An open database (only read).
    thresholds : sequence of float
        The v values, grid units (default: the paper's Table 7).

    Returns
    -------
    list of KStats
        One per k present, ascending; empty for an empty database.
    """
    best = best_mp_query().subquery()
    with db.session() as s:
        rows = s.execute(
            select(
                OrderType.k,
                OrderType.unique_min,
                OrderType.chiral,
                best.c.mp,
                OrderType.lambda_text,
                OrderType.mirror_lambda_text,
            ).join(best, best.c.order_type_id == OrderType.id)
        ).all()
    if not rows:
        return []
    ks = np.array([r[0] for r in rows])
    uniq = np.array([bool(r[1]) for r in rows])
    chiral = np.array([bool(r[2]) for r in rows])
    mp = np.array([float(r[3]) for r in rows])
    stored = {r[4] for r in rows}
    # One per reflection pair: drop the chiral type whose mirror is stored with a smaller λ.
    rep = np.array([not r[2] or r[5] not in stored or r[4] < r[5] for r in rows])
    out = []
    for k in sorted(set(ks.tolist())):
        sel = ks == k
        pair = sel & rep
        out.append(
            KStats(
                k=int(k),
                order_types=int(sel.sum()),
                unique_min=int(uniq[sel].sum()),
                chiral=int(chiral[sel].sum()),
                mp_at_least={float(v): int((mp[sel] >= v).sum()) for v in thresholds},
                up_to_reflection=int(pair.sum()),
                unique_min_up_to_reflection=int(uniq[pair].sum()),
                mp_at_least_up_to_reflection={float(v): int((mp[pair] >= v).sum()) for v in thresholds},
                complete=COMPLETE_COUNTS.get(int(k)) == int(sel.sum()),
            )
        )
    return out
