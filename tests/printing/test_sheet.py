"""PDF tag sheets read back with pypdf: page size, exact tag squares, 100 mm ruler, labels, errors."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from pypdf import PdfReader
from pypdf.generic import ContentStream

from ottag_db.core.layout import compute_layout
from ottag_db.errors import ExportError, UsageError
from ottag_db.printing.geometry import TagGeometry, build_tag_geometry
from ottag_db.printing.pdf import MM_TO_PT
from ottag_db.printing.sheet import (
    RULER_LENGTH_MM,
    SheetOptions,
    SheetTag,
    parse_length,
    parse_page,
    sheet_grid,
    sheet_layout,
    write_tag_sheet,
)

pdfium = pytest.importorskip("pypdfium2")

SETS = [
    np.array([(20, 20), (230, 40), (200, 230), (60, 200), (120, 110)]),
    np.array([(77, 63), (191, 206), (78, 215), (224, 137), (149, 56), (27, 145)]),
    np.array([(2, 135), (209, 203), (42, 71), (138, 55), (31, 192), (252, 177), (228, 94)]),
    np.array([(142, 249), (16, 73), (229, 172), (235, 89), (40, 24), (191, 108), (191, 5), (99, 242)]),
]
TOL_MM = 0.01


def _geoms() -> list[TagGeometry]:
    out = []
    for pts in SETS:
        g = build_tag_geometry(pts, compute_layout(pts).triangles, tag_size=50.0)
        out += [g, g.with_polarity("inverted")]
    return out


def _tags(n: int) -> list[SheetTag]:
    geoms = _geoms()
    return [SheetTag(geoms[i % len(geoms)], f"{geoms[i % len(geoms)].k}:{i:04d}") for i in range(n)]


def _mm(v: float) -> float:
    return v / MM_TO_PT


def _page_ops(reader: PdfReader, page_no: int) -> tuple[list[tuple[float, ...]], list[tuple[float, ...]]]:
    """Rectangles ``(x, y, w, h)`` and straight segments ``(x1, y1, x2, y2)`` in page mm."""
    page = reader.pages[page_no]
    content = ContentStream(page.get_contents(), reader)
    ctm = np.eye(3)
    stack: list[np.ndarray] = []
    rects: list[tuple[float, ...]] = []
    segs: list[tuple[float, ...]] = []
    current = None

    def apply(x: float, y: float) -> tuple[float, float]:
        v = np.array([x, y, 1.0]) @ ctm
        return _mm(float(v[0])), _mm(float(v[1]))

    for operands, op in content.operations:
        if op == b"q":
            stack.append(ctm.copy())
        elif op == b"Q":
            ctm = stack.pop()
        elif op == b"cm":
            a, b, c, d, e, f = (float(v) for v in operands)
            ctm = np.array([[a, b, 0], [c, d, 0], [e, f, 1]]) @ ctm
        elif op == b"re":
            x, y, w, h = (float(v) for v in operands)
            x0, y0 = apply(x, y)
            x1, y1 = apply(x + w, y + h)
            rects.append((x0, y0, x1 - x0, y1 - y0))
        elif op == b"m":
            current = apply(*(float(v) for v in operands))
        elif op == b"l":
            nxt = apply(*(float(v) for v in operands))
            assert current is not None
            segs.append((*current, *nxt))
            current = nxt
    return rects, segs


def _squares(rects: list[tuple[float, ...]], side: float) -> list[tuple[float, ...]]:
    return [r for r in rects if abs(r[2] - side) < 0.5 and abs(r[3] - side) < 0.5]


def test_sheet_pages_squares_ruler_labels(tmp_path: Path) -> None:
    options = SheetOptions(tag_size_mm=30.0, page="A4", filter_summary="k = 5 … 8, test selection")
    cols, rows = sheet_grid(options, _tags(len(_geoms())))  # both polarities: no shared quiet zones
    per_page = cols * rows
    assert (cols, rows) == sheet_grid(options, _tags(per_page + 3))
    tags = _tags(per_page + 3)
    out = tmp_path / "sheet.pdf"
    seen: list[tuple[int, int]] = []
    report = write_tag_sheet(out, tags, options, progress=lambda d, t: seen.append((d, t)))
    assert report.pages == 2 and report.tags == len(tags) and report.per_page == per_page
    assert seen == [(per_page, len(tags)), (len(tags), len(tags))]
    assert report.quiet_zone_mm == 7.5 and report.page_size_mm == (210.0, 297.0)
    reader = PdfReader(out)
    assert len(reader.pages) == 2
    meta = reader.metadata
    assert meta is not None
    assert meta.title == "Order Type Tags" and meta.author == "ottag-db" and meta.creator == "ottag-db"
    assert meta.subject
    for page_no, on_page in enumerate((per_page, 3)):
        page = reader.pages[page_no]
        assert abs(_mm(float(page.mediabox.width)) - 210.0) < TOL_MM
        assert abs(_mm(float(page.mediabox.height)) - 297.0) < TOL_MM
        rects, segs = _page_ops(reader, page_no)
        data = _squares(rects, 30.0)
        outer = _squares(rects, 45.0)
        assert len(data) == on_page and len(outer) == on_page
        for r in data:
            assert abs(r[2] - 30.0) < TOL_MM and abs(r[3] - 30.0) < TOL_MM
            # inside its quiet zone, 7.5 mm from each side
            assert any(abs(r[0] - o[0] - 7.5) < TOL_MM and abs(r[1] - o[1] - 7.5) < TOL_MM for o in outer)
            assert r[0] >= 10.0 - TOL_MM and r[0] + r[2] <= 200.0 + TOL_MM  # inside the margins
        # the ruler: one horizontal 100 mm baseline with 101 ticks 1 mm apart
        base = [s for s in segs if abs(s[1] - s[3]) < 1e-6 and abs(abs(s[2] - s[0]) - RULER_LENGTH_MM) < TOL_MM]
        assert len(base) == 1
        x0, y0 = min(base[0][0], base[0][2]), base[0][1]
        ticks = sorted(
            s[0] for s in segs if abs(s[0] - s[2]) < 1e-6 and abs(s[1] - y0) < 1e-6 and x0 - 0.01 <= s[0] <= x0 + 100.01
        )
        assert len(ticks) == 101
        assert np.allclose(np.diff(ticks), 1.0, atol=TOL_MM)
        text = page.extract_text()
        assert "k = 5 … 8, test selection" in text or "test selection" in text
        assert "Tag size 30 mm" in text and "100 % scale" in text
        assert f"page {page_no + 1} / 2" in text
        assert "k=" in text and "MP" in text and "mm" in text
    first_text = reader.pages[0].extract_text()
    assert "5:0000" in first_text and "inverted" in first_text and "normal" in first_text


def test_labels_show_printed_mp_at_the_sheet_size(tmp_path: Path) -> None:
    geom = _geoms()[4]  # built at 50 mm
    out = tmp_path / "one.pdf"
    write_tag_sheet(out, [SheetTag(geom, "7:abc", caption="#12")], SheetOptions(tag_size_mm=20.0))
    text = PdfReader(out).pages[0].extract_text()
    assert f"MP {geom.mp_unit * 20.0:.2f} mm" in text
    assert "7:abc" in text and "#12" in text and "k=7" in text


def test_output_is_deterministic_and_options_work(tmp_path: Path) -> None:
    tags = _tags(5)
    a, b = tmp_path / "a.pdf", tmp_path / "b.pdf"
    write_tag_sheet(a, tags, SheetOptions())
    write_tag_sheet(b, tags, SheetOptions())
    assert a.read_bytes() == b.read_bytes()
    plain = tmp_path / "plain.pdf"
    report = write_tag_sheet(
        plain, tags, SheetOptions(labels=False, cut_marks=False, page="Letter", compress=False, spacing_mm=0)
    )
    reader = PdfReader(plain)
    assert abs(_mm(float(reader.pages[0].mediabox.width)) - 215.9) < TOL_MM
    assert "k=" not in reader.pages[0].extract_text()
    assert report.columns * report.rows >= 5 and not report.packed  # mixed polarities
    custom = tmp_path / "custom.pdf"
    write_tag_sheet(custom, tags, SheetOptions(page="150x200mm", tag_size_mm=15.0, title="Mine"))
    reader = PdfReader(custom)
    box = reader.pages[0].mediabox
    assert abs(_mm(float(box.width)) - 150) < TOL_MM and abs(_mm(float(box.height)) - 200) < TOL_MM
    assert reader.metadata is not None and reader.metadata.title == "Mine"


def test_errors_write_nothing(tmp_path: Path) -> None:
    out = tmp_path / "x.pdf"
    with pytest.raises(ExportError, match="no tags"):
        write_tag_sheet(out, [], SheetOptions())
    assert not out.exists()
    with pytest.raises(ExportError, match="does not fit"):
        write_tag_sheet(out, _tags(1), SheetOptions(tag_size_mm=200.0))
    assert not out.exists()
    with pytest.raises(ExportError, match="ruler"):
        write_tag_sheet(out, _tags(1), SheetOptions(page="110x200mm", tag_size_mm=20.0))
    missing = tmp_path / "no" / "such" / "dir" / "x.pdf"
    with pytest.raises(ExportError, match=str(missing).replace("\\", "\\\\")):
        write_tag_sheet(missing, _tags(1), SheetOptions())
    with pytest.raises(ExportError, match="directory"):
        write_tag_sheet(tmp_path, _tags(1), SheetOptions())
    with pytest.raises(UsageError):
        write_tag_sheet(out, _tags(1), SheetOptions(tag_size_mm=-1.0))
    with pytest.raises(UsageError):
        write_tag_sheet(out, _tags(1), SheetOptions(page="A9"))
    assert not out.exists()


def test_parse_length_and_page() -> None:
    assert parse_length("50mm") == 50.0
    assert parse_length("5cm") == 50.0
    assert parse_length("2in") == pytest.approx(50.8)
    assert parse_length(" 12.5 mm ") == 12.5
    assert parse_length("72pt") == pytest.approx(25.4)
    assert parse_length("1.5IN") == pytest.approx(38.1)
    for bad in ("50", "-5mm", "0mm", "5 furlongs", "abc", "", "mm"):
        with pytest.raises(UsageError):
            parse_length(bad)
    assert parse_length("0mm", allow_zero=True) == 0.0 and parse_length("2cm", allow_zero=True) == 20.0
    for bad in ("0", "-1mm", "-0.5cm"):
        with pytest.raises(UsageError):
            parse_length(bad, allow_zero=True)
    with pytest.raises(UsageError, match="greater than zero"):
        parse_length("0mm")
    assert parse_page("A4") == (210.0, 297.0)
    assert parse_page("letter") == (215.9, 279.4)
    assert parse_page("A4-landscape") == (297.0, 210.0)
    assert parse_page("210x297mm") == (210.0, 297.0)
    w, h = parse_page("8.5x11in")
    assert w == pytest.approx(215.9) and h == pytest.approx(279.4)
    for bad in ("A9", "210x297", "0x297mm", "x297mm"):
        with pytest.raises(UsageError):
            parse_page(bad)


def test_many_tags_fill_pages_in_order(tmp_path: Path) -> None:
    # Speed is measured by benchmarks/export_speed.py, not here.
    geoms = _geoms()
    n = 500
    tags = [SheetTag(geoms[i % len(geoms)], f"{geoms[i % len(geoms)].k}:{i:05d}") for i in range(n)]
    report = write_tag_sheet(tmp_path / "big.pdf", tags, SheetOptions(tag_size_mm=40.0))
    assert report.pages == math.ceil(n / report.per_page)
    assert len(PdfReader(tmp_path / "big.pdf").pages) == report.pages


def _readme_tags(n: int, polarities: tuple[str, ...]) -> list[SheetTag]:
    """k = 8 tags labelled like ``export`` labels them (short ID and database id)."""
    base = _geoms()[6]  # k = 8, normal
    out = []
    for i in range(n):
        geom = base.with_polarity(polarities[i % len(polarities)])  # type: ignore[arg-type]
        out.append(SheetTag(geom, f"8-{i:08x}", caption=f"#{1490 + i}"))
    return out


def _overlap(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    """Boxes ``(x, y, w, h)`` share interior points."""
    eps = TOL_MM  # PDF coordinates are written rounded
    return (
        a[0] + a[2] > b[0] + eps and b[0] + b[2] > a[0] + eps and a[1] + a[3] > b[1] + eps and b[1] + b[3] > a[1] + eps
    )


def _check_page(pdf: Path, page_no: int, options: SheetOptions, n_tags: int, polarities: list[str]) -> None:
    """The page's tags: exact data areas and quiet zones, inside the printable area, no ink of
    anything else (another tag, a label, header, footer) in any tag's quiet zone or data area."""
    size, quiet = options.tag_size_mm, options.quiet_mm()
    total = size + 2 * quiet
    pw, ph = options.page_size_mm()
    m = options.margin_mm
    reader = PdfReader(pdf)
    rects, _ = _page_ops(reader, page_no)
    data = sorted(_squares(rects, size), key=lambda r: (-round(r[1], 3), r[0]))  # row by row
    outer = sorted(_squares(rects, total), key=lambda r: (-round(r[1], 3), r[0]))
    assert len(data) == n_tags and len(outer) == n_tags
    for d, o in zip(data, outer, strict=True):
        assert abs(d[2] - size) < TOL_MM and abs(d[3] - size) < TOL_MM
        assert abs(o[2] - total) < TOL_MM and abs(o[3] - total) < TOL_MM
        assert abs(d[0] - o[0] - quiet) < TOL_MM and abs(d[1] - o[1] - quiet) < TOL_MM  # centred
        # inside the printable area (the margins)
        assert o[0] >= m - TOL_MM and o[0] + o[2] <= pw - m + TOL_MM
        assert o[1] >= m - TOL_MM and o[1] + o[3] <= ph - m + TOL_MM
    for i, (o, pol) in enumerate(zip(outer, polarities, strict=True)):
        for j, (d2, o2) in enumerate(zip(data, outer, strict=True)):
            if i == j:
                continue
            assert not _overlap(o, d2), (i, j)  # another tag's data area never in a quiet zone
            if pol != polarities[j] or options.cut_marks:
                assert not _overlap(o, o2), (i, j)  # quiet zones of other tones never overlap
    # text (labels, header, footer) never inside a tag's quiet zone or data area
    doc = pdfium.PdfDocument(str(pdf))
    try:
        page = doc[page_no]
        text = page.get_textpage()
        boxes = [text.get_charbox(c) for c in range(text.count_chars())]
        assert boxes
        for left, bottom, right, top in boxes:
            if right - left < 1e-3:
                continue  # spaces, line breaks
            box = (_mm(left), _mm(bottom), _mm(right - left), _mm(top - bottom))
            assert not any(_overlap(box, o) for o in outer), box
        # rasterized: every quiet zone is all its own tone (white for normal, black for inverted)
        dpi = 200.0
        img = page.render(scale=dpi / 72.0, grayscale=True).to_numpy()
        text.close()
        page.close()
    finally:
        doc.close()
    img = img[:, :, 0] if img.ndim == 3 else img
    px = dpi / 25.4
    cols = (np.arange(img.shape[1]) + 0.5) / px
    rows = ph - (np.arange(img.shape[0]) + 0.5) / px  # page mm, y up
    pad = 1.5 / px
    for d, o, pol in zip(data, outer, polarities, strict=True):
        in_x = (cols > o[0] + pad) & (cols < o[0] + o[2] - pad)
        in_y = (rows > o[1] + pad) & (rows < o[1] + o[3] - pad)
        out_data_x = (cols < d[0] - pad) | (cols > d[0] + d[2] + pad)
        out_data_y = (rows < d[1] - pad) | (rows > d[1] + d[3] + pad)
        ring = in_y[:, None] & in_x[None, :] & (out_data_y[:, None] | out_data_x[None, :])
        values = img[ring]
        assert values.size > 0.9 * (total**2 - size**2) * px * px
        if pol == "normal":
            assert values.min() >= 250, (pol, d)
        else:
            assert values.max() <= 5, (pol, d)


@pytest.mark.parametrize(
    ("polarities", "cut_marks", "packed"),
    [
        (("normal",), False, True),
        (("inverted",), False, True),
        (("normal", "inverted"), False, False),
        (("normal",), True, False),
    ],
)
def test_packed_pages_keep_every_quiet_zone_clean(
    tmp_path: Path, polarities: tuple[str, ...], cut_marks: bool, packed: bool
) -> None:
    """README settings (A4, 40 mm, default quiet zone, margins and spacing, labels): ≥ 3 × 4
    tags per page when the tags share quiet zones, and every page checked for exact sizes,
    the printable area and quiet zones free of any other ink."""
    options = SheetOptions(tag_size_mm=40.0, cut_marks=cut_marks)
    probe = _readme_tags(8, polarities)
    layout = sheet_layout(options, probe)
    assert layout.packed == packed
    n = layout.per_page + 2
    tags = _readme_tags(n, polarities)
    out = tmp_path / "packed.pdf"
    report = write_tag_sheet(out, tags, options)
    assert report.per_page == layout.per_page and report.packed == packed and report.pages == 2
    if packed:
        assert (report.columns, report.rows) == (3, 4)  # the README's sheet: 12 tags per A4 page
        # neighbours share one quiet zone: data areas exactly one quiet zone apart
        assert layout.pitch_x == pytest.approx(40.0 + 10.0)
    for page_no, count in ((0, layout.per_page), (1, 2)):
        first = page_no * layout.per_page
        pols = [t.polarity for t in tags[first : first + count]]
        _check_page(out, page_no, options, count, pols)
    text = PdfReader(out).pages[0].extract_text()
    assert "8-00000000" in text and "#1490" in text and "MP" in text


def test_packing_without_labels_shares_rows_too(tmp_path: Path) -> None:
    options = SheetOptions(tag_size_mm=30.0, labels=False, cut_marks=False)
    tags = _readme_tags(30, ("normal",))
    layout = sheet_layout(options, tags)
    assert layout.packed and layout.pitch_x == layout.pitch_y == pytest.approx(37.5)
    unpacked = sheet_layout(dataclasses.replace(options, pack=False), tags)
    assert not unpacked.packed and unpacked.pitch_y == pytest.approx(45.0)
    assert (layout.columns, layout.rows) == (4, 6) and (unpacked.columns, unpacked.rows) == (4, 5)
    out = tmp_path / "plain.pdf"
    write_tag_sheet(out, tags, options)
    _check_page(out, 0, options, layout.per_page, ["normal"] * layout.per_page)
    # the grid without tags holds any tags (no sharing, two-line labels)
    assert sheet_grid(SheetOptions(tag_size_mm=40.0)) == (3, 3)
