"""Universal numbers of order types: rank by canonical λ within a complete k (same in every database)."""

from __future__ import annotations

from sqlalchemy import Connection, bindparam, func, select, update

from ottag_db.core.types import COMPLETE_COUNTS
from ottag_db.store.models import OrderType

__all__ = ["assign_numbers"]


def assign_numbers(conn: Connection) -> dict[int, bool]:
    """Number the order types of every complete k by rank of canonical λ (0 = smallest).

    The set of order types of k ≤ 9 points is finite and fixed, so once a database holds
    all of them the rank is the same in every database built by this tool. Incomplete k
    keep ``number = NULL``.

    Parameters
    ----------
    conn : Connection
        Connection inside the caller's transaction (the import's).

    Returns
    -------
    dict of int to bool
        ``{k: complete}`` for every k in the database.
    """
    out: dict[int, bool] = {}
    counts = conn.execute(select(OrderType.k, func.count()).group_by(OrderType.k)).all()
    for k, n in counts:
        complete = COMPLETE_COUNTS.get(int(k)) == int(n)
        out[int(k)] = complete
        if not complete:
            continue
        missing = conn.execute(
            select(func.count()).select_from(OrderType).where(OrderType.k == k, OrderType.number.is_(None))
        ).scalar_one()
        if not missing:
            continue
        ids = conn.execute(select(OrderType.id).where(OrderType.k == k).order_by(OrderType.lambda_text)).all()
        conn.execute(update(OrderType).where(OrderType.k == k).values(number=None))
        conn.execute(
            update(OrderType).where(OrderType.id == bindparam("b_id")).values(number=bindparam("b_number")),
            [{"b_id": row[0], "b_number": i} for i, row in enumerate(ids)],
        )
    return out
