"""Segmentation stage: a candidate's data area → bright-triangle mask → triangle decompositions."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.image import otsu
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.placement_check import square_homography
from ottag_db.decode.splitting import FitBudget, FitMemo, SearchBudget, component_decompositions
from ottag_db.decode.triangles import triangle_fit
from ottag_db.decode.types import DataArea, Decomposition, Quad, Rejection

__all__ = [
    "MAX_DECOMPOSITIONS",
    "MAX_TRIANGLES",
    "NO_DECOMPOSITION",
    "RECTILINEAR_MAX_DEG",
    "RECTILINEAR_MIN_EDGE_PX",
    "RECTILINEAR_MIN_EDGE_REL",
    "bridge",
    "decompose",
    "rectilinear",
    "segment",
    "then_alternatives",
    "triangles_by_opening",
]

_F64 = NDArray[np.float64]

#: At most this many alternative decompositions of one data area are read.
MAX_DECOMPOSITIONS = 10
#: More triangles than this cannot hold a tag's points (each triangle has 3 of them, two
#: triangles share at most one): the component soup of a non-tag.
MAX_TRIANGLES = 12
#: Detail of the rejection when no decomposition was found at all.
NO_DECOMPOSITION = "a component is not a union of triangles"
#: Data areas whose side (px) is at least this are cleared of components that cross their
#: border (``_without_intrusions``). A printed triangle keeps a tenth of the side from the
#: border, but the quad of a small, blurred data area can be a few px off (an inverted tag 55 px
#: wide, its white area shrunk by blur): below this, a triangle's tip brought to the edge
#: touches as many edge pixels as a finger 4–6 % of the side wide does.
INTRUSION_MIN_SIDE = 80.0
#: A component crosses the data area's edge when it runs along the interior's outermost pixels
#: for this fraction of the side: a finger or bar 4–6 % of the side wide does, a triangle's tip
#: brought near the edge by a rough quad touches it at a pixel or two.
INTRUSION_MIN_WIDTH = 0.03
#: 3 × 3 cross: the interior's outermost pixels (see ``_without_intrusions``).
_CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
#: A component whose long outline edges all lie within this angle (degrees, in data-area
#: units; plus the turn of a pixel across the edge) of the data area's sides is no union of
#: triangles (:func:`rectilinear`). Every triangle has a side off both axes: of the 19,988
#: triangles of the 6,671 tags the bundled data prints (k = 3 … 8 with mirrors), the least
#: tilted such side lies 7.2° off an axis (5 % of the triangles have none beyond 21°). On the
#: 100 ArUco frames of benchmarks/decode_speed.py 99 of the 100 marker components searched
#: were recognised. Of 1,729 components in tag data areas (700 random frames, data area
#: 25–200 px, tilt ≤ 62°, blur ≤ 1.5 px; 400 of them of the 12 tags with the least tilted
#: sides) none was; the closest came within 2.6° of the tolerance.
RECTILINEAR_MAX_DEG = 3.0
#: Outline edges shorter than this (px, or this fraction of the data-area side) are not
#: judged: the bevels of blurred corners and the pinches of cells meeting at a corner.
RECTILINEAR_MIN_EDGE_PX = 8.0
RECTILINEAR_MIN_EDGE_REL = 0.06


def segment(gray: NDArray[np.uint8], quad: Quad, params: DetectorParams) -> DataArea | Rejection:
    """Cut out the data area of ``quad`` and separate its triangles (local Otsu threshold).

    The interior mask is the quad without a band along its border (the blur of the quiet
    zone's edge; 1 px when the usual band leaves too little to threshold, as of a data area
    nearly edge-on); the triangles are the pixels brighter than the level halfway between the
    two Otsu classes of the interior (for an inverted tag the ROI is inverted first).

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    quad : Quad
        The candidate (image pixels).
    params : DetectorParams
        Uses ``min_contrast``.

    Returns
    -------
    DataArea or Rejection
        ``"low_contrast"`` without two grey levels ``min_contrast`` apart, ``"no_triangles"``
        when the bright part is below 1 % or above 75 % of the interior.
    """
    h, w = gray.shape
    q = quad.corners
    (ax, ay), (bx, by), (cx, cy), (dx, dy) = q.tolist()  # 4 corners: plain Python is cheaper
    x0 = max(math.floor(min(ax, bx, cx, dx)) - 4, 0)
    y0 = max(math.floor(min(ay, by, cy, dy)) - 4, 0)
    x1 = min(math.ceil(max(ax, bx, cx, dx)) + 5, w)
    y1 = min(math.ceil(max(ay, by, cy, dy)) + 5, h)
    roi = gray[y0:y1, x0:x1]
    if quad.polarity == "inverted":
        roi = 255 - roi
    origin = np.array([x0, y0], dtype=np.float64)
    ql = q - origin
    side = math.sqrt(quad.area)
    qi: NDArray[Any] = np.round(ql * 16).astype(np.int32).reshape(4, 1, 2)
    # A normal tag at 84–86° gives a data area 4–6 px thin (its dark area thins under blur):
    # the 2 px band left nothing of it (``low_contrast`` without grey levels) while the same
    # poses inverted read (benchmarks/decode_sweeps.py); with 1 px its slivers or model read.
    for band in (max(2, round(0.02 * side)), 1):
        mask: NDArray[Any] = np.zeros((roi.shape[0], roi.shape[1]), dtype=np.uint8)
        cv2.fillPoly(mask, [qi], 255, cv2.LINE_8, 4)
        cv2.polylines(mask, [qi], True, 0, 2 * band + 1, cv2.LINE_8, 4)
        hist = cv2.calcHist([roi], [0], mask, [256], [0, 256]).ravel()
        split = otsu(hist)
        if split is not None:
            break
    if split is None or split.contrast < params.min_contrast:
        return Rejection("low_contrast", "" if split is None else f"{split.contrast:.0f} grey levels")
    level = 0.5 * (split.dark + split.bright)
    fg: NDArray[Any] = cv2.bitwise_and(cv2.threshold(roi, level, 255, cv2.THRESH_BINARY)[1], mask)
    fg, intrusions = _without_intrusions(fg, mask, side) if side >= INTRUSION_MIN_SIDE else (fg, 0)
    fg, cut = _without_cut_components(fg, (x0, y0, x1, y1), (w, h))
    intrusions += cut
    frac = cv2.countNonZero(fg) / max(cv2.countNonZero(mask), 1)
    if frac < 0.01 or frac > 0.75:
        return Rejection("no_triangles", f"bright fraction {frac:.2f}")
    return DataArea(roi, origin, ql, side, level, fg, intrusions)


def _without_cut_components(
    fg: NDArray[Any], box: tuple[int, int, int, int], frame: tuple[int, int]
) -> tuple[NDArray[Any], int]:
    """``fg`` (of the ROI ``box`` = x0, y0, x1, y1 of a ``frame`` = W, H) without the components
    that reach the frame's edge, and how many there were: a triangle cut by the edge has a side
    along it and a false vertex where the edge crosses it."""
    x0, y0, x1, y1 = box
    w, h = frame
    if x0 > 0 and y0 > 0 and x1 < w and y1 < h:
        return fg, 0  # the ROI does not reach the frame's edge
    rim = np.zeros_like(fg)
    if x0 == 0:
        rim[:, 0] = 255
    if y0 == 0:
        rim[0, :] = 255
    if x1 == w:
        rim[:, -1] = 255
    if y1 == h:
        rim[-1, :] = 255
    return _without_touching(fg, rim, 1.0)


def _without_intrusions(fg: NDArray[Any], interior: NDArray[Any], side: float) -> tuple[NDArray[Any], int]:
    """``fg`` without its components that cross the interior's edge, and how many there were.

    A printed tag keeps every point, and so every triangle, at least
    :data:`~ottag_db.core.placement.DEFAULT_INNER_MARGIN` (a tenth of the side) inside its data
    area, while the band left out of the interior is 2 % of the side: a component that runs
    along the interior's outermost pixels for :data:`INTRUSION_MIN_WIDTH` of the side (3 px at
    least) comes from outside — a finger, a bar, a pen across the tag (a triangle's tip that a
    rough quad brings near the edge touches it at a pixel or two). It is no triangle; the reading
    without it must show the tag as printed (see :attr:`~ottag_db.decode.types.DataArea.intrusions`).
    """
    edge = cv2.bitwise_and(interior, cv2.bitwise_not(cv2.erode(interior, _CROSS)))
    return _without_touching(fg, edge, max(3.0, INTRUSION_MIN_WIDTH * side))


def _without_touching(fg: NDArray[Any], where: NDArray[Any], least: float) -> tuple[NDArray[Any], int]:
    """``fg`` without its components that have at least ``least`` pixels in the mask ``where``,
    and how many there were."""
    touching = cv2.bitwise_and(fg, where)
    if cv2.countNonZero(touching) < least:
        return fg, 0
    count, labels = cv2.connectedComponents(fg, connectivity=8)
    along = np.bincount(labels[touching > 0], minlength=count)
    dropped = np.flatnonzero(along >= least)
    dropped = dropped[dropped > 0]
    if not len(dropped):
        return fg, 0
    kept: NDArray[Any] = np.where(np.isin(labels, dropped), 0, fg).astype(np.uint8)
    return kept, len(dropped)


def decompose(
    fg: NDArray[np.uint8],
    side: float,
    params: DetectorParams,
    alternatives: SearchBudget | None,
    memo: FitMemo | None = None,
    quad: _F64 | None = None,
) -> list[Decomposition] | Rejection:
    """Split the bright components of a data area into triangles (contour side chains).

    Parameters
    ----------
    fg : numpy.ndarray
        uint8 mask of the bright triangles (ROI pixels).
    side : float
        Data-area side (√area, px): bounds the component areas.
    params : DetectorParams
        Uses ``min_triangle_area_px``.
    alternatives : SearchBudget or None
        None: only the first decomposition (cheap; what almost every tag needs). Else, within
        this budget (shared by all components), each component's first decomposition by the
        splitter's cuts between concave points, then the 3×3 opening, then slit (notch) cuts;
        the alternatives of one component at a time are combined with the first ones of the
        others.
    memo : FitMemo or None
        Fits and cuts of this mask's contours from an earlier call (None: a fresh memo).
    quad : numpy.ndarray or None
        ``(4, 2)`` data-area corners in ``fg`` pixels, in order around the quad, when they are
        accurate enough to rectify outline edges: a component that is :func:`rectilinear`
        then gets no alternative search (None: every component does).

    Returns
    -------
    list of Decomposition or Rejection
        At most :data:`MAX_DECOMPOSITIONS`, most plausible first (one empty decomposition
        when the mask holds no component); ``"non_triangle"`` when a component is too large,
        a filled square, or not a union of triangles, or when there are more components than
        :data:`MAX_TRIANGLES`.
    """
    contours, hier = cv2.findContours(fg, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if hier is None:
        return [Decomposition(())]
    hh = hier[0]
    if memo is None:
        memo = FitMemo()
    min_area = max(params.min_triangle_area_px, 2e-4 * side * side)
    max_area = 0.45 * side * side  # no triangle of a tag covers half its data area
    options: list[list[list[_F64]]] = []
    # the alternative searches of all components share one budget
    notch = None if alternatives is None else FitBudget(alternatives.notch_fits)
    strict = None if alternatives is None else FitBudget(alternatives.strict_fits)
    # data-area units of the ROI, to recognise the cells of square markers (ArUco, AprilTag,
    # QR) that the alternative searches would otherwise cut for their whole budget
    from_unit = None if alternatives is None or quad is None else square_homography(quad)
    to_unit: _F64 | None = None if from_unit is None else np.asarray(np.linalg.inv(from_unit), dtype=np.float64)
    # Every component is checked before any is split: a component too large for a triangle
    # refuses the data area at once. The white paper around an ArUco marker, outlined as a
    # normal data area, held the marker's cells too; splitting them first cost 8–18 ms.
    components: list[int] = []
    for i, c in enumerate(contours):
        if hh[i][3] >= 0 or len(c) < 8:
            continue
        area = abs(float(cv2.contourArea(c)))
        if area + 0.35 * len(c) < min_area:
            continue
        if area > max_area:
            return Rejection("non_triangle")
        if area > 0.1 * side * side:
            # a filled square (e.g. the data area of a nested, inverted tag) is no triangle
            poly = cv2.approxPolyDP(c, 0.03 * len(c), True)
            if len(poly) == 4 and cv2.isContourConvex(poly):
                return Rejection("non_triangle")
        components.append(i)
    # Every decomposition has at least one triangle per component: a data area of more
    # components than a tag has triangles is refused before any is fitted (on the patterns of
    # benchmarks/decode_clutter.py such areas, mostly text, took 7 of the 22 ms per frame).
    if len(components) > MAX_TRIANGLES:
        return Rejection("non_triangle", f"{len(components)} components")
    for i in components:
        pts = contours[i].reshape(-1, 2)
        # A ring of triangles (each sharing vertices with the next) encloses a hole: bridge
        # every hole into the outer contour at their closest points (a shared vertex) so
        # the splitter sees one contour pinched at the shared vertices.
        child = hh[i][2]
        while child >= 0:
            hole = contours[child].reshape(-1, 2)
            if len(hole) >= 8:
                pts = bridge(pts, hole)
            child = hh[child][0]
        opening = functools.partial(triangles_by_opening, fg, contours, hier, i)
        searched = alternatives
        if to_unit is not None and rectilinear(contours[i], to_unit, side):
            searched = None  # cells of a square marker: no cut makes them triangles
        alts = component_decompositions(pts, opening, searched, notch, strict, memo)
        if not alts:
            return Rejection("non_triangle")
        options.append(alts)
    if not options:
        return [Decomposition(())]
    firsts = [o[0] for o in options]
    out = [Decomposition(tuple(ch for f in firsts for ch in f))]
    for ci, alts in enumerate(options):
        for alt in alts[1:]:
            if len(out) >= MAX_DECOMPOSITIONS:
                break
            combo = [*firsts[:ci], alt, *firsts[ci + 1 :]]
            out.append(Decomposition(tuple(ch for f in combo for ch in f)))
    return out


def rectilinear(contour: NDArray[Any], to_unit: _F64, side: float) -> bool:
    """Whether a component's outline runs only along the data area's axes (a square marker's cells).

    Each edge of the outline's polygon approximation (1 px) at least
    :data:`RECTILINEAR_MIN_EDGE_PX` (or :data:`RECTILINEAR_MIN_EDGE_REL` of ``side``) long
    gets a line fitted to the contour points along its middle 70 %; mapped to data-area
    units, every such line must lie within :data:`RECTILINEAR_MAX_DEG` (plus
    ``atan(1 px / length)``) of an axis, and there must be at least three of them. A union
    of triangles meeting at vertices keeps every triangle's sides on its outline, and every
    triangle has a side off both axes, so it is never rectilinear (short edges, as at a
    blurred shared vertex, are not judged).

    Parameters
    ----------
    contour : numpy.ndarray
        ``(n, 1, 2)`` integer outer contour of the component (pixels).
    to_unit : numpy.ndarray
        ``(3, 3)`` homography pixels → data-area units (the inverse of
        :func:`~ottag_db.decode.placement_check.square_homography`; which corner comes first
        does not matter, as a quarter turn or a reflection keeps the axes).
    side : float
        Data-area side (√area, pixels).

    Returns
    -------
    bool
        True for a rectilinear outline (no alternative decomposition is worth searching).
    """
    poly = cv2.approxPolyDP(contour, 1.0, True).reshape(-1, 2).astype(np.float64)
    if len(poly) < 4:
        return False
    edge = np.roll(poly, -1, axis=0) - poly
    length = np.hypot(edge[:, 0], edge[:, 1])
    long_edge = length >= max(RECTILINEAR_MIN_EDGE_PX, RECTILINEAR_MIN_EDGE_REL * side)
    if np.count_nonzero(long_edge) < 3:
        return False
    # each long edge's line fitted to the contour points along its middle (the polygon's
    # corners lie anywhere within its 1 px tolerance: on a 10 px edge, a 10° turn)
    start, length = poly[long_edge], length[long_edge]
    along_u = edge[long_edge] / length[:, None]
    across_u = np.stack([along_u[:, 1], -along_u[:, 0]], axis=1)
    rel = contour.reshape(1, -1, 2) - start[:, None, :]  # (E, n, 2)
    along = rel[..., 0] * along_u[:, 0, None] + rel[..., 1] * along_u[:, 1, None]
    across = rel[..., 0] * across_u[:, 0, None] + rel[..., 1] * across_u[:, 1, None]
    on = (np.abs(across) <= 1.5) & (along >= 0.15 * length[:, None]) & (along <= 0.85 * length[:, None])
    count = np.count_nonzero(on, axis=1)
    if (count < 3).any():
        return False
    mean_a = (along * on).sum(axis=1) / count
    mean_c = (across * on).sum(axis=1) / count
    da = (along - mean_a[:, None]) * on
    slope = (da * (across - mean_c[:, None])).sum(axis=1) / np.maximum((da * da).sum(axis=1), 1e-9)
    c0 = mean_c - slope * mean_a  # the fitted line's offset at the edge's two ends
    c1 = mean_c + slope * (length - mean_a)
    ends = np.concatenate([start + c0[:, None] * across_u, start + edge[long_edge] + c1[:, None] * across_u])
    mapped = ends @ to_unit[:, :2].T + to_unit[:, 2]
    if not (mapped[:, 2] > 0).all() and not (mapped[:, 2] < 0).all():
        return False  # the quad's horizon crosses the component: no rectification
    unit = mapped[:, :2] / mapped[:, 2:3]
    d = unit[len(unit) // 2 :] - unit[: len(unit) // 2]
    angle = np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0])))  # [0, 90]
    tol = RECTILINEAR_MAX_DEG + np.degrees(np.arctan(1.0 / length))  # a pixel across the edge
    return bool((np.minimum(angle, 90.0 - angle) <= tol).all())


def then_alternatives(
    first: list[Decomposition], more: Callable[[], list[Decomposition] | Rejection]
) -> Iterator[Decomposition]:
    """``first``, then the decompositions of ``more()`` not already in ``first`` (computed lazily,
    only when ``first`` is a single decomposition and all of it was read)."""
    yield from first
    if len(first) > 1:
        return  # ``first`` already holds the alternatives
    alts = more()
    if isinstance(alts, Rejection):
        return
    keys = {tuple(np.round(np.concatenate(t.chains)[:, 0]).tolist()) for t in first if t.chains}
    for t in alts:
        if t.chains and tuple(np.round(np.concatenate(t.chains)[:, 0]).tolist()) in keys:
            continue
        yield t


def bridge(outer: NDArray[Any], hole: NDArray[Any]) -> NDArray[Any]:
    """One contour running around ``outer`` and, through their closest points, ``hole``.

    Parameters
    ----------
    outer, hole : numpy.ndarray
        ``(n, 2)`` and ``(m, 2)`` integer contours.

    Returns
    -------
    numpy.ndarray
        ``(n + m + 2, 2)``: ``outer`` up to the bridge point, all of ``hole``, back to ``outer``.
    """

    def closest(a: NDArray[Any], b: NDArray[Any]) -> tuple[int, int]:
        d = ((a[:, None, :].astype(np.int64) - b[None, :, :]) ** 2).sum(axis=2)
        i, j = np.unravel_index(int(np.argmin(d)), d.shape)
        return int(i), int(j)

    step = max(1, int(math.sqrt(len(outer) * len(hole) / 4096)))
    i, j = closest(outer[::step], hole[::step])
    i, j = i * step, j * step
    lo_i, lo_j = max(i - step, 0), max(j - step, 0)
    di, dj = closest(outer[lo_i : i + step + 1], hole[lo_j : j + step + 1])
    i, j = lo_i + di, lo_j + dj
    return np.concatenate([outer[: i + 1], hole[j:], hole[: j + 1], outer[i:]])


def triangles_by_opening(fg: NDArray[Any], contours: Any, hier: NDArray[Any], index: int) -> list[_F64] | None:
    """Paper's fallback: open one component with a 3×3 kernel and fit its parts.

    Parameters
    ----------
    fg : numpy.ndarray
        The bright mask the contours were traced in.
    contours, hier : sequence, numpy.ndarray
        OpenCV contours and hierarchy of ``fg`` (``RETR_CCOMP``).
    index : int
        The component's outer contour.

    Returns
    -------
    list of numpy.ndarray or None
        Side chains (three per triangle, ``fg`` pixels), or None when a part is no triangle.
    """
    x, y, w, h = cv2.boundingRect(contours[index])
    x0, y0 = max(x - 2, 0), max(y - 2, 0)
    x1, y1 = min(x + w + 2, fg.shape[1]), min(y + h + 2, fg.shape[0])
    comp = np.zeros((y1 - y0, x1 - x0), dtype=np.uint8)
    cv2.drawContours(comp, contours, index, 255, cv2.FILLED, cv2.LINE_8, hier, 1, (-x0, -y0))
    comp &= fg[y0:y1, x0:x1]
    opened = cv2.morphologyEx(comp, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    parts, ph = cv2.findContours(opened, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if ph is None:
        return None
    out: list[_F64] = []
    offset = np.array([x0, y0], dtype=np.float64)
    for k, c in enumerate(parts):
        if ph[0][k][3] >= 0:
            if len(c) >= 8:
                return None
            continue
        if len(c) < 8:
            continue
        tri = triangle_fit(c.reshape(-1, 2))
        if tri is None:
            return None
        out.extend(ch + offset for ch in tri)
    return out or None
