"""Candidate stage: convex quadrilateral contours of a binarized frame (possible data areas)."""

from __future__ import annotations

import math
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.types import Polarity
from ottag_db.decode.types import Detection, DetectorParams, Quad

__all__ = ["Binarization", "around_detection", "find_quads", "same_quad", "same_tag", "squeeze"]

_F64 = NDArray[np.float64]

#: How a frame is binarized for the quad search: local mean or global Otsu threshold.
Binarization = Literal["adaptive", "otsu"]

#: The half-resolution candidate search is used only while the smallest data area keeps at
#: least this side (px) there.
HALF_RES_MIN_SIDE = 6.0


def find_quads(gray: NDArray[np.uint8], kind: Binarization, params: DetectorParams) -> list[Quad]:
    """Convex quadrilateral contours of one binarization of ``gray``, largest first.

    Outer contours of dark regions are candidate *normal* data areas, hole contours (bright
    regions inside dark) candidate *inverted* ones.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    kind : {"adaptive", "otsu"}
        Local mean thresholding or global Otsu.
    params : DetectorParams
        Uses the binarization, polarity, size and ``max_candidates`` settings.

    Returns
    -------
    list of Quad
        At most ``params.max_candidates`` quads (image pixels), largest area first, no two
        the same (see :func:`same_quad`).
    """
    p = params
    h, w = gray.shape
    # The automatic local threshold searches the image at half resolution (a quarter of the
    # pixels to threshold and trace) when even the smallest data area keeps sides of
    # ``HALF_RES_MIN_SIDE`` px there; quads are mapped back (half-res pixel u covers image
    # pixels 2u, 2u + 1: centre 2u + 0.5) and their sides are refined on the full image.
    f = 1
    if kind == "otsu":
        _, mask = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
    else:
        block = p.adaptive_block or max(15, (min(h, w) // 16) | 1)
        src: NDArray[Any] = gray
        if not p.adaptive_block and min(h, w) >= 240 and p.min_quad_side_px >= 2 * HALF_RES_MIN_SIDE:
            f = 2
            src = cv2.resize(gray, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
            block = max(7, (block // 2) | 1)
        mask = cv2.adaptiveThreshold(src, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block, p.adaptive_c)
    want_normal = "normal" in p.polarities
    want_inverted = "inverted" in p.polarities
    min_len = 4 * p.min_quad_side_px / f
    min_area = max(p.min_quad_area_px, p.min_quad_side_px**2)
    max_area = 0.95 * h * w
    quads: list[Quad] = []
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if hier is None:
        return quads
    parents = hier[0][:, 3]
    for i, c in enumerate(contours):
        if len(c) < min_len:
            continue
        inverted = bool(parents[i] >= 0)
        if (inverted and not want_inverted) or (not inverted and not want_normal):
            continue
        approx = cv2.approxPolyDP(c, 0.03 * len(c), True)
        if len(approx) != 4:
            # a steep view makes a thin quad whose short sides fall within 3 % of the
            # perimeter of the long ones
            approx = cv2.approxPolyDP(c, 0.012 * len(c), True)
        if len(approx) != 4 or not cv2.isContourConvex(approx):
            continue
        q = approx.reshape(4, 2).astype(np.float64)
        if f != 1:
            q = q * f + 0.5 * (f - 1)
            approx = q.astype(np.float32).reshape(4, 1, 2)
        area = abs(float(cv2.contourArea(approx)))
        if area < min_area or area > max_area:
            continue
        # plain Python on the 4 corners (numpy reductions cost more than they save here)
        (ax, ay), (bx, by), (cx, cy), (dx, dy) = q.tolist()
        if (
            min(ax, bx, cx, dx) < 2
            or min(ay, by, cy, dy) < 2
            or max(ax, bx, cx, dx) > w - 3
            or max(ay, by, cy, dy) > h - 3
        ):
            continue
        if min(
            math.hypot(bx - ax, by - ay), math.hypot(cx - bx, cy - by),
            math.hypot(dx - cx, dy - cy), math.hypot(ax - dx, ay - dy),
        ) < p.min_quad_side_px:  # fmt: skip
            continue
        polarity: Polarity = "inverted" if inverted else "normal"
        cand = Quad(polarity, clockwise(q), area)
        if not any(same_quad(cand, o) for o in quads):
            quads.append(cand)
    quads.sort(key=lambda qq: -qq.area)
    return quads[: p.max_candidates]


def clockwise(q: _F64) -> _F64:
    """Order 4 corners clockwise on screen (y down), starting nearest the image origin.

    Parameters
    ----------
    q : numpy.ndarray
        ``(4, 2)`` corners of a convex quad, any order.

    Returns
    -------
    numpy.ndarray
        ``(4, 2)`` float64, the same corners reordered.
    """
    pts = q.tolist()
    cx = sum(x for x, _ in pts) / len(pts)
    cy = sum(y for _, y in pts) / len(pts)
    pts.sort(key=lambda xy: math.atan2(xy[1] - cy, xy[0] - cx))
    sums = [x + y for x, y in pts]
    start = sums.index(min(sums))
    return np.array(pts[start:] + pts[:start], dtype=np.float64)


def same_quad(a: Quad, b: Quad) -> bool:
    """True when two candidates are the same data area: same polarity, areas within a factor
    1.4, centres closer than 15 % of the larger side."""
    if a.polarity != b.polarity:
        return False
    ratio = a.area / max(b.area, 1e-9)
    if not 0.7 < ratio < 1.4:
        return False
    ax, ay = _centre(a.corners.tolist())
    bx, by = _centre(b.corners.tolist())
    return math.sqrt((ax - bx) ** 2 + (ay - by) ** 2) < 0.15 * math.sqrt(max(a.area, b.area))


def around_detection(quad: Quad, detections: list[Detection]) -> bool:
    """True when ``quad`` is centred on a tag already decoded and not smaller than its data area.

    Candidates are read smallest first, so this skips the outline of a decoded tag's quiet
    zone (or a frame around it) and duplicates of its data area without reading them.
    """
    if not detections:
        return False
    # plain Python on 4 corners per detection: a frame with many tags calls this per candidate
    cx, cy = _centre(quad.corners.tolist())
    reach = 0.15 * math.sqrt(quad.area)
    for d in detections:
        corners = d.corners.astype(np.float32).tolist()  # the area as OpenCV's of float32 points
        if quad.area > 0.8 * _area(corners):
            dx, dy = _centre(d.corners.tolist())
            if math.sqrt((dx - cx) ** 2 + (dy - cy) ** 2) < reach:
                return True
    return False


def same_tag(a: Detection, b: Detection) -> bool:
    """True when two detections are one tag (same polarity, centres closer than 20 % of the
    diagonal of ``a``)."""
    if a.polarity != b.polarity:
        return False
    ac = a.corners.tolist()
    ax, ay = _centre(ac)
    bx, by = _centre(b.corners.tolist())
    (x0, y0), _, (x2, y2), _ = ac
    return math.sqrt((ax - bx) ** 2 + (ay - by) ** 2) < 0.2 * math.sqrt((x0 - x2) ** 2 + (y0 - y2) ** 2)


def _centre(corners: list[list[float]]) -> tuple[float, float]:
    """Mean of a few ``[x, y]`` points."""
    n = len(corners)
    return sum(x for x, _ in corners) / n, sum(y for _, y in corners) / n


def _area(corners: list[list[float]]) -> float:
    """Unsigned area of a polygon given by its ``[x, y]`` corners (shoelace)."""
    (px, py) = corners[-1]
    twice = 0.0
    for x, y in corners:
        twice += px * y - py * x
        px, py = x, y
    return abs(0.5 * twice)


def squeeze(quad: Quad) -> float:
    """How strongly a candidate is foreshortened: the smaller over the larger singular value of
    the affine map taking the unit square's diagonals to the quad's (1 head-on, about
    cos(tilt) for a tilt about any axis; a side ratio would miss a tilt about a diagonal).

    Parameters
    ----------
    quad : Quad
        The candidate (image pixels).

    Returns
    -------
    float
        In [0, 1].
    """
    q = quad.corners
    diagonals = np.stack([q[2] - q[0], q[3] - q[1]], axis=1)
    sv = np.linalg.svd(diagonals, compute_uv=False)
    return float(sv[1] / max(float(sv[0]), 1e-12))
