"""Splitting stage: components of triangles joined at vertices, cut apart."""

from __future__ import annotations

import cv2
import numpy as np

from ottag_db.decode.splitting import (
    RECTIFIED_SEARCH,
    FitBudget,
    FitMemo,
    component_decompositions,
    notch_cuts,
    reflex_corners,
    split_triangles,
)


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
    alts = component_decompositions(pts, lambda: None, alternatives=None)
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


def test_notch_cut_follows_a_slit_to_the_shared_tip() -> None:
    # two triangles sharing the tip (120, 200) at a narrow angle; the blur has closed the slit
    # between them from y = 120 on, leaving one concave point (the slit bottom)
    pts = _contour(np.array([[20, 20], [110, 20], [118, 120], [130, 20], [220, 20], [120, 200]]))
    flat = pts.astype(np.float64)
    c = pts.reshape(-1, 1, 2).astype(np.int32)
    hull = np.sort(cv2.convexHull(c, returnPoints=False).ravel()).reshape(-1, 1)
    dfs = cv2.convexityDefects(c, hull.astype(np.int32)).reshape(-1, 4)
    cuts = notch_cuts(flat, dfs[dfs[:, 3] >= 180], 8)
    # from the slit bottom on along the slit to the shared tip
    slit = [(i, j) for _, i, j in cuts if np.abs(flat[i] - (118, 116)).max() <= 4]
    assert slit, "the slit gives a cut"
    assert all(np.abs(flat[j] - (120, 200)).max() <= 6 for _, j in slit)
    halves = list(split_triangles(pts, 0, True))
    assert halves and len(halves[0]) == 6  # the cut splits the union into the two triangles


def test_notch_search_is_bounded() -> None:
    # a comb (an ArUco-like blob of cells) is no union of triangles; its slit search must stop
    # at the fit budget instead of trying every cut of every half
    teeth = [np.array([[x, 20], [x + 12, 20], [x + 12, 200], [x, 200]]) for x in range(20, 220, 24)]
    pts = _contour(np.array([[20, 190], [220, 190], [220, 220], [20, 220]]), *teeth)
    budget = FitBudget(RECTIFIED_SEARCH.notch_fits)
    assert list(split_triangles(pts, 0, True, budget=budget)) == []
    assert 0 <= budget.remaining < RECTIFIED_SEARCH.notch_fits


def test_a_memo_saves_fits_but_not_budget() -> None:
    """Three triangles in a chain, searched with every alternative: with one memo the same
    decompositions come out, each budget is spent as without it, and a second search of the
    same contour fits nothing new."""
    pts = _contour(
        np.array([[10, 20], [80, 110], [10, 200]]),
        np.array([[80, 110], [150, 20], [160, 200]]),
        np.array([[160, 200], [230, 120], [225, 230]]),
    )

    def search(memo: FitMemo | None) -> tuple[list[list[np.ndarray]], int, int]:
        notch, strict = FitBudget(RECTIFIED_SEARCH.notch_fits), FitBudget(RECTIFIED_SEARCH.strict_fits)
        alts = component_decompositions(pts, lambda: None, RECTIFIED_SEARCH, notch, strict, memo)
        return alts, notch.remaining, strict.remaining

    plain, plain_notch, plain_strict = search(None)
    memo = FitMemo()
    kept, kept_notch, kept_strict = search(memo)
    assert len(kept) == len(plain) >= 1
    for a, b in zip(kept, plain, strict=True):
        assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert (kept_notch, kept_strict) == (plain_notch, plain_strict)
    fitted = len(memo.fits)
    assert fitted > 0
    search(memo)
    assert len(memo.fits) == fitted
