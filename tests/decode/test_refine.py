"""Refinement stage: least-squares lines, intersections, sub-pixel edges."""

from __future__ import annotations

import cv2
import numpy as np

from ottag_db.decode.refine import (
    fit_chains,
    intersect,
    lines_through,
    polygon_vertices,
    refine,
    refine_lines,
    triangle_vertices,
)
from ottag_db.decode.types import Decomposition


def test_fit_chains_and_vertices_of_exact_lines() -> None:
    tri = np.array([[10.0, 10.0], [90.0, 20.0], [30.0, 80.0]])
    chains = [np.linspace(tri[j], tri[(j + 1) % 3], 12)[1:-1] for j in range(3)]
    normal, offset = fit_chains(chains)
    assert np.allclose(np.hypot(normal[:, 0], normal[:, 1]), 1.0)
    for j in range(3):
        assert np.allclose(chains[j] @ normal[j], offset[j])
    assert np.allclose(triangle_vertices(normal, offset)[0], tri)


def test_lines_through_a_square_and_its_corners_back() -> None:
    sq = np.array([[0, 0], [10, 0], [10, 10], [0, 10.0]])
    normal, offset = lines_through(sq)
    assert np.allclose(polygon_vertices(normal, offset, 4), sq)
    par = intersect(np.array([[1.0, 0.0]]), np.array([1.0]), np.array([[1.0, 0.0]]), np.array([2.0]))
    assert np.isnan(par).all()


def test_refine_moves_lines_to_the_grey_level_edge() -> None:
    # a bright triangle on dark, drawn 8× and reduced: edges at sub-pixel positions
    tri = np.array([[12.3, 10.6], [88.7, 18.2], [31.4, 79.9]])
    big = np.zeros((800, 800), np.uint8)
    cv2.fillPoly(big, [np.round((tri + 0.5) * 8 - 0.5).astype(np.int32)], 255)
    img = cv2.resize(big, (100, 100), interpolation=cv2.INTER_AREA).astype(np.float32)
    rough = tri + np.array([[0.8, -0.6], [-0.7, 0.5], [0.6, 0.7]])
    chains = [np.linspace(rough[j], rough[(j + 1) % 3], 20)[2:-2] for j in range(3)]
    tris, corners = refine(img, Decomposition(tuple(chains)), 127.5)
    assert corners is None
    assert np.abs(tris.vertices[0] - tri).max() < 0.3
    assert np.abs(rough - tri).max() > 0.5
    # a side with no crossing keeps its line
    n0, c0 = fit_chains(chains)
    n1, c1 = refine_lines(np.zeros((100, 100), np.float32), n0, c0, triangle_vertices(n0, c0), 127.5)
    assert np.array_equal(n1, n0) and np.array_equal(c1, c0)


def _dark_square_with_bright_triangle(quad: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """60×60 grey image: a dark data area on white with a white triangle, drawn 8× and reduced, blur σ 0.6 px."""
    big = np.full((480, 480), 255, np.uint8)
    cv2.fillPoly(big, [np.round((quad + 0.5) * 8 - 0.5).astype(np.int32)], 0)
    cv2.fillPoly(big, [np.round((tri + 0.5) * 8 - 0.5).astype(np.int32)], 255)
    img = cv2.resize(big, (60, 60), interpolation=cv2.INTER_AREA).astype(np.float32)
    return cv2.GaussianBlur(img, (0, 0), 0.6)


def test_refine_quad_ignores_a_triangle_edge_near_the_border() -> None:
    # a 30 px data area, a triangle side 4 px inside its top side along half of it, and a rough
    # top side 2.5 px inward at its right end: there the crossing nearest the rough line is the
    # triangle's edge (the fit with it put the corners 0.8 px off)
    quad = np.array([[15.0, 15.0], [45.0, 15.0], [45.0, 45.0], [15.0, 45.0]])
    rough = quad + np.array([[0.0, 0.0], [0.0, 2.5], [0.0, 0.0], [0.0, 0.0]])
    corners = {}
    for name, tri in (
        ("near", np.array([[27.0, 19.0], [41.0, 19.0], [34.0, 32.0]])),
        ("far", np.array([[27.0, 27.0], [41.0, 27.0], [34.0, 40.0]])),
    ):
        chains = [np.linspace(tri[j], tri[(j + 1) % 3], 12)[1:-1] for j in range(3)]
        img = _dark_square_with_bright_triangle(quad, tri)
        _, got = refine(img, Decomposition(tuple(chains)), 127.5, rough)
        assert got is not None
        corners[name] = got
    assert np.abs(corners["near"] - quad).max() < 0.25
    assert np.abs(corners["near"] - corners["far"]).max() < 0.05
