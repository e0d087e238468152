"""Tests of ottag_db.app.export and ottag_db.store.tags on the bundled database (real PDF, real SQLite).

Export only reads: layouts and placements come from the database, so it works on a read-only
file and places nothing afresh.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from pypdf import PdfReader
from sqlalchemy import select

from ottag_db.app.export import (
    TagFilter,
    export_sheet,
    render_tag,
    resolve_tag,
    select_for_export,
    short_id,
    tag_geometries,
)
from ottag_db.core.canonical import canonical_form
from ottag_db.core.layout_check import validate_layout
from ottag_db.core.placement import apply_placements
from ottag_db.decode import Detection, Detector
from ottag_db.errors import ExportError, NotFoundError, UsageError
from ottag_db.printing.geometry import build_tag_geometries
from ottag_db.printing.sheet import SheetOptions
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary
from ottag_db.store.layouts import ensure_layouts
from ottag_db.store.lookups import load_lookup
from ottag_db.store.models import LayoutRow, Realization
from ottag_db.store.queries import list_order_types
from ottag_db.store.tags import select_tags
from tests.support.database import dump_database
from tests.support.paper import TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)
MM = 72.0 / 25.4


@pytest.fixture
def db_copy(bundled_db_path: Path, tmp_path: Path) -> Path:
    path = tmp_path / "db.sqlite"
    shutil.copyfile(bundled_db_path, path)
    return path


def test_every_stored_layout_is_valid(bundled_db_path: Path) -> None:
    db = open_database(bundled_db_path)
    try:
        assert ensure_layouts(db) == 0  # import stored them all
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


def test_select_tags_and_lookup(bundled_db_path: Path) -> None:
    db = open_database(bundled_db_path)
    try:
        tags = select_tags(db, ks=[7], min_mp=6.0)
        listed = list_order_types(db, ks=[7], min_mp=6.0)
        assert [t.lambda_text for t in tags] == [o.lambda_text for o in listed]
        assert [t.mp for t in tags] == [o.mp for o in listed]  # the tag is the best realization
        assert all(t.mp >= 6.0 and t.k == 7 for t in tags)
        assert all((t.mirror in {u.lambda_text for u in tags}) for t in tags if t.chiral)  # both chiralities
        assert select_tags(db, ks=[4]) == []  # k = 4 cannot be drawn
        lookup = load_lookup(db)
        assert len(lookup) == 1 + 2 + 3 + 20 + 242 + 6405
        entry = lookup.get(TABLE9_TEXT)
        assert entry is not None and entry.unique_min
        # Lookup realizations are in canonical label order: their canonical labeling is the identity.
        form = canonical_form(entry.realizations[0])
        assert form.text == TABLE9_TEXT and form.labeling == tuple(range(7))
    finally:
        db.close()


def test_geometry_from_stored_placements_equals_a_fresh_placement(bundled_db_path: Path) -> None:
    db = open_database(bundled_db_path)
    try:
        tags = select_tags(db, ks=[6, 7, 8], min_mp=8.0)
    finally:
        db.close()
    stored = tag_geometries(tags, "normal", 40.0)
    for k in (6, 7, 8):
        part = [t for t in tags if t.k == k]
        fresh = build_tag_geometries(
            np.stack([t.points for t in part]).astype(np.float64), [t.triangles for t in part], tag_size=40.0
        )
        assert [g for g, t in zip(stored, tags, strict=True) if t.k == k] == fresh
    for g, t in zip(stored, tags, strict=True):
        assert g.mp_unit == t.printed_mp_unit


def test_export_reads_only(db_copy: Path, tmp_path: Path) -> None:
    """A read-only database file exports and renders; its bytes stay the same."""
    before = db_copy.read_bytes()
    db_copy.chmod(0o444)
    db = open_database(f"sqlite:///file:{db_copy}?mode=ro&uri=true")
    try:
        rep = export_sheet(db, tmp_path / "ro.pdf", TagFilter(ks=(7,), min_mp=8.0), SheetOptions(), polarity="both")
        assert rep.tags > 0 and (tmp_path / "ro.pdf").stat().st_size > 0
        render_tag(db, TABLE9_TEXT, tmp_path / "t.svg")
    finally:
        db.close()
    assert db_copy.read_bytes() == before


def test_export_draws_the_stored_placement(db_copy: Path) -> None:
    """Export reads each tag's placement from the database instead of placing it afresh: a
    stored map changed by hand is the one drawn."""
    db = open_database(db_copy)
    try:
        (tag,) = select_tags(db, lambdas=[TABLE9_TEXT])
        moved = tag.placement * np.array([[0.9], [0.9]]) + np.array([[0, 0, 0.05], [0, 0, 0.05]])
        with db.session() as s:
            row = s.execute(select(LayoutRow).where(LayoutRow.realization_id == tag.realization_id)).scalar_one()
            row.placement = json.dumps(moved.tolist())
        (reread,) = select_tags(db, lambdas=[TABLE9_TEXT])
    finally:
        db.close()
    (geom,) = tag_geometries([reread], "normal", 40.0)
    assert np.allclose(np.asarray(geom.points_array), apply_placements(moved[None], reread.points[None])[0])
    assert not np.allclose(moved, tag.placement)


def test_export_is_deterministic(db_copy: Path, tmp_path: Path) -> None:
    db = open_database(db_copy)
    try:
        flt = TagFilter(ks=(6, 7), min_mp=7.0)
        export_sheet(db, tmp_path / "a.pdf", flt, SheetOptions(), polarity="both")
        before = dump_database(db_copy)
        export_sheet(db, tmp_path / "b.pdf", flt, SheetOptions(), polarity="both")
        assert dump_database(db_copy) == before
    finally:
        db.close()
    assert (tmp_path / "a.pdf").read_bytes() == (tmp_path / "b.pdf").read_bytes()


def test_export_sheet_dimensions(db_copy: Path, tmp_path: Path) -> None:
    out = tmp_path / "sheet.pdf"
    db = open_database(db_copy)
    try:
        rep = export_sheet(db, out, TagFilter(ks=(6,)), SheetOptions(tag_size_mm=30.0, page="Letter"), polarity="both")
        first = select_tags(db, ks=[6])[0].lambda_text
    finally:
        db.close()
    assert rep.tags == 40
    reader = PdfReader(out)
    box = reader.pages[0].mediabox
    assert float(box.width) == pytest.approx(8.5 * 72, abs=0.01)
    assert float(box.height) == pytest.approx(11 * 72, abs=0.01)
    meta = reader.metadata
    assert meta is not None and meta.title and "ottag-db" in (meta.author or "")
    text = reader.pages[0].extract_text()
    assert "100 %" in text and "30 mm" in text and short_id(first) in text


def test_export_bad_inputs(db_copy: Path, tmp_path: Path) -> None:
    out = tmp_path / "x.pdf"
    db = open_database(db_copy)
    try:
        cases: list[tuple[TagFilter, SheetOptions, str, type[Exception], str]] = [
            (TagFilter(ks=(5,)), SheetOptions(tag_size_mm=400.0), "normal", ExportError, "fit"),
            (TagFilter(ks=(8,), min_mp=50.0), SheetOptions(), "normal", ExportError, "no tags match the filters"),
            (TagFilter(ks=(4,)), SheetOptions(), "normal", ExportError, "no tags match"),
            (TagFilter(ks=(5,)), SheetOptions(), "sideways", UsageError, "polarity"),
        ]
        for flt, opts, polarity, error, message in cases:
            with pytest.raises(error, match=message):
                export_sheet(db, out, flt, opts, polarity=polarity)
            assert not out.exists()
        with pytest.raises(ExportError, match="does not exist"):
            export_sheet(db, tmp_path / "nodir" / "x.pdf", TagFilter(ks=(5,)), SheetOptions())
        with pytest.raises(ExportError, match="directory"):
            export_sheet(db, tmp_path, TagFilter(ks=(5,)), SheetOptions())
    finally:
        db.close()


def test_filters_by_ids_and_dictionary_sheet(db_copy: Path, tmp_path: Path) -> None:
    db = open_database(db_copy)
    try:
        fig4 = resolve_tag(db, TABLE9_TEXT)
        other = select_tags(db, ks=[5])[0]
        both = select_for_export(db, TagFilter(ids=(TABLE9_TEXT, str(other.order_type_id))))
        assert [t.lambda_text for t in both] == [other.lambda_text, fig4.lambda_text]  # by k, then λ
        assert resolve_tag(db, str(fig4.order_type_id)).lambda_text == TABLE9_TEXT
        with pytest.raises(NotFoundError):
            resolve_tag(db, "4:0210001221001200")  # k = 4: no layout
        create_dictionary(db, "robots", DictionaryOptions(ks=(7,), polarity="both", max_size=20))
        rep = export_sheet(db, tmp_path / "d.pdf", TagFilter(), SheetOptions(), dictionary="robots")
        assert rep.tags == 20
        text = PdfReader(tmp_path / "d.pdf").pages[0].extract_text()
        assert "robots tag 0" in text and "dictionary robots" in text
    finally:
        db.close()


def test_short_id_is_stable() -> None:
    assert short_id(TABLE9_TEXT).startswith("7-") and len(short_id(TABLE9_TEXT)) == 10
    assert short_id(TABLE9_TEXT) == short_id(TABLE9_TEXT) != short_id("3:011001100")


def test_render_png_and_svg(db_copy: Path, tmp_path: Path) -> None:
    import cv2

    db = open_database(db_copy)
    try:
        png = tmp_path / "t.png"
        render_tag(db, TABLE9_TEXT, png, px=200)
        img = cv2.imread(str(png), cv2.IMREAD_GRAYSCALE)
        assert img.shape == (300, 300)  # 200 px data area + 2 × 50 px quiet zone
        assert img[5, 5] == 255 and img[60, 60] == 0
        inv = tmp_path / "i.png"
        render_tag(db, TABLE9_TEXT, inv, polarity="inverted")
        assert cv2.imread(str(inv), cv2.IMREAD_GRAYSCALE)[5, 5] == 0
        svg = tmp_path / "t.svg"
        render_tag(db, TABLE9_TEXT, svg)
        assert svg.read_text().lstrip().startswith("<")
        with pytest.raises(UsageError, match=r"\.png or \.svg"):
            render_tag(db, TABLE9_TEXT, tmp_path / "t.gif")
        with pytest.raises(NotFoundError):
            render_tag(db, "4:0210001221001200", tmp_path / "k4.png")
    finally:
        db.close()


def _decode_page(pdf: Path, page_no: int, det: Detector, dpi: float) -> list[tuple[str, str]]:
    """(λ, polarity) of the tags found on a rasterized page, row by row from the top left."""
    import pypdfium2 as pdfium

    doc = pdfium.PdfDocument(str(pdf))
    try:
        page = doc[page_no]
        img = page.render(scale=dpi / 72.0, grayscale=True).to_numpy()
        page.close()
    finally:
        doc.close()
    img = img[:, :, 0] if img.ndim == 3 else img
    dets = sorted(det.detect(np.ascontiguousarray(img)), key=lambda d: d.center[1])
    rows: list[list[Detection]] = []
    for d in dets:  # a new row where the centres jump by more than half a tag
        if rows and d.center[1] - rows[-1][-1].center[1] < 20 / 25.4 * dpi:
            rows[-1].append(d)
        else:
            rows.append([d])
    return [(d.lambda_text, d.polarity) for row in rows for d in sorted(row, key=lambda d: d.center[0])]


def test_readme_export_packs_twelve_tags_per_a4_page(db_copy: Path, tmp_path: Path) -> None:
    """The README's set-up export: 3 × 4 tags of 40 mm per A4 page, counted in the report
    line, and every tag of a packed page (shared quiet zones) decodes at its place, in
    either polarity."""
    from click.testing import CliRunner

    from ottag_db.app.detector import open_detector
    from ottag_db.cli import cli

    flt = TagFilter(ks=(8,), min_mp=10.0)
    db = open_database(db_copy)
    try:
        expected = [t.lambda_text for t in select_for_export(db, flt)]
    finally:
        db.close()
    runner = CliRunner()
    args = ["export", "--db", str(db_copy), "--quiet", "--k", "8", "--min-mp", "10", "--tag-size", "40mm"]
    out = tmp_path / "tags.pdf"
    res = runner.invoke(cli, [*args, str(out)])
    assert res.exit_code == 0, res.output
    pages = -(-len(expected) // 12)
    assert f"{len(expected)} tags on {pages} page(s), 12 per page (3×4, shared quiet zones)" in res.stdout
    assert len(PdfReader(out).pages) == pages
    det = open_detector(str(db_copy))
    assert _decode_page(out, 0, det, 150) == [(lam, "normal") for lam in expected[:12]]
    last = (pages - 1) * 12
    assert _decode_page(out, pages - 1, det, 150) == [(lam, "normal") for lam in expected[last:]]
    inv = tmp_path / "inverted.pdf"
    res = runner.invoke(cli, [*args, "--polarity", "inverted", str(inv)])
    assert res.exit_code == 0 and "12 per page (3×4, shared quiet zones)" in res.stdout
    assert _decode_page(inv, 0, det, 150) == [(lam, "inverted") for lam in expected[:12]]
    # the previous layout: whole quiet zones each, 5 mm apart
    res = runner.invoke(cli, [*args, "--no-pack", "--spacing", "5mm", str(tmp_path / "loose.pdf")])
    assert res.exit_code == 0 and "shared" not in res.stdout
    res = runner.invoke(cli, [*args, "--spacing", "-1mm", str(tmp_path / "bad.pdf")])
    assert res.exit_code == 2 and "-1mm" in res.output


# ----------------------------------------------------------------------------- issue 11, item 8
def test_export_refuses_non_pdf_names(db_copy: Path, tmp_path: Path) -> None:
    db = open_database(db_copy)
    try:
        for name in ("x.png", "x.svg", "sheet", "x.pdf.tmp"):
            with pytest.raises(UsageError, match=r"name it \.pdf.*ottag-db render ID OUT\.png\|OUT\.svg"):
                export_sheet(db, tmp_path / name, TagFilter(ks=(5,)), SheetOptions())
            assert not (tmp_path / name).exists()
        rep = export_sheet(db, tmp_path / "upper.PDF", TagFilter(ks=(5,)), SheetOptions())
        assert rep.tags == 3 and (tmp_path / "upper.PDF").read_bytes().startswith(b"%PDF")
    finally:
        db.close()


def test_four_point_tags_are_explained(db_copy: Path, tmp_path: Path) -> None:
    db = open_database(db_copy)
    try:
        k4 = list_order_types(db, ks=(4,))
        assert len(k4) == 2
        why = "order types of 4 points cannot be drawn as tags.*no shared edge"
        for flt in (TagFilter(ks=(4,)), TagFilter(ids=(k4[0].lambda_text,)), TagFilter(ids=(str(k4[1].id),))):
            with pytest.raises(ExportError, match="no tags match.*" + why):
                export_sheet(db, tmp_path / "k4.pdf", flt, SheetOptions())
        with pytest.raises(ExportError, match="no tags match") as info:
            export_sheet(db, tmp_path / "k8.pdf", TagFilter(ks=(8,), min_mp=50.0), SheetOptions())
        assert "4 points" not in str(info.value)  # only said when 4-point tags were asked for
        assert "no order types of k" not in str(info.value)
        with pytest.raises(ExportError, match=r"no order types of k = 9: import them first"):
            export_sheet(db, tmp_path / "k9.pdf", TagFilter(ks=(9,)), SheetOptions())
        for ident in (k4[0].lambda_text, str(k4[0].id)):
            with pytest.raises(NotFoundError, match=why):
                render_tag(db, ident, tmp_path / "k4.png")
        with pytest.raises(NotFoundError, match="no order type with id 999999"):
            render_tag(db, "999999", tmp_path / "none.png")
        assert not list(tmp_path.glob("k4.*"))
    finally:
        db.close()


def test_export_progress_in_pages_and_whole_wall_time(db_copy: Path, tmp_path: Path) -> None:
    import time

    calls: list[tuple[int, int]] = []
    db = open_database(db_copy)
    try:
        started = time.perf_counter()
        rep = export_sheet(
            db, tmp_path / "p.pdf", TagFilter(ks=(7,)), SheetOptions(), progress=lambda d, t: calls.append((d, t))
        )
        elapsed = time.perf_counter() - started
        select_started = time.perf_counter()
        select_for_export(db, TagFilter(ks=(7,)))
        select_seconds = time.perf_counter() - select_started
    finally:
        db.close()
    assert rep.pages > 1
    assert calls == [(p, rep.pages) for p in range(rep.pages + 1)]  # 0 before drawing, then each page
    assert len(PdfReader(tmp_path / "p.pdf").pages) == rep.pages
    # The report's seconds cover the whole call (selection too), not only the drawing.
    assert select_seconds * 0.5 < rep.seconds <= elapsed
