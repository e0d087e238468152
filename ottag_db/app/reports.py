"""Machine-readable reports on the database: the JSON of ``stats``/``show`` and the CSV of ``list``.

These are the contracts described in README.md; the command line prints them as they come
from here, so a library user gets the very same documents.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ottag_db.store.queries import KStats, OrderTypeDetail, OrderTypeSummary

__all__ = ["LIST_CSV_COLUMNS", "PAPER_TABLE7", "order_type_json", "order_types_csv", "stats_json"]

#: The paper's Table 7: |D^k| (order types up to reflection with MP ≥ v) for v = 0.5, 1.0, …, 9.0
#: grid units, printed beside our counts by ``ottag-db stats``.
PAPER_TABLE7: dict[int, tuple[int, ...]] = {
    8: (3315, 3296, 1240, 642, 371, 231, 135, 83, 56, 37, 26, 15, 10, 6, 5, 4, 3, 3),
    7: (135, 135, 135, 135, 135, 86, 60, 47, 32, 26, 18, 15, 8, 7, 4, 3, 3, 3),
    6: (16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 12, 10, 8, 6, 5),
    5: (3,) * 18,
}

#: Header row of ``list --format csv``.
LIST_CSV_COLUMNS = ("id", "k", "lambda", "mp", "points", "hull_size", "unique_min", "chiral", "mirror", "number")


def stats_json(stats: Sequence[KStats]) -> dict[str, Any]:
    """The document of ``ottag-db stats --json``.

    Parameters
    ----------
    stats : sequence of KStats
        Per-k counts as :func:`ottag_db.store.queries.database_stats` returns them.

    Returns
    -------
    dict
        ``{"k": {"order_types", "unique_min", "chiral", "complete", "mp_at_least",
        "up_to_reflection"}}`` keyed by k as text (``complete``: every order type of k points is
        stored, so the counts are the complete ones); ``mp_at_least`` maps v (grid units, one decimal, as text) to the
        number of order types whose best realization has MP ≥ v. ``up_to_reflection`` holds the
        same counts with a chiral pair taken once (the paper's convention).
    """
    return {
        str(s.k): {
            "order_types": s.order_types,
            "unique_min": s.unique_min,
            "chiral": s.chiral,
            "complete": s.complete,
            "mp_at_least": {f"{v:.1f}": c for v, c in s.mp_at_least.items()},
            "up_to_reflection": {
                "order_types": s.up_to_reflection,
                "unique_min": s.unique_min_up_to_reflection,
                "mp_at_least": {f"{v:.1f}": c for v, c in s.mp_at_least_up_to_reflection.items()},
            },
        }
        for s in stats
    }


def order_type_json(detail: OrderTypeDetail) -> dict[str, Any]:
    """The document of ``ottag-db show ID --json``.

    Parameters
    ----------
    detail : OrderTypeDetail
        One order type as :func:`ottag_db.store.queries.get_order_type` returns it.

    Returns
    -------
    dict
        The summary of ``list --format json`` plus ``lambda_matrix`` (k × k, diagonal 0),
        ``mirror_id`` (database id of the mirror image, or None) and ``all_realizations``
        (best first; ``points`` in grid units in file order, ``labeling`` the file index of
        canonical label 0, 1, …).
    """
    out: dict[str, Any] = detail.summary.as_json()
    out["lambda_matrix"] = detail.lambda_matrix.tolist()
    out["mirror_id"] = detail.mirror_id
    out["all_realizations"] = [
        {
            "id": r.id,
            "source": r.source,
            "record": r.record_index,
            "mirrored": r.mirrored,
            "points": r.points,
            "mp": r.mp,
            "labeling": list(r.labeling),
        }
        for r in detail.realizations
    ]
    return out


def order_types_csv(rows: Sequence[OrderTypeSummary]) -> str:
    """The table of ``ottag-db list --format csv``: a header row, then one row per order type.

    Parameters
    ----------
    rows : sequence of OrderTypeSummary
        Order types as :func:`ottag_db.store.queries.list_order_types` returns them.

    Returns
    -------
    str
        CSV text with ``\\n`` line ends: columns :data:`LIST_CSV_COLUMNS`; ``mp`` in grid units
        with six decimals, ``points`` as ``"x,y x,y …"`` in file order, booleans as 0/1,
        ``number`` empty when the order type has none.
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(LIST_CSV_COLUMNS)
    for r in rows:
        w.writerow(
            [
                r.id,
                r.k,
                r.lambda_text,
                f"{r.mp:.6f}",
                " ".join(f"{x},{y}" for x, y in r.points),
                r.hull_size,
                int(r.unique_min),
                int(r.chiral),
                r.mirror,
                "" if r.number is None else r.number,
            ]
        )
    return buf.getvalue()
