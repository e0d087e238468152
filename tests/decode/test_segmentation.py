"""Segmentation stage: data area → bright mask → triangle decompositions."""

from __future__ import annotations

import cv2
import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from ottag_db.decode import DetectorParams
from ottag_db.decode.placement_check import square_homography
from ottag_db.decode.segmentation import (
    NO_DECOMPOSITION,
    bridge,
    decompose,
    rectilinear,
    segment,
    then_alternatives,
)
from ottag_db.decode.splitting import FRAME_SEARCH, FitMemo
from ottag_db.decode.types import DataArea, Decomposition, Quad, Rejection
from tests.support import synthetic_tags as syn


def _quad(side: float, origin: tuple[float, float], polarity: str = "normal") -> Quad:
    x, y = origin
    c = np.array([[x, y], [x + side, y], [x + side, y + side], [x, y + side]]) - 0.5
    return Quad(polarity, c, side * side)  # type: ignore[arg-type]


def test_segment_separates_the_triangles() -> None:
    for inverted in (False, True):
        image = syn.draw_tags((260, 260), [(200, (30, 30))], inverted=inverted)
        area = segment(image, _quad(200, (30, 30), "inverted" if inverted else "normal"), DetectorParams())
        assert isinstance(area, DataArea)
        assert area.side == 200 and 50 < area.level < 200
        assert np.array_equal(area.origin + area.quad, _quad(200, (30, 30)).corners)
        n, _ = cv2.connectedComponents(area.fg)
        assert n - 1 == 2  # two triangles (plus the background label)


def test_segment_rejects_flat_and_full_areas() -> None:
    flat = np.full((200, 200), 255, np.uint8)
    flat[40:160, 40:160] = 0
    rej = segment(flat, _quad(120, (40, 40)), DetectorParams())
    assert isinstance(rej, Rejection) and rej.reason == "low_contrast"
    low = flat.copy()
    low[70:90, 70:90] = 10  # two levels, too close
    rej = segment(low, _quad(120, (40, 40)), DetectorParams())
    assert isinstance(rej, Rejection) and rej.reason == "low_contrast" and rej.detail == "10 grey levels"
    full = flat.copy()
    full[46:154, 46:154] = 255  # the interior is bright almost everywhere
    full[100:104, 100:104] = 0
    rej = segment(full, _quad(120, (40, 40)), DetectorParams())
    assert isinstance(rej, Rejection) and rej.reason == "no_triangles" and rej.detail.startswith("bright fraction")


def test_decompose_two_triangles_and_a_square() -> None:
    image = syn.draw_tags((260, 260), [(200, (30, 30))])
    area = segment(image, _quad(200, (30, 30)), DetectorParams())
    assert isinstance(area, DataArea)
    decomps = decompose(area.fg, area.side, DetectorParams(), None)
    assert isinstance(decomps, list) and len(decomps) == 1 and decomps[0].count == 2
    assert all(ch.ndim == 2 and ch.shape[1] == 2 for ch in decomps[0].chains)
    square = np.zeros((100, 100), np.uint8)
    square[20:70, 20:70] = 255
    rej = decompose(square, 100.0, DetectorParams(), FRAME_SEARCH)
    assert isinstance(rej, Rejection) and rej.reason == "non_triangle"
    assert decompose(np.zeros((50, 50), np.uint8), 50.0, DetectorParams(), FRAME_SEARCH) == [Decomposition(())]
    assert NO_DECOMPOSITION


def test_more_components_than_a_tag_has_triangles_are_refused_before_any_fit() -> None:
    """Each component holds a triangle at least: 13 (text, a checkerboard) cannot be a tag."""
    fg = np.zeros((200, 200), np.uint8)
    cells = [(20 + 40 * (i % 4), 20 + 40 * (i // 4)) for i in range(13)]
    # 12 triangles and a square: the square alone would cost an alternative search
    for x, y in cells[:12]:
        cv2.fillPoly(fg, [np.array([[x, y], [x + 30, y + 4], [x + 8, y + 28]], np.int32)], 255)
    twelve = decompose(fg, 200.0, DetectorParams(), None)
    assert isinstance(twelve, list) and twelve[0].count == 12  # as many as a tag may have: read on
    x, y = cells[12]
    fg[y : y + 25, x : x + 25] = 255
    memo = FitMemo()
    rej = decompose(fg, 200.0, DetectorParams(), FRAME_SEARCH, memo)
    assert isinstance(rej, Rejection) and rej.reason == "non_triangle" and rej.detail == "13 components"
    assert not memo.fits  # refused before a single triangle fit


def test_then_alternatives_is_lazy_and_skips_repeats() -> None:
    a = Decomposition((np.array([[1.0, 2.0], [3.0, 4.0]]),))
    b = Decomposition((np.array([[5.0, 6.0], [7.0, 8.0]]),))
    calls: list[int] = []

    def more() -> list[Decomposition] | Rejection:
        calls.append(1)
        return [a, b]

    it = then_alternatives([a], more)
    assert next(it) is a and calls == []
    assert list(it) == [b] and calls == [1]
    assert list(then_alternatives([a, b], more)) == [a, b] and calls == [1]
    assert list(then_alternatives([a], lambda: Rejection("non_triangle"))) == [a]


def test_bridge_joins_a_hole_at_the_closest_points() -> None:
    outer = np.array([[0, 0], [10, 0], [10, 10], [0, 10]])
    hole = np.array([[4, 4], [6, 4], [6, 6], [4, 6]])
    joined = bridge(outer, hole)
    assert len(joined) == len(outer) + len(hole) + 2
    assert {tuple(p) for p in joined} == {tuple(p) for p in outer} | {tuple(p) for p in hole}


# ---------------------------------------------------------------------- square markers' cells
#: Cells of a square marker (unions of grid squares), in data-area units.
_CELLS = (
    [(0.25, 0.25), (0.5, 0.25), (0.5, 0.5), (0.375, 0.5), (0.375, 0.75), (0.25, 0.75)],  # an L
    [(0.125, 0.375), (0.875, 0.375), (0.875, 0.5), (0.125, 0.5)],  # a bar
    [(0.25, 0.25), (0.75, 0.25), (0.75, 0.375), (0.5625, 0.375), (0.5625, 0.75), (0.4375, 0.75),
     (0.4375, 0.375), (0.25, 0.375)],  # a T
)  # fmt: skip
_UNIT = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64)


def _to_unit(corners: np.ndarray) -> np.ndarray:
    hom = square_homography(corners)
    assert hom is not None
    return np.linalg.inv(hom)


def _outline(shape: np.ndarray, corners: np.ndarray, size: int) -> np.ndarray:
    """The outer contour of ``shape`` (data-area units) drawn into the quad ``corners``."""
    hom = cv2.getPerspectiveTransform(_UNIT.astype(np.float32), corners.astype(np.float32))
    pts = cv2.perspectiveTransform(np.asarray(shape, dtype=np.float64).reshape(1, -1, 2), hom)[0]
    mask = np.zeros((size, size), np.uint8)
    cv2.fillPoly(mask, [np.round(pts * 16).astype(np.int32)], 255, cv2.LINE_8, 4)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return max(contours, key=len)


def _most_tilted_side_deg(tri: np.ndarray) -> float:
    d = np.roll(tri, -1, axis=0) - tri
    angle = np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0])))
    return float(np.minimum(angle, 90.0 - angle).max())


@settings(max_examples=150, deadline=None)
@given(
    tri=st.lists(st.tuples(st.floats(0.08, 0.92), st.floats(0.08, 0.92)), min_size=3, max_size=3),
    jitter=st.lists(st.floats(-0.12, 0.12), min_size=8, max_size=8),
    side=st.floats(40.0, 300.0),
)
def test_no_triangle_is_rectilinear_under_any_view(
    tri: list[tuple[float, float]], jitter: list[float], side: float
) -> None:
    """Every triangle whose most tilted side is as tilted as the least of the bundled tags'
    (7.2°) keeps that side off the axes under any mild perspective, at any size."""
    shape = np.array(tri)
    d = np.roll(shape, -1, axis=0) - shape
    assume(abs(d[0, 0] * d[1, 1] - d[0, 1] * d[1, 0]) * side * side > 200)  # not a speck or a line
    assume(_most_tilted_side_deg(shape) >= 7.2)
    corners = _UNIT * side + 20 + np.reshape(jitter, (4, 2)) * side
    assert not rectilinear(_outline(shape, corners, int(side * 1.4) + 40), _to_unit(corners), side)


def test_square_marker_cells_are_rectilinear_in_any_order_of_the_corners() -> None:
    for side, jitter in ((120.0, 0.0), (160.0, 0.06), (220.0, -0.08)):
        corners = _UNIT * side + 20 + np.array([[jitter, 0], [0, -jitter], [jitter, jitter], [0, 0]]) * side
        for shape in _CELLS:
            contour = _outline(np.array(shape), corners, int(side * 1.4) + 40)
            for first in range(4):  # a quarter turn of the data area keeps its axes
                assert rectilinear(contour, _to_unit(np.roll(corners, first, axis=0)), side)
        tri = np.array([[0.2, 0.2], [0.8, 0.2], [0.8, 0.276]])  # legs on both axes, 7.2° hypotenuse
        assert not rectilinear(_outline(tri, corners, int(side * 1.4) + 40), _to_unit(corners), side)


def test_a_square_markers_cells_get_no_alternative_search() -> None:
    """The cells of an ArUco marker are refused at once when the quad is known; the alternative
    searches would cut them for their whole budget (tens of triangle fits) in vain."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    marker = cv2.aruco.generateImageMarker(dictionary, 5, 160)  # 20 px cells, black border
    corners = np.array([[20.0, 20.0], [140.0, 20.0], [140.0, 140.0], [20.0, 140.0]]) - 0.5
    seen_corners = np.float32([[30, 24], [150, 38], [140, 150], [24, 140]])
    hom = cv2.getPerspectiveTransform(corners.astype(np.float32), seen_corners)
    image = cv2.warpPerspective(marker, hom, (180, 180), flags=cv2.INTER_AREA, borderValue=255)
    image = cv2.GaussianBlur(image, (0, 0), 0.8)
    # the marker's outline (its cells touch the inner square, and would be left out there as
    # crossing the border)
    outline = np.array([[0.0, 0.0], [160.0, 0.0], [160.0, 160.0], [0.0, 160.0]]) - 0.5
    seen = cv2.perspectiveTransform(outline.reshape(1, 4, 2), hom)[0]
    quad = Quad("normal", seen, float(cv2.contourArea(seen.astype(np.float32))))
    area = segment(image, quad, DetectorParams())
    assert isinstance(area, DataArea)
    searched, skipped = FitMemo(), FitMemo()
    without = decompose(area.fg, area.side, DetectorParams(), FRAME_SEARCH, searched)
    with_quad = decompose(area.fg, area.side, DetectorParams(), FRAME_SEARCH, skipped, area.quad)
    assert isinstance(without, Rejection) and isinstance(with_quad, Rejection)
    assert without.reason == with_quad.reason == "non_triangle"
    assert len(skipped.fits) <= 3 < 20 <= len(searched.fits)
