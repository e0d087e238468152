"""Splitting stage: components of triangles joined at vertices, cut apart."""

from __future__ import annotations

import cv2
import numpy as np

from ottag_db.decode.splitting import FitBudget, component_decompositions, reflex_corners, split_triangles


def _contour(*polys: np.ndarray, size: int = 240) -> np.ndarray:
    img = np.zeros((size, size), np.uint8)
    cv2.fillPoly(img, [p.astype(np.int32) for p in polys], 255)
    contours, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    assert len(contours) == 1
    return contours[0].reshape(-1, 2)


def test_two_triangles_sharing_a_vertex_split_into_two() -> None:
    a = np.array([[20, 20], [120, 110], [20, 200]])
    b = np.array([[120, 110], [220, 30], [210, 210]])
    pts = _contour(a, b)
    first = next(split_triangles(pts, 0, False), None)
    assert first is not None and len(first) == 6
    alts = component_decompositions(pts, lambda: None, alternatives=False)
    assert len(alts) == 1 and len(alts[0]) == 6


def test_one_triangle_needs_no_alternatives() -> None:
    pts = _contour(np.array([[20, 20], [200, 40], [60, 200]]))
    opened: list[int] = []

    def opening() -> None:
        opened.append(1)

    assert [len(d) for d in component_decompositions(pts, opening)] == [3]
    assert opened == []  # the opening is only computed when needed


def test_fit_budget() -> None:
    budget = FitBudget(2)
    assert budget.take() and budget.take() and not budget.take()
    assert budget.remaining == 0
    pts = _contour(np.array([[20, 20], [120, 110], [20, 200]]), np.array([[120, 110], [220, 30], [210, 210]]))
    assert list(split_triangles(pts, 0, False, 1.5, FitBudget(0))) == []


def test_reflex_corners_of_an_l_shape() -> None:
    pts = _contour(np.array([[20, 20], [200, 20], [200, 80], [80, 80], [80, 200], [20, 200]]))
    rows = reflex_corners(pts)
    assert rows.shape[1] == 4 and len(rows) == 1
    assert np.abs(pts[rows[0, 2]] - [80, 80]).max() <= 1
