"""Tests of ottag_db.store.sources: listing imported files and removing one in one transaction."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner
from sqlalchemy import func, select

from ottag_db.cli import cli
from ottag_db.errors import DictionaryError, NotFoundError
from ottag_db.files.bundled import bundled_point_files
from ottag_db.store.db import check_integrity, open_database
from ottag_db.store.importer import import_point_file
from ottag_db.store.models import LayoutRow, OrderType, Realization
from ottag_db.store.sources import list_sources, remove_source
from tests.support.database import dump_database


def _bundled(k: int) -> Path:
    return next(p for p, kk in bundled_point_files() if kk == k)


def test_list_and_remove_with_renumbering(bundled_db_path: Path, tmp_path: Path) -> None:
    path = tmp_path / "b.sqlite"
    shutil.copyfile(bundled_db_path, path)
    db = open_database(path)
    try:
        rows = list_sources(db)
        assert [r.name for r in rows] == [p.name for p, _k in bundled_point_files()]
        seven = next(r for r in rows if r.n == 7)
        assert (seven.records, seven.realizations, seven.order_types, seven.mirrors_included) == (135, 242, 242, True)
        with db.session() as s:
            layouts = s.execute(select(func.count()).select_from(LayoutRow)).scalar_one()
        removed = remove_source(db, "ottag-k07.b08")
        assert (removed.realizations, removed.order_types) == (242, 242)
        assert [r.n for r in list_sources(db)] == [3, 4, 5, 6, 8]
        with db.session() as s:
            assert s.execute(select(func.count()).where(OrderType.k == 7)).scalar_one() == 0
            # Layouts went with their realizations (check_integrity also runs foreign_key_check).
            assert s.execute(select(func.count()).select_from(LayoutRow)).scalar_one() == layouts - 242
            assert s.execute(select(func.count()).select_from(Realization)).scalar_one() == 6673 - 242
        assert check_integrity(db) == []
        with pytest.raises(NotFoundError, match=r"no source 'ottag-k07\.b08'"):
            remove_source(db, "ottag-k07.b08")
        # Import again: the numbers of k = 7 come back (the set is complete again).
        import_point_file(db, _bundled(7), with_mirrors=True)
        with db.session() as s:
            assert (
                s.execute(select(func.count()).where(OrderType.k == 7, OrderType.number.isnot(None))).scalar_one()
                == 242
            )
    finally:
        db.close()


def test_partial_removal_keeps_shared_order_types_and_clears_numbers(tmp_path: Path) -> None:
    path = tmp_path / "p.sqlite"
    copy = tmp_path / "again.b08"
    copy.write_bytes(_bundled(6).read_bytes()[:-12])  # the first 15 records of the 6-point file
    db = open_database(path)
    try:
        import_point_file(db, _bundled(6), with_mirrors=True)
        import_point_file(db, copy, n=6)
        with db.session() as s:
            assert s.execute(select(func.count()).where(OrderType.number.isnot(None))).scalar_one() == 20
        removed = remove_source(db, "ottag-k06.b08")
        # The 15 order types the second file also realizes stay; the rest (and the numbers) go.
        assert removed.order_types == 5 and removed.realizations == 20
        with db.session() as s:
            assert s.execute(select(func.count()).select_from(OrderType)).scalar_one() == 15
            assert s.execute(select(func.count()).where(OrderType.number.isnot(None))).scalar_one() == 0
    finally:
        db.close()


def test_removal_is_refused_while_a_dictionary_uses_it(bundled_db_path: Path, tmp_path: Path) -> None:
    path = tmp_path / "d.sqlite"
    shutil.copyfile(bundled_db_path, path)
    runner = CliRunner()
    res = runner.invoke(cli, ["--db", str(path), "-q", "dictionary", "create", "six", "--k", "6"])
    assert res.exit_code == 0, res.output
    before = dump_database(path)
    res = runner.invoke(cli, ["--db", str(path), "sources", "remove", "ottag-k06.b08"])
    assert res.exit_code == 1
    assert "dictionary six use(s) its tags; delete them first" in res.stderr
    assert dump_database(path) == before
    db = open_database(path)
    try:
        with pytest.raises(DictionaryError):
            remove_source(db, "4")
    finally:
        db.close()
    res = runner.invoke(cli, ["--db", str(path), "sources", "remove", "ottag-k07.b08"])
    assert res.exit_code == 0 and "removed ottag-k07.b08 (id 5): 242 realizations, 242 order types" in res.stdout
    res = runner.invoke(cli, ["--db", str(path), "sources", "--json"])
    assert [r["name"] for r in json.loads(res.stdout)] == [
        "ottag-k03.b08",
        "ottag-k04.b08",
        "ottag-k05.b08",
        "ottag-k06.b08",
        "ottag-k08.b08",
    ]
