"""Tests of ottag_db.app.reports: the JSON of stats/show and the CSV of list."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from ottag_db.app.reports import LIST_CSV_COLUMNS, PAPER_TABLE7, order_type_json, order_types_csv, stats_json
from ottag_db.core.types import MP_THRESHOLDS
from ottag_db.store.db import open_database
from ottag_db.store.queries import (
    KStats,
    OrderTypeDetail,
    OrderTypeSummary,
    RealizationInfo,
    database_stats,
    get_order_type,
    list_order_types,
)
from tests.support.paper import TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)


def _summary(**kw: object) -> OrderTypeSummary:
    base: dict[str, object] = {
        "id": 7,
        "k": 3,
        "lambda_text": "3:010001100",
        "mp": 12.5,
        "points": [[0, 0], [10, 0], [0, 10]],
        "hull_size": 3,
        "unique_min": False,
        "minimal_orderings": 3,
        "chiral": False,
        "mirror": "3:010001100",
        "realizations": 1,
        "number": None,
    }
    base.update(kw)
    return OrderTypeSummary(**base)  # type: ignore[arg-type]


def test_paper_table7_has_one_count_per_threshold() -> None:
    assert set(PAPER_TABLE7) == {5, 6, 7, 8}
    assert all(len(row) == len(MP_THRESHOLDS) for row in PAPER_TABLE7.values())
    assert PAPER_TABLE7[8][MP_THRESHOLDS.index(6.0)] == 15


def test_stats_json_shape() -> None:
    s = KStats(
        k=5,
        order_types=3,
        unique_min=2,
        chiral=0,
        mp_at_least={0.5: 3, 1.0: 2},
        up_to_reflection=3,
        unique_min_up_to_reflection=2,
        mp_at_least_up_to_reflection={0.5: 3, 1.0: 1},
    )
    assert stats_json([s]) == {
        "5": {
            "order_types": 3,
            "unique_min": 2,
            "chiral": 0,
            "complete": False,
            "mp_at_least": {"0.5": 3, "1.0": 2},
            "up_to_reflection": {"order_types": 3, "unique_min": 2, "mp_at_least": {"0.5": 3, "1.0": 1}},
        }
    }
    assert stats_json([]) == {}


def test_stats_json_of_the_bundled_database(bundled_db_path: Path) -> None:
    with open_database(bundled_db_path, migrate=False) as db:
        doc = stats_json(database_stats(db))
    assert list(doc) == ["3", "4", "5", "6", "7", "8"]
    assert doc["8"]["up_to_reflection"]["order_types"] == 3315
    assert list(doc["8"]["mp_at_least"]) == [f"{v:.1f}" for v in MP_THRESHOLDS]
    assert all(doc[k]["complete"] for k in doc)


def test_order_type_json(bundled_db_path: Path) -> None:
    with open_database(bundled_db_path, migrate=False) as db:
        detail = get_order_type(db, TABLE9_TEXT)
    doc = order_type_json(detail)
    assert doc["lambda"] == TABLE9_TEXT and doc["lambda_matrix"] == TABLE9
    assert {k: doc[k] for k in detail.summary.as_json()} == detail.summary.as_json()
    assert doc["mirror_id"] == detail.mirror_id
    best = doc["all_realizations"][0]
    assert set(best) == {"id", "source", "record", "mirrored", "points", "mp", "labeling"}
    assert best["points"] == doc["points"] and isinstance(best["labeling"], list)


def test_order_type_json_synthetic() -> None:
    real = RealizationInfo(
        id=3,
        source="a.b08",
        record_index=0,
        mirrored=True,
        points=[[0, 0], [10, 0], [0, 10]],
        mp=1.5,
        labeling=(2, 0, 1),
    )
    detail = OrderTypeDetail(_summary(), np.zeros((3, 3), dtype=np.int8), None, [real])
    doc = order_type_json(detail)
    assert doc["lambda_matrix"] == [[0, 0, 0]] * 3 and doc["mirror_id"] is None
    assert doc["all_realizations"] == [
        {
            "id": 3,
            "source": "a.b08",
            "record": 0,
            "mirrored": True,
            "points": real.points,
            "mp": 1.5,
            "labeling": [2, 0, 1],
        }
    ]


def test_order_types_csv_exact() -> None:
    rows = [_summary(), _summary(id=8, mp=1 / 3, unique_min=True, chiral=True, mirror="3:x", number=4)]
    assert order_types_csv(rows) == (
        "id,k,lambda,mp,points,hull_size,unique_min,chiral,mirror,number\n"
        '7,3,3:010001100,12.500000,"0,0 10,0 0,10",3,0,0,3:010001100,\n'
        '8,3,3:010001100,0.333333,"0,0 10,0 0,10",3,1,1,3:x,4\n'
    )
    assert order_types_csv([]) == ",".join(LIST_CSV_COLUMNS) + "\n"


def test_order_types_csv_reads_back(bundled_db_path: Path) -> None:
    with open_database(bundled_db_path, migrate=False) as db:
        rows = list_order_types(db, ks=(6,))
    table = list(csv.DictReader(io.StringIO(order_types_csv(rows))))
    assert [int(r["id"]) for r in table] == [r.id for r in rows]
    assert [r["lambda"] for r in table] == [r.lambda_text for r in rows]
    assert all(len(r["points"].split()) == 6 for r in table)
