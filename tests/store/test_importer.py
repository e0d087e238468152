"""Tests of ottag_db.store.importer against the reference files (real SQLite, real files)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import func, select

from ottag_db.errors import PointFileError
from ottag_db.files.pointfile import write_point_file
from ottag_db.store.db import open_database
from ottag_db.store.importer import import_point_file
from ottag_db.store.models import OrderType, Realization
from ottag_db.store.queries import database_stats
from tests.support.database import dump_database
from tests.support.paper import TABLE9


def test_import_counts_and_noop(otdb_dir: Path, tmp_path: Path) -> None:
    db = open_database(tmp_path / "a.sqlite")
    try:
        rep = import_point_file(db, otdb_dir / "otypes07.b08")
        assert (rep.records, rep.new_order_types, rep.new_realizations, rep.skipped) == (135, 135, 135, False)
        again = import_point_file(db, otdb_dir / "otypes07.b08")
        assert again.skipped and again.new_realizations == 0
        more = import_point_file(db, otdb_dir / "otypes07.b08", with_mirrors=True)
        assert (more.new_order_types, more.new_realizations) == (107, 107)
        assert import_point_file(db, otdb_dir / "otypes07.b08", with_mirrors=True).skipped
        with db.session() as s:
            assert s.execute(select(func.count()).select_from(OrderType)).scalar_one() == 242
            assert s.execute(select(func.count()).select_from(Realization)).scalar_one() == 242
    finally:
        db.close()


def test_stats_reproduce_tables_2_3_7(reference_db_path: Path) -> None:
    db = open_database(reference_db_path)
    try:
        stats = {s.k: s for s in database_stats(db)}
    finally:
        db.close()
    assert {k: s.order_types for k, s in stats.items()} == {3: 1, 4: 2, 5: 3, 6: 16, 7: 135, 8: 3315}
    assert {k: stats[k].unique_min for k in (5, 6, 7, 8)} == {5: 2, 6: 11, 7: 131, 8: 3303}
    table7 = {
        8: [3315, 3296, 1240, 642, 371, 231, 135, 83, 56, 37, 26, 15, 10, 6, 5, 4, 3, 3],
        7: [135, 135, 135, 135, 135, 86, 60, 47, 32, 26, 18, 15, 8, 7, 4, 3, 3, 3],
        6: [16] * 13 + [12, 10, 8, 6, 5],
        5: [3] * 18,
    }
    for k, column in table7.items():
        assert list(stats[k].mp_at_least.values()) == column


def test_mirrors_counts(mirrors_db_path: Path) -> None:
    db = open_database(mirrors_db_path)
    try:
        stats = {s.k: s.order_types for s in database_stats(db)}
    finally:
        db.close()
    assert stats == {3: 1, 4: 2, 5: 3, 6: 20, 7: 242, 8: 6405}


def test_stored_labeling_and_fig4(reference_db_path: Path) -> None:
    db = open_database(reference_db_path)
    try:
        with db.session() as s:
            r = s.execute(
                select(Realization).where(Realization.record_index == 2, Realization.source.has(n=7))
            ).scalar_one()
            assert r.points().tolist() == [
                [206, 159],
                [214, 127],
                [176, 49],
                [42, 144],
                [47, 175],
                [129, 178],
                [149, 206],
            ]
            assert r.order_type.canonical_lambda == "7:" + "".join(str(v) for row in TABLE9 for v in row)
            assert r.labeling() == (4, 6, 5, 0, 1, 2, 3)
    finally:
        db.close()


def test_failed_import_leaves_database_unchanged(otdb_dir: Path, reference_db_path: Path, tmp_path: Path) -> None:
    path = tmp_path / "copy.sqlite"
    shutil.copyfile(reference_db_path, path)
    before = dump_database(path)
    good = np.fromfile(otdb_dir / "otypes06.b08", dtype=np.uint8).reshape(-1, 6, 2).astype(np.int64)
    pts = np.tile(good, (1250, 1, 1))  # 20000 records in general position, several chunks
    pts[19000] = [[0, 0], [10, 10], [20, 20], [5, 90], [90, 4], [200, 100]]  # collinear, in chunk 3
    bad = tmp_path / "bad.b08"
    write_point_file(bad, pts)
    db = open_database(path)
    try:
        with pytest.raises(PointFileError, match=r"bad.b08: record 19000 \(byte offset 228000\).*collinear"):
            import_point_file(db, bad, n=6)
    finally:
        db.close()
    assert dump_database(path) == before
