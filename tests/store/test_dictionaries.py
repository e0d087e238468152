"""Tests of ottag_db.store.dictionaries and the dictionary commands (real SQLite, both chiralities)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner
from sqlalchemy import select

from ottag_db.cli import cli
from ottag_db.errors import DictionaryError
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import (
    DictionaryOptions,
    create_dictionary,
    ensure_flip_graph,
    get_dictionary,
    neighbours,
)
from ottag_db.store.importer import import_point_file
from ottag_db.store.models import FlipEdgeRow, OrderType


@pytest.fixture
def mdb(mirrors_db_path: Path, tmp_path: Path) -> Path:
    path = tmp_path / "m.sqlite"
    shutil.copyfile(mirrors_db_path, path)
    return path


def test_universal_numbers_are_ranks_and_stable(mdb: Path, otdb_dir: Path, tmp_path: Path) -> None:
    db = open_database(mdb)
    try:
        with db.session() as s:
            rows = s.execute(select(OrderType.k, OrderType.canonical_lambda, OrderType.number)).all()
    finally:
        db.close()
    by_k: dict[int, list[tuple[str, int]]] = {}
    for k, text, number in rows:
        assert number is not None
        by_k.setdefault(k, []).append((text, number))
    for items in by_k.values():
        assert [n for _, n in sorted(items)] == list(range(len(items)))
    # Rebuilt in another order: the same numbers.
    other = open_database(tmp_path / "other.sqlite")
    try:
        for k in (8, 7, 6, 5, 4, 3):
            import_point_file(other, otdb_dir / f"otypes{k:02d}.b08", with_mirrors=True)
        with other.session() as s:
            again = {
                (k, t): n for k, t, n in s.execute(select(OrderType.k, OrderType.canonical_lambda, OrderType.number))
            }
    finally:
        other.close()
    assert again == {(k, t): n for k, t, n in rows}


def test_incomplete_k_has_no_numbers_and_no_flip_graph(reference_db_path: Path, tmp_path: Path) -> None:
    path = tmp_path / "r.sqlite"
    shutil.copyfile(reference_db_path, path)
    db = open_database(path)
    try:
        with db.session() as s:
            assert s.execute(select(OrderType.number).where(OrderType.k == 8)).scalars().first() is None
            assert s.execute(select(OrderType.number).where(OrderType.k == 5)).scalars().first() is not None
        with pytest.raises(DictionaryError, match="needs every order type of 8 points"):
            ensure_flip_graph(db, [8])
    finally:
        db.close()


def test_d2_dictionary_has_no_internal_edge(mdb: Path) -> None:
    db = open_database(mdb)
    try:
        info = create_dictionary(db, "d2", DictionaryOptions(min_flip_distance=2))
        members = {m.order_type_id for m in info.members}
        with db.session() as s:
            edges = s.execute(select(FlipEdgeRow.source_id, FlipEdgeRow.target_id)).all()
        assert edges
        internal = [(a, b) for a, b in edges if a != b and a in members and b in members]
        assert internal == []
        first = next(m for m in info.members if m.k == 8)
        nbrs = neighbours(db, first.lambda_text)
        member_texts = {m.lambda_text for m in info.members}
        assert nbrs and all(t not in member_texts or t == first.lambda_text for t, _ in nbrs)
        assert [m.number for m in info.members] == list(range(len(info.members)))
        counts = info.counts()
        assert counts[8] > 1000  # more tags than ArUco 6x6_1000, with single-flip protection
        mps = [m.mp for m in info.members]
        assert mps == sorted(mps, reverse=True)  # documented greedy order: highest MP first
    finally:
        db.close()


def test_cli_create_export_import_round_trip(runner: CliRunner, mdb: Path, tmp_path: Path) -> None:
    db = str(mdb)
    res = runner.invoke(
        cli, ["dictionary", "create", "--db", db, "-q", "robots", "--k", "7", "--polarity", "both", "--max-size", "20"]
    )
    assert res.exit_code == 0, res.output
    assert "robots: 20 tags" in res.stdout
    out = tmp_path / "robots.json"
    res = runner.invoke(cli, ["dictionary", "export", "--db", db, "robots", "-o", str(out)])
    assert res.exit_code == 0, res.output
    data = json.loads(out.read_text())
    assert data["name"] == "robots" and data["min_flip_distance"] == 2
    tag0 = data["tags"][0]
    assert {"number", "lambda", "k", "polarity", "points", "triangles", "mp"} <= set(tag0)
    assert [t["polarity"] for t in data["tags"][:2]] == ["normal", "inverted"]
    res = runner.invoke(cli, ["dictionary", "import", "--db", db, str(out)])
    assert res.exit_code == 1 and "exists already" in res.stderr
    res = runner.invoke(cli, ["dictionary", "import", "--db", db, str(out), "--name", "robots2"])
    assert res.exit_code == 0, res.output
    again = runner.invoke(cli, ["dictionary", "export", "--db", db, "robots2"]).stdout
    data2 = json.loads(again)
    assert data2["tags"] == data["tags"] and data2["parameters"] == data["parameters"]
    listing = runner.invoke(cli, ["dictionary", "list", "--db", db]).stdout
    assert "robots\t20 tags" in listing and "robots2\t20 tags" in listing
    csv_text = runner.invoke(cli, ["dictionary", "export", "--db", db, "robots", "--format", "csv"]).stdout
    assert csv_text.splitlines()[0].startswith("number,lambda,k,polarity")
    assert runner.invoke(cli, ["dictionary", "delete", "--db", db, "robots2"]).exit_code == 0
    assert runner.invoke(cli, ["dictionary", "show", "--db", db, "robots2"]).exit_code == 1
    sheet = tmp_path / "robots.pdf"
    res = runner.invoke(cli, ["export", "--db", db, "-q", "--dictionary", "robots", str(sheet)])
    assert res.exit_code == 0 and "20 tags" in res.stdout


def test_dictionary_numbers_identical_after_rebuild(otdb_dir: Path, tmp_path: Path) -> None:
    exports = []
    for run in range(2):
        db = open_database(tmp_path / f"rebuild{run}.sqlite")
        try:
            for k in (5, 6, 7):
                import_point_file(db, otdb_dir / f"otypes{k:02d}.b08", with_mirrors=True)
            create_dictionary(db, "d", DictionaryOptions(ks=(6, 7), min_flip_distance=2))
            exports.append([(m.number, m.lambda_text, m.universal_number) for m in get_dictionary(db, "d").members])
        finally:
            db.close()
    assert exports[0] == exports[1]


def test_bad_dictionary_inputs(runner: CliRunner, mdb: Path, tmp_path: Path) -> None:
    db = str(mdb)
    res = runner.invoke(cli, ["dictionary", "create", "--db", db, "bad name!"])
    assert res.exit_code == 2 and "dictionary name" in res.stderr
    res = runner.invoke(cli, ["dictionary", "create", "--db", db, "x", "--k", "8", "--min-mp", "99"])
    assert res.exit_code == 1 and "no order type matches" in res.stderr
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    res = runner.invoke(cli, ["dictionary", "import", "--db", db, str(bad)])
    assert res.exit_code == 1 and "not JSON" in res.stderr
    bad.write_text(
        json.dumps(
            {"name": "z", "tags": [{"number": 0, "lambda": "5:0321000321100322100332101", "polarity": "normal"}]}
        )
    )
    res = runner.invoke(cli, ["dictionary", "import", "--db", db, str(bad)])
    assert res.exit_code != 0
    res = runner.invoke(cli, ["dictionary", "import", "--db", db, str(tmp_path / "missing.json")])
    assert res.exit_code == 1 and "cannot read" in res.stderr
