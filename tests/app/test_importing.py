"""Tests of ottag_db.app.importing: what an import imports, and the totals."""

from __future__ import annotations

from pathlib import Path

from ottag_db.app.importing import ImportJob, ImportTotals, import_totals, plan_import
from ottag_db.files.bundled import bundled_point_files
from ottag_db.store.importer import ImportReport


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
