"""Read one data area: segmentation → triangles → refine → cluster → identify.

The direct reading (:func:`ottag_db.decode.detector.read_quad`, also on the 2× upsampled data
area) and the rectified retry (:mod:`ottag_db.decode.rectify`) run the same stages on an
image; they differ only in where the points are identified. A :class:`FrameMap` takes the
points, side lines and corners measured in the image to the frame's pixels (the rectified
view's inverse homography); without one they are identified where they were measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.cluster import cluster_hypotheses
from ottag_db.decode.identify import Catalogue, identify
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.profile import StageClock
from ottag_db.decode.quads import squeeze
from ottag_db.decode.refine import refine
from ottag_db.decode.segmentation import MAX_TRIANGLES, NO_DECOMPOSITION, decompose, segment, then_alternatives
from ottag_db.decode.splitting import FitMemo, SearchBudget
from ottag_db.decode.tips import apices, with_apices
from ottag_db.decode.triangles import bad_triangles
from ottag_db.decode.types import Decomposition, Detection, PointHypothesis, Quad, Rejection

__all__ = ["FrameMap", "points_fit", "read_area", "scaled_params"]

_F64 = NDArray[np.float64]


class FrameMap(Protocol):
    """Maps an image (e.g. a rectified view) to the frame the points are identified in."""

    def points_to_frame(self, pts: _F64) -> _F64:
        """``(m, 2)`` image points in frame pixels."""
        ...

    def lines_to_frame(self, normal: _F64, offset: _F64) -> tuple[_F64, _F64]:
        """Lines ``n·x = c`` of the image as unit-normal lines of the frame."""
        ...


def read_area(
    image: NDArray[np.uint8],
    quad: Quad,
    params: DetectorParams,
    catalogue: Catalogue,
    alternatives: SearchBudget | None,
    clock: StageClock,
    to_frame: FrameMap | None = None,
    frame_quad: Quad | None = None,
    print_required: frozenset[str] = frozenset(),
) -> tuple[Detection | Rejection, _F64 | None]:
    """Read the data area of ``quad`` in ``image``; identify each point hypothesis in the frame.

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W)`` uint8 grey image holding the data area.
    quad : Quad
        The candidate in ``image`` pixels.
    params : DetectorParams
        Settings of the segmentation, triangle and clustering stages (lengths in ``image``
        pixels).
    catalogue : Catalogue
        Lookup and settings of identification and verification (lengths in frame pixels).
    alternatives : SearchBudget or None
        Also try the alternative decompositions (opening, slit cuts, strict fits) within this
        budget when the first does not read (None: not).
    clock : StageClock
        Charged per stage.
    to_frame : FrameMap, optional
        From ``image`` to the frame; None when ``image`` is the frame's scale and place
        (points are identified as measured).
    frame_quad : Quad, optional
        The candidate in frame pixels, as identification reports it (``quad`` when None).
    print_required : frozenset of str, optional
        IDs an earlier reading of this data area was refused as because they were not shown
        as printed (:attr:`Rejection.not_printed`): read here, they must show the tag as
        printed, layout and placement, at any view.

    Returns
    -------
    result : Detection or Rejection
        The first hypothesis that reads with its points within the reprojection bound (else
        the reading whose points fit best), else the most telling rejection (the first one
        after the triangle checks, if any hypothesis got that far).
    corners : numpy.ndarray or None
        ``(4, 2)`` data-area corners (refined on the grey levels when they could be) in frame
        pixels, None when no decomposition was found.
    """
    area = segment(image, quad, params)
    clock.lap("segmentation")
    if isinstance(area, Rejection):
        return replace(area, not_printed=print_required), None
    side = area.side
    memo = FitMemo()  # the alternatives below fit the first decomposition's contours again
    # The corners rectify outline edges well enough to tell a square marker's cells (that need
    # no alternative search) from triangles only in a view that is not strongly foreshortened.
    axes = area.quad if to_frame is None and squeeze(quad) > params.rectify_max_ratio else None
    decomps = decompose(area.fg, side, params, None, memo)
    if isinstance(decomps, Rejection) and alternatives is not None:
        # no plain decomposition: try the alternatives (opening, slit cuts) right away
        decomps = decompose(area.fg, side, params, alternatives, memo, axes)
    clock.lap("triangles")
    if isinstance(decomps, Rejection):
        detail = decomps.detail or (NO_DECOMPOSITION if decomps.reason == "non_triangle" else "")
        return Rejection(decomps.reason, detail, decomposed=False, not_printed=print_required), None
    if not decomps or decomps[0].count == 0:
        return Rejection("no_triangles", not_printed=print_required), None
    if decomps[0].count > MAX_TRIANGLES:
        return Rejection("non_triangle", f"{decomps[0].count} triangles", not_printed=print_required), None

    def more() -> list[Decomposition] | Rejection:
        alts = decompose(area.fg, side, params, alternatives, memo, axes) if alternatives is not None else []
        clock.lap("triangles")
        return alts

    roi_f = area.roi.astype(np.float32)
    tol = max(params.merge_radius_px, params.merge_radius_rel * side)
    sure = max(2 * params.merge_radius_px, 2 * params.merge_radius_rel * side)
    first: Rejection | None = None
    # IDs refused as not printed (layout or placement): another decomposition or clustering of
    # the same data area must show them as printed too (an 8-point tag 59 px wide at 43° whose
    # two triangles merged read as a 7-point type, refused 21 px off its placement, and then
    # as the same type by the next decomposition, 1.4 px off the fit, within the bound)
    not_printed = print_required
    occluded = area.intrusions > 0  # something crossed the border: the tag must show its print
    corners_l: _F64 | None = None
    corners = quad.corners  # replaced by the refined corners before any identification
    for dec in then_alternatives(decomps, more):
        # sub-pixel triangle sides on the grey image (with the data-area sides, first time)
        tris, refined = refine(roi_f, dec, area.level, area.quad if corners_l is None else None)
        if corners_l is None:
            corners_l = area.quad
            if (
                refined is not None
                and np.isfinite(refined).all()
                and np.abs(refined - area.quad).max() <= 0.1 * side + 3
            ):
                corners_l = refined
            corners = corners_l + area.origin
            if to_frame is not None:
                corners = to_frame.points_to_frame(corners)
        clock.lap("refine")
        bad = bad_triangles(tris.vertices, corners_l, side)
        if bad is not None:
            if first is None:
                first = bad
            continue
        normal, offset = tris.normal, tris.offset + tris.normal @ area.origin  # side lines in image pixels
        if to_frame is not None:
            normal, offset = to_frame.lines_to_frame(normal, offset)
        hypotheses = cluster_hypotheses(tris, 0.15 * side, sure, tol)
        clock.lap("cluster")
        geometry = _Geometry(area.origin, to_frame, normal, offset, corners, frame_quad or quad, occluded)
        tried = _read_hypotheses(hypotheses, geometry, catalogue, clock, first, not_printed)
        if tried[0] is None:
            # sharp tips at their apex, measured on the grey image only when no hypothesis's
            # points fit from their side lines, and the hypotheses read again as if measured
            # first: the apex costs about 0.4 ms a tip (two or three per tag), and the lines'
            # intersection misses it only on slivers a few px wide, whose points then miss the bound
            measured = apices(roi_f, tris, area.level)
            clock.lap("cluster")
            moved = [with_apices(hyp, measured) for hyp in hypotheses]
            if any(m is not h for m, h in zip(moved, hypotheses, strict=True)):
                tried = _read_hypotheses(moved, geometry, catalogue, clock, first, not_printed)
        fitting, loose, first, not_printed = tried
        if fitting is not None:
            return fitting, corners
        if loose is not None:
            return loose, corners
    refusal = first if first is not None else Rejection("non_triangle", "degenerate vertex")
    return replace(refusal, not_printed=not_printed), corners


@dataclass(frozen=True)
class _Geometry:
    """Where a data area's hypotheses are read: ROI origin, map to the frame (or None), the side
    lines in frame pixels, the data-area corners, the quad judged and the occluded flag."""

    origin: NDArray[np.float64]
    to_frame: FrameMap | None
    normal: NDArray[np.float64]
    offset: NDArray[np.float64]
    corners: NDArray[np.float64]
    quad: Quad
    occluded: bool


def _read_hypotheses(
    hypotheses: list[PointHypothesis],
    at: _Geometry,
    catalogue: Catalogue,
    clock: StageClock,
    first: Rejection | None,
    not_printed: frozenset[str],
) -> tuple[Detection | None, Detection | None, Rejection | None, frozenset[str]]:
    """Identify each hypothesis in turn: the first detection whose points fit (else None), the
    detection whose points fit best, the most telling rejection and the IDs refused as not
    printed, the last two carried on from ``first`` and ``not_printed``."""
    loose: Detection | None = None
    for hyp in hypotheses:
        pts = hyp.points + at.origin
        if at.to_frame is not None:
            pts = at.to_frame.points_to_frame(pts)
        lines = [(at.normal[ids], at.offset[ids]) for ids in hyp.line_ids]
        result = identify(pts, lines, at.corners, at.quad, catalogue, clock, not_printed, at.occluded)
        clock.lap("identify")
        if isinstance(result, Detection):
            if points_fit(result, at.quad, catalogue.params):
                return result, loose, first, not_printed
            if loose is None or _point_error(result) < _point_error(loose):
                loose = result
            continue
        not_printed = not_printed | result.not_printed
        if first is None or first.reason == "non_triangle":
            first = result
    return None, loose, first, not_printed


def _point_error(det: Detection) -> float:
    return math.inf if det.reprojection_error_px is None else det.reprojection_error_px


def points_fit(det: Detection, quad: Quad, params: DetectorParams) -> bool:
    """Whether the reading's points, not only its side lines, lie within the reprojection bound.

    Verification fits the side lines (a sharp tip's point slides along its bisector), so a
    merge of two tips of different triangles can verify although the tips are far apart in the
    image: a nine-point tag then reads as an eight-point type (one in 2,000 printed nine-point
    tags, ``benchmarks/roundtrip_k9.py``). When the points miss the bound, the other
    hypotheses are tried too and the reading whose points fit best is kept.

    Parameters
    ----------
    det : Detection
        A reading (points and ``reprojection_error_px`` in the pixels of ``quad``).
    quad : Quad
        Its candidate: the bound is ``max(max_reproj_px, max_reproj_rel × √area)``.
    params : DetectorParams
        ``max_reproj_px`` and ``max_reproj_rel``.

    Returns
    -------
    bool
        False also when the reading has no reprojection error.
    """
    bound = max(params.max_reproj_px, params.max_reproj_rel * math.sqrt(quad.area))
    return _point_error(det) <= bound


def scaled_params(p: DetectorParams, f: float, *, identification: bool = True) -> DetectorParams:
    """``p`` for an image scaled by ``f`` (image px per frame px): lengths times ``f``, areas times ``f²``.

    Parameters
    ----------
    p : DetectorParams
        Settings in frame pixels.
    f : float
        Scale of the image the stages run on.
    identification : bool, optional
        Also scale the margin, the reprojection bound and ``print_check_side_px`` (False when
        the points are mapped back and identified in frame pixels, as in the rectified view).

    Returns
    -------
    DetectorParams
        The scaled settings.
    """
    scaled = replace(
        p,
        min_quad_area_px=p.min_quad_area_px * f * f,
        min_quad_side_px=p.min_quad_side_px * f,
        min_triangle_area_px=p.min_triangle_area_px * f * f,
        merge_radius_px=p.merge_radius_px * f,
    )
    if not identification:
        return scaled
    return replace(
        scaled,
        min_margin_px=p.min_margin_px * f,
        max_reproj_px=p.max_reproj_px * f,
        print_check_side_px=p.print_check_side_px * f,  # judged on the scaled quad
    )
