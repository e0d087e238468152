"""Reading by model: the printed tags projected through a grazing quad, the best aligned to the image."""

from __future__ import annotations

import numpy as np
import pytest

from ottag_db.core.canonical import canonical_lambda
from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.decode import Detector, DetectorParams
from ottag_db.decode.candidates import HALF_RES_MIN_SIDE, find_quads
from ottag_db.decode.model_align import align_outline, neighbourhood
from ottag_db.decode.model_match import NOT_HELD, read_model, wants_model
from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography, square_homography
from ottag_db.decode.profile import StageClock
from ottag_db.decode.segmentation import segment
from ottag_db.decode.templates import MODEL_GRID, draw_through, rasterize, template_bank
from ottag_db.decode.types import Detection, ModelGuess, Quad, Rejection
from ottag_db.printing import scenes as sc
from tests.support.grazing import grazing_corners, grazing_frame, grazing_set

_REASONS = frozenset({"non_triangle", "point_count", "low_margin", "verification"})


def test_rasterize_gives_the_covered_fraction_of_each_cell() -> None:
    half = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 0.5], [0.0, 0.5]]])  # the upper half
    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
    tri4 = np.pad(tri, ((0, 0), (0, 1), (0, 0)), mode="edge")  # 4 vertices, like the half
    img = rasterize(np.stack([half, tri4] * 200), 0.0, 1.0, 8)  # more than one mosaic canvas
    assert img.shape == (400, 8, 8)
    np.testing.assert_allclose(img[0, :4], 1.0)
    np.testing.assert_allclose(img[0, 5:], 0.0)
    assert img[0, 4].max() <= 0.26  # an edge on supersampled pixel centres fills that row
    assert img[1].mean() == pytest.approx(0.5, abs=0.06)  # its diagonal fills half a pixel more
    np.testing.assert_array_equal(img[398], img[0])
    np.testing.assert_array_equal(img[399], img[1])


def test_draw_through_draws_the_print_as_a_camera_sees_it() -> None:
    """Quiet zone and triangles bright, data area dark, the rest 0; pixel areas, not samples."""
    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])  # half of the data area
    # data area [10, 50) × [10, 50) in pixel edges: unit u ↦ 10 + 40 u − 0.5 at pixel centres
    to_pixels = np.array([[40.0, 0, 9.5], [0, 40.0, 9.5], [0, 0, 1.0]])
    img = draw_through(tri, 0.25, to_pixels, (70, 80))
    assert img.shape == (70, 80) and img.dtype == np.float32
    assert img[10:50, 10:50].mean() == pytest.approx(0.5, abs=0.02)
    np.testing.assert_allclose(img[12:20, 12:20], 1.0)  # inside the triangle
    np.testing.assert_allclose(img[40:48, 40:48], 0.0)  # the dark rest of the data area
    np.testing.assert_allclose(img[0:10, 0:60], 1.0)  # quiet zone: 10 px above the data area
    np.testing.assert_allclose(img[:, 61:], 0.0)  # beyond it nothing is drawn
    # a map that squeezes the tag 8× averages the triangle over each pixel instead of sampling it
    squeezed = np.array([[40.0, 0, 9.5], [0, 5.0, 9.5], [0, 0, 1.0]])
    thin = draw_through(tri, 0.25, squeezed, (30, 80))
    assert 0.3 < thin[12, 10:50].mean() < 0.7 and np.ptp(thin[12, 12:48]) > 0.5


@pytest.mark.filterwarnings("error")
def test_draw_through_stops_the_quiet_zone_at_the_horizon() -> None:
    """Nearly edge-on, the quiet zone's far edge may lie at or beyond the horizon of the map:
    it is drawn up to there, with no garbage from points behind the camera and no NaN cast to
    pixels; a data area that reaches the horizon is no view of a tag at all (blank)."""
    tri = np.array([[[0.1, 0.1], [0.9, 0.1], [0.1, 0.9]]])
    # tag-plane points: in the triangle (bright), in the dark data area, in the quiet zone (bright)
    probes = np.array([[0.3, 0.3], [0.7, 0.5], [-0.1, 0.3]])
    for horizon in (1.1, 1.25):  # y of the horizon: the quiet zone's far edge (1.25) beyond, on it
        cut = np.array([[40.0, 0, 9.5], [0, 40.0, 9.5], [0, -1 / horizon, 1.0]])
        img = draw_through(tri, 0.25, cut, (70, 80))
        assert img.shape == (70, 80) and img.dtype == np.float32 and img.min() >= 0 and img.max() <= 1
        px = np.round(apply_homography(cut, probes)).astype(int)
        assert [float(img[y, x]) for x, y in px] == [1.0, 0.0, 1.0]
    across = np.array([[40.0, 0, 9.5], [0, 40.0, 9.5], [0, -2.0, 1.0]])  # horizon at y = 0.5
    assert not draw_through(tri, 0.25, across, (70, 80)).any()


def test_the_bank_holds_every_printed_tag_normalized(printed) -> None:
    lookup, _ = printed
    bank = template_bank(lookup, 100_000)
    assert bank is not None
    placed = sum(
        1 for e in lookup for lay, place in zip(e.layouts, e.placements, strict=False) if lay and place is not None
    )
    assert len(bank) == placed > 6000
    assert bank.coarse.shape == (placed, MODEL_GRID * MODEL_GRID)
    np.testing.assert_allclose(np.linalg.norm(bank.coarse, axis=1), 1.0, atol=1e-4)
    np.testing.assert_allclose(bank.coarse.mean(axis=1), 0.0, atol=1e-5)
    assert template_bank(lookup, 100) is None  # too many for the bound
    bare = MemoryLookup(LookupEntry(e.lambda_text, e.k, e.order_type_id, e.unique_min, e.realizations) for e in lookup)
    assert template_bank(bare, 100_000) is None  # no layouts or placements: nothing printed


def test_which_candidates_are_read_by_model() -> None:
    thin = Quad("normal", np.array([[0, 0], [100, 0], [100, 20], [0, 20.0]]), 2000.0)
    square = Quad("normal", np.array([[0, 0], [100, 0], [100, 100], [0, 100.0]]), 10000.0)
    p = DetectorParams()
    assert wants_model(thin, Rejection("point_count"), _REASONS, p)
    assert wants_model(thin, Rejection("no_triangles"), _REASONS, p)
    assert not wants_model(square, Rejection("point_count"), _REASONS, p)
    small = Quad("normal", np.array([[0, 0], [20, 0], [20, 20], [0, 20.0]]), 400.0)  # a tag at 7 m
    assert wants_model(small, Rejection("non_triangle"), _REASONS, p)
    assert not wants_model(small, Rejection("non_triangle"), _REASONS, DetectorParams(model_max_side_px=0))
    # a tag at 3.7 m, or the dark quiet zone of an inverted tag at 6 m
    middling = Quad("normal", np.array([[0, 0], [40, 0], [40, 40], [0, 40.0]]), 1600.0)
    assert wants_model(middling, Rejection("non_triangle"), _REASONS, p)
    assert not wants_model(middling, Rejection("non_triangle"), _REASONS, DetectorParams(model_max_side_px=32))
    # not a quad without contrast inside: thin dark strips in clutter are such quads (on the
    # frames of benchmarks/decode_speed.py, one in four frames has one, 10–90 ms each by model)
    assert not wants_model(thin, Rejection("low_contrast"), _REASONS, p)
    # … except from the last-resort passes of a frame that read nothing, and foreshortened
    assert wants_model(thin, Rejection("low_contrast"), _REASONS, p, edge_on_pass=True)
    assert not wants_model(square, Rejection("low_contrast"), _REASONS, p, edge_on_pass=True)
    assert not wants_model(small, Rejection("low_contrast"), _REASONS, p, edge_on_pass=True)
    assert not wants_model(thin, Rejection("point_count"), _REASONS, DetectorParams(model_match=False))
    # the points read clearly a tag the lookup does not hold: none of its look-alikes by model
    for reason in NOT_HELD:
        assert not wants_model(thin, Rejection(reason), _REASONS | NOT_HELD, p)
        assert not wants_model(small, Rejection(reason), _REASONS | NOT_HELD, p, blurred=True)


@pytest.mark.parametrize("seed", [0, 7])
def test_a_small_inverted_tag_seen_only_as_its_dark_quiet_zone_is_read_by_model(printed, seed) -> None:
    """An inverted 21 cm tag at 6 m: a 24 px data area whose blurred dark triangles join its
    dark quiet zone, so that the quiet zone's outline (36 px) is the only candidate; read by
    model, the dark quad's views include the inverted tag inside it."""
    lookup, tags = printed
    rng = np.random.default_rng(seed)
    tag = tags[seed % len(tags)]
    spec = sc.posed_spec(tag, rng, 24.5, 15.0, "inverted")
    image = sc.render_scene((480, 640), [spec], rng, blur=0.7, noise=1.0, gradient=0.25, jpeg=85).image
    dets, rejected = Detector(lookup, DetectorParams(model_match=False)).detect_with_rejections(image)
    assert dets == [] and rejected
    for r in rejected:
        x, y = r.corners.T
        side = np.sqrt(abs(x @ np.roll(y, -1) - np.roll(x, -1) @ y) / 2)
        # the dark quiet zone's outline; the white data area, notched where the triangles join
        # the quiet zone, only as the lines of its sides (outlines.lines_outline)
        assert (r.polarity == "normal" and 34 < side < 38) or (r.polarity == "inverted" and side < 28)
    read = Detector(lookup).detect(image)
    assert [(d.lambda_text, d.polarity) for d in read] == [(tag.lambda_text, "inverted")]
    assert read[0].model_correlation is not None
    # from the 36 px quiet zone only with model_max_side_px above it (the data area's own
    # outline of lines, under 28 px, may still be read: never as another tag)
    assert all(
        d.lambda_text == tag.lambda_text for d in Detector(lookup, DetectorParams(model_max_side_px=32)).detect(image)
    )


def test_grazing_set_is_read_with_no_wrong_id(printed, capsys) -> None:
    """The grazing set (80–86°, both polarities): zero wrong IDs, and reading by model adds
    reads (measured 28/28 with it, 12/28 without; 27/28 before a data area 4–6 px thin was
    thresholded inside a 1 px band: an 86° normal tag had shown no contrast inside and was not
    read by model, see :func:`test_which_candidates_are_read_by_model`)."""
    lookup, tags = printed
    full = Detector(lookup)
    without = Detector(lookup, DetectorParams(model_match=False))
    n = ok = ok_without = wrong = by_model = 0
    for seed, tilt, pol in grazing_set():
        tag, image = grazing_frame(tags, seed, tilt, pol)
        n += 1
        dets = full.detect(image)
        ok += any(d.lambda_text == tag.lambda_text for d in dets)
        wrong += sum(d.lambda_text != tag.lambda_text for d in dets)
        by_model += sum(d.model_correlation is not None for d in dets)
        ok_without += any(d.lambda_text == tag.lambda_text for d in without.detect(image))
    with capsys.disabled():
        print(f"\ngrazing 80–86°: {ok}/{n} ({by_model} by model), without reading by model {ok_without}/{n}")
    assert wrong == 0
    assert ok >= 27 and ok >= ok_without + 10


def test_a_reading_by_model_needs_a_quiet_zone_as_its_polarity_prints_it(printed) -> None:
    """A normal tag at 84° (seed 121 of the grazing set) is read by model with ρ 0.99 and a
    white quiet band 0.06 off its print (in units of the tag's contrast): a limit under that
    refuses it, and the refusal says why."""
    lookup, tags = printed
    tag, image = grazing_frame(tags, 121, 84.0, "normal")
    read = Detector(lookup).detect(image)
    assert [(d.lambda_text, d.polarity) for d in read] == [(tag.lambda_text, "normal")]
    assert read[0].model_correlation is not None and read[0].model_correlation > 0.98
    strict = Detector(lookup, DetectorParams(model_max_quiet_misfit=0.05))
    dets, rejected = strict.detect_with_rejections(image)
    assert dets == [] and any("by model: ρ 0.99" in r.detail and "quiet zone 0.06" in r.detail for r in rejected)


def test_tags_missing_from_the_lookup_are_not_read_as_others(printed) -> None:
    """A dictionary does not hold every tag in view: at grazing views the best stored tag can
    resemble the one seen (correlation up to 0.89 when the seen tag's own template is missing);
    the misfit rule must refuse it. The grazing frames (78–86°) of the 24 tags, decoded with
    a lookup that lacks exactly those 24 order types, give no detection at all."""
    lookup, tags = printed
    missing = {t.lambda_text for t in tags}
    others = Detector(MemoryLookup(e for e in lookup if e.lambda_text not in missing))
    found = []
    for seed in range(60):
        tilt = 78.0 + seed % 9
        _, image = grazing_frame(tags, seed, tilt, "normal" if seed % 3 else "inverted")
        found += [(seed, tilt, d.lambda_text, d.model_correlation) for d in others.detect(image)]
    assert found == []


def test_a_model_reading_maps_the_stored_tag_onto_the_image(printed) -> None:
    lookup, tags = printed
    found = []
    for seed in range(40):
        tag, image = grazing_frame(tags, seed, 83.0)
        found += [(tag, d) for d in Detector(lookup).detect(image) if d.model_correlation is not None]
        if found:
            break
    assert found, "no frame of 40 at 83° read by model"
    tag, det = found[0]
    assert det.lambda_text == tag.lambda_text
    assert det.reprojection_error_px is None and det.homography is not None
    entry = lookup.get(det.lambda_text)
    assert entry is not None and det.order_type_id == entry.order_type_id
    # the points are the stored realization mapped by the homography, and keep its order type
    real = next(r for r in entry.realizations if det.model_points is None or np.array_equal(r, det.model_points))
    np.testing.assert_allclose(apply_homography(det.homography, real), det.points, atol=1e-6)
    assert canonical_lambda(det.points) == det.lambda_text
    assert det.margin_px > 0 and 0.8 <= (det.model_correlation or 0) <= 1.0


def test_thin_quads_are_found_at_full_resolution(printed) -> None:
    """At 85° the data area is a sliver 5–8 px across: the half-resolution pass misses it, the
    full-resolution pass for thin quads finds it (and only thin quads)."""
    _, tags = printed
    _, image = grazing_frame(tags, 109, 85.0)
    p = DetectorParams()
    assert find_quads(image, "adaptive", p) == []
    thin = find_quads(image, "adaptive_thin", p)
    assert len(thin) == 1 and thin[0].area < 2 * HALF_RES_MIN_SIDE * 100.0
    _, head_on = grazing_frame(tags, 109, 10.0)
    assert find_quads(head_on, "adaptive", p) and find_quads(head_on, "adaptive_thin", p) == []


def test_a_rival_from_another_outline_of_the_data_area_counts(printed) -> None:
    """Each outline of a data area nearly edge-on gets its own reading by model; the best tag of
    a refused one (``Rejection.model_best``) is a rival of the others' winner unless it is the
    same tag: within ``model_min_gap`` of the winner it makes the reading ambiguous."""
    lookup, tags = printed
    tag, image = grazing_frame(tags, 121, 84.0, "normal")
    params = DetectorParams()
    bank = template_bank(lookup, params.model_max_templates)
    first = Rejection("non_triangle")
    readings = []
    for kind in ("adaptive", "otsu", "adaptive_thin"):
        for quad in find_quads(image, kind, params):
            result = read_model(image, quad, first, bank, params, StageClock())
            if isinstance(result, Detection) and result.lambda_text == tag.lambda_text:
                readings.append((quad, result))
    assert readings, "no outline of the tag reads by model"
    quad, read = readings[0]
    rho = read.model_correlation or 0.0
    other = next(t.lambda_text for t in tags if t.lambda_text != tag.lambda_text)
    close = read_model(image, quad, first, bank, params, StageClock(), (ModelGuess(other, "normal", rho - 0.02),))
    assert isinstance(close, Rejection) and close.model_best is not None
    assert (close.model_best.lambda_text, close.model_best.polarity) == (tag.lambda_text, "normal")
    far = read_model(image, quad, first, bank, params, StageClock(), (ModelGuess(other, "normal", rho - 0.2),))
    same = read_model(image, quad, first, bank, params, StageClock(), (ModelGuess(tag.lambda_text, "normal", 1.0),))
    assert isinstance(far, Detection) and isinstance(same, Detection)
    assert far.lambda_text == same.lambda_text == tag.lambda_text


def test_an_edge_on_data_area_without_contrast_inside_is_read_by_model(printed) -> None:
    """At 86–87° a normal tag's data area is 4–6 px thin and dark up to its outline, its slivers
    blurred into the quiet zone: inside the band segmentation leaves out, nothing but dark
    shows (``low_contrast``). From the last-resort passes (``adaptive_thin``, ``bright_holes``)
    such a quad is read by model; these two frames read no other way (they did not before)."""
    lookup, tags = printed
    p = DetectorParams()
    bank = template_bank(lookup, p.model_max_templates)
    assert bank is not None
    for seed, tilt in ((0, 86.0), (147, 87.0)):
        tag, image = grazing_frame(tags, seed, tilt)
        reads = []
        for quad in find_quads(image, "adaptive_thin", p):
            first = segment(image, quad, p)
            assert isinstance(first, Rejection) and first.reason == "low_contrast"
            assert wants_model(quad, first, _REASONS, p, edge_on_pass=True)
            reads.append(read_model(image, quad, first, bank, p, StageClock()))
        assert [(r.lambda_text, r.polarity) for r in reads if isinstance(r, Detection)] == [(tag.lambda_text, "normal")]
        assert [d.lambda_text for d in Detector(lookup).detect(image)] == [tag.lambda_text]


def _corner_error(corners: np.ndarray, truth: np.ndarray) -> float:
    """How far (data-area units, in its best turn) the data area ``corners`` outline puts the
    true corners."""
    errors = []
    for r in range(4):
        hom = square_homography(np.roll(corners, -r, axis=0))
        if hom is not None:
            errors.append(float(np.abs(apply_homography(np.linalg.inv(hom), truth) - UNIT_SQUARE).max()))
    return min(errors)


def test_the_outline_alignment_finds_the_data_area_nearly_edge_on(printed) -> None:
    """A normal tag's contour corners at 84–86° miss the data area by 8 % of its side (median);
    aligned to the outline of a tag (quiet zone and the rim of the data area, its triangles
    masked out) they miss it by 4 % (a blank template of the whole data area made them worse)."""
    _, tags = printed
    p = DetectorParams()
    before, after = [], []
    for seed in range(12):
        tilt = 84.0 + seed % 3
        _, image = grazing_frame(tags, seed, tilt)
        truth = grazing_corners(tags, seed, tilt)
        for kind in ("adaptive", "otsu", "adaptive_thin", "bright_holes"):
            for quad in find_quads(image, kind, p):
                if _corner_error(quad.corners, truth) > 0.3:
                    continue  # not the data area
                roi, origin = neighbourhood(image, [quad.corners])
                to_frame = align_outline(roi, origin, "normal", quad.corners)
                assert to_frame is not None
                before.append(_corner_error(quad.corners, truth))
                after.append(_corner_error(apply_homography(to_frame, UNIT_SQUARE), truth))
    assert len(before) >= 24
    assert np.median(after) <= 0.6 * np.median(before)
    assert np.mean(np.less(after, before)) >= 0.7
