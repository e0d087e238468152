"""Tests of the stored flip graph, dictionaries, dictionary files and lookups (bundled data, real SQLite)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from sqlalchemy import select, update

from ottag_db.errors import DictionaryError, NotFoundError, OttagError, UsageError
from ottag_db.files.bundled import bundled_point_files
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import (
    DictionaryOptions,
    create_dictionary,
    delete_dictionary,
    get_dictionary,
    list_dictionaries,
)
from ottag_db.store.dictionary_files import export_dictionary, import_dictionary
from ottag_db.store.flipgraph import ensure_flip_graph, neighbours
from ottag_db.store.importer import import_point_file
from ottag_db.store.lookups import dictionary_lookup, load_lookup, neighbour_members
from ottag_db.store.models import DictionaryTag, FlipEdgeRow, OrderType

BUNDLED = dict((k, p) for p, k in bundled_point_files())


@pytest.fixture
def mdb(bundled_db_path: Path, tmp_path: Path) -> Path:
    path = tmp_path / "m.sqlite"
    shutil.copyfile(bundled_db_path, path)
    return path


def test_universal_numbers_are_ranks_and_stable(mdb: Path, tmp_path: Path) -> None:
    db = open_database(mdb)
    try:
        with db.session() as s:
            rows = s.execute(select(OrderType.k, OrderType.lambda_text, OrderType.number)).all()
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
        for k in (7, 6, 5, 4, 3):
            import_point_file(other, BUNDLED[k], n=k, with_mirrors=True)
        with other.session() as s:
            again = {(k, t): n for k, t, n in s.execute(select(OrderType.k, OrderType.lambda_text, OrderType.number))}
    finally:
        other.close()
    assert again == {(k, t): n for k, t, n in rows if k <= 7}


def test_incomplete_k_has_no_numbers_and_no_flip_graph(tmp_path: Path) -> None:
    db = open_database(tmp_path / "r.sqlite")
    try:
        for k in (5, 7):
            import_point_file(db, BUNDLED[k], n=k)  # no mirrors: k = 7 lacks the chiral twins
        with db.session() as s:
            assert s.execute(select(OrderType.number).where(OrderType.k == 7)).scalars().first() is None
            assert s.execute(select(OrderType.number).where(OrderType.k == 5)).scalars().first() is not None
        with pytest.raises(DictionaryError, match="needs every order type of 7 points"):
            ensure_flip_graph(db, [7])
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


def test_create_export_import_round_trip(mdb: Path) -> None:
    db = open_database(mdb)
    try:
        info = create_dictionary(db, "robots", DictionaryOptions(ks=(7,), polarity="both", max_size=20))
        assert len(info.members) == 20 and info.min_flip_distance == 2
        data = json.loads(export_dictionary(db, "robots"))
        assert data["name"] == "robots" and data["min_flip_distance"] == 2
        assert {"number", "lambda", "k", "polarity", "points", "triangles", "mp"} <= set(data["tags"][0])
        assert [t["polarity"] for t in data["tags"][:2]] == ["normal", "inverted"]
        text = json.dumps(data)
        with pytest.raises(DictionaryError, match="exists already"):
            import_dictionary(db, text)
        import_dictionary(db, text, name="robots2")
        data2 = json.loads(export_dictionary(db, "robots2"))
        assert data2["tags"] == data["tags"] and data2["parameters"] == data["parameters"]
        assert [(n, size) for n, _, size, _ in list_dictionaries(db)] == [("robots", 20), ("robots2", 20)]
        assert export_dictionary(db, "robots", "csv").splitlines()[0].startswith("number,lambda,k,polarity")
        with pytest.raises(UsageError):
            export_dictionary(db, "robots", "xml")
        assert delete_dictionary(db, "robots2") == 20
        with pytest.raises(NotFoundError):
            get_dictionary(db, "robots2")
        # Decoder lookups: only the members, each with its tag numbers per polarity.
        lookup = dictionary_lookup(db, "robots")
        assert len(lookup) == 10 and lookup.ks == frozenset({7})
        first = lookup.get(data["tags"][0]["lambda"])
        assert first is not None and first.tag == 0 and first.extra["tags"] == {"normal": 0, "inverted": 1}
        near = neighbour_members(db, "robots")
        assert near and set(near.values()) <= {t["number"] for t in data["tags"]}
        assert not set(near) & {t["lambda"] for t in data["tags"]}  # distance 2: no member is a neighbour
    finally:
        db.close()


def test_dictionary_numbers_identical_after_rebuild(tmp_path: Path) -> None:
    exports = []
    for run, order in enumerate([(5, 6, 7), (7, 6, 5)]):
        db = open_database(tmp_path / f"rebuild{run}.sqlite")
        try:
            for k in order:
                import_point_file(db, BUNDLED[k], n=k, with_mirrors=True)
            create_dictionary(db, "d", DictionaryOptions(ks=(6, 7), min_flip_distance=2))
            exports.append([(m.number, m.lambda_text, m.universal_number) for m in get_dictionary(db, "d").members])
        finally:
            db.close()
    assert exports[0] == exports[1]


def test_bad_dictionary_inputs(mdb: Path) -> None:
    db = open_database(mdb)
    try:
        with pytest.raises(UsageError, match="dictionary name"):
            create_dictionary(db, "bad name!", DictionaryOptions())
        with pytest.raises(DictionaryError, match="no order type matches"):
            create_dictionary(db, "x", DictionaryOptions(ks=(8,), min_mp=99.0))
        with pytest.raises(DictionaryError, match="not JSON"):
            import_dictionary(db, "{not json")
        unknown = {"name": "z", "tags": [{"number": 0, "lambda": "5:0321000321100322100332101", "polarity": "normal"}]}
        with pytest.raises(OttagError, match="diagonal"):
            import_dictionary(db, json.dumps(unknown))
        assert list_dictionaries(db) == []
    finally:
        db.close()


def test_members_are_pinned_to_one_realization(mdb: Path) -> None:
    """A created member names its realization; the lookup verifies against it alone; a member of a
    dictionary made before revision 0005 (no realization) falls back to all of them."""
    db = open_database(mdb)
    try:
        info = create_dictionary(db, "pinned", DictionaryOptions(ks=(6,), min_flip_distance=1, max_size=5))
        with db.session() as s:
            rows = s.execute(select(DictionaryTag.number, DictionaryTag.realization_id)).all()
            assert len(rows) == 5 and all(rid is not None for _, rid in rows)
            best = {m.number: m.realization_id for m in info.members}
            assert dict(rows) == best
        lookup = dictionary_lookup(db, "pinned")
        assert all(len(e.realizations) == 1 for e in lookup)
        full = load_lookup(db, ks=[6])
        with db.session() as s:
            s.execute(update(DictionaryTag).values(realization_id=None))
        old = dictionary_lookup(db, "pinned")
        for e in old:
            whole = full.get(e.lambda_text)
            assert whole is not None and len(e.realizations) == len(whole.realizations)
        again = get_dictionary(db, "pinned")
        assert [(m.points, m.triangles) for m in again.members] == [(m.points, m.triangles) for m in info.members]
    finally:
        db.close()
