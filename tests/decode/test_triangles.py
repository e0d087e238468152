"""Triangle stage: one-triangle fits and the tag rules for fitted triangles."""

from __future__ import annotations

import cv2
import numpy as np

from ottag_db.decode.triangles import bad_triangles, off_triangle, triangle_fit, triangle_fit_parts


def _contour(poly: np.ndarray, size: int = 200) -> np.ndarray:
    img = np.zeros((size, size), np.uint8)
    cv2.fillPoly(img, [poly.astype(np.int32)], 255)
    contours, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    assert len(contours) == 1
    return contours[0].reshape(-1, 2)


def test_a_triangle_fits_with_three_side_chains() -> None:
    tri = np.array([[20, 30], [180, 50], [70, 170]])
    pts = _contour(tri)
    chains = triangle_fit(pts)
    assert chains is not None and len(chains) == 3
    fit = triangle_fit_parts(pts)
    assert fit is not None
    # the corners are contour points next to the drawn ones
    assert all(np.min(np.abs(fit.corners - c).sum(axis=1)) <= 3 for c in tri)
    assert off_triangle(fit.contour, fit.corners, 1.5) == 0


def test_non_triangles_do_not_fit() -> None:
    assert triangle_fit(_contour(np.array([[20, 20], [180, 20], [180, 180], [20, 180]]))) is None
    assert triangle_fit(np.array([[0, 0], [1, 0], [0, 1]])) is None  # too short a contour


def test_off_triangle_counts_points_away_from_the_sides() -> None:
    tri = np.array([[0, 0], [100, 0], [0, 100.0]])
    pts = np.array([[50, 0], [0, 50], [50, 50], [30, 30], [10, 10.0]])
    assert off_triangle(pts, tri, 1.0) == 2  # (30, 30) and (10, 10) are inside, off every side


def test_bad_triangles_rules() -> None:
    quad = np.array([[0, 0], [100, 0], [100, 100], [0, 100.0]])
    good = np.array([[[10, 10], [40, 10], [10, 40]], [[60, 60], [90, 60], [60, 90]]], dtype=np.float64)
    assert bad_triangles(good, quad, 100.0) is None
    outside = good.copy()
    outside[1, 1] = [130, 60]
    rej = bad_triangles(outside, quad, 100.0)
    assert rej is not None and rej.reason == "non_triangle" and "outside" in rej.detail
    # a wrong split: two triangles on both sides of one segment
    split = np.array([[[10, 10], [90, 10], [10, 90]], [[90, 10], [90, 90], [10, 90]]], dtype=np.float64)
    rej = bad_triangles(split, quad, 100.0)
    assert rej is not None and rej.detail == "two triangles share part of a side"
    nan = good.copy()
    nan[0, 0] = np.nan
    rej = bad_triangles(nan, quad, 100.0)
    assert rej is not None and rej.detail == "degenerate triangle"
