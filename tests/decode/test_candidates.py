"""Candidate stage: quads of a binarized frame."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ottag_db.decode import Detector, DetectorParams, candidates
from ottag_db.decode.blur import edge_blur
from ottag_db.decode.camera_blur import motion_kernel
from ottag_db.decode.candidates import find_quads
from ottag_db.decode.image import DIM_OFFSET_MIN, frame_departure, threshold_offset
from ottag_db.decode.quads import clockwise, squeeze
from ottag_db.decode.types import Quad
from ottag_db.printing import scenes as sc
from tests.support import synthetic_tags as syn
from tests.support.grazing import grazing_corners, grazing_frame, printed_tags


def _expected_corners(side: float, origin: tuple[float, float]) -> np.ndarray:
    x, y = origin
    return np.array([[x, y], [x + side, y], [x + side, y + side], [x, y + side]]) - 0.5


def test_quads_of_a_tag_in_both_polarities() -> None:
    params = DetectorParams()
    for inverted in (False, True):
        image = syn.draw_tags((300, 400), [(160, (60, 70))], inverted=inverted)
        for kind in ("adaptive", "otsu"):
            quads = [q for q in find_quads(image, kind, params) if abs(q.area - 160**2) < 0.1 * 160**2]
            assert len(quads) == 1, (inverted, kind)
            q = quads[0]
            assert q.polarity == ("inverted" if inverted else "normal")
            # the automatic local threshold searches at half resolution: corners to ±2 half-res px
            assert np.abs(q.corners - _expected_corners(160, (60, 70))).max() <= 4.0


def test_polarity_filter_and_size_limits() -> None:
    image = syn.draw_tags((300, 400), [(160, (60, 70))])
    assert all(q.polarity == "normal" for q in find_quads(image, "otsu", DetectorParams(polarities=("normal",))))
    only_inverted = find_quads(image, "otsu", DetectorParams(polarities=("inverted",)))
    assert all(q.polarity == "inverted" for q in only_inverted)
    assert find_quads(image, "otsu", DetectorParams(min_quad_area_px=200**2)) == []
    assert find_quads(np.full((50, 50), 255, np.uint8), "otsu", DetectorParams()) == []


def test_the_bright_holes_pass_finds_foreshortened_normal_data_areas_only() -> None:
    """A thin dark data area inside a white quiet zone, its bright triangles close to its border,
    is a hole of the bright mask: found, as a normal quad. A head-on dark square is left to the
    dark passes, and bright regions are no candidates of this pass."""
    img = np.full((240, 320), 150, np.uint8)
    zone = np.array([[40, 90], [280, 70], [282, 110], [42, 130]], np.int32)
    area = np.array([[60, 94], [260, 77], [261, 104], [61, 121]], np.int32)
    cv2.fillPoly(img, [zone], 255)
    cv2.fillPoly(img, [area], 30)
    for x in (90, 150, 210):  # bright triangles 2 px inside the data area's upper side
        y = 94 - (x - 60) * 17 / 200 + 2
        cv2.fillPoly(img, [np.array([[x, y], [x + 30, y - 2.5], [x + 15, y + 14]], np.int32)], 255)
    cv2.rectangle(img, (20, 170), (80, 230), 255, -1)
    cv2.rectangle(img, (32, 182), (68, 218), 30, -1)  # a head-on normal data area
    img = cv2.GaussianBlur(img, (0, 0), 0.8)
    found = find_quads(img, "bright_holes", DetectorParams())
    assert found and all(q.polarity == "normal" for q in found)
    assert all(squeeze(q) <= DetectorParams().rectify_max_ratio for q in found)
    assert not any(q.corners[:, 1].min() > 160 for q in found)  # not the head-on square
    miss = [float(np.abs(np.sort(q.corners, axis=0) - np.sort(area, axis=0)).max()) for q in found]
    assert min(miss) < 3.0


def _corner_miss(quad: Quad, corners: np.ndarray) -> float:
    """Largest corner distance (px) between a candidate and the true corners, in the best turn."""
    ordered = clockwise(corners)
    return min(float(np.hypot(*(np.roll(quad.corners, r, axis=0) - ordered).T).max()) for r in range(4))


@pytest.mark.parametrize("seed", [3, 12])
def test_a_data_area_cut_into_pieces_is_outlined_by_the_hull_of_its_pieces(printed, seed) -> None:
    """Normal tags at 85° on a dark frame (grey 55): the white triangles blur into the white
    quiet zone and cut the dark data area into pieces, and its outline merges with the frame.
    The holes of the quiet zone's region, joined, outline the data area (the region's outline
    lies where the printed quiet zone ends), and the tag reads; neither read before
    (benchmarks/decode_polarity.py --background 55: normal tags 30 → 52 of 60 at 85°)."""
    lookup, tags = printed
    tag, image = grazing_frame(tags, seed, 85.0, "normal", background=55)
    truth = grazing_corners(tags, seed, 85.0, "normal")
    found = find_quads(image, "bright_holes", DetectorParams())
    assert min(_corner_miss(q, truth) for q in found) < 5.0  # 5 % of the 98 px side
    assert [d.lambda_text for d in Detector(lookup).detect(image)] == [tag.lambda_text]


def test_a_thin_data_area_notched_by_its_triangles_is_outlined_by_its_hull(printed, monkeypatch) -> None:
    """A normal tag at 86° on the usual frame: its white triangles blur into the white quiet
    zone and notch the dark data area's outline, which is no quad. The thin-quad pass outlines
    the dark region's hull instead, within a pixel of the true corners, and the tag reads from
    it; without the hull that pass finds nothing (the half-resolution pass's four straightest
    runs of the notched outline may still read the tag, never another)."""
    lookup, tags = printed
    tag, image = grazing_frame(tags, 233, 86.0, "normal")
    truth = grazing_corners(tags, 233, 86.0, "normal")
    found = find_quads(image, "adaptive_thin", DetectorParams())
    assert [q.polarity for q in found] == ["normal"] and _corner_miss(found[0], truth) < 1.0
    assert [d.lambda_text for d in Detector(lookup).detect(image)] == [tag.lambda_text]
    monkeypatch.setattr(candidates, "NOTCHED_MIN_FILL", 2.0)  # no hull fills twice its area
    assert find_quads(image, "adaptive_thin", DetectorParams()) == []
    assert all(d.lambda_text == tag.lambda_text for d in Detector(lookup).detect(image))


@pytest.mark.parametrize("seed", [67, 164])
def test_a_small_data_area_lost_at_half_resolution_is_outlined_by_the_full_resolution_pass(printed, seed) -> None:
    """A normal tag at 8 m (an 18 px data area, blur σ 0.8 px, noise σ 2): at half resolution
    it is 9 px wide and its outline no quad, the global threshold's outline is notched by its
    triangles; the full-resolution pass of a frame that read nothing keeps it though it is not
    thin, as it is small."""
    lookup, tags = printed
    rng = np.random.default_rng(seed)
    tag = tags[seed % len(tags)]
    spec = sc.posed_spec(tag, rng, 18.4, 20.0, "normal")
    image = sc.render_scene((480, 640), [spec], rng, blur=0.8, noise=2.0, gradient=0.05, jpeg=85).image
    p = DetectorParams()
    assert find_quads(image, "adaptive", p) == [] and find_quads(image, "otsu", p) == []
    (quad,) = find_quads(image, "adaptive_thin", p)
    assert quad.polarity == "normal" and 250 < quad.area < 340
    truth = sc.project(spec.homography, np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]))
    assert _corner_miss(quad, truth) < 2.0
    assert [d.lambda_text for d in Detector(lookup).detect(image)] == [tag.lambda_text]


def test_a_dim_frame_is_searched_again_at_a_lowered_offset(bundled_db_path) -> None:
    """Dim tags (their contrast an eighth of the print's, about 20 grey levels; defocused by
    2.5 px, noise σ 6) in a dim frame: the local threshold's offset lowered with the frame's
    departure (the ``"adaptive_dim"`` pass, on the search smoothed) outlines 10 or more of 12
    data areas, the full offset of 7 grey levels (``"adaptive"``) at most 4; a plain wall with
    the same noise gives no candidate in any pass."""
    _, tags = printed_tags(bundled_db_path)
    p = DetectorParams()
    unit = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    lowered = full = 0
    for seed in range(30, 42):
        rng = np.random.default_rng(seed)
        spec = sc.posed_spec(tags[seed % len(tags)], rng, 70.0, float(rng.uniform(0, 40)), "normal")
        image = sc.render_scene((480, 640), [spec], rng, blur=2.5).image.astype(np.float64)
        image = image.mean() + 0.12 * (image - image.mean()) + rng.normal(0, 6.0, image.shape)
        gray = np.clip(np.rint(image), 0, 255).astype(np.uint8)
        centre = sc.project(spec.homography, unit).mean(axis=0)
        departure = frame_departure(gray)
        assert threshold_offset(departure, p.adaptive_c) == DIM_OFFSET_MIN

        def outlined(kind: str, gray: np.ndarray = gray, centre: np.ndarray = centre, dep: float = departure) -> bool:
            quads = find_quads(gray, kind, p, dep)  # type: ignore[arg-type]
            return any(np.linalg.norm(q.corners.mean(axis=0) - centre) < 5 for q in quads if q.polarity == "normal")

        lowered += outlined("adaptive_dim")
        full += outlined("adaptive")
    assert lowered >= 10 and full <= 4, (lowered, full)
    wall = np.clip(np.rint(np.random.default_rng(0).normal(110.0, 6.0, (480, 640))), 0, 255).astype(np.uint8)
    kinds = ("adaptive", "adaptive_dim", "otsu", "adaptive_thin", "bright_holes")
    assert all(find_quads(wall, kind, p) == [] for kind in kinds)  # type: ignore[arg-type]


def test_a_long_motion_keeps_the_data_area_whole_in_the_local_range(bundled_db_path) -> None:
    """Tags 98 px wide tilted 30–50° on a grey wall (print tones 170 and 20 on 100, as a lit
    print in a room) moved by 17 px: their smeared triangles, brighter than the local mean
    near the data area's border, notch its outline under the local mean threshold
    (``"adaptive"``: 4 or more of 24 lose it), while the midpoint of the local darkest and
    brightest (``"local_range"``) keeps every one whole. On noisy walls its few quads (specks
    of noise over ``min_contrast``) are no blurred tag's: the detector reads none of them."""
    _, tags = printed_tags(bundled_db_path)
    p = DetectorParams()
    unit = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    by_mean = by_range = 0
    for seed in range(24):
        rng = np.random.default_rng(seed)
        spec = sc.posed_spec(tags[seed % len(tags)], rng, 98.0, float(rng.uniform(30, 50)), "normal")
        image = sc.render_scene((480, 640), [spec], rng, white=170, black=20, background=100, blur=0.7).image
        kernel = motion_kernel(17, float(rng.uniform(0, 180)))
        moved = cv2.filter2D(image.astype(np.float64), -1, kernel, borderType=cv2.BORDER_REPLICATE)
        gray = np.clip(np.rint(moved + rng.normal(0, 2.0, moved.shape)), 0, 255).astype(np.uint8)
        centre = sc.project(spec.homography, unit).mean(axis=0)

        def outlined(kind: str, gray: np.ndarray = gray, centre: np.ndarray = centre) -> bool:
            quads = find_quads(gray, kind, p)  # type: ignore[arg-type]
            return any(np.linalg.norm(q.corners.mean(axis=0) - centre) < 5 for q in quads if q.polarity == "normal")

        by_mean += outlined("adaptive")
        by_range += outlined("local_range")
    assert by_range == 24 and by_mean <= 20, (by_range, by_mean)
    for seed, noise in enumerate((2.0, 4.0, 6.0, 6.0, 8.0)):
        wall = np.clip(np.rint(np.random.default_rng(seed).normal(110.0, noise, (480, 640))), 0, 255)
        specks = find_quads(wall.astype(np.uint8), "local_range", p)
        assert not any(edge_blur(wall.astype(np.uint8), q).blurred for q in specks)


def test_a_data_areas_triangles_are_not_outlined_as_hidden_data_areas(printed) -> None:
    """Triangles first: a dark quad holding three or more bright holes is a data area and its
    holes are its triangles, not inverted data areas whose border is partly hidden, so no
    outline by lines is inferred inside it (before: 7 such quads in these 8 frames, each read
    only when its tag did not read); the tag still reads."""
    lookup, tags = printed
    inferred_inside = held = 0
    for seed in range(8):
        rng = np.random.default_rng(seed)
        tag = tags[seed % len(tags)]
        spec = sc.posed_spec(tag, rng, 170.0, 30.0, "normal")
        image = sc.render_scene((480, 640), [spec], rng, blur=0.7, noise=2.0, jpeg=85).image
        quads = find_quads(image, "adaptive", DetectorParams())
        areas = [q for q in quads if q.polarity == "normal" and not q.inferred and q.area > 120**2]
        assert len(areas) == 1
        outline = areas[0].corners.astype(np.float32).reshape(-1, 1, 2)
        for q in quads:
            centre = tuple(float(v) for v in q.corners.mean(axis=0))
            if q.polarity == "inverted" and cv2.pointPolygonTest(outline, centre, False) > 0:
                inferred_inside += q.inferred
        contours, hierarchy = _contours(image)
        regions = [r for r in range(len(contours)) if hierarchy[r][3] < 0]
        held += any(candidates._holds_triangles(contours, hierarchy, r, 24.0) for r in regions)
        assert [d.lambda_text for d in Detector(lookup).detect(image)] == [tag.lambda_text]
    assert held >= 6  # tags whose triangles leave at least three holes
    assert inferred_inside == 0


def _contours(image: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """The half-resolution local threshold's contours and hierarchy, as the adaptive pass traces them."""
    h, w = image.shape
    src = cv2.resize(image, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
    mask = cv2.adaptiveThreshold(src, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, 15, 7.0)
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    return list(contours), hier[0]
