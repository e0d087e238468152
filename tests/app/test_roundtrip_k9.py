"""Round trip of nine-point tags: point file → database → PDF sheet → raster page → decoder.

Twenty nine-point sets of :mod:`tests.support.k9_sample` (seeded random sets with a decent MP,
no reference or bundle bytes) are written as a ``.b08`` file, imported with mirrors into a
fresh database, exported on one A4 sheet (30 mm tags, packed), rasterized with pdfium and
decoded with a detector loaded from that database: every tag must decode with its own ID and
polarity, nothing else may decode. ``benchmarks/roundtrip_k9.py`` runs the same on 2,000 tags.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from ottag_db.app.detector import open_detector
from ottag_db.app.export import TagFilter, export_sheet, render_tag, select_for_export
from ottag_db.core.canonical import canonical_batch
from ottag_db.core.layout import validate_layout
from ottag_db.files.pointfile import read_point_file, write_point_file
from ottag_db.files.resources import data_dir
from ottag_db.printing.sheet import SheetOptions
from ottag_db.store.db import open_database
from ottag_db.store.importer import import_point_file
from tests.support.k9_sample import nine_point_sets

pdfium = pytest.importorskip("pypdfium2")

DPI = 250


@pytest.fixture(scope="module")
def k9_db(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    """A database holding the 20 sample order types and their mirrors (some are achiral); the samples' IDs."""
    tmp = tmp_path_factory.mktemp("k9")
    pts = nine_point_sets(20)
    src = tmp / "sample09.b08"
    write_point_file(src, pts, bits=8)
    path = tmp / "k9.sqlite"
    db = open_database(path)
    try:
        report = import_point_file(db, src, n=9, with_mirrors=True)
    finally:
        db.close()
    texts = canonical_batch(pts).texts()
    mirrors = canonical_batch(pts * np.array([-1, 1])).texts()
    assert report.records == 20 and report.new_order_types == len(set(texts) | set(mirrors))
    return path, texts


def test_nine_point_layouts_are_stored(k9_db: tuple[Path, list[str]]) -> None:
    path, texts = k9_db
    db = open_database(path)
    try:
        tags = select_for_export(db, TagFilter(ks=(9,)))
    finally:
        db.close()
    assert len(tags) > 20 and set(texts) <= {t.lambda_text for t in tags}
    for t in tags:
        assert len(t.triangles) == 3 and sorted(v for tri in t.triangles for v in tri) == list(range(9))
        assert validate_layout(t.points, t.triangles) == []
        assert 0 < t.printed_mp_unit < 0.1


def test_nine_point_sheet_decodes_every_tag(k9_db: tuple[Path, list[str]], tmp_path: Path) -> None:
    path, texts = k9_db
    flt = TagFilter(ids=tuple(texts))
    db = open_database(path)
    try:
        expected = [t.lambda_text for t in select_for_export(db, flt)]
        pdf = tmp_path / "k9.pdf"
        report = export_sheet(db, pdf, flt, SheetOptions(tag_size_mm=30.0, cut_marks=False))
    finally:
        db.close()
    assert report.tags == 20 and sorted(expected) == sorted(texts)
    det = open_detector(str(path))
    doc = pdfium.PdfDocument(str(pdf))
    try:
        assert len(doc) == report.pages
        for page_no in range(len(doc)):
            page = doc[page_no]
            img = page.render(scale=DPI / 72.0, grayscale=True).to_numpy()
            page.close()
            if img.ndim == 3:
                img = img[:, :, 0]
            dets = det.detect(np.ascontiguousarray(img))
            want = expected[page_no * report.per_page : (page_no + 1) * report.per_page]
            got = Counter((d.lambda_text, d.polarity) for d in dets)
            assert got == Counter((lam, "normal") for lam in want), f"page {page_no + 1}"
            assert all(d.k == 9 and len(d.points) == 9 for d in dets)
    finally:
        doc.close()


def test_nine_point_tag_renders(k9_db: tuple[Path, list[str]], tmp_path: Path) -> None:
    path, texts = k9_db
    db = open_database(path)
    try:
        out = tmp_path / "tag.png"
        render_tag(db, texts[0], out, px=400, polarity="inverted")
    finally:
        db.close()
    import cv2

    img = cv2.imread(str(out), cv2.IMREAD_GRAYSCALE)
    assert img is not None
    found = open_detector(str(path)).detect(img)
    assert [(d.lambda_text, d.polarity) for d in found] == [(texts[0], "inverted")]


#: Record 74,211 of the bundled ``ottag-k09.b08``: its tag's sliver tip lies near another
#: triangle's tip, and at 300 dpi the side lines of both tips nearly meet in one point.
MERGED_TIPS_RECORD = 74211
MERGED_TIPS_ID = "9:076543210001342567160641325241053436333204454456430321524334043615425302702136450"


def test_tips_of_two_triangles_are_not_read_as_one_shared_point(bundled_db_path: Path, tmp_path: Path) -> None:
    # In the 2,000-tag round trip this tag read as the eight-point type 8:0654…: merging the two
    # tips fitted that type's side lines, though its points missed by 26 px. Next to all eight-point
    # types, it must read as itself.
    path = tmp_path / "k8k9.sqlite"
    path.write_bytes(bundled_db_path.read_bytes())
    src = tmp_path / "one09.b08"
    record = read_point_file(data_dir() / "ottag-k09.b08", 9)[MERGED_TIPS_RECORD]
    write_point_file(src, record[None], bits=8)
    db = open_database(path)
    try:
        import_point_file(db, src, n=9, with_mirrors=True)
        flt = TagFilter(ids=(MERGED_TIPS_ID,))
        sheet = export_sheet(db, tmp_path / "one.pdf", flt, SheetOptions(tag_size_mm=40.0))
    finally:
        db.close()
    assert sheet.tags == 1
    doc = pdfium.PdfDocument(str(tmp_path / "one.pdf"))
    try:
        image = doc[0].render(scale=300 / 72.0, grayscale=True).to_numpy()
    finally:
        doc.close()
    image = image[:, :, 0] if image.ndim == 3 else image
    detections = open_detector(str(path)).detect(np.ascontiguousarray(image))
    assert [d.lambda_text for d in detections] == [MERGED_TIPS_ID]
