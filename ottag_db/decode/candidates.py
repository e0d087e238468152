"""Candidate stage: convex quadrilateral contours of a binarized frame (possible data areas)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.types import QUIET_ZONE, Polarity
from ottag_db.decode.binarize import (
    HALF_RES_MIN_SIDE,
    LOCAL_PASSES,
    Binarization,
    binarize,
    searches_at_half_resolution,
)
from ottag_db.decode.outlines import (
    SPIKE_MAX_HOLES,
    at_frame_edge,
    cut_by_frame_only,
    data_area_inside,
    lines_outline,
    without_spikes,
)
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.placement_check import UNIT_SQUARE
from ottag_db.decode.quads import clockwise, same_quad, squeeze
from ottag_db.decode.segmentation import MAX_TRIANGLES
from ottag_db.decode.types import Quad

__all__ = [
    "JOINED_MAX_HOLES",
    "JOINED_QUIET_TOLERANCE",
    "NOTCHED_MIN_FILL",
    "SMALL_QUAD_SIDE",
    "TRIANGLE_HOLDER_MIN_HOLES",
    "Binarization",
    "find_quads",
    "searches_at_half_resolution",
]

_F64 = NDArray[np.float64]

#: The full-resolution pass for thin quads (``"adaptive_thin"``, run on a frame that read nothing)
#: also keeps dark quads whose shortest side is under this (px), thin or not: at half resolution
#: a normal data area of 18 px (a 21 cm tag at 8 m) is 9 px wide, and blur and noise there
#: break its outline (benchmarks/decode_sweeps.py --paired, normal tags at 8 m: 6 of 200 had no
#: candidate, all read now; the same scenes at 7–8 m with the tags removed from the lookup read
#: no look-alike). Not bright quads: the white cells of markers are such (127 on the 100 ArUco
#: frames of benchmarks/decode_speed.py, 25 % more time there), and a small inverted tag's
#: dark quiet zone, twice the size, is found at half resolution.
SMALL_QUAD_SIDE = 4 * HALF_RES_MIN_SIDE
#: A thin quad (a data area seen at 84–86°, short sides 7–10 px at 1.5 m) is kept with short
#: sides down to this fraction of ``min_quad_side_px`` when its two long sides are at least
#: ``THIN_QUAD_LONG_SIDE`` times it: reading by model (:mod:`~ottag_db.decode.model_match`)
#: can still choose the tag, and the long sides keep specks and text strokes out.
THIN_QUAD_MIN_SIDE = 0.5
THIN_QUAD_LONG_SIDE = 3.0
#: The hull of a region's holes is a data area (:func:`_joined_holes`) only when the region's
#: outline lies within this (data-area units) of where the printed quiet zone ends. On
#: grazing frames (78–86°, 40 seeds, both polarities, frame grey 55 and 200) 44 of the 49
#: hulls that were a data area came within 0.3 (most within 0.15), 34 of the 339 other hulls,
#: mostly of a tag's own triangles (none within 0.15). At 0.15 the normal tags read on a dark frame at
#: 84–87° (benchmarks/decode_polarity.py --background 55) were 51, 44, 25, 15 of 60; at 0.3
#: 55, 52, 34, 28; without the test 57, 52, 41, 31, no tag read wrong in any.
JOINED_QUIET_TOLERANCE = 0.3
#: A region with more holes than this is no tag's quiet zone: on noise the background's
#: thousands of holes cost tens of ms per frame to join. A data area's pieces are few, but
#: nearly edge-on blur, noise and JPEG leave specks in it: with at most 32 holes, the normal
#: tags read on a dark frame at 86° fell from 34 to 26 of 60.
JOINED_MAX_HOLES = 256
#: Outlines by lines per pass (:func:`~ottag_db.decode.outlines.lines_outline`, and
#: :func:`~ottag_db.decode.outlines.without_spikes` after it), a bound on the work per frame:
#: at most this many regions that are no quad, or whose quad meets the frame's edge, the
#: largest by area, are outlined so. Foliage, gravel and text hold 20–150 such regions per pass
#: (scikit-image's photographs at 640×480), each costing 0.05–0.3 ms; a tag whose border is
#: partly hidden is one region, as large as its data area. Occluded tags drawn on those
#: photographs (bar and covered corner, both polarities, 110–170 px) read alike with and
#: without the bound.
LINES_MAX_OUTLINES = 8
#: In the thin-quad pass, a dark region whose own outline is no quad is outlined by its convex
#: hull when it fills at least this fraction of it (:func:`_notched_outline`). The hulls of a
#: normal data area at 84–86° were filled 0.65–0.75 on the usual frame; those of the test
#: patterns' markers, checkerboards and text (5 of the 6 hulls in 25 frames) and of noise 0.37–0.59:
#: without the limit, reading them by model cost 2.4 ms per pattern frame
#: (benchmarks/decode_clutter.py, model stage 0.7 → 3.1 ms); with it, nothing.
NOTCHED_MIN_FILL = 0.6
#: The local range pass (``"local_range"``, run on a frame that read nothing) keeps at most
#: this many quads, the largest: a bound on the work per frame, as each is judged for blur
#: (:func:`~ottag_db.decode.blur.edge_blur`, about 0.4 ms). Of scikit-image's 20 photographs
#: at 640×480, 19 gave it 0–8 quads, brick 54.
RANGE_MAX_QUADS = 8
#: A dark quad region holding at least this many bright holes is a normal data area holding its
#: triangles (:func:`_holds_triangles`), whose holes are not outlined by lines as inverted data
#: areas. An inverted data area is one hole of its quiet zone; a bar across it or a triangle
#: merged with the quiet zone nearly edge-on cuts it in two, whose larger piece the lines can
#: still outline. On frames with one tag the lines outlines of its triangles took 7 % of the
#: instructions (``benchmarks/decode_speed.py``'s frames under ``valgrind --tool=callgrind``),
#: for quads read only when the tag did not read; the same tags read.
TRIANGLE_HOLDER_MIN_HOLES = 3
#: The printed quiet zone's outline in data-area units (corners in the unit square's order).
_QUIET_OUTLINE = (UNIT_SQUARE - 0.5) * (1 + 2 * QUIET_ZONE) + 0.5
#: The passes that outline regions by lines: the local ones, which search the whole frame, and Otsu's.
_LINES_PASSES = (*LOCAL_PASSES, "otsu")


def find_quads(
    gray: NDArray[np.uint8], kind: Binarization, params: DetectorParams, departure: float | None = None
) -> list[Quad]:
    """Convex quadrilateral contours of one binarization of ``gray``, largest first.

    Outer contours of dark regions are candidate *normal* data areas, hole contours (bright
    regions inside dark) candidate *inverted* ones; with ``"bright_holes"``, hole contours of
    the bright regions (dark regions inside a bright quiet zone) are candidate *normal* ones.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    kind : {"adaptive", "adaptive_dim", "otsu", "adaptive_thin", "bright_holes", "local_range"}
        Local mean thresholding (at half resolution when :func:`searches_at_half_resolution`);
        ``"adaptive_dim"`` the same with the offset lowered for a dim frame
        (:func:`~ottag_db.decode.image.threshold_offset`) on the search smoothed first
        (:data:`~ottag_db.decode.image.DIM_SMOOTHING_PX`); global Otsu; or local mean
        thresholding at full resolution keeping only the thin quads (area over longest side
        under ``2 · HALF_RES_MIN_SIDE``) a half-resolution search cannot see;
        ``"bright_holes"``: the pixels brighter than their local mean at full resolution,
        keeping the foreshortened quads (:func:`~ottag_db.decode.quads.squeeze` at most
        ``rectify_max_ratio``) of their holes. Nearly edge-on, a normal data area's dark outline
        breaks where its bright triangles blur into the quiet zone, while the inverted one's
        is a hole in the dark quiet zone whatever its triangles do; this pass finds the normal
        one as that hole too. Both last-resort passes also outline, as one quad, the hull of
        all holes of a region (:func:`_joined_holes`): a data area its triangles cut into
        pieces (normal from ``"bright_holes"``, inverted from ``"adaptive_thin"``). The thin
        pass also outlines a dark region notched by its triangles by its hull
        (:func:`_notched_outline`). ``"local_range"``: a pixel is dark below the midpoint of
        the darkest and brightest pixel around it (the local mean window; AprilTag's
        threshold), where they differ by ``min_contrast`` or more (at half resolution when
        :func:`searches_at_half_resolution`). A long motion smears a tag's
        triangles into its border, brighter than the local mean there, which notches the
        data area's outline; the midpoint of a blurred step is the print's edge, and the
        smeared triangles stay below it near the bright quiet zone. A notched region is
        outlined by its hull here too; at most :data:`RANGE_MAX_QUADS` quads are kept.
    params : DetectorParams
        Uses the binarization, polarity, size and ``max_candidates`` settings.
    departure : float, optional
        The frame's largest departure (:func:`~ottag_db.decode.image.frame_departure`; measured
        here for the passes that need it when not given): the Otsu pass runs only when it
        reaches ``min_contrast`` (see :func:`~ottag_db.decode.image.frame_has_contrast`), and it
        sets the ``"adaptive_dim"`` pass's offset.

    Returns
    -------
    list of Quad
        At most ``params.max_candidates`` quads (image pixels), largest area first, no two
        the same (see :func:`~ottag_db.decode.quads.same_quad`).
    """
    p = params
    h, w = gray.shape
    # (half-resolution quads are mapped back: half-res pixel u covers image pixels 2u, 2u + 1,
    # centre 2u + 0.5; their sides are refined on the full image)
    b = binarize(gray, kind, p, departure)  # the pass's mask and contours (OpenCV's work)
    if b is None:
        return []
    mask, contours, hier, f, min_len = b.mask, b.contours, b.hierarchy, b.scale, b.min_len
    want_normal = "normal" in p.polarities
    want_inverted = "inverted" in p.polarities
    min_area = max(p.min_quad_area_px, p.min_quad_side_px**2)
    max_area = 0.95 * h * w
    quads: list[Quad] = []
    if hier is None:
        return quads
    parents = hier[:, 3]
    # (contour, inverted, its length in px, its first hole or -1: a dark region with bright
    # holes holds triangles, maybe; the dark region a bright hole lies in, or -1)
    outlines: list[tuple[NDArray[Any], bool, float, int, int]] = []
    # (a frame of foliage or text traces thousands of contours: their lengths at once)
    lengths = np.fromiter(map(len, contours), dtype=np.int64, count=len(contours))
    for i in np.flatnonzero(lengths >= min_len).tolist():
        c = contours[i]
        inverted = bool(parents[i] >= 0)
        if kind == "bright_holes":
            if not inverted:
                continue  # a bright region: the dark mask's passes outline it
            inverted = False  # a dark hole in a bright quiet zone: a normal data area
        if (inverted and not want_inverted) or (not inverted and not want_normal):
            continue
        outlines.append((c, inverted, int(lengths[i]), int(hier[i][2]), int(parents[i]) if inverted else -1))
    outlines.extend((c, True, len(c), -1, -1) for c in b.edge_holes)
    # the last-resort passes also outline a data area cut into pieces (see _joined_holes): the
    # holes of the dark mask are bright areas (inverted), those of the bright mask dark (normal)
    joined_inverted = kind == "adaptive_thin"
    if kind in ("adaptive_thin", "bright_holes") and (want_inverted if joined_inverted else want_normal):
        hulls = _joined_holes(contours, hier, min_len)
        outlines.extend((hull, joined_inverted, cv2.arcLength(hull, True), -1, -1) for hull in hulls)
    # (outline, inverted, length, first hole, its quad, outlined by lines, an opened ring)
    shaped: list[tuple[NDArray[Any], bool, float, int, NDArray[Any] | None, bool, bool]] = []
    holders: dict[int, bool] = {}  # per dark region asked: whether its holes are a data area's triangles
    for c, inverted, perimeter, first_hole, region in outlines:
        holds_holes = first_hole >= 0
        approx = _quad_outline(c, perimeter)
        if approx is None and kind in ("adaptive_thin", "local_range") and not inverted:
            approx = _notched_outline(c)
        cut = approx is not None and at_frame_edge(approx, mask.shape)  # a corner beyond it?
        lines = p.outline_by_lines and (approx is None or cut) and kind in _LINES_PASSES
        lines = lines and perimeter >= 2 * min_len
        # triangles first: only a dark region holding bright holes is a normal data area (an
        # inverted one, a hole itself, holds separate regions: its solidity decides below)
        opened = lines and not inverted and not holds_holes and want_inverted
        lines = lines and (inverted or holds_holes)
        if lines and region >= 0:  # a bright hole: one of a data area's triangles?
            if region not in holders:
                holders[region] = _holds_triangles(contours, hier, region, min_len)
            lines = not holders[region]
        if approx is not None or lines or opened:
            shaped.append((c, inverted, perimeter, first_hole, approx, lines, opened))
    # outlines by lines within the pass's budget (LINES_MAX_OUTLINES): the largest regions
    by_lines = [i for i, s in enumerate(shaped) if s[5] or s[6]]
    if len(by_lines) > LINES_MAX_OUTLINES:
        kept = set(sorted(by_lines, key=lambda i: -abs(cv2.contourArea(shaped[i][0])))[:LINES_MAX_OUTLINES])
        # the others keep a quad of their own (a cut one) without lines, or are dropped
        shaped = [
            s if i in kept else (*s[:5], False, False) for i, s in enumerate(shaped) if i in kept or s[4] is not None
        ]
    for c, inverted, perimeter, first_hole, approx, lines, opened in shaped:
        if lines:
            traced = approx
            approx = lines_outline(c, perimeter, mask.shape)
            if approx is None and not inverted:  # a bar or an occluder's edges as spikes?
                approx = without_spikes(c, _holes(contours, hier, first_hole), mask.shape)
            if approx is None and traced is not None:
                # no runs outline it: a corner at the frame's edge cut by less than the outline's
                # tolerance, which the polygon rounds off (judged below as a traced quad)
                approx, lines = traced, False
        elif opened:  # an inverted tag's quiet zone, opened: its data area inside
            outer = lines_outline(c, perimeter, mask.shape, ring=True)
            approx = None if outer is None else data_area_inside(outer)
            inverted = lines = approx is not None
        if approx is None:
            continue
        outline = approx  # (at the mask's scale)
        q = approx.reshape(4, 2).astype(np.float64)
        if f != 1:
            q = q * f + 0.5 * (f - 1)
            approx = q.astype(np.float32).reshape(4, 1, 2)
        area = abs(float(cv2.contourArea(approx)))
        if area < min_area or area > max_area:
            continue
        # plain Python on the 4 corners (numpy reductions cost more than they save here)
        (ax, ay), (bx, by), (cx, cy), (dx, dy) = q.tolist()
        at_edge = sum(x < 2 or y < 2 or x > w - 3 or y > h - 3 for x, y in ((ax, ay), (bx, by), (cx, cy), (dx, dy)))
        if at_edge and not lines and at_frame_edge(c, mask.shape, 0):  # (a quad of runs may reach beyond the frame)
            if at_edge > 1 or not (inverted or first_hole >= 0):
                continue  # a region the frame's edge cuts, no data area holding its triangles
            # one corner on the frame's edge, maybe beyond it by a few px: a data area seen whole
            # but for that corner, read as one whose border is partly hidden (the print decides)
            lines = True
        sides = sorted((
            math.hypot(bx - ax, by - ay), math.hypot(cx - bx, cy - by),
            math.hypot(dx - cx, dy - cy), math.hypot(ax - dx, ay - dy),
        ))  # fmt: skip
        thick = area >= 2 * HALF_RES_MIN_SIDE * sides[3]  # area over the longest side
        if kind == "adaptive_thin" and thick and (inverted or sides[0] >= SMALL_QUAD_SIDE):
            continue  # neither thin nor a small dark quad: the half-resolution pass sees it
        if sides[0] < p.min_quad_side_px and (
            sides[0] < THIN_QUAD_MIN_SIDE * p.min_quad_side_px or sides[2] < THIN_QUAD_LONG_SIDE * p.min_quad_side_px
        ):
            continue
        polarity: Polarity = "inverted" if inverted else "normal"
        # the points may decide where only the frame's edge cuts the quad (one that reaches it)
        frame_cut = lines and at_frame_edge(outline, mask.shape) and cut_by_frame_only(c, outline, mask.shape)
        cand = Quad(polarity, clockwise(q), area, inferred=lines, frame_cut=frame_cut)
        if kind == "bright_holes" and squeeze(cand) > p.rectify_max_ratio:
            continue
        if not any(same_quad(cand, o) for o in quads):
            quads.append(cand)
    quads.sort(key=lambda qq: -qq.area)
    return quads[: RANGE_MAX_QUADS if kind == "local_range" else p.max_candidates]


def _holds_triangles(
    contours: Sequence[NDArray[Any]], hierarchy: NDArray[np.int32], region: int, min_len: float
) -> bool:
    """Whether a dark region (``RETR_CCOMP`` index) outlines a normal data area holding its
    triangles: a convex quad outline of at least ``min_len`` points around at least
    :data:`TRIANGLE_HOLDER_MIN_HOLES` and at most
    :data:`~ottag_db.decode.segmentation.MAX_TRIANGLES` bright holes (specks of under 4 contour
    points left out).

    Its holes are a tag's triangles, not an inverted data area whose border is partly hidden:
    :func:`find_quads` does not outline them by lines (an inverted data area is one hole of its
    quiet zone, or two where a bar or a merged triangle cuts it).
    """
    if len(contours[region]) < min_len:
        return False
    count = 0
    child = int(hierarchy[region][2])
    while child >= 0:
        if len(contours[child]) >= 4:
            count += 1
            if count > MAX_TRIANGLES:
                return False
        child = int(hierarchy[child][0])
    return count >= TRIANGLE_HOLDER_MIN_HOLES and _quad_outline(contours[region], len(contours[region])) is not None


def _holes(contours: Sequence[NDArray[Any]], hierarchy: NDArray[np.int32], first: int) -> list[NDArray[Any]]:
    """The holes of a region (``RETR_CCOMP``), from its ``first`` hole on; only the first
    ``SPIKE_MAX_HOLES + 1`` (a region with more holds no data area with spikes)."""
    out: list[NDArray[Any]] = []
    while first >= 0 and len(out) <= SPIKE_MAX_HOLES:
        out.append(contours[first])
        first = int(hierarchy[first][0])
    return out


def _quad_outline(contour: NDArray[Any], perimeter: float) -> NDArray[Any] | None:
    """The convex quad that approximates ``contour`` (``perimeter`` px long), or None."""
    approx = cv2.approxPolyDP(contour, 0.03 * perimeter, True)
    if len(approx) < 4:
        # a steep view makes a thin quad whose short sides fall within 3 % of the perimeter of
        # the long ones. (A finer tolerance only adds vertices to more than four: of 32,530
        # contours of photographs, tags and grazing views, none with more went to four.)
        approx = cv2.approxPolyDP(contour, 0.012 * perimeter, True)
    if len(approx) != 4 or not cv2.isContourConvex(approx):
        return None
    return approx


def _notched_outline(contour: NDArray[Any]) -> NDArray[Any] | None:
    """The convex quad of a dark region's hull, when the region fills at least
    :data:`NOTCHED_MIN_FILL` of it; else None.

    Nearly edge-on, a normal tag's white triangles blur into its white quiet zone where they
    come near the data area's border and notch its dark outline, which then is no quad; the
    hull closes the notches. (An inverted tag's black triangles merge with its black quiet zone
    instead, and its white data area stays a hole of it.) On 200 paired scenes at 85° of
    benchmarks/decode_sweeps.py's tilt sweep (two draws), the normal tags read went from 169 to
    172 and from 168 to 173 (the inverted ones: 176, 177); on 1,000 grazing frames at 78–86°
    (tests/support/grazing.py, both polarities) the tags read from 984 to 989 on the usual frame
    and from 971 to 975 on a dark one, and a lookup without the 24 tags seen read no more
    look-alikes (0 and 1, as before).

    Parameters
    ----------
    contour : numpy.ndarray
        ``(n, 1, 2)`` int32 outer contour of a region of the dark mask.

    Returns
    -------
    numpy.ndarray or None
        ``(4, 1, 2)`` corners of the hull's quad (see :func:`_quad_outline`).
    """
    hull = cv2.convexHull(contour)
    if abs(cv2.contourArea(contour)) < NOTCHED_MIN_FILL * abs(cv2.contourArea(hull)):
        return None
    return _quad_outline(hull, cv2.arcLength(hull, True))


def _joined_holes(contours: Sequence[NDArray[Any]], hierarchy: NDArray[np.int32], min_len: float) -> list[NDArray[Any]]:
    """The convex hull of all holes of a region that outlines a tag's quiet zone around them.

    Nearly edge-on, a normal tag's bright triangles blur into its quiet zone and cut the dark
    data area, the quiet zone's hole, into pieces; no piece outlines the data area, while the
    hull of all of them does (on a dark frame, where the data area's own dark outline merges
    with the frame, the normal tags read at 84–87° went from 41, 30, 14, 9 to 55, 52, 34, 28
    of 60, benchmarks/decode_polarity.py --background 55). The hull of a data area's own
    triangles (the holes of an inverted tag's white data area) is no data area: the region's
    outline must be a quad where the printed quiet zone ends, within
    :data:`JOINED_QUIET_TOLERANCE` in the hull's data-area units. Holes of under 4 contour
    points (specks) are left out, and regions of more than :data:`JOINED_MAX_HOLES` holes (the
    frame's background on noise) are no quiet zone.

    Parameters
    ----------
    contours : sequence of numpy.ndarray
        ``findContours`` output (``RETR_CCOMP``), ``(n, 1, 2)`` int32 each.
    hierarchy : numpy.ndarray
        ``(N, 4)`` its hierarchy (next, previous, first child, parent).
    min_len : float
        Regions whose outline has fewer contour points are left out (the quiet zone's outline
        is longer than the smallest data area's; on noise most regions are specks).

    Returns
    -------
    list of numpy.ndarray
        ``(m, 1, 2)`` int32 hulls, one per such region with at least two holes.
    """
    parents = hierarchy[:, 3]
    holes_per_region = np.bincount(parents[parents >= 0], minlength=len(contours))
    hulls: list[NDArray[Any]] = []
    joinable = (holes_per_region >= 2) & (holes_per_region <= JOINED_MAX_HOLES)
    for region in np.flatnonzero(joinable).tolist():
        if len(contours[region]) < min_len:
            continue
        outer = _quad_outline(contours[region], len(contours[region]))
        if outer is None:
            continue
        group: list[NDArray[Any]] = []
        child = int(hierarchy[region][2])
        while child >= 0:
            if len(contours[child]) >= 4:
                group.append(contours[child])
            child = int(hierarchy[child][0])
        if len(group) < 2:
            continue
        hull = cv2.convexHull(np.concatenate(group))
        inner = _quad_outline(hull, cv2.arcLength(hull, True))
        if inner is not None and _quiet_zone_miss(inner, outer) <= JOINED_QUIET_TOLERANCE:
            hulls.append(hull)
    return hulls


def _quiet_zone_miss(inner: NDArray[Any], outer: NDArray[Any]) -> float:
    """How far (data-area units of ``inner``, largest coordinate error of a corner) the quad
    ``outer`` is from the printed quiet zone's outline around the quad ``inner``."""
    to_unit = cv2.getPerspectiveTransform(
        clockwise(inner.reshape(4, 2).astype(np.float64)).astype(np.float32), UNIT_SQUARE.astype(np.float32)
    )
    seen = cv2.perspectiveTransform(clockwise(outer.reshape(4, 2).astype(np.float64)).reshape(1, 4, 2), to_unit)[0]
    s: list[list[float]] = seen.tolist()  # the four turns on 8 numbers: plain Python
    q: list[list[float]] = _QUIET_OUTLINE.tolist()
    return min(max(abs(a - b) for i in range(4) for a, b in zip(s[i - r], q[i], strict=True)) for r in range(4))
