"""The compiled run-and-quad search of :func:`~ottag_db.decode.outlines.lines_outline`
(``ottag_native.lines``) gives exactly what its plain-Python formulation gives, on outlines of
squares with spikes, notches and corners cut by the frame's edge.

The plain-Python formulation below is the test's oracle (it was the decoder's code before the
kernel); it calls OpenCV's ``isContourConvex``, ``contourArea`` and ``arcLength``, which the
kernel computes as OpenCV does.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
import ottag_native.lines
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from ottag_db.decode import outlines

_Run = tuple[float, float, float, float, float, int]


def _lines_outline_python(
    contour: NDArray[Any], perimeter: float, shape: tuple[int, ...], ring: bool = False
) -> NDArray[Any] | None:
    """The plain-Python :func:`~ottag_db.decode.outlines.lines_outline` (the oracle)."""
    region = abs(float(cv2.contourArea(contour)))
    (least_solid, most_solid), (least, most) = (
        (outlines._RING_SOLIDITY, outlines._RING_AREA_RATIO)
        if ring
        else ((outlines.LINES_MIN_SOLIDITY, 1.0), outlines._LINES_AREA_RATIO)
    )
    solidity = region / max(abs(float(cv2.contourArea(cv2.convexHull(contour)))), 1.0)
    if not least_solid <= solidity <= most_solid:
        return None  # ragged: texture, not a square with a spike, a notch or a cut corner
    tol = max(1.5, outlines._LINE_DISTANCE * perimeter)
    poly: list[list[float]] = cv2.approxPolyDP(contour, tol, True).reshape(-1, 2).astype(float).tolist()
    if len(poly) < 5 and not ring:  # a corner cut off by a few px: the polygon rounds it off
        fine = max(1.0, outlines._FINE_TOLERANCE * tol)
        poly = cv2.approxPolyDP(contour, fine, True).reshape(-1, 2).astype(float).tolist()
    if len(poly) < 5 or len(poly) > 24:
        return None
    h, w = shape[:2]
    # plain Python on a few dozen numbers (numpy's per-call cost would dominate)
    edges: list[tuple[float, int, float, float, float, float]] = []  # (length, index, x, y, ux, uy)
    for i, ((ax, ay), (bx, by)) in enumerate(zip(poly, poly[1:] + poly[:1], strict=True)):
        along_frame = (ax <= 1 and bx <= 1) or (ay <= 1 and by <= 1) or (ax >= w - 2 and bx >= w - 2)
        if along_frame or (ay >= h - 2 and by >= h - 2):
            continue  # the frame's edge, not a side
        length = math.hypot(bx - ax, by - ay)
        if length >= 2 * tol:
            edges.append((length, i, ax, ay, (bx - ax) / length, (by - ay) / length))
    cos_tol = math.cos(math.radians(outlines._LINE_ANGLE_DEG))
    runs: list[_Run] = []
    spans: dict[int, list[tuple[float, float]]] = {}  # per run (its first edge): edges along its line
    for length, i, ax, ay, ux, uy in sorted(edges, reverse=True):
        bx, by = ax + length * ux, ay + length * uy
        for j, (support, px, py, dx, dy, first) in enumerate(runs):
            if (
                abs(ux * dx + uy * dy) >= cos_tol
                and max(abs((ax - px) * dy - (ay - py) * dx), abs((bx - px) * dy - (by - py) * dx)) <= tol
            ):
                runs[j] = (support + length, px, py, dx, dy, first)
                s0, s1 = (ax - px) * dx + (ay - py) * dy, (bx - px) * dx + (by - py) * dy
                spans[first].append((min(s0, s1), max(s0, s1)))
                break
        else:
            runs.append((length, ax, ay, ux, uy, i))
            spans[i] = [(0.0, length)]
    if len(runs) < 4:
        return None
    best_quad: NDArray[Any] | None = None
    best_support = 0.0
    # the four lines of the sides among the longest runs: the combination that covers the
    # outline's area as a convex quad with the most support (a spike's edges can be longer);
    # a run supports its side only between the side's corners (a bar's edge runs on beyond)
    for four in itertools.combinations(sorted(runs, reverse=True)[: outlines._LINES_CONSIDERED], 4):
        if sum(r[0] for r in four) <= best_support:
            continue
        ordered = sorted(four, key=lambda r: r[5])  # in the outline's order
        quad = _lines_quad(ordered)
        if quad is None:
            continue
        area = abs(float(cv2.contourArea(quad)))
        if least * region <= area <= most * region:
            support = _support_within(ordered, spans, quad.reshape(4, 2).tolist())
            if support > best_support:
                best_quad, best_support = quad, support
    if best_quad is None or best_support < outlines.LINES_MIN_SUPPORT * _length_in_frame(best_quad, (w, h)):
        return None
    return best_quad


def _support_within(
    lines: Sequence[_Run], spans: dict[int, list[tuple[float, float]]], corners: list[list[float]]
) -> float:
    """How much of the runs' edges lies on their sides between the quad's corners (px); side
    ``i`` runs from corner ``i − 1`` to corner ``i`` (:func:`_lines_quad`)."""
    total = 0.0
    for i, (_, px, py, dx, dy, first) in enumerate(lines):
        (ax, ay), (bx, by) = corners[i - 1], corners[i]
        t0, t1 = (ax - px) * dx + (ay - py) * dy, (bx - px) * dx + (by - py) * dy
        lo, hi = min(t0, t1), max(t0, t1)
        total += sum(max(0.0, min(hi, s1) - max(lo, s0)) for s0, s1 in spans[first])
    return total


def _length_in_frame(quad: NDArray[Any], size: tuple[int, int]) -> float:
    """The length of the sides of ``quad`` (``(4, 1, 2)``) within a frame of ``size`` = (W, H):
    what of its outline can be seen (a corner cut by the frame's edge takes parts of two sides
    with it, as much as a quarter of a side nearly parallel to that edge). Only one corner may
    lie beyond the edge (three seen ones hold the quad, as
    :data:`~ottag_db.decode.placement_check.CORNERS_TO_TRUST_PRINT` hold the print): with more,
    the whole perimeter counts, as for a quad within the frame."""
    w, h = size
    pts: list[list[float]] = quad.reshape(4, 2).astype(float).tolist()
    if sum(not (0 <= x <= w - 1 and 0 <= y <= h - 1) for x, y in pts) > 1:
        return float(cv2.arcLength(quad, True))
    total = 0.0
    for (ax, ay), (bx, by) in zip(pts, pts[1:] + pts[:1], strict=True):
        lo, hi = 0.0, 1.0  # the part of a→b inside the frame (Liang–Barsky)
        for p, q in ((ax - bx, ax), (bx - ax, w - 1 - ax), (ay - by, ay), (by - ay, h - 1 - ay)):
            if p == 0:
                if q < 0:
                    hi = lo - 1.0  # parallel to this edge and outside
                continue
            t = q / p
            if p < 0:
                lo = max(lo, t)
            else:
                hi = min(hi, t)
        if hi > lo:
            total += (hi - lo) * math.hypot(bx - ax, by - ay)
    return total


def _lines_quad(lines: Sequence[_Run]) -> NDArray[Any] | None:
    """The convex quad whose sides lie on four runs' lines, each meeting the next at a corner;
    None when neighbours are nearly parallel or the quad is not convex."""
    corners: list[tuple[float, float]] = []
    for (_, px, py, dx, dy, _), (_, qx, qy, ex, ey, _) in zip(lines, [*lines[1:], lines[0]], strict=True):
        det = dx * ey - dy * ex
        if abs(det) < 0.2:  # nearly parallel neighbours: no corner between them
            return None
        t = ((qx - px) * ey - (qy - py) * ex) / det
        corners.append((px + t * dx, py + t * dy))
    quad = np.asarray(corners, dtype=np.float32).reshape(4, 1, 2)
    return quad if cv2.isContourConvex(quad) else None


def _outline(seed: int) -> tuple[NDArray[Any], tuple[int, int]]:
    """The largest outline of a square (any size, turn and place, maybe cut by the frame's edge)
    with a bar across it or a notch in it."""
    rng = np.random.default_rng(seed)
    image = np.zeros((120, 160), np.uint8)
    centre, side, turn = rng.uniform(-20, 180, 2), rng.uniform(20, 90), rng.uniform(0, math.pi)
    corners = [
        centre
        + side * rng.uniform(0.8, 1.2) * np.array([math.cos(turn + k * math.pi / 2), math.sin(turn + k * math.pi / 2)])
        for k in range(4)
    ]
    cv2.fillPoly(image, [np.array(corners, np.int32)], 255)
    if rng.random() < 0.7:
        start = tuple(int(v) for v in rng.uniform(0, 160, 2))
        cv2.line(image, start, tuple(int(v) for v in centre), int(rng.choice([0, 255])), int(rng.integers(2, 8)))
    found, _ = cv2.findContours(image, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return max(found, key=len) if found else np.zeros((0, 1, 2), np.int32), (120, 160)


@settings(max_examples=400, deadline=None)
@given(seed=st.integers(0, 1_000_000), ring=st.booleans())
def test_the_lines_kernel_is_the_plain_python_formulation(seed: int, ring: bool) -> None:
    contour, shape = _outline(seed)
    if len(contour) < 20:
        return
    perimeter = float(len(contour))
    got = outlines.lines_outline(contour, perimeter, shape, ring)
    expected = _lines_outline_python(contour, perimeter, shape, ring)
    assert (got is None) == (expected is None)
    if got is not None and expected is not None:
        assert got.dtype == expected.dtype and np.array_equal(got, expected)


def test_the_lines_kernel_outlines_a_square_whose_corner_the_frame_cuts() -> None:
    image = np.zeros((120, 160), np.uint8)
    cv2.fillPoly(image, [np.array([[60, 30], [150, 20], [175, 100], [70, 110]], np.int32)], 255)
    contour = max(cv2.findContours(image, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)[0], key=len)
    quad = outlines.lines_outline(contour, float(len(contour)), image.shape)
    assert quad is not None
    truth = np.array([[60, 30], [150, 20], [175, 100], [70, 110]], np.float64)
    gaps = np.linalg.norm(quad.reshape(1, 4, 2) - truth.reshape(4, 1, 2), axis=2).min(axis=1)
    assert gaps.max() < 3  # the corner beyond the frame's edge too, from the lines of the seen sides
    out = np.empty((4, 2), np.float32)
    with pytest.raises(ValueError, match="poly must be"):
        ottag_native.lines.lines_quad(np.zeros((40, 2)), 1.5, 0.99, 160, 120, 0.0, 1e9, 7, 0.85, out)
