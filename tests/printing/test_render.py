"""Tag placement and renderers: raster and PDF (rasterised at 300 dpi) agree to sub-pixel precision."""

from __future__ import annotations

import io
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from ottag_db.core.canonical import canonical_lambda
from ottag_db.core.geometry import maximal_perturbation
from ottag_db.core.layout import compute_layout
from ottag_db.core.layout_check import validate_layout
from ottag_db.core.placement import tag_placement
from ottag_db.errors import UsageError
from ottag_db.printing.geometry import TagGeometry, build_tag_geometries, build_tag_geometry
from ottag_db.printing.pdf import MM_TO_PT, draw_tag_pdf
from ottag_db.printing.raster import raster_positions, render_raster
from ottag_db.printing.svg import render_svg

SET5 = np.array([(20, 20), (230, 40), (200, 230), (60, 200), (120, 110)])
SET6 = np.array([(77, 63), (191, 206), (78, 215), (224, 137), (149, 56), (27, 145)])
SET7 = np.array([(2, 135), (209, 203), (42, 71), (138, 55), (31, 192), (252, 177), (228, 94)])
SET8 = np.array([(142, 249), (16, 73), (229, 172), (235, 89), (40, 24), (191, 108), (191, 5), (99, 242)])

DPI = 300
DATA_PX = 400
QUIET_PX = 100
TAG_MM = DATA_PX / DPI * 25.4
QUIET_MM = QUIET_PX / DPI * 25.4


def _geom(points: np.ndarray, polarity: str = "normal") -> TagGeometry:
    lay = compute_layout(points)
    return build_tag_geometry(
        points,
        lay.triangles,
        polarity=polarity,  # type: ignore[arg-type]
        tag_size=TAG_MM,
        quiet_zone=QUIET_MM,
    )


def _pdf_raster(geom: TagGeometry) -> np.ndarray:
    """The tag drawn alone on a page of exactly its size, rasterised by pdfium at 300 dpi."""
    import pypdfium2 as pdfium
    from reportlab.pdfgen.canvas import Canvas

    side = geom.total_size * MM_TO_PT
    buf = io.BytesIO()
    canvas = Canvas(buf, pagesize=(side, side), invariant=1)
    draw_tag_pdf(canvas, geom, 0.0, 0.0)
    canvas.showPage()
    canvas.save()
    pdf = pdfium.PdfDocument(buf.getvalue())
    image = pdf[0].render(scale=DPI / 72.0).to_pil().convert("L")
    arr = np.asarray(image, dtype=np.float64)
    size = DATA_PX + 2 * QUIET_PX
    assert abs(arr.shape[0] - size) <= 1 and abs(arr.shape[1] - size) <= 1
    return arr[:size, :size]


def _sample(img: np.ndarray, xy: np.ndarray) -> np.ndarray:
    # continuous pixel coordinates (pixel [r, c] covers [c, c+1) × [r, r+1)) → array indices
    return np.asarray(map_coordinates(img, [xy[..., 1] - 0.5, xy[..., 0] - 0.5], order=1, mode="nearest"))


def _inside(tri: np.ndarray, p: np.ndarray) -> bool:
    s = []
    for i in range(3):
        u, v = tri[(i + 1) % 3] - tri[i], p - tri[i]
        s.append(u[0] * v[1] - u[1] * v[0])
    return bool(all(v > 0 for v in s) or all(v < 0 for v in s))


def _fitted_vertices(img: np.ndarray, geom: TagGeometry) -> list[tuple[int, np.ndarray]]:
    """Vertices found in ``img`` by fitting lines to sub-pixel edge points of each triangle.

    Edge points come from intensity profiles across the middle part of each edge (step-edge
    position = L − ∫ normalised intensity); a vertex is the intersection of its two fitted
    edges. Returns ``(point index, estimated position)`` per triangle corner.
    """
    pos = raster_positions(geom, DATA_PX, QUIET_PX)
    _, data_tone, tri_tone = geom.tones()
    pts = pos.points
    half = 2.5
    offsets = np.linspace(-half, half, 101)
    step = offsets[1] - offsets[0]
    found: list[tuple[int, np.ndarray]] = []
    for t in geom.triangles:
        tri = pts[list(t)]
        lines = []
        for e in range(3):
            p, q, r = tri[e], tri[(e + 1) % 3], tri[(e + 2) % 3]
            d = (q - p) / np.linalg.norm(q - p)
            n = np.array([-d[1], d[0]])
            if np.dot(r - p, n) < 0:
                n = -n
            edge_pts = []
            for s in np.linspace(0.2, 0.8, 25):
                c = p + s * (q - p)
                deep, out = c + (half + 0.7) * n, c - (half + 0.7) * n
                others = [pts[list(o)] for o in geom.triangles if o != t]
                if not _inside(tri, deep) or any(_inside(o, out) for o in others):
                    continue
                prof = _sample(img, c[None] + offsets[:, None] * n[None])
                f = (prof - data_tone) / (tri_tone - data_tone)
                s0 = half - np.trapezoid(f, dx=step)
                edge_pts.append(c + s0 * n)
            assert len(edge_pts) >= 5, "edge too short for the fit"
            arr = np.array(edge_pts)
            centre = arr.mean(axis=0)
            direction = np.linalg.svd(arr - centre)[2][0]
            lines.append((centre, direction))
        for v in range(3):
            (c1, d1), (c2, d2) = lines[(v + 2) % 3], lines[v]  # edges meeting at corner v
            a = np.array([d1, -d2]).T
            s = np.linalg.solve(a, c2 - c1)
            found.append((t[v], c1 + s[0] * d1))
    return found


@pytest.mark.parametrize("points", [SET5, SET6, SET7, SET8], ids=["k5", "k6", "k7", "k8"])
@pytest.mark.parametrize("polarity", ["normal", "inverted"])
def test_raster_and_pdf_show_the_same_vertices(points: np.ndarray, polarity: str) -> None:
    geom = _geom(points, polarity)
    raster = render_raster(geom, DATA_PX, quiet_px=QUIET_PX).astype(np.float64)
    pdf = _pdf_raster(geom)
    assert raster.shape == pdf.shape == (DATA_PX + 2 * QUIET_PX,) * 2
    expected = raster_positions(geom, DATA_PX, QUIET_PX).points
    for name, img in (("raster", raster), ("pdf", pdf)):
        for idx, est in _fitted_vertices(img, geom):
            err = float(np.linalg.norm(est - expected[idx]))
            assert err < 0.3, f"{name}: vertex {idx} off by {err:.3f} px"
    # the two images agree almost everywhere (only anti-aliased edge pixels differ)
    diff = np.abs(raster - pdf)
    assert (diff > 128).mean() < 1e-3
    assert diff.mean() < 2.0


@pytest.mark.parametrize("polarity", ["normal", "inverted"])
def test_raster_tones_corners_and_no_mirroring(polarity: str) -> None:
    geom = _geom(SET7, polarity)
    img = render_raster(geom, DATA_PX, quiet_px=QUIET_PX)
    pos = raster_positions(geom, DATA_PX, QUIET_PX)
    quiet, data, tri = geom.tones()
    assert img.dtype == np.uint8 and img.shape == (pos.size, pos.size)
    assert img[2, 2] == quiet and img[-3, -3] == quiet
    assert img[QUIET_PX + 2, QUIET_PX + 2] == data
    np.testing.assert_array_equal(pos.corners, [[100, 100], [500, 100], [500, 500], [100, 500]])
    # the corners are exactly where the tone changes
    assert img[QUIET_PX, QUIET_PX] == data and img[QUIET_PX - 1, QUIET_PX - 1] == quiet
    # file point (x, y) → column ∝ x, row ∝ y: pixel position = q + px · (A·p + t) with det A > 0
    m = np.array(geom.transform)
    assert np.linalg.det(m[:, :2]) > 0
    np.testing.assert_allclose(pos.points, QUIET_PX + DATA_PX * (SET7 @ m[:, :2].T + m[:, 2]))
    for t in geom.triangles:
        cx, cy = pos.points[list(t)].mean(axis=0)
        assert img[int(cy), int(cx)] == tri


def test_placement_keeps_order_type_margin_and_improves_mp() -> None:
    for pts in (SET5, SET6, SET7, SET8):
        m = tag_placement(pts, inner_margin=0.1)
        placed = pts @ m[:, :2].T + m[:, 2]
        assert canonical_lambda(placed) == canonical_lambda(pts)
        assert placed.min() >= 0.1 - 1e-9 and placed.max() <= 0.9 + 1e-9
        lo, hi = placed.min(axis=0), placed.max(axis=0)
        assert max(hi - lo) == pytest.approx(0.8)
        identity_mp = maximal_perturbation(pts) * 0.8 / (pts.max(axis=0) - pts.min(axis=0)).max()
        geom = _geom(pts)
        assert geom.mp_unit == pytest.approx(maximal_perturbation(placed), rel=1e-9)
        assert geom.mp_unit >= identity_mp - 1e-12
        assert geom.mp_mm == pytest.approx(geom.mp_unit * TAG_MM)
        assert validate_layout(geom.points_array, geom.triangles) == []


def test_bundled_sets_place_and_keep_their_order_type(bundled_sets: dict[int, np.ndarray]) -> None:
    from ottag_db.core.layout import compute_layouts

    sets = bundled_sets[7]
    layouts = compute_layouts(sets)
    geoms = build_tag_geometries(sets, [lay.triangles for lay in layouts], tag_size=40.0)
    for pts, g in zip(sets, geoms, strict=True):
        assert canonical_lambda(g.points_array) == canonical_lambda(pts)
        assert g.quiet_zone == 10.0 and g.total_size == 60.0
        assert g.mp_mm > 0
    # Given placements are used as they are (here: the same maps, so the same geometries).
    maps = np.array([g.transform for g in geoms])
    again = build_tag_geometries(sets, [lay.triangles for lay in layouts], tag_size=40.0, placements=maps)
    assert again == geoms
    with pytest.raises(ValueError, match="placements"):
        build_tag_geometries(sets, [lay.triangles for lay in layouts], placements=maps[:3])


def test_geometry_helpers_and_bad_input() -> None:
    geom = _geom(SET6)
    big = geom.resized(50.0)
    assert big.tag_size == 50.0 and big.quiet_zone == 12.5 and big.points == geom.points
    assert geom.with_polarity("inverted").tones() == (0, 255, 0)
    with pytest.raises(UsageError):
        geom.resized(0.0)
    with pytest.raises(UsageError):
        geom.with_polarity("sideways")  # type: ignore[arg-type]
    with pytest.raises(UsageError):
        render_raster(geom, 0)
    with pytest.raises(UsageError):
        tag_placement(SET6, inner_margin=0.6)


def test_svg_is_well_formed_and_in_mm() -> None:
    geom = _geom(SET7).resized(40.0, 10.0)
    text = render_svg(geom, title="7:012 <test> & co")
    root = ET.fromstring(text.encode("utf-8"))
    ns = "{http://www.w3.org/2000/svg}"
    assert root.tag == f"{ns}svg"
    assert root.get("width") == "60mm" and root.get("height") == "60mm"
    assert root.get("viewBox") == "0 0 60 60"
    rects = root.findall(f"{ns}rect")
    assert [(r.get("width"), r.get("fill")) for r in rects] == [("60", "#ffffff"), ("40", "#000000")]
    assert rects[1].get("x") == "10" and rects[1].get("y") == "10"
    path = root.find(f"{ns}path")
    assert path is not None and path.get("fill") == "#ffffff"
    nums = [float(v) for v in path.get("d", "").replace("M", " ").replace("L", " ").replace("Z", " ").split()]
    coords = np.array(nums).reshape(-1, 3, 2)
    expected = 10.0 + 40.0 * geom.points_array
    for tri, t in zip(coords, geom.triangles, strict=True):
        np.testing.assert_allclose(tri, expected[list(t)], atol=1e-4)
    inv = ET.fromstring(render_svg(geom.with_polarity("inverted")))
    assert [r.get("fill") for r in inv.findall(f"{ns}rect")] == ["#000000", "#ffffff"]
