"""Calibration boards (ottag_db.app.boards, ottag_db.printing.board) on the bundled database:
real SQLite, real PDF (read back with pypdf and rasterized with pypdfium2)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from pypdf import PdfReader

from ottag_db.app.boards import BOARD_FORMAT, board_lookup, board_path_for, create_board, read_board
from ottag_db.core.canonical import canonical_form
from ottag_db.errors import BoardError, ExportError
from ottag_db.printing.pdf import MM_TO_PT
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary
from ottag_db.store.flipgraph import flip_adjacency
from ottag_db.store.tags import select_tags


@pytest.fixture(scope="module")
def board_db(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the bundled database (board creation stores the flip graph of k = 8)."""
    path = tmp_path_factory.mktemp("boarddb") / "board.sqlite"
    shutil.copy(bundled_db_path, path)
    return path


@pytest.fixture(scope="module")
def made_board(board_db: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    out = tmp_path_factory.mktemp("board") / "board.pdf"
    db = open_database(board_db)
    try:
        _, board_file = create_board(db, out, rows=4, cols=3, tag_size_mm=40.0, spacing_mm=10.0)
    finally:
        db.close()
    return out, board_file


def test_board_file_geometry(made_board: tuple[Path, Path], board_db: Path) -> None:
    pdf, board_file = made_board
    assert board_file == board_path_for(pdf) == pdf.with_name("board.board.json")
    data = json.loads(board_file.read_text())
    assert data["format"] == BOARD_FORMAT
    assert (data["rows"], data["cols"], data["tag_size_mm"], data["k"]) == (4, 3, 40.0, 8)
    tags = data["tags"]
    assert len(tags) == 12 and len({t["lambda"] for t in tags}) == 12
    for i, t in enumerate(tags):
        assert (t["row"], t["col"]) == divmod(i, 3)
        x0, y0 = 50.0 * t["col"], 50.0 * t["row"]
        assert t["corners_mm"] == [[x0, y0], [x0 + 40, y0], [x0 + 40, y0 + 40], [x0, y0 + 40]]
        pts = np.array(t["points_mm"])
        assert pts.shape == (8, 2)
        assert np.all((pts > [x0, y0]) & (pts < [x0 + 40, y0 + 40]))
        # canonical label order: the points' own canonical labeling is the identity
        form = canonical_form(pts)
        assert form.text == t["lambda"] and form.unique_min and form.labeling == tuple(range(8))
    # the highest-MP unique-minimum tags, no two one flip apart
    db = open_database(board_db)
    try:
        recs = {r.lambda_text: r for r in select_tags(db, ks=[8], matchable=True)}
        adj = flip_adjacency(db, [8])
    finally:
        db.close()
    chosen = [recs[t["lambda"]] for t in tags]
    ids = {r.order_type_id for r in chosen}
    assert all(not (adj.get(r.order_type_id, set()) & ids) for r in chosen)
    # the greedy choice of `dictionary create --matchable` (MP descending, then λ), first 12
    expected: list[int] = []
    for r in sorted(recs.values(), key=lambda r: (-r.mp, r.lambda_text)):
        if len(expected) < 12 and not (adj.get(r.order_type_id, set()) & set(expected)):
            expected.append(r.order_type_id)
    assert [r.order_type_id for r in chosen] == expected


def test_pdf_is_exact_size_with_tags_where_the_file_says(made_board: tuple[Path, Path]) -> None:
    import pypdfium2 as pdfium

    pdf, board_file = made_board
    reader = PdfReader(str(pdf))
    assert len(reader.pages) == 1
    box = reader.pages[0].mediabox
    assert float(box.width) == pytest.approx(210 * MM_TO_PT, abs=0.01)
    assert float(box.height) == pytest.approx(297 * MM_TO_PT, abs=0.01)
    board = read_board(board_file)
    assert board.page_origin_mm is not None
    ppmm = 8.0
    doc = pdfium.PdfDocument(str(pdf))
    try:
        page = doc[0].render(scale=ppmm / MM_TO_PT, grayscale=True).to_numpy()
    finally:
        doc.close()
    page = page[..., 0] if page.ndim == 3 else page
    ox, oy = board.page_origin_mm
    for t in board.tags:
        (x0, y0), (x1, _) = t.corners_mm[0], t.corners_mm[2]
        # inside the data area near its border: black; 2 mm outside: white paper
        inner = page[int((oy + y0 + 0.6) * ppmm), int((ox + (x0 + x1) / 2) * ppmm)]
        outer = page[int((oy + y0 - 2) * ppmm), int((ox + (x0 + x1) / 2) * ppmm)]
        assert inner < 60 and outer > 200
        # every point is a triangle vertex: white and black pixels meet within 0.5 mm of it
        for x, y in t.points_mm:
            c, r = int((ox + x) * ppmm), int((oy + y) * ppmm)
            patch = page[r - 4 : r + 5, c - 4 : c + 5]
            assert patch.min() < 60 and patch.max() > 200


def test_board_that_does_not_fit_names_the_largest_grid(board_db: Path, tmp_path: Path) -> None:
    db = open_database(board_db)
    try:
        with pytest.raises(ExportError, match="largest board that fits is 4 rows × 3 columns"):
            create_board(db, tmp_path / "big.pdf", rows=5, cols=4, tag_size_mm=40.0, spacing_mm=10.0)
        with pytest.raises(ExportError, match="landscape"):
            create_board(db, tmp_path / "wide.pdf", rows=3, cols=5, tag_size_mm=30.0, spacing_mm=10.0)
    finally:
        db.close()
    assert not (tmp_path / "big.pdf").exists() and not (tmp_path / "big.board.json").exists()


def test_board_from_a_dictionary(board_db: Path, tmp_path: Path) -> None:
    db = open_database(board_db)
    try:
        create_dictionary(db, "cal7", DictionaryOptions(ks=(7,), matchable=True, polarity="both"))
        board, path = create_board(
            db, tmp_path / "d.pdf", rows=2, cols=2, tag_size_mm=30, spacing_mm=8, page="A5", dictionary="cal7"
        )
    finally:
        db.close()
    assert board.dictionary == "cal7" and board.ks == (7,)
    assert [t.polarity for t in board.tags] == ["normal", "inverted", "normal", "inverted"]
    lookup = board_lookup(read_board(path))  # one entry per order type, a tag number per polarity
    assert len(lookup) == 2
    entry = lookup.get(board.tags[0].lambda_text)
    assert entry is not None and dict(entry.extra["tags"]) == {"normal": 0, "inverted": 1}


def test_bad_board_files(made_board: tuple[Path, Path], tmp_path: Path) -> None:
    _, board_file = made_board
    with pytest.raises(BoardError, match="not found"):
        read_board(tmp_path / "missing.board.json")
    bad = tmp_path / "x.board.json"
    bad.write_text("not json")
    with pytest.raises(BoardError, match="not a JSON board file"):
        read_board(bad)
    bad.write_text(json.dumps({"format": "ottag-dictionary/1"}))
    with pytest.raises(BoardError, match="not an ottag-board/1 board file"):
        read_board(bad)
    data = json.loads(board_file.read_text())
    data["tags"][3]["points_mm"] = data["tags"][3]["points_mm"][::-1]  # not in canonical order
    bad.write_text(json.dumps(data))
    with pytest.raises(BoardError, match=r"tag 3 .*canonical label order"):
        read_board(bad)
    data = json.loads(board_file.read_text())
    del data["tags"][0]["corners_mm"]
    bad.write_text(json.dumps(data))
    with pytest.raises(BoardError, match="tag 0 has no 'corners_mm'"):
        read_board(bad)
