"""Tests of ottag_db.open_detector: a detector from a database path, an open database, one of its
dictionaries or a dictionary file alone; typed errors for what cannot be opened."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

import ottag_db
from ottag_db.app.detector import open_detector
from ottag_db.app.export import render_tag
from ottag_db.cli import cli
from ottag_db.decode import DetectorParams
from ottag_db.errors import DatabaseError, DictionaryError, NotFoundError, UsageError
from ottag_db.files.bundled import bundled_point_files
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary, get_dictionary
from ottag_db.store.dictionary_files import export_dictionary
from ottag_db.store.importer import import_point_file
from tests.support.paper import TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)


@pytest.fixture(scope="module")
def small_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The bundled order types of 3 … 7 points (mirrors included) and a dictionary of 6-point tags."""
    path = tmp_path_factory.mktemp("open_detector") / "small.sqlite"
    db = open_database(path)
    try:
        for file, k in bundled_point_files():
            if k <= 7:
                import_point_file(db, file, with_mirrors=True)
        create_dictionary(db, "six", DictionaryOptions(ks=(6,)))
        render_tag(db, TABLE9_TEXT, path.parent / "table9.png", px=240)
        member = get_dictionary(db, "six").members[0]
        render_tag(db, member.lambda_text, path.parent / "six0.png", px=240)
        (path.parent / "six.json").write_text(export_dictionary(db, "six"))
    finally:
        db.close()
    return path


def _read(detector: ottag_db.Detector, png: Path) -> list[str]:
    import cv2

    return [d.lambda_text for d in detector.detect(cv2.imread(str(png), cv2.IMREAD_GRAYSCALE))]


def test_the_package_exports_it() -> None:
    assert ottag_db.open_detector is open_detector


def test_from_a_database_path_and_an_open_database(small_db: Path) -> None:
    png = small_db.parent / "table9.png"
    assert _read(open_detector(small_db), png) == [TABLE9_TEXT]
    assert _read(open_detector(str(small_db), params=DetectorParams(verify=False)), png) == [TABLE9_TEXT]
    db = open_database(small_db)
    try:
        assert _read(open_detector(db), png) == [TABLE9_TEXT]
        assert db.engine is not None  # the caller's database stays open
        ottag_db.database_stats(db)
    finally:
        db.close()


def test_a_dictionary_decodes_only_its_members(small_db: Path) -> None:
    detector = open_detector(small_db, dictionary="six")
    assert _read(detector, small_db.parent / "table9.png") == []
    import cv2

    (det,) = detector.detect(cv2.imread(str(small_db.parent / "six0.png")))
    assert det.tag == 0 and det.k == 6


def test_a_dictionary_file_alone(small_db: Path) -> None:
    for file in (small_db.parent / "six.json", str(small_db.parent / "six.json")):
        detector = open_detector(dictionary_file=file)
        assert _read(detector, small_db.parent / "table9.png") == []
        assert len(_read(detector, small_db.parent / "six0.png")) == 1


def test_what_cannot_be_opened_is_a_typed_error(small_db: Path, tmp_path: Path) -> None:
    missing = tmp_path / "missing.sqlite"
    with pytest.raises(DatabaseError, match=r"missing\.sqlite"):
        open_detector(missing)
    assert not missing.exists()  # refused, not created
    with pytest.raises(NotFoundError, match="nope"):
        open_detector(small_db, dictionary="nope")
    with pytest.raises(DictionaryError, match="cannot read"):
        open_detector(dictionary_file=tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(DictionaryError):
        open_detector(dictionary_file=bad)
    with pytest.raises(UsageError, match="alone"):
        open_detector(small_db, dictionary_file=small_db.parent / "six.json")
    assert all(issubclass(e, ottag_db.OttagError) for e in (DatabaseError, NotFoundError, DictionaryError, UsageError))


def test_the_cli_says_what_cannot_be_opened_in_one_line(small_db: Path, tmp_path: Path, runner: CliRunner) -> None:
    png = str(small_db.parent / "table9.png")
    for args in (
        ["decode", png, "--dictionary-file", str(tmp_path / "missing.json")],
        ["decode", png, "--db", str(tmp_path / "missing.sqlite")],
        ["decode", png, "--db", str(small_db), "--dictionary", "nope"],
    ):
        result = runner.invoke(cli, args)
        assert result.exit_code == 1, result.output
        assert result.stderr.count("\n") == 1 and result.stderr.startswith("error: "), result.stderr
    result = runner.invoke(cli, ["decode", png, "--dictionary-file", str(small_db.parent / "six.json")])
    assert result.exit_code == 0 and "0 tag(s)" in result.stdout
