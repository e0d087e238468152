"""Quad geometry: corner order, foreshortening, the same data area or tag within a frame."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.decode import DetectorParams
from ottag_db.decode.quads import (
    around_detection,
    clockwise,
    outlined_before,
    reading_order,
    same_quad,
    same_tag,
    seen_before,
    shows_print,
    squeeze,
)
from ottag_db.decode.types import Detection, Quad


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


def _square(x: float, y: float, side: float, polarity: str) -> Quad:
    c = np.array([[x, y], [x + side, y], [x + side, y + side], [x, y + side]], dtype=np.float64)
    return Quad(polarity, c, side * side)  # type: ignore[arg-type]


def test_pieces_of_a_candidate_are_read_right_after_it() -> None:
    """Smallest first, except that a piece (under a quarter of the area of a candidate of the other
    polarity holding its centre) follows its holder, and a piece of a piece follows that; a data
    area inside its quiet zone's outline (0.44 of its area) is no piece and is read first."""
    quads = [
        _square(0, 0, 100, "normal"),  # a data area
        _square(40, 40, 20, "inverted"),  # a triangle's outline in it
        _square(200, 0, 30, "normal"),  # elsewhere
        _square(-25, -25, 150, "inverted"),  # the quiet zone's outline around the data area
        _square(10, 10, 10, "inverted"),  # another triangle's outline
        _square(45, 45, 5, "normal"),  # a speck inside the first triangle's outline
        _square(60, 5, 10, "normal"),  # the data area's polarity: a piece of the quiet zone's outline
    ]
    assert reading_order(quads) == [(2, None), (0, None), (4, 0), (1, 0), (5, 1), (3, None), (6, 3)]
    assert reading_order([]) == []


def test_a_tags_pieces_are_not_read_once_it_reads(bundled) -> None:
    """The outlines of a normal tag's triangles (bright holes of its data area, inverted
    candidates) were each read and refused before the tag (smallest first): now they follow it
    and are skipped."""
    from ottag_db.decode import Detector
    from ottag_db.printing import scenes as sc

    lookup, tags = bundled
    det = Detector(lookup)
    pieces = 0
    for seed in range(6):
        tag = [t for t in tags if t.k == 8][seed]
        rng = np.random.default_rng(seed)
        spec = sc.posed_spec(tag, rng, 150.0, 20.0)
        frame = sc.render_scene((480, 640), [spec], rng, blur=0.6, noise=1.5).image
        dets, rejected = det.detect_with_rejections(frame)
        assert [d.lambda_text for d in dets] == [tag.lambda_text]
        area = abs(float(cv2.contourArea(dets[0].corners.astype(np.float32))))
        centre = dets[0].corners.mean(axis=0)
        for r in rejected:  # a piece of the tag: its centre inside, a fifth of its area at most
            inside = np.linalg.norm(r.corners.mean(axis=0) - centre) < 0.5 * np.sqrt(area)
            pieces += bool(inside and abs(float(cv2.contourArea(r.corners.astype(np.float32)))) < 0.2 * area)
    assert pieces == 0


@given(st.lists(st.tuples(st.integers(0, 60), st.integers(0, 40), st.integers(2, 6), st.booleans()), max_size=25))
def test_without_pieces_the_order_is_smallest_first_in_the_passs_order(boxes: list[tuple[int, int, int, bool]]) -> None:
    """Candidates none of which lies inside another of the other polarity are read smallest
    first, equal areas in the pass's order (a stable sort)."""
    quads = [_square(10.0 * x, 10.0 * y, 4.0 * s, "normal" if n else "inverted") for x, y, s, n in boxes]
    order = reading_order(quads)
    if all(holder is None for _, holder in order):
        assert [i for i, _ in order] == sorted(range(len(quads)), key=lambda i: quads[i].area)
    assert sorted(i for i, _ in order) == list(range(len(quads)))


def test_an_inferred_outline_does_not_stand_in_for_a_whole_one() -> None:
    """A data area outlined only from its visible sides (a corner on the frame's edge: its
    reading must show the print) is read again when a later binarization outlines it whole, so
    that the points can decide; a whole outline stands in for a later one of either kind."""
    corners = np.array([[100.0, 100.0], [260.0, 110.0], [250.0, 270.0], [95.0, 260.0]])
    area = float(abs(cv2.contourArea(corners.astype(np.float32))))
    whole = Quad("inverted", corners, area)
    inferred = Quad("inverted", corners + 0.5, area, inferred=True)
    ratio = DetectorParams().rectify_max_ratio
    assert not seen_before(whole, [inferred], ratio)
    assert seen_before(inferred, [inferred], ratio)
    assert seen_before(whole, [whole], ratio) and seen_before(inferred, [whole], ratio)


def test_an_inferred_outline_whose_corner_moved_is_read_again() -> None:
    """Two thresholds fit a side seen along a short run differently (a corner cut by the frame's
    edge): an inferred outline with a corner 2 % of the side or more from every corner of the
    earlier outline is read again, one that moved a px is the same outline."""
    corners = np.array([[100.0, 100.0], [260.0, 110.0], [250.0, 270.0], [95.0, 260.0]])
    area = float(abs(cv2.contourArea(corners.astype(np.float32))))
    side = np.sqrt(area)
    first = Quad("normal", corners, area, inferred=True)
    ratio = DetectorParams().rectify_max_ratio
    refit = corners.copy()
    refit[3] += [1.0, 0.03 * side]  # one corner 3 % of the side away
    moved = Quad("normal", refit, area, inferred=True)
    nudged = Quad("normal", corners + 1.0, area, inferred=True)
    assert not seen_before(moved, [first], ratio)
    assert seen_before(nudged, [first], ratio)
    assert seen_before(Quad("normal", refit, area), [Quad("normal", corners, area)], ratio)  # whole: as before
