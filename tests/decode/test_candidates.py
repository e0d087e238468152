"""Candidate stage: quads of a binarized frame, corner order, duplicates."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import Detector, DetectorParams
from ottag_db.decode.candidates import (
    around_detection,
    clockwise,
    find_quads,
    outlined_before,
    same_quad,
    same_tag,
    seen_before,
    shows_print,
    squeeze,
)
from ottag_db.decode.types import Detection, Quad
from ottag_db.printing.scenes import DrawableTag
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


def test_clockwise_starts_nearest_the_origin() -> None:
    q = np.array([[10, 10], [0, 10], [10, 0], [0, 0.0]])
    assert clockwise(q).tolist() == [[0, 0], [10, 0], [10, 10], [0, 10]]


def test_same_quad_same_tag_and_around_detection() -> None:
    c = np.array([[0, 0], [100, 0], [100, 100], [0, 100.0]])
    a = Quad("normal", c, 10000.0)
    assert same_quad(a, Quad("normal", c + 2, 10000.0))
    assert not same_quad(a, Quad("inverted", c, 10000.0))
    assert not same_quad(a, Quad("normal", c * 2, 40000.0))
    det = Detection("3:010001100", 3, 1, 1, "normal", np.zeros((3, 2)), None, c, None, None, 5.0)
    assert same_tag(det, det) and not same_tag(det, replace(det, polarity="inverted"))
    frame = Quad("normal", (c - 50) * 2 + 50, 40000.0)  # the quiet zone's outline around the tag
    assert around_detection(frame, [det])
    assert not around_detection(Quad("normal", c * 0.5, 2500.0), [det])


def test_a_thin_data_area_outlined_anew_by_a_later_binarization_is_read_again() -> None:
    thin = Quad("normal", np.array([[0, 0], [100, 0], [100, 8], [0, 8.0]]), 800.0)
    square = Quad("normal", np.array([[0, 0], [100, 0], [100, 100], [0, 100.0]]), 10000.0)
    r = DetectorParams().rectify_max_ratio
    assert not seen_before(thin, [], r)
    assert not seen_before(thin, [square], r)  # another data area
    # found again by Otsu with two corners 2 px out: nearly edge-on, a new outline
    moved = Quad("normal", thin.corners + np.array([[0, 0], [0, 0], [0, 2], [0, 2.0]]), 1000.0)
    assert not seen_before(moved, [thin], r)
    # the same outline within a pixel, in another corner order: seen
    again = Quad("normal", np.roll(thin.corners, 1, axis=0) + 0.5, 800.0)
    assert seen_before(again, [thin], r)
    # head-on, any outline of the same data area is seen (no second reading)
    grown = Quad("normal", square.corners + np.array([[0, 0], [0, 0], [0, 2], [0, 2.0]]), 10100.0)
    assert seen_before(grown, [square], r)
    assert seen_before(moved, [thin], 0.0)  # no candidate is foreshortened enough: seen
    # read again, but as an outline of a data area read before (by model only)
    assert outlined_before(moved, [square, thin]) and not outlined_before(thin, [square])


def test_readings_must_show_the_print_at_oblique_views_and_on_small_data_areas() -> None:
    def square(side: float) -> Quad:
        return Quad("normal", np.array([[0, 0], [side, 0], [side, side], [0, side]]), side * side)

    thin = Quad("normal", np.array([[0, 0], [100, 0], [100, 20], [0, 20.0]]), 2000.0)
    p = DetectorParams()
    assert shows_print(thin, p)  # foreshortened to 0.2
    assert shows_print(square(24.0), p)  # a tag at 6–7 m
    assert shows_print(square(50.0), p)  # where two triangles of an 8-point tag can merge
    assert not shows_print(square(80.0), p)  # head-on and large enough: other programs' tags read
    assert not shows_print(square(24.0), replace(p, print_check_side_px=0.0))
    assert not shows_print(thin, replace(p, layout_check_ratio=0.0))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-500, 500, allow_nan=False), min_size=8, max_size=8))
def test_squeeze_is_the_singular_value_ratio_of_the_diagonals(coords: list[float]) -> None:
    """The closed form equals numpy's SVD of the 2×2 matrix of the diagonals."""
    q = np.array(coords).reshape(4, 2)
    sv = np.linalg.svd(np.stack([q[2] - q[0], q[3] - q[1]], axis=1), compute_uv=False)
    expected = sv[1] / sv[0] if sv[0] > 1e-9 else 0.0
    assert squeeze(Quad("normal", q, 1.0)) == pytest.approx(expected, abs=1e-6)


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


@pytest.fixture(scope="module")
def printed(bundled_db_path) -> tuple[MemoryLookup, list[DrawableTag]]:
    return printed_tags(bundled_db_path)


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
