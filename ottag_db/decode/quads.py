"""Geometry of candidate quads: corner order, foreshortening, and which candidates and detections
of one frame are the same data area or the same tag (the detector's memory within a frame)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.params import DetectorParams
from ottag_db.decode.types import Detection, Quad

__all__ = [
    "INFERRED_MOVED",
    "OUTLINE_MOVED_PX",
    "Outlined",
    "around_detection",
    "centres_inside",
    "clockwise",
    "in_frame_corners",
    "outlined_before",
    "reading_order",
    "same_quad",
    "same_tag",
    "seen_before",
    "shows_print",
    "squeeze",
    "thinnest_side",
    "within_detection",
]

_F64 = NDArray[np.float64]

#: A candidate whose area is under this fraction of a candidate of the other polarity that holds
#: its centre is a piece of it (a triangle's outline inside a data area) and is read after it
#: (:func:`reading_order`). A quiet zone's outline holds its own data area at 1 / (1 + 2 · 0.25)²
#: = 0.44 of its area (0.35 or more under the perspective of a steep view), and that data area
#: is read first, as before; the triangles' outlines inside a data area (one tag a frame:
#: 1–3 candidates) take 0.01–0.42 of its area, nine in ten of them under this.
NESTED_MAX_AREA = 0.25
#: A foreshortened candidate that a later binarization outlines with a corner at least this far
#: (px) from every corner of the earlier outline is read again (see :func:`seen_before`).
OUTLINE_MOVED_PX = 1.5
#: An outline inferred from the lines of a partly hidden border is read again when a corner
#: lies this fraction of the side or more from every corner of the data area's earlier
#: outline: two outlines that far apart cannot both put their corners within 2 % of the side
#: of the tag's, the decoder design's bound, and a side seen only along a short run (a corner
#: cut by the frame's edge, the side nearly along it) is fitted differently by each threshold.
INFERRED_MOVED = 0.02


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


class Outlined(Protocol):
    """Anything with data-area corners: a :class:`~ottag_db.decode.types.Detection`, or a
    :class:`~ottag_db.decode.types.Quad` whose points read a tag the lookup does not hold."""

    @property
    def corners(self) -> NDArray[np.float64]:
        """``(4, 2)`` data-area corners, frame pixels."""


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


def within_detection(quad: Quad, detections: Sequence[Outlined]) -> bool:
    """True when the centre of ``quad`` lies on a decoded tag: inside its data area grown by the
    quiet zone ``export`` prints (0.25 of the side each way, so 1.5 × about its centre).

    Reading by model runs after a pass's other readings and skips such candidates: pieces of a
    decoded tag (a triangle's outline, a slit) are not other tags, nor are the pieces of a tag
    whose points read an order type the lookup does not hold.
    """
    if not detections:
        return False
    px, py = _centre(quad.corners.tolist())
    for d in detections:
        corners = d.corners.tolist()
        cx, cy = _centre(corners)
        grown = [(cx + 1.5 * (x - cx), cy + 1.5 * (y - cy)) for x, y in corners]
        # inside a convex polygon: the same side of every edge
        signs = [
            (bx - ax) * (py - ay) - (by - ay) * (px - ax)
            for (ax, ay), (bx, by) in zip(grown, grown[1:] + grown[:1], strict=True)
        ]
        if all(s >= 0 for s in signs) or all(s <= 0 for s in signs):
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


def outlined_before(quad: Quad, seen: list[Quad]) -> bool:
    """Whether an earlier binarization of the frame outlined this candidate's data area too.

    A foreshortened data area outlined anew (:func:`seen_before`) is read again, by model only
    (the detector's reasons are at its call).

    Parameters
    ----------
    quad : Quad
        A candidate of the current binarization.
    seen : list of Quad
        The candidates of the earlier ones.

    Returns
    -------
    bool
        True when one of them is the same data area (:func:`same_quad`).
    """
    return bool(_twins(quad, seen))


def centres_inside(inner: Sequence[Quad], outer: Sequence[Quad]) -> NDArray[np.bool_]:
    """Which candidates' centres lie inside which quads (on an edge counts as inside).

    Parameters
    ----------
    inner : sequence of Quad
        The candidates whose centres (the mean of their corners) are tested.
    outer : sequence of Quad
        The convex quads tested against.

    Returns
    -------
    numpy.ndarray
        ``(len(inner), len(outer))`` bool.
    """
    if not inner or not outer:
        return np.zeros((len(inner), len(outer)), dtype=bool)
    centres = np.stack([q.corners for q in inner]).mean(axis=1)  # (m, 2)
    corners = np.stack([q.corners for q in outer])  # (n, 4, 2)
    edges = np.roll(corners, -1, axis=1) - corners
    # the side of each edge of quad j that the centre of candidate i lies on: (i, j, 4)
    rel = centres[:, None, None, :] - corners[None, :, :, :]
    cross = edges[None, :, :, 0] * rel[..., 1] - edges[None, :, :, 1] * rel[..., 0]
    inside: NDArray[np.bool_] = (cross >= 0).all(axis=2) | (cross <= 0).all(axis=2)
    return inside


def reading_order(quads: Sequence[Quad]) -> list[tuple[int, int | None]]:
    """The order in which a pass reads its candidates: smallest first (so that the outline of a
    decoded tag's quiet zone is skipped, :func:`around_detection`), except that a piece of a
    larger candidate of the other polarity (under :data:`NESTED_MAX_AREA` of its area, its centre
    inside it: a triangle's outline inside a data area) comes right after that candidate, whose
    reading as a tag makes its pieces no tags (:func:`within_detection`).

    Parameters
    ----------
    quads : sequence of Quad
        The pass's candidates.

    Returns
    -------
    list of (int, int or None)
        Each candidate's index into ``quads`` in reading order, with the index of the candidate
        it is a piece of (the smallest such), or None.
    """
    n = len(quads)
    if n == 0:
        return []
    areas = np.array([q.area for q in quads])
    inside = centres_inside(quads, quads)
    normal = np.array([q.polarity == "normal" for q in quads])
    holds = inside & (normal[:, None] != normal[None, :]) & (areas[:, None] < NESTED_MAX_AREA * areas[None, :])
    holder: list[int | None] = []
    for i in range(n):
        around = np.flatnonzero(holds[i])
        holder.append(int(around[areas[around].argmin()]) if len(around) else None)
    pieces: list[list[int]] = [[] for _ in range(n)]
    for i in sorted(range(n), key=lambda i: areas[i]):
        h = holder[i]
        if h is not None:
            pieces[h].append(i)
    order: list[int] = []
    # smallest on top of the stack (equal areas in the pass's order, as a stable sort keeps them)
    stack = sorted((i for i in range(n) if holder[i] is None), key=lambda i: (-areas[i], -i))
    while stack:  # each candidate, then its pieces (smallest first), then theirs
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(pieces[i]))
    return [(i, holder[i]) for i in order]


def seen_before(quad: Quad, seen: list[Quad], max_ratio: float) -> bool:
    """Whether an earlier binarization of the frame found this candidate already.

    A data area found again (:func:`same_quad`) is not read twice, except where only an
    inferred outline (:attr:`~ottag_db.decode.types.Quad.inferred`) found it before, a foreshortened one
    (:func:`squeeze` at most ``max_ratio``) whose new outline has a corner
    ``OUTLINE_MOVED_PX`` or more from every corner of the earlier one, and an inferred one whose
    corner moved :data:`INFERRED_MOVED` of the side (or that, if less). Nearly edge-on, a data
    area is a few pixels thin and each threshold moves its outline by a good part of that: the
    tag seen ranked 7th–23rd among the printed tags from the local threshold's corners and 1st
    from Otsu's (tilt sweep of benchmarks/decode_sweeps.py, 84–86°), which were dropped as the
    same candidate.

    Parameters
    ----------
    quad : Quad
        A candidate of the current binarization.
    seen : list of Quad
        The candidates of the earlier ones.
    max_ratio : float
        ``DetectorParams.rectify_max_ratio``: the foreshortening from which outlines are compared.

    Returns
    -------
    bool
    """
    # an outline inferred from a hidden or cut border (whose reading must show the print) does
    # not stand in for a later binarization's whole outline of the data area, which the points
    # may decide (a corner 2 px inside the frame's edge: the local threshold's quad reached it)
    twins = [o for o in _twins(quad, seen) if quad.inferred or not o.inferred]
    if not twins:
        return False
    moved = OUTLINE_MOVED_PX if squeeze(quad) <= max_ratio else math.inf
    if quad.inferred:  # corners inferred from lines: each threshold's may fit other runs
        moved = min(moved, max(OUTLINE_MOVED_PX, INFERRED_MOVED * math.sqrt(quad.area)))
    if moved == math.inf:
        return True
    corners = quad.corners
    for o in twins:
        gaps = np.hypot(*(corners[:, None, :] - o.corners[None, :, :]).transpose(2, 0, 1))  # (4, 4)
        if float(gaps.min(axis=1).max()) < moved:
            return True
    return False


def _twins(quad: Quad, seen: Sequence[Quad]) -> list[Quad]:
    """The candidates of ``seen`` that are the same data area as ``quad`` (:func:`same_quad`'s
    test, on all of them at once: a frame of brick or foliage holds a hundred candidates a
    pass, each compared with every earlier one)."""
    alike = [o for o in seen if o.polarity == quad.polarity]
    if not alike:
        return []
    areas = np.array([o.area for o in alike])
    ratio = quad.area / np.maximum(areas, 1e-9)
    near = (ratio > 0.7) & (ratio < 1.4)
    if not near.any():
        return []
    alike = [o for o, keep in zip(alike, near.tolist(), strict=True) if keep]
    centres = np.stack([o.corners for o in alike]).sum(axis=1) / 4  # (m, 2), as _centre sums
    cx, cy = _centre(quad.corners.tolist())
    gap = np.sqrt((cx - centres[:, 0]) ** 2 + (cy - centres[:, 1]) ** 2)
    close = gap < 0.15 * np.sqrt(np.maximum(quad.area, areas[near]))
    return [o for o, keep in zip(alike, close.tolist(), strict=True) if keep]


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
    small, big = _diagonal_singular_values(quad)
    return small / big if big > 1e-12 else 0.0


def _diagonal_singular_values(quad: Quad) -> tuple[float, float]:
    """The smaller and larger singular value of the 2×2 map taking the unit square's diagonals
    to the quad's, in closed form (plain floats: this runs for every candidate, where
    np.linalg.svd's call overhead was 2 % of a frame)."""
    (ax, ay), (bx, by), (cx, cy), (dx, dy) = quad.corners.tolist()
    m11, m21, m12, m22 = cx - ax, cy - ay, dx - bx, dy - by
    frob = m11 * m11 + m12 * m12 + m21 * m21 + m22 * m22
    det = abs(m11 * m22 - m12 * m21)
    root = math.sqrt(max(frob * frob - 4.0 * det * det, 0.0))
    big = math.sqrt(0.5 * (frob + root))
    return (det / big if big > 1e-12 else 0.0), big


def thinnest_side(quad: Quad) -> float:
    """The data area's side along its most foreshortened direction, px: the smaller singular
    value of the affine map taking the unit square's diagonals to the quad's, over √2 (the side
    itself head-on; about side · cos(tilt) at a tilt).

    Parameters
    ----------
    quad : Quad
        The candidate (image pixels).

    Returns
    -------
    float
    """
    return _diagonal_singular_values(quad)[0] / math.sqrt(2.0)


def shows_print(quad: Quad, params: DetectorParams) -> bool:
    """Whether a reading of this candidate must show its tag as printed (the stored layout and
    placement, when the lookup knows them): on small data areas (side ``sqrt(area)`` under
    ``print_check_side_px``), and at oblique views (:func:`squeeze` at most
    ``layout_check_ratio``) whose side along the foreshortened direction
    (:func:`thinnest_side`) is under ``print_check_side_px`` too. There a vertex lost at a sliver
    tip or in a blurred corner can leave the points of another order type that fits within the
    bound. What loses a vertex is how few pixels span the triangles across their thinnest
    direction, not the tilt itself: a large tag seen obliquely keeps as many pixels across as
    a tag of that side head-on, where the points decide, so a tag drawn by another program
    (other triangles, another placement) reads there too.

    Parameters
    ----------
    quad : Quad
        The candidate.
    params : DetectorParams
        ``layout_check_ratio`` (0: never) and ``print_check_side_px`` (0: never by size).

    Returns
    -------
    bool
    """
    if params.layout_check_ratio <= 0:
        return False
    if math.sqrt(quad.area) < params.print_check_side_px:
        return True
    return squeeze(quad) <= params.layout_check_ratio and thinnest_side(quad) < params.print_check_side_px


def in_frame_corners(detection: Detection, shape: tuple[int, ...]) -> Detection:
    """The detection with its corners outside the frame marked as not seen.

    A data area cut by the frame's edge is outlined by the lines of its visible sides; the
    corner beyond the edge is where they meet, or where the print puts it, never seen.

    Parameters
    ----------
    detection : Detection
        A detection of a frame of ``shape``.
    shape : tuple of int
        ``(H, W)`` of the frame.

    Returns
    -------
    Detection
        ``detection`` itself when every corner lies inside the frame (pixel centres from 0 to
        W − 1 and H − 1, half a pixel of slack).
    """
    h, w = shape[:2]
    x, y = detection.corners[:, 0], detection.corners[:, 1]
    inside = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
    if inside.all():
        return detection
    seen = detection.corners_seen if detection.corners_seen is not None else (True,) * 4
    return replace(detection, corners_seen=tuple(bool(s and i) for s, i in zip(seen, inside, strict=True)))
