"""Segmentation stage: data area → bright mask → triangle decompositions."""

from __future__ import annotations

import cv2
import numpy as np

from ottag_db.decode import DetectorParams
from ottag_db.decode.segmentation import NO_DECOMPOSITION, bridge, decompose, segment, then_alternatives
from ottag_db.decode.splitting import FRAME_SEARCH
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
