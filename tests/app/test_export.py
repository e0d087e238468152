"""Tests of ottag_db.store.tags / ottag_db.app.export and the export and render commands (real PDF, real SQLite)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from pypdf import PdfReader

from ottag_db.cli import cli
from ottag_db.core.layout import validate_layout
from ottag_db.store.db import open_database
from ottag_db.store.models import LayoutRow, Realization
from ottag_db.store.tags import ensure_layouts, load_lookup, select_tags
from tests.support.paper import TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)
MM = 72.0 / 25.4


@pytest.fixture(scope="module")
def laid_out_db(mirrors_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("layouts") / "layouts.sqlite"
    shutil.copyfile(mirrors_db_path, path)
    db = open_database(path)
    try:
        ensure_layouts(db)
    finally:
        db.close()
    return path


@pytest.fixture
def db_copy(laid_out_db: Path, tmp_path: Path) -> Path:
    path = tmp_path / "db.sqlite"
    shutil.copyfile(laid_out_db, path)
    return path


def test_every_stored_layout_is_valid(laid_out_db: Path) -> None:
    db = open_database(laid_out_db)
    try:
        with db.session() as s:
            rows = s.query(Realization, LayoutRow).join(LayoutRow, LayoutRow.realization_id == Realization.id).all()
            checked = {5: 0, 6: 0, 7: 0, 8: 0}
            for real, lay in rows:
                pts = real.points()
                k = len(pts)
                assert validate_layout(pts, lay.triangle_list()) == [], (real.id, lay.triangles)
                assert lay.triangle_count == -(-k // 3)
                placement = np.array(json.loads(lay.placement))
                placed = pts @ placement[:, :2].T + placement[:, 2]
                assert placed.min() > 0 and placed.max() < 1  # inside the data area
                if k in checked:
                    checked[k] += 1
        assert checked == {5: 3, 6: 20, 7: 242, 8: 6405}
    finally:
        db.close()


def test_every_layout_of_the_bundled_database_is_valid(tmp_path: Path) -> None:
    from ottag_db.files.bundled import bundled_point_files
    from ottag_db.store.importer import import_point_file

    db = open_database(tmp_path / "bundled.sqlite")
    try:
        for path, k in bundled_point_files():
            import_point_file(db, path, n=k, with_mirrors=True)
        assert ensure_layouts(db) == 6673 - 2  # every realization but the two of k = 4
        counts = {5: 0, 6: 0, 7: 0, 8: 0}
        with db.session() as s:
            pairs = s.query(Realization, LayoutRow).join(LayoutRow, LayoutRow.realization_id == Realization.id)
            for real, lay in pairs:
                pts = real.points()
                assert validate_layout(pts, lay.triangle_list()) == [], (real.id, lay.triangles)
                if len(pts) in counts:
                    counts[len(pts)] += 1
        assert counts == {5: 3, 6: 20, 7: 242, 8: 6405}
    finally:
        db.close()


def test_select_tags_and_lookup(laid_out_db: Path) -> None:
    db = open_database(laid_out_db)
    try:
        tags = select_tags(db, ks=[7], min_mp=6.0)
        # Table 7: 15 seven-point sets with MP >= 6; 9 of them are chiral, so their mirrors count too.
        assert len(tags) == 15 + 9
        assert sum(t.chiral for t in tags) == 18
        assert all(t.mp >= 6.0 and t.k == 7 for t in tags)
        lookup = load_lookup(db)
        assert len(lookup) == 1 + 2 + 3 + 20 + 242 + 6405
        entry = lookup.get(TABLE9_TEXT)
        assert entry is not None and entry.unique_min
        assert entry.realizations[0].tolist() == [
            [47, 175],
            [149, 206],
            [129, 178],
            [206, 159],
            [214, 127],
            [176, 49],
            [42, 144],
        ]
    finally:
        db.close()


def test_export_sheet_dimensions(runner: CliRunner, db_copy: Path, tmp_path: Path) -> None:
    out = tmp_path / "sheet.pdf"
    res = runner.invoke(
        cli,
        [
            "export",
            "--db",
            str(db_copy),
            "-q",
            "--k",
            "6",
            "--polarity",
            "both",
            "--tag-size",
            "3cm",
            "--page",
            "Letter",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "40 tags" in res.stdout
    reader = PdfReader(out)
    box = reader.pages[0].mediabox
    assert float(box.width) == pytest.approx(8.5 * 72, abs=0.01)
    assert float(box.height) == pytest.approx(11 * 72, abs=0.01)
    meta = reader.metadata
    assert meta is not None and meta.title and "ottag-db" in (meta.author or "")
    text = reader.pages[0].extract_text()
    assert "100 %" in text and "30 mm" in text


def test_export_bad_inputs(runner: CliRunner, db_copy: Path, tmp_path: Path) -> None:
    cases = [
        (["--page", "B7x"], 2, "page"),
        (["--tag-size", "50"], 2, "needs a unit"),
        (["--tag-size", "-5mm"], 2, "greater than zero"),
        (["--tag-size", "400mm"], 1, "fit"),
        (["--k", "8", "--min-mp", "50"], 1, "no tags match the filters"),
        (["--k", "4"], 1, "no tags match"),
    ]
    for args, code, message in cases:
        out = tmp_path / "x.pdf"
        res = runner.invoke(cli, ["export", "--db", str(db_copy), "-q", *args, str(out)])
        assert res.exit_code == code, (args, res.stdout, res.stderr)
        assert message in res.stderr, (args, res.stderr)
        assert not out.exists()
    res = runner.invoke(cli, ["export", "--db", str(db_copy), "-q", "--k", "5", str(tmp_path / "nodir" / "x.pdf")])
    assert res.exit_code == 1 and "does not exist" in res.stderr
    if os.geteuid() != 0:  # root can write anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        res = runner.invoke(cli, ["export", "--db", str(db_copy), "-q", "--k", "5", str(locked / "x.pdf")])
        assert res.exit_code == 1 and "cannot write" in res.stderr


def test_render_png_and_svg(runner: CliRunner, db_copy: Path, tmp_path: Path) -> None:
    import cv2

    png = tmp_path / "t.png"
    res = runner.invoke(cli, ["render", "--db", str(db_copy), TABLE9_TEXT, str(png), "--px", "200"])
    assert res.exit_code == 0, res.output
    img = cv2.imread(str(png), cv2.IMREAD_GRAYSCALE)
    assert img.shape == (300, 300)  # 200 px data area + 2 × 50 px quiet zone
    assert img[5, 5] == 255 and img[60, 60] == 0
    inv = tmp_path / "i.png"
    assert (
        runner.invoke(cli, ["render", "--db", str(db_copy), TABLE9_TEXT, str(inv), "--polarity", "inverted"]).exit_code
        == 0
    )
    assert cv2.imread(str(inv), cv2.IMREAD_GRAYSCALE)[5, 5] == 0
    svg = tmp_path / "t.svg"
    assert runner.invoke(cli, ["render", "--db", str(db_copy), TABLE9_TEXT, str(svg)]).exit_code == 0
    assert svg.read_text().lstrip().startswith("<")
    bad = runner.invoke(cli, ["render", "--db", str(db_copy), TABLE9_TEXT, str(tmp_path / "t.gif")])
    assert bad.exit_code == 2 and ".png or .svg" in bad.stderr
    k4 = runner.invoke(cli, ["render", "--db", str(db_copy), "4:0210001221001200", str(tmp_path / "k4.png")])
    assert k4.exit_code == 1
