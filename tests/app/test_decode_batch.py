"""Tests of ottag_db.app.decode_batch: options, loading once (database or dictionary file), a batch of images."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from ottag_db.app.decode_batch import (
    DecodeOptions,
    decode_images,
    decode_options,
    prepare_decoding,
    prepare_file_decoding,
)
from ottag_db.app.export import render_tag
from ottag_db.errors import DictionaryError, UsageError
from ottag_db.store.db import Database, open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary, get_dictionary
from ottag_db.store.dictionary_files import export_dictionary
from tests.support.paper import TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)


@pytest.fixture(scope="module")
def db(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Database:
    path = tmp_path_factory.mktemp("batch") / "db.sqlite"
    shutil.copyfile(bundled_db_path, path)
    d = open_database(path)
    create_dictionary(d, "five", DictionaryOptions(ks=(5,)))
    return d


@pytest.fixture(scope="module")
def tag_png(db: Database, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("img") / "table9.png"
    render_tag(db, TABLE9_TEXT, out, px=240)
    return out


def test_options_go_together(tmp_path: Path) -> None:
    assert decode_options(None, None) == DecodeOptions()
    cam = tmp_path / "cam.json"
    cam.write_text(json.dumps({"fx": 800, "fy": 800, "cx": 300, "cy": 300}))
    with pytest.raises(UsageError, match="go together"):
        decode_options(cam, None)
    with pytest.raises(UsageError, match="go together"):
        decode_options(None, "5cm")
    opts = decode_options(cam, "5cm", tmp_path / "draw")
    assert opts.tag_size_mm == pytest.approx(50.0) and opts.camera is not None
    assert opts.camera.matrix[0, 0] == 800 and opts.draw_dir == tmp_path / "draw"
    assert not (tmp_path / "draw").exists()  # reading the options writes nothing


def test_batch_decodes_each_image_and_reports_unreadable_ones(db: Database, tag_png: Path, tmp_path: Path) -> None:
    setup = prepare_decoding(db)
    assert setup.dictionary is None and setup.near == {} and setup.numbers
    draw = tmp_path / "draw"
    records = list(decode_images(setup, [tag_png, tmp_path / "nope.png"], DecodeOptions(draw_dir=draw)))
    assert [r["image"] for r in records] == [str(tag_png), str(tmp_path / "nope.png")]
    (det,) = records[0]["detections"]
    assert det["lambda"] == TABLE9_TEXT and det["number"] is not None and "error" not in records[0]
    assert "no such file" in records[1]["error"]
    assert (draw / "table9_decoded.png").exists()
    assert all("one_flip_from_tag" not in r for rec in records for r in rec.get("rejections", []))


def test_dictionary_rejections_say_how_near_they_came(db: Database, tag_png: Path) -> None:
    setup = prepare_decoding(db, "five")
    assert setup.dictionary == "five" and setup.near
    (rec,) = decode_images(setup, [tag_png], DecodeOptions())
    assert rec["detections"] == [] and rec["rejected"] >= 1
    assert all("one_flip_from_tag" in r for r in rec["rejections"])


def test_a_dictionary_file_decodes_without_a_database(db: Database, tmp_path: Path) -> None:
    info = get_dictionary(db, "five")
    member = info.members[0]
    png = tmp_path / "member.png"
    render_tag(db, member.lambda_text, png, px=240)  # the best realization: the one "five" pinned
    file = tmp_path / "five.json"
    file.write_text(export_dictionary(db, "five"))
    setup = prepare_file_decoding(file)
    assert setup.dictionary == "five" and setup.near == {}
    (rec,) = decode_images(setup, [png], DecodeOptions())
    (det,) = rec["detections"]
    assert (det["tag"], det["lambda"], det["number"]) == (member.number, member.lambda_text, member.universal_number)
    with pytest.raises(DictionaryError, match="cannot read"):
        prepare_file_decoding(tmp_path / "missing.json")
