"""Outlines of data areas whose border is partly hidden or cut by the frame's edge.

A finger or bar across a tag's border, a covered corner or the frame's edge leave an outline that
is no quad: a spike, a notch, a corner cut off, or — for an inverted tag — a dark quiet zone
opened into a C, its white data area no longer a hole of it. The sides that remain visible
still lie on four lines (:func:`lines_outline`); the candidate stage
(:mod:`~ottag_db.decode.candidates`) outlines such data areas by them, and a quad so inferred
(``Quad.inferred``) must show its tag's print to be read.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from ottag_native.lines import lines_quad

from ottag_db.core.geometry import segment_distances
from ottag_db.core.types import QUIET_ZONE
from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography, square_homography
from ottag_db.decode.quads import clockwise

__all__ = [
    "FRAME_CUT_INNER_MARGIN",
    "FRAME_CUT_TOLERANCE",
    "LINES_MIN_SOLIDITY",
    "LINES_MIN_SUPPORT",
    "SPIKE_MAX_HOLES",
    "SPIKE_RADIUS",
    "at_frame_edge",
    "cut_by_frame_only",
    "data_area_inside",
    "holes_at_frame_edge",
    "lines_outline",
    "without_spikes",
]

#: An outline that is no quad (a finger or bar across the border, a corner cut by the frame)
#: is outlined by its four straightest runs (:func:`lines_outline`) when they cover at least
#: this fraction of the quad they make: the visible sides carry the outline, the occluder's
#: edges and the frame's edge are shorter runs. On scikit-image's 20 photographs and textures
#: (640×480) the two half-resolution passes' quads went from 119 to 163 at 0.7 and to 139 at
#: 0.85, while occluded tags outlined fell from 17 of 30 to 15.
LINES_MIN_SUPPORT = 0.85
#: Polygon edges within this angle (degrees) and distance (px, or 1.5 % of the outline's
#: length) of a line are runs of that line: the two visible parts of a side cut by a bar.
_LINE_ANGLE_DEG = 4.0
_LINE_DISTANCE = 0.015
_LINE_COS = math.cos(math.radians(_LINE_ANGLE_DEG))  # (the kernel compares directions' cosines)
#: The longest runs among which the four sides are looked for, and the range of the quad's
#: area over the outline's own (a spike adds little area, a notch or a cut corner takes little).
_LINES_CONSIDERED = 7
#: An outline is tried only when its region fills this much of its convex hull: a data area
#: with a bar across a side fills 0.7–0.95 of its hull (the bar's long spike the least), the
#: regions of foliage, gravel and text mostly much less.
LINES_MIN_SOLIDITY = 0.6
_LINES_AREA_RATIO = (0.8, 1.3)
#: A quad-like outline (fewer than five polygon vertices at the usual tolerance) is
#: approximated again at this fraction of it: a corner the frame's edge cuts 2–6 px deep (4–7 %
#: of a 110–170 px side at half resolution) is shallower than the tolerance, which rounds the
#: cut into a single vertex on the frame's edge instead of the two ends of the edge's run.
_FINE_TOLERANCE = 0.35
#: The same for an inverted tag's quiet zone opened into a C (``ring``): it fills 0.56 of its
#: outline (0.45–0.75 under blur and an occluder), and 0.35–0.75 of its hull (a solid region
#: is no ring).
_RING_AREA_RATIO = (1 / 0.75, 1 / 0.45)
_RING_SOLIDITY = (0.35, 0.75)
#: A dark region whose outline is a data area with spikes (:func:`without_spikes`) keeps what
#: a disk of this radius, in units of the side of its holes' hull (about the data area's), can
#: reach within it: a bar across the border is 4–6 % of the side wide and the edges of an
#: occluder a few px (at half resolution), thinner than the disk's 20 %, which the data area's
#: 50–85 px at half resolution hold with ease.
SPIKE_RADIUS = 0.1
#: The region is looked at within this margin (in units of the holes' hull side) around the
#: hull: in the local threshold's mask the holes are the data area's interior (its uniform
#: parts and triangles), in the global one its triangles, whose hull spans most of the side.
#: A wider margin takes in more of an occluder (whose edges may close around it and keep it
#: thick): with 0.7 and 1.0, 3 of 80 covered corners no longer read that 0.5 reads.
_SPIKE_MARGIN = 0.5
#: Holes of fewer contour points than this are specks, not parts of the data area's interior.
_SPIKE_MIN_HOLE = 4
#: A region with more holes than this holds no data area with spikes: a data area's holes in
#: the local threshold's mask are its triangles (at most 12 hold a tag's points) and the
#: uniform parts of its interior between them, 1–35 in occluded views at 110–170 px; the
#: regions of foliage, gravel and text hold hundreds to thousands, whose hull is most of the
#: frame.
SPIKE_MAX_HOLES = 64
#: A data area whose outline only the frame's edge cuts is read as seen whole, its points
#: deciding (:func:`cut_by_frame_only`), when the square this fraction of the side inside its
#: border lies in the frame: no triangle can then lie wholly beyond the edge unless all three
#: of its vertices lie within this of the border. The project prints them a tenth of the side
#: inside (:data:`~ottag_db.core.placement.DEFAULT_INNER_MARGIN`); a triangle that the edge
#: cuts is left out of the data area (:mod:`~ottag_db.decode.segmentation`), and the reading
#: must then show the print.
FRAME_CUT_INNER_MARGIN = 0.04
#: … and when every point of its outline off the frame's edge lies within this fraction of
#: the side (1.5 px at least) of the quad's sides: a finger, bar or covered corner moves the
#: outline by 4 % of the side or more (the occluders of benchmarks/decode_occlusion.py),
#: the pixel steps and blur of a traced outline by a px or two.
FRAME_CUT_TOLERANCE = 0.025


def lines_outline(
    contour: NDArray[Any], perimeter: float, shape: tuple[int, ...], ring: bool = False
) -> NDArray[Any] | None:
    """The quad of an outline's four straightest runs, or None.

    A finger or bar across a data area's border adds a spike or a notch to its outline, a frame
    edge cuts a corner off; the sides that remain visible still lie on four lines. The outline
    is approximated by a polygon, its edges along the frame's edge are left out, and edges that
    lie on one line (within ``_LINE_ANGLE_DEG`` and ``_LINE_DISTANCE``) are runs of one side.
    The four lines with the longest runs, in their order around the outline, meet at the quad's
    corners (which may lie outside the frame); the quad is kept when it is convex and its runs
    cover at least :data:`LINES_MIN_SUPPORT` of its perimeter.

    Parameters
    ----------
    contour : numpy.ndarray
        ``(n, 1, 2)`` int32 contour.
    perimeter : float
        Its length, px.
    shape : tuple of int
        ``(H, W)`` of the image the contour was traced in.
    ring : bool, optional
        The region is an inverted tag's dark quiet zone opened by a finger or the frame's edge
        (a ring cut into a C, the white data area no longer a hole of it): the quad is its outer
        outline, which a ring fills to ``1 − 1 / (1 + 2 · QUIET_ZONE)²`` (0.56).

    Returns
    -------
    numpy.ndarray or None
        ``(4, 1, 2)`` float32 corners.
    """
    region = abs(float(cv2.contourArea(contour)))
    (least_solid, most_solid), (least, most) = (
        (_RING_SOLIDITY, _RING_AREA_RATIO) if ring else ((LINES_MIN_SOLIDITY, 1.0), _LINES_AREA_RATIO)
    )
    solidity = region / max(abs(float(cv2.contourArea(cv2.convexHull(contour)))), 1.0)
    if not least_solid <= solidity <= most_solid:
        return None  # ragged: texture, not a square with a spike, a notch or a cut corner
    tol = max(1.5, _LINE_DISTANCE * perimeter)
    poly = cv2.approxPolyDP(contour, tol, True).reshape(-1, 2).astype(np.float64)
    if len(poly) < 5 and not ring:  # a corner cut off by a few px: the polygon rounds it off
        fine = max(1.0, _FINE_TOLERANCE * tol)
        poly = cv2.approxPolyDP(contour, fine, True).reshape(-1, 2).astype(np.float64)
    if len(poly) < 5 or len(poly) > 24:
        return None
    h, w = shape[:2]
    # compiled (ottag_native.lines): the edges off the frame's edge, at least twice the
    # tolerance long, that lie on one line (within _LINE_ANGLE_DEG and the tolerance) are runs of
    # one side; of the _LINES_CONSIDERED longest runs, the four whose lines, in the outline's
    # order, meet at the corners of a convex quad covering the outline's area with the most
    # support (a spike's edges can be longer; a run supports its side only between the side's
    # corners: a bar's edge runs on beyond), kept when that support is at least
    # LINES_MIN_SUPPORT of the quad's outline inside the frame (only one corner may lie beyond
    # the edge, as three seen ones hold the quad: with more, the whole perimeter counts)
    quad = np.empty((4, 2), np.float32)
    if not lines_quad(
        poly, tol, _LINE_COS, w, h, least * region, most * region, _LINES_CONSIDERED, LINES_MIN_SUPPORT, quad
    ):
        return None
    return quad.reshape(4, 1, 2)


def without_spikes(contour: NDArray[Any], holes: Sequence[NDArray[Any]], shape: tuple[int, ...]) -> NDArray[Any] | None:
    """The quad of a dark region's outline without its spikes, or None.

    A bar across a normal tag's border, or the edges of an occluder covering a corner, join the
    dark data area to dark parts outside the quiet zone: the region's outline is the data area
    with long, thin spikes, too ragged for :func:`lines_outline`. The data area is where the
    region is thick: of the filled outline near the hull of its holes (the triangles and the
    interior), what lies within twice :data:`SPIKE_RADIUS` of the hull's side of the points
    more than that radius deep inside it keeps the data area, its corners too, and cuts the
    spikes to stubs; that is outlined by :func:`lines_outline`. Regions of more than
    :data:`SPIKE_MAX_HOLES` holes are not looked at.

    Parameters
    ----------
    contour : numpy.ndarray
        ``(n, 1, 2)`` int32 outer contour of a dark region.
    holes : sequence of numpy.ndarray
        The contours of its holes.
    shape : tuple of int
        ``(H, W)`` of the image the contour was traced in.

    Returns
    -------
    numpy.ndarray or None
        ``(4, 1, 2)`` float32 corners.
    """
    if len(holes) > SPIKE_MAX_HOLES:
        return None
    inner = [hole for hole in holes if len(hole) >= _SPIKE_MIN_HOLE]
    if not inner:
        return None
    hull = cv2.convexHull(np.concatenate(inner))
    side = math.sqrt(abs(float(cv2.contourArea(hull))))
    radius = round(SPIKE_RADIUS * side)
    if radius < 2:
        return None
    x, y, bw, bh = cv2.boundingRect(hull)
    pad = round(_SPIKE_MARGIN * side) + radius
    x0, y0 = max(x - pad, 0), max(y - pad, 0)
    x1, y1 = min(x + bw + pad, shape[1]), min(y + bh + pad, shape[0])
    filled = np.zeros((y1 - y0, x1 - x0), dtype=np.uint8)
    cv2.drawContours(filled, [contour], -1, 255, cv2.FILLED, offset=(-x0, -y0))
    # opened by the disk (distance transforms: linear in the pixels, whatever the radius)
    deep = (cv2.distanceTransform(filled, cv2.DIST_L2, 3) > radius).astype(np.uint8)
    near = cv2.distanceTransform(1 - deep, cv2.DIST_L2, 3) <= 2 * radius
    kept = np.where(near, filled, 0).astype(np.uint8)
    found, _ = cv2.findContours(kept, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE, offset=(x0, y0))
    if not found:
        return None
    main = max(found, key=len)
    return lines_outline(main, float(len(main)), shape)


def holes_at_frame_edge(mask: NDArray[Any], min_len: float) -> list[NDArray[Any]]:
    """Bright regions of the dark ``mask`` that reach the frame's edge, as outlines of at least
    ``min_len`` points.

    An inverted data area with a corner beyond the frame's edge is no hole of the dark mask: its
    dark quiet zone no longer closes around it. Traced in the mask padded with a dark border, it
    is one again (so is the background, which no quad outlines: its runs lie along the edge).
    """
    if not (mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any()):
        return []  # nothing dark reaches the edge: every bright region there is background
    padded = cv2.copyMakeBorder(mask, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=255)
    contours, hier = cv2.findContours(padded, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE, offset=(-1, -1))
    if hier is None:
        return []
    h, w = mask.shape[:2]
    # (a frame of foliage or text traces tens of thousands of contours: the holes of the right
    # length are picked at once, and only they are looked at; longer: the background along the edge)
    lengths = np.fromiter(map(len, contours), dtype=np.int64, count=len(contours))
    holes = (hier[0][:, 3] >= 0) & (lengths >= min_len) & (lengths <= w + h)
    out = []
    for i in np.flatnonzero(holes).tolist():
        c = contours[i]
        x, y = c[:, 0, 0], c[:, 0, 1]
        if x.min() <= 0 or y.min() <= 0 or x.max() >= w - 1 or y.max() >= h - 1:
            out.append(c)
    return out


def data_area_inside(quiet: NDArray[Any]) -> NDArray[Any] | None:
    """The data area inside a quiet zone's outer outline (``(4, 1, 2)``), as printed."""
    to_frame = square_homography(clockwise(quiet.reshape(4, 2).astype(np.float64)))
    if to_frame is None:
        return None
    q = QUIET_ZONE / (1 + 2 * QUIET_ZONE)
    inner = apply_homography(to_frame, q + (1 - 2 * q) * UNIT_SQUARE)
    return inner.astype(np.float32).reshape(4, 1, 2) if np.isfinite(inner).all() else None


def at_frame_edge(points: NDArray[Any], shape: tuple[int, ...], within: int = 1) -> bool:
    """Whether a point of ``points`` (a quad's corners or a contour, ``(n, 1, 2)``) lies within
    ``within`` px of the frame's outermost pixels (0: on them)."""
    q = points.reshape(-1, 2)
    h, w = shape[:2]
    lo, hi = q.min(axis=0), q.max(axis=0)
    return bool((lo <= within).any() or hi[0] >= w - 1 - within or hi[1] >= h - 1 - within)


def cut_by_frame_only(contour: NDArray[Any], quad: NDArray[Any], shape: tuple[int, ...]) -> bool:
    """Whether the frame's edge is all that hides part of the data area ``quad`` outlined by
    ``contour``: its inner square (:data:`FRAME_CUT_INNER_MARGIN`) lies in the frame and the
    outline off the frame's edge follows the quad's sides (:data:`FRAME_CUT_TOLERANCE`).

    Parameters
    ----------
    contour : numpy.ndarray
        ``(n, 1, 2)`` outline of the region (pixels of a frame of ``shape``).
    quad : numpy.ndarray
        ``(4, 1, 2)`` or ``(4, 2)`` corners inferred for it, in order around it.
    shape : tuple of int
        The frame's ``(H, W)``.

    Returns
    -------
    bool
        True when the reading's points may decide as for a data area seen whole.
    """
    h, w = shape[:2]
    corners = quad.reshape(4, 2).astype(np.float64)
    to_frame = square_homography(clockwise(corners))
    if to_frame is None:
        return False
    m = FRAME_CUT_INNER_MARGIN
    inner = apply_homography(to_frame, m + (1 - 2 * m) * UNIT_SQUARE)
    if not np.isfinite(inner).all() or inner.min() < 0 or (inner[:, 0] > w - 1).any() or (inner[:, 1] > h - 1).any():
        return False
    # (at most some 256 outline points: an occluder's notch or spike spans many more px)
    pts = contour.reshape(-1, 2)[:: max(1, len(contour) // 256)].astype(np.float64)
    off_edge = (pts[:, 0] > 1) & (pts[:, 1] > 1) & (pts[:, 0] < w - 2) & (pts[:, 1] < h - 2)
    pts = pts[off_edge]
    if not len(pts):
        return False
    gap = segment_distances(pts, corners, np.roll(corners, -1, axis=0)).min(axis=1)  # to the nearest side
    side = math.sqrt(abs(float(cv2.contourArea(corners.astype(np.float32)))))
    return bool(gap.max() <= max(1.5, FRAME_CUT_TOLERANCE * side))
