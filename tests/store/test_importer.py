"""Tests of ottag_db.store.importer on the bundled data (real SQLite, real files); the paper's
tables against the reference files as the extra layer."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import func, select

from ottag_db.core.canonical import canonical_batch, canonical_lambda
from ottag_db.core.layout_check import validate_layout
from ottag_db.core.placement import tag_placements
from ottag_db.errors import PointFileError
from ottag_db.files.bundled import bundled_point_files
from ottag_db.files.pointfile import write_point_file
from ottag_db.store.db import open_database
from ottag_db.store.importer import (
    _analyse,
    _upsert_generic,
    _upsert_order_types,
    import_point_file,
    is_imported,
)
from ottag_db.store.models import LayoutRow, OrderType, Realization, Source, coordinates_from_blob
from ottag_db.store.queries import database_stats
from tests.support.database import dump_database
from tests.support.k9_sample import nine_point_sets
from tests.support.paper import TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)


def _bundled(k: int) -> Path:
    return next(p for p, kk in bundled_point_files() if kk == k)


def test_import_counts_and_noop(tmp_path: Path) -> None:
    db = open_database(tmp_path / "a.sqlite")
    try:
        rep = import_point_file(db, _bundled(7), n=7)
        assert (rep.records, rep.new_order_types, rep.new_realizations, rep.skipped) == (135, 135, 135, False)
        again = import_point_file(db, _bundled(7), n=7)
        assert again.skipped and again.new_realizations == 0
        more = import_point_file(db, _bundled(7), n=7, with_mirrors=True)
        assert (more.new_order_types, more.new_realizations) == (107, 107)
        assert import_point_file(db, _bundled(7), n=7, with_mirrors=True).skipped
        with db.session() as s:
            assert s.execute(select(func.count()).select_from(OrderType)).scalar_one() == 242
            assert s.execute(select(func.count()).select_from(Realization)).scalar_one() == 242
            # Every realization, the mirrors added later included, got its layout with the import.
            assert s.execute(select(func.count()).select_from(LayoutRow)).scalar_one() == 242
    finally:
        db.close()


def test_import_stores_layouts_and_placements(bundled_db_path: Path, bundled_sets: dict[int, np.ndarray]) -> None:
    db = open_database(bundled_db_path)
    try:
        with db.session() as s:
            rows = s.execute(
                select(Realization, LayoutRow, Source.n)
                .join(LayoutRow, LayoutRow.realization_id == Realization.id)
                .join(Source, Source.id == Realization.source_id)
                .where(Realization.mirrored.is_(False))
                .order_by(Source.n, Realization.record_index)
            ).all()
            per_k: dict[int, list[tuple[Realization, LayoutRow]]] = {}
            for real, lay, n in rows:
                per_k.setdefault(n, []).append((real, lay))
            assert s.execute(select(func.count()).select_from(LayoutRow)).scalar_one() == 6673 - 2  # not k = 4
        assert sorted(per_k) == [3, 5, 6, 7, 8]
        for k, pairs in per_k.items():
            assert len(pairs) == len(bundled_sets[k])
            stored = np.array([json.loads(lay.placement) for _, lay in pairs[:300]])
            # The stored map is the exact map of a fresh placement (whatever the batch).
            np.testing.assert_array_equal(stored, tag_placements(bundled_sets[k][:300]))
            for real, lay in pairs[:50]:
                assert validate_layout(real.points(), lay.triangle_list()) == []
                assert lay.triangle_count == -(-k // 3)
        with db.session() as s:
            mirrors = s.execute(
                select(Realization, LayoutRow)
                .join(LayoutRow, LayoutRow.realization_id == Realization.id)
                .join(Source, Source.id == Realization.source_id)
                .where(Realization.mirrored.is_(True), Source.n == 8)
                .order_by(Realization.record_index)
                .limit(200)
            ).all()
            # Below k = 9 a mirror image's placement is searched on its own (tags were printed so).
            own = tag_placements(np.stack([real.points() for real, _ in mirrors]))
            np.testing.assert_array_equal(np.array([json.loads(lay.placement) for _, lay in mirrors]), own)
    finally:
        db.close()


def _layout_rows(path: Path) -> list[tuple[int, bool, bytes, str, str, float, float]]:
    db = open_database(path)
    try:
        with db.session() as s:
            rows = s.execute(
                select(
                    Realization.record_index,
                    Realization.mirrored,
                    Realization.coordinates,
                    LayoutRow.triangles,
                    LayoutRow.placement,
                    LayoutRow.printed_mp_unit,
                    LayoutRow.score,
                )
                .join(LayoutRow, LayoutRow.realization_id == Realization.id)
                .order_by(Realization.record_index, Realization.mirrored)
            ).all()
        return [tuple(r) for r in rows]  # type: ignore[misc]
    finally:
        db.close()


def test_nine_point_mirrors_are_their_originals_reflected_and_workers_store_the_same(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "nine.b08"
    sets = nine_point_sets(12)
    write_point_file(path, sets)
    chiral = sum(
        t != m for t, m in zip(canonical_batch(sets).texts(), canonical_batch(sets * [-1, 1]).texts(), strict=True)
    )
    monkeypatch.setattr("ottag_db.store.layouts.LAYOUT_BATCH", 5)  # several batches per worker pool
    dumps = []
    for jobs in (1, 2):
        db = open_database(tmp_path / f"jobs{jobs}.sqlite")
        try:
            import_point_file(db, path, n=9, with_mirrors=True, jobs=jobs)  # jobs = 2: a real process pool
        finally:
            db.close()
        dumps.append(_layout_rows(tmp_path / f"jobs{jobs}.sqlite"))
    assert dumps[0] == dumps[1]
    rows = {(r[0], r[1]): r for r in dumps[0]}
    assert sum(mirrored for _, mirrored in rows) == chiral > 0
    for (record, mirrored), (_, _, blob, triangles, placement, printed, score) in rows.items():
        if not mirrored:
            continue
        _, _, o_blob, o_triangles, o_placement, o_printed, o_score = rows[(record, False)]
        assert (triangles, score) == (o_triangles, o_score)
        placed = _placed(blob, placement)
        o_placed = _placed(o_blob, o_placement)
        # The mirror's printed tag is the original's reflected in the data area, same MP.
        np.testing.assert_allclose(placed, np.stack([1.0 - o_placed[:, 0], o_placed[:, 1]], axis=1), atol=1e-12)
        assert printed == pytest.approx(o_printed, rel=1e-12)
        assert placed.min() > 0.1 - 1e-12 and placed.max() < 0.9 + 1e-12


def _placed(blob: bytes, placement: str) -> np.ndarray:
    m = np.array(json.loads(placement))
    pts = coordinates_from_blob(blob).astype(np.float64)
    placed: np.ndarray = pts @ m[:, :2].T + m[:, 2]
    return placed


def test_generic_bulk_insert_uses_column_names(tmp_path: Path, bundled_sets: dict[int, np.ndarray]) -> None:
    """The path for databases other than SQLite inserts by SQL column (``canonical_lambda``)."""
    db = open_database(tmp_path / "g.sqlite")
    try:
        data = _analyse(bundled_sets[6], 0)
        with db.engine.begin() as conn:
            rows: dict[str, tuple[object, ...]] = {
                t: (6, t, True, 1, 3, m, m != t) for t, m in zip(data.texts, data.mirror_texts, strict=True)
            }
            ids = _upsert_generic(conn, 6, rows)
            assert _upsert_order_types(conn, 6, data) == ids  # the SQLite path finds the same rows
        with db.session() as s:
            texts = set(s.execute(select(OrderType.lambda_text).where(OrderType.k == 6)).scalars())
        assert texts == set(data.texts) and len(ids) == 16
    finally:
        db.close()


def test_mirrors_counts(bundled_db_path: Path) -> None:
    db = open_database(bundled_db_path)
    try:
        stats = {s.k: s for s in database_stats(db)}
        with db.session() as s:
            fig4 = s.execute(select(OrderType).where(OrderType.lambda_text == TABLE9_TEXT)).scalar_one()
            best = max(fig4.realizations, key=lambda r: r.mp)
            assert canonical_lambda(best.points()) == TABLE9_TEXT
    finally:
        db.close()
    assert {k: s.order_types for k, s in stats.items()} == {3: 1, 4: 2, 5: 3, 6: 20, 7: 242, 8: 6405}
    # Up to reflection, the paper's Table 2 counts.
    assert {k: s.up_to_reflection for k, s in stats.items()} == {3: 1, 4: 2, 5: 3, 6: 16, 7: 135, 8: 3315}


@pytest.mark.parametrize("jobs", [1, 2])
def test_failed_import_leaves_database_unchanged(
    bundled_db_path: Path,
    bundled_sets: dict[int, np.ndarray],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    jobs: int,
) -> None:
    # jobs = 2: the bad chunk is analysed in a worker process while the one before is laid out.
    monkeypatch.setattr("ottag_db.store.importer._CHUNK_RECORDS", 500)
    path = tmp_path / "copy.sqlite"
    shutil.copyfile(bundled_db_path, path)
    before = dump_database(path)
    pts = np.tile(bundled_sets[6], (125, 1, 1))  # 2000 records in general position, several chunks
    pts[1900] = [[0, 0], [10, 10], [20, 20], [5, 90], [90, 4], [200, 100]]  # collinear, in the last chunk
    bad = tmp_path / "bad.b08"
    write_point_file(bad, pts)
    db = open_database(path)
    try:
        with pytest.raises(PointFileError, match=r"bad.b08: record 1900 \(byte offset 22800\).*collinear"):
            import_point_file(db, bad, n=6, jobs=jobs)
    finally:
        db.close()
    assert dump_database(path) == before  # no realization, layout or source of the failed file


def test_progress_counts_records(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("ottag_db.store.layouts.LAYOUT_BATCH", 50)
    calls: list[tuple[int, int]] = []
    db = open_database(tmp_path / "p.sqlite")
    try:
        import_point_file(db, _bundled(7), n=7, with_mirrors=True, progress=lambda d, t: calls.append((d, t)))
    finally:
        db.close()
    assert calls and all(t == 135 for _, t in calls)
    done = [d for d, _ in calls]
    assert done == sorted(done) and done[-1] == 135 and len(done) >= 5  # per layout batch, not once


def test_reference_files_reproduce_the_paper(reference_db_path: Path) -> None:
    """Extra layer: Tables 2, 3, 7 and the Fig. 4 realization from Aichholzer's files."""
    db = open_database(reference_db_path)
    try:
        stats = {s.k: s for s in database_stats(db)}
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
            assert r.order_type.lambda_text == TABLE9_TEXT
            assert r.labeling() == (4, 6, 5, 0, 1, 2, 3)
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


def test_repeated_order_types_are_refused_unless_allowed(tmp_path: Path, bundled_sets: dict[int, np.ndarray]) -> None:
    pts = np.concatenate([bundled_sets[6], bundled_sets[6][:3]])  # records 16, 17, 18 repeat 0, 1, 2
    dup = tmp_path / "dup.b08"
    write_point_file(dup, pts)
    path = tmp_path / "d.sqlite"
    db = open_database(path)
    try:
        before = dump_database(path)
        with pytest.raises(
            PointFileError, match=r"dup.b08: records 0 and 16 have the same order type.*is --points right"
        ):
            import_point_file(db, dup, n=6)
        assert dump_database(path) == before and not is_imported(db, dup)
        rep = import_point_file(db, dup, n=6, allow_duplicates=True)
        assert (rep.records, rep.new_order_types, rep.new_realizations) == (19, 16, 19)
        assert is_imported(db, dup)
    finally:
        db.close()


def test_a_wrong_points_value_is_caught(tmp_path: Path) -> None:
    seven = tmp_path / "seven.b08"  # 135 × 7 points = 189 × 5 = 105 × 9: the sizes divide
    seven.write_bytes(_bundled(7).read_bytes())
    db = open_database(tmp_path / "w.sqlite")
    try:
        for n in (5, 9):
            with pytest.raises(PointFileError, match=r"seven.b08: record.*is --points right\?"):
                import_point_file(db, seven, n=n)
        assert import_point_file(db, seven, n=7).new_order_types == 135
    finally:
        db.close()
