"""Tests of ottag_db.app.importing: what an import imports, and the totals."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select

from ottag_db.app.importing import ImportJob, ImportTotals, import_totals, plan_import
from ottag_db.core.canonical import canonical_batch
from ottag_db.errors import PointFileError, UsageError
from ottag_db.files.bundled import bundled_point_files
from ottag_db.files.pointfile import write_point_file
from ottag_db.store.db import open_database
from ottag_db.store.importer import ImportReport, import_point_file
from ottag_db.store.models import OrderType
from ottag_db.store.queries import database_stats
from tests.support.k9_sample import nine_point_sets


def test_no_files_plan_the_bundled_data_with_mirrors() -> None:
    plan = plan_import([])
    assert plan.with_mirrors is True
    assert plan.jobs == tuple(ImportJob(p, k) for p, k in bundled_point_files())
    assert [j.points for j in plan.jobs] == [3, 4, 5, 6, 7, 8]
    assert plan_import([], points=5, with_mirrors=False).with_mirrors is False
    assert [j.points for j in plan_import([], points=5).jobs] == [3, 4, 5, 6, 7, 8]


def test_named_files_keep_order_and_default_to_no_mirrors(tmp_path: Path) -> None:
    a, b = tmp_path / "b.b08", tmp_path / "a.b08"
    plan = plan_import([a, b], points=5)
    assert plan.jobs == (ImportJob(a, 5), ImportJob(b, 5)) and plan.with_mirrors is False
    assert plan_import([a], with_mirrors=True).with_mirrors is True
    assert plan_import([a]).jobs == (ImportJob(a, None),)


def test_import_totals() -> None:
    def rep(records: int, types: int, reals: int, skipped: bool = False) -> ImportReport:
        return ImportReport(
            path=Path("x.b08"),
            n=5,
            records=records,
            new_order_types=types,
            new_realizations=reals,
            skipped=skipped,
            seconds=0.1,
            mirrors=False,
        )

    assert import_totals([rep(3, 3, 3), rep(16, 0, 0, True), rep(135, 20, 40)]) == ImportTotals(154, 23, 43)
    assert import_totals([]) == ImportTotals(0, 0, 0)


def test_k_selects_bundled_files_and_not_named_ones(tmp_path: Path) -> None:
    assert [j.points for j in plan_import([], ks=(8, 3)).jobs] == [3, 8]
    assert plan_import([], ks=(7,)).with_mirrors is True
    with pytest.raises(UsageError, match="--k selects bundled files"):
        plan_import([tmp_path / "a.b08"], ks=(9,))
    with pytest.raises(PointFileError, match="no file for k = 9"):
        plan_import([], ks=(9,), data_folder=_folder_without_nine(tmp_path))


def _folder_without_nine(tmp_path: Path) -> Path:
    folder = tmp_path / "data"
    folder.mkdir()
    shutil.copy(next(p for p, k in bundled_point_files() if k == 5), folder)
    return folder


def test_import_k9_on_request_and_not_by_default(tmp_path: Path) -> None:
    """A small nine-point bundle: the default plan leaves it out, --k 9 imports it with mirrors."""
    folder = tmp_path / "data"
    folder.mkdir()
    shutil.copy(next(p for p, k in bundled_point_files() if k == 5), folder)
    sets = nine_point_sets(8)
    texts = canonical_batch(sets).texts()
    mirrors = canonical_batch(sets * np.array([-1, 1])).texts()
    # Bundle convention: the chirality with the smaller ID, sorted by ID.
    sets = np.where(
        np.array([m < t for t, m in zip(texts, mirrors, strict=True)])[:, None, None], sets * [-1, 1] + [255, 0], sets
    )
    sets = sets[np.argsort([min(t, m) for t, m in zip(texts, mirrors, strict=True)])]
    write_point_file(folder / "ottag-k09.b08", sets)
    (folder / "manifest.json").write_text(
        json.dumps({"files": {"9": {"file": "ottag-k09.b08", "points": 9, "default": False}}}), encoding="utf-8"
    )
    assert [j.points for j in plan_import([], data_folder=folder).jobs] == [5]
    plan = plan_import([], ks=(9,), data_folder=folder)
    assert [j.points for j in plan.jobs] == [9] and plan.with_mirrors
    db = open_database(tmp_path / "k9.sqlite")
    try:
        for job in plan_import([], data_folder=folder).jobs:
            import_point_file(db, job.path, n=job.points, with_mirrors=plan.with_mirrors)
        assert [s.k for s in database_stats(db)] == [5]
        reports = [import_point_file(db, j.path, n=j.points, with_mirrors=plan.with_mirrors) for j in plan.jobs]
        achiral = sum(t == m for t, m in zip(texts, mirrors, strict=True))
        assert reports[0].new_order_types == 2 * 8 - achiral
        stats = {s.k: s for s in database_stats(db)}
        nine = stats[9]
        assert (nine.order_types, nine.up_to_reflection, nine.complete) == (16 - achiral, 8, False)
        assert stats[5].complete
        with db.session() as s:
            ot = s.execute(select(OrderType.k, OrderType.number).where(OrderType.k == 9)).all()
        assert len(ot) == 16 - achiral and all(number is None for _k, number in ot)  # incomplete: no numbers
    finally:
        db.close()
