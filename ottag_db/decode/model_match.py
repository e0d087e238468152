"""Model-based reading: the stored tags projected through the quad and scored against the image.

At grazing views (beyond about 80°) a tag's triangles are slivers a pixel or two across: even
the rectified view (:mod:`~ottag_db.decode.rectify`) cannot always segment them, and the
points are too close to call. The quad still gives the homography from the data area to the
image, and every tag the lookup holds is known in print (its stored realization, layout and
placement), so the image can *choose among the stored tags* instead (issue 13, scope 1):

1. **Coarse match.** Each printed tag is rasterized once into a ``32 × 32`` template of its
   data area (:class:`~ottag_db.decode.templates.TemplateBank`, built with the detector). The
   candidate's data area is warped to the same grid in its four rotations (and, for a dark
   quad, as the quiet zone of an inverted tag whose white data area was not found as a quad of
   its own); one matrix product scores every template against every view by normalized
   correlation.
2. **Refinement.** The best few tags (distinct IDs) are each aligned to the frame by OpenCV's
   ECC (:func:`cv2.findTransformECC`, a homography from a finer template of the data area and
   a band of its quiet zone), which also corrects the whole-pixel contour corners.
3. **Decision.** Each aligned tag is judged as the camera would see it: drawn into the frame
   through the aligned homography, blurred like a camera image and sampled back like the
   frame (:func:`~ottag_db.decode.templates.draw_through`). At a grazing view a pixel averages
   a long strip of the data area; a template compared in data-area units makes the correct
   tag's sliver tips misfit like another tag's triangle. The best aligned tag is accepted
   only when its correlation inside the data area reaches ``model_min_correlation``, it
   nowhere misfits the image by more than ``model_max_misfit`` (a stored tag that merely
   resembles the one seen leaves a patch where a triangle differs), its quiet zone is as bright
   or dark as its polarity prints it (``model_max_quiet_misfit``: a dark data area nearly
   edge-on can pass for the inside of an inverted tag's quiet zone), and it beats by
   ``model_min_gap`` every other refined tag that fits as well; its points are the stored
   realization mapped by the aligned homography, and their order type must be the tag's own
   (a projective map that keeps orientation keeps it).

The ID is still an order type: the image only chooses which stored one it shows, so a tag
drawn with other triangles or another placement is not read this way. The detector runs this
stage last, for a foreshortened or small candidate that no reading decoded
(:func:`wants_model`), after the other readings of its candidate pass and only off the tags
they decoded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import lambda_text
from ottag_db.core.single_set import read_set
from ottag_db.core.types import Polarity
from ottag_db.decode.candidates import squeeze
from ottag_db.decode.identify import for_polarity
from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography, square_homography
from ottag_db.decode.profile import StageClock
from ottag_db.decode.templates import (
    MODEL_GRID,
    TemplateBank,
    draw_through,
    normalized_rows,
    placement,
    rasterize,
)
from ottag_db.decode.types import Detection, DetectorParams, Quad, Rejection

__all__ = ["MODEL_CANDIDATES", "read_model", "wants_model"]

_F64 = NDArray[np.float64]
_F32 = NDArray[np.float32]

#: Tags (distinct IDs) refined by ECC after the coarse match.
MODEL_CANDIDATES = 3
#: Side of the refinement templates, px, and the quiet-zone band they include (data-area
#: units on each side; within the 0.25 quiet zone ``export`` prints).
_FINE_GRID = 48
_FINE_BAND = 0.12
#: The refinement template's cells inside the data area (a cell's width off its edge).
_FINE_INSIDE = slice(
    math.ceil(_FINE_BAND / (1 + 2 * _FINE_BAND) * _FINE_GRID) + 1,
    math.floor((1 + _FINE_BAND) / (1 + 2 * _FINE_BAND) * _FINE_GRID) - 1,
)
#: The refinement template's cells of the quiet band (the outer 3 of its 4.6 on each side).
_FINE_BAND_CELLS = np.ones((_FINE_GRID, _FINE_GRID), dtype=bool)
_FINE_BAND_CELLS[3:-3, 3:-3] = False
#: The quiet zone assumed when a dark quad is read as an inverted tag's quiet zone (data-area
#: units, :data:`~ottag_db.printing.geometry.DEFAULT_QUIET_ZONE_RATIO`; ECC corrects a mismatch).
_INVERTED_QUIET = 0.25
#: A coarse score below this cannot become a detection: the candidate is not refined.
_MIN_COARSE = 0.35
#: Side of the window (refinement-template cells, 1/10 of the data area) over which the
#: aligned tag's local misfit is averaged (see :class:`_Aligned`).
_MISFIT_WINDOW = 4
#: Gaussian σ (frame pixels) of the camera blur the tag is drawn with when it is judged, and the
#: quiet zone drawn around it (data-area units, :data:`_INVERTED_QUIET`).
_CAMERA_BLUR_PX = 0.45
_DRAWN_QUIET = _INVERTED_QUIET
_ECC_SMOOTHING = 1  # ECC's Gaussian kernel (1: none)
_ECC_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 60, 1e-5)


def wants_model(quad: Quad, first: Rejection, retry_reasons: frozenset[str], params: DetectorParams) -> bool:
    """Whether a candidate no reading decoded is read by model (see the module docstring).

    Parameters
    ----------
    quad : Quad
        The candidate.
    first : Rejection
        Its rejection after every other reading.
    retry_reasons : frozenset of str
        Reasons given after the quad was read (the detector's retry set); ``"no_triangles"``
        too.
    params : DetectorParams
        ``model_match`` (False turns the stage off); only quads foreshortened to at most
        ``rectify_max_ratio`` and data areas with a side under ``model_max_side_px`` are read
        by model.

    Returns
    -------
    bool
    """
    if not params.model_match or not (first.reason in retry_reasons or first.reason == "no_triangles"):
        return False
    return squeeze(quad) <= params.rectify_max_ratio or math.sqrt(quad.area) < params.model_max_side_px


@dataclass(frozen=True)
class _View:
    """One interpretation of a candidate: data-area corners in tag order and the polarity."""

    corners: _F64
    polarity: Polarity


@dataclass(frozen=True)
class _Aligned:
    """A refined candidate: template row, view, homography data-area units → frame, the
    correlation of the aligned tag with the frame inside the data area, and its largest local
    misfit there. Both compare the frame with the tag as the camera would see it: drawn into
    the frame through the aligned homography, blurred by ``_CAMERA_BLUR_PX`` and sampled back
    like the frame. The misfit is the mean absolute residual of the frame against that view
    (scaled to the frame's contrast by least squares) over a window of ``_MISFIT_WINDOW``
    cells, in units of that contrast: a tag that resembles the one seen fits well overall but
    leaves a patch where a triangle differs. The quiet misfit is the mean absolute residual
    over the quiet band around the data area, with the scale and offset fitted inside it: the
    band must be as bright or dark as the reading's polarity prints it."""

    row: int
    view: _View
    to_frame: _F64
    correlation: float
    misfit: float
    quiet_misfit: float


def _views(quad: Quad, params: DetectorParams) -> list[_View]:
    """The candidate's readings as a data area: its four rotations in its polarity, and for a
    dark quad also the four of the white data area inside it, as an inverted tag's quiet zone."""
    views = [_View(np.roll(quad.corners, -r, axis=0), quad.polarity) for r in range(4)]
    if quad.polarity == "normal" and "inverted" in params.polarities:
        outer = square_homography(quad.corners)
        if outer is not None:
            q = _INVERTED_QUIET / (1 + 2 * _INVERTED_QUIET)
            inner = apply_homography(outer, q + (1 - 2 * q) * UNIT_SQUARE)
            if np.isfinite(inner).all():
                views += [_View(np.roll(inner, -r, axis=0), "inverted") for r in range(4)]
    return [v for v in views if v.polarity in params.polarities]


def _outline_views(roi: _F32, origin: _F64, views: list[_View], side: float) -> list[_View]:
    """The views again with corners aligned by ECC to a blank tag (quiet band, dark data area):
    at a grazing view the contour's whole-pixel corners are off by a large part of the data
    area's short side, and the coarse match then ranks the tag seen below look-alikes."""
    out: list[_View] = []
    for polarity in ("normal", "inverted"):
        first = next((v for v in views if v.polarity == polarity), None)
        if first is None:
            continue
        found = _ecc(roi, origin, _fine_template(np.zeros((0, 3, 2)), polarity), first.corners)
        if found is None:
            continue
        corners = apply_homography(found[0], UNIT_SQUARE)
        # an alignment that wandered off the quad is no better start
        if not np.isfinite(corners).all() or np.abs(corners - first.corners).max() > 0.25 * side + 3:
            continue
        out += [_View(np.roll(corners, -r, axis=0), polarity) for r in range(4)]
    return out


def _sample(gray: NDArray[np.uint8], to_frame: _F64, lo: float, hi: float, size: int) -> _F32 | None:
    """The frame over the window ``[lo, hi]²`` of the data area, ``size²`` cells, area-averaged
    from a 4× finer bilinear warp. None when the map is degenerate."""
    fine = size * 4
    step = (hi - lo) / fine
    cell_to_unit = np.array([[step, 0, lo + step / 2], [0, step, lo + step / 2], [0, 0, 1.0]])
    m = to_frame @ cell_to_unit
    if not np.isfinite(m).all():
        return None
    warped = cv2.warpPerspective(
        gray, m, (fine, fine), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE
    )
    return np.asarray(cv2.resize(warped, (size, size), interpolation=cv2.INTER_AREA), dtype=np.float32)


def _fine_template(triangles: _F64, polarity: Polarity) -> _F32:
    """The refinement template: data area with its triangles and a band of quiet zone, 0 … 1,
    bright where the print is bright."""
    b = _FINE_BAND
    ring = np.array(
        [
            [[-b, -b], [1 + b, -b], [1 + b, 0], [-b, 0]],
            [[-b, 1], [1 + b, 1], [1 + b, 1 + b], [-b, 1 + b]],
            [[-b, 0], [0, 0], [0, 1], [-b, 1]],
            [[1, 0], [1 + b, 0], [1 + b, 1], [1, 1]],
        ]
    )
    img = rasterize(ring[None], -b, 1 + b, _FINE_GRID)[0]
    if len(triangles):
        img += rasterize(triangles[None], -b, 1 + b, _FINE_GRID)[0]
    out: _F32 = img if polarity == "normal" else 1.0 - img
    return out


def _neighbourhood(gray: NDArray[np.uint8], corners: list[_F64]) -> tuple[_F32, _F64]:
    """The part of the frame around data areas with these corners (and twice their quiet band),
    as float32 (ECC needs the template's type), and the frame position of its pixel (0, 0)."""
    h, w = gray.shape
    if not corners:
        return np.zeros((0, 0), dtype=np.float32), np.zeros(2)
    pts = np.concatenate(corners)
    centre = pts.mean(axis=0)
    reach = 1 + 4 * _FINE_BAND  # the band on both sides, with room for the alignment to move
    lo = np.floor(centre + (pts.min(axis=0) - centre) * reach) - 2
    hi = np.ceil(centre + (pts.max(axis=0) - centre) * reach) + 3
    x0, y0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    x1, y1 = min(int(hi[0]), w), min(int(hi[1]), h)
    return np.asarray(gray[y0:y1, x0:x1], dtype=np.float32), np.array([x0, y0], dtype=np.float64)


def _to_roi(origin: _F64) -> _F64:
    """The translation from frame pixels to those of a neighbourhood whose pixel (0, 0) lies at
    frame position ``origin`` (see :func:`_neighbourhood`)."""
    return np.array([[1.0, 0, -origin[0]], [0, 1.0, -origin[1]], [0, 0, 1.0]])


def _ecc(roi: _F32, origin: _F64, template: _F32, corners: _F64) -> tuple[_F64, _F64] | None:
    """ECC alignment of a refinement template (see :func:`_fine_template`) to the frame, from the
    data-area ``corners``; ``roi`` is the frame around the quad, its pixel (0, 0) at frame
    position ``origin``. Returns the homographies data-area units → frame and template pixels →
    ``roi``, or None when ECC fails."""
    start = square_homography(corners)
    if start is None or roi.shape[0] < 4 or roi.shape[1] < 4:
        return None
    b = _FINE_BAND
    step = (1 + 2 * b) / _FINE_GRID
    px_to_unit = np.array([[step, 0, -b + step / 2], [0, step, -b + step / 2], [0, 0, 1.0]])
    to_roi = _to_roi(origin)
    warp = (to_roi @ start @ px_to_unit).astype(np.float32)
    try:
        # no mask (the stubs do not list a None mask)
        rho, warp = cv2.findTransformECC(  # type: ignore[call-overload]
            template, roi, warp, cv2.MOTION_HOMOGRAPHY, _ECC_CRITERIA, None, _ECC_SMOOTHING
        )
    except cv2.error:
        return None  # ECC did not converge (or the warp became singular)
    warp64 = np.asarray(warp, dtype=np.float64)
    to_frame = np.linalg.inv(to_roi) @ warp64 @ np.linalg.inv(px_to_unit)
    to_frame /= to_frame[2, 2]
    if not np.isfinite(to_frame).all() or not math.isfinite(rho):
        return None
    return to_frame, warp64


def _align(roi: _F32, origin: _F64, bank: TemplateBank, row: int, view: _View) -> _Aligned | None:
    """ECC alignment of template ``row`` to the frame from the view's corners (see :func:`_ecc`),
    judged against the tag as the camera would see it there; None when ECC fails."""
    template = _fine_template(bank.triangles[row], view.polarity)
    found = _ecc(roi, origin, template, view.corners)
    if found is None:
        return None
    to_frame, warp = found
    size = template.shape[::-1]
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    seen = cv2.warpPerspective(roi, warp, size, flags=flags, borderMode=cv2.BORDER_REPLICATE)
    # The tag drawn into the frame through the aligned homography and blurred like a camera
    # image, then sampled back like the frame: at a grazing view each pixel averages a long
    # strip of the data area, which a template blurred in data-area units does not model (the
    # correct tag's sliver tips then misfit like a different tag's triangle).
    drawn = draw_through(bank.triangles[row], _DRAWN_QUIET, _to_roi(origin) @ to_frame, (roi.shape[0], roi.shape[1]))
    if view.polarity == "inverted":
        drawn = np.float32(1.0) - drawn
    drawn = np.asarray(cv2.GaussianBlur(drawn, (0, 0), _CAMERA_BLUR_PX), dtype=np.float32)
    expected = cv2.warpPerspective(drawn, warp, size, flags=flags, borderMode=cv2.BORDER_REPLICATE)
    # judged inside the data area only: the quiet band that anchors the alignment looks the
    # same for every tag and would lift every candidate's score alike
    inside = _FINE_INSIDE
    e_in = np.asarray(expected, dtype=np.float32)[inside, inside]
    s_in = np.asarray(seen, dtype=np.float32)[inside, inside]
    pair = normalized_rows(np.stack([e_in.ravel(), s_in.ravel()]))
    a_mat = np.stack([e_in.ravel(), np.ones(e_in.size, dtype=np.float32)], axis=1)
    coef = np.linalg.lstsq(a_mat, s_in.ravel(), rcond=None)[0]
    resid = np.abs(s_in - (coef[0] * e_in + coef[1]))
    local = cv2.boxFilter(resid, -1, (_MISFIT_WINDOW, _MISFIT_WINDOW), borderType=cv2.BORDER_REPLICATE)
    misfit = float(local.max() / max(abs(float(coef[0])), 1e-6))
    # the quiet band under the same scale and offset: as bright (normal) or dark (inverted) as
    # the print, where the data area alone can pass for the other polarity's
    band = _FINE_BAND_CELLS
    seen_band = np.asarray(seen, dtype=np.float32)[band]
    quiet = np.abs(seen_band - (coef[0] * np.asarray(expected, dtype=np.float32)[band] + coef[1]))
    quiet_misfit = float(quiet.mean() / max(abs(float(coef[0])), 1e-6))
    return _Aligned(row, view, to_frame, float(pair[0] @ pair[1]), misfit, quiet_misfit)


def read_model(
    gray: NDArray[np.uint8],
    quad: Quad,
    first: Rejection,
    bank: TemplateBank,
    params: DetectorParams,
    clock: StageClock,
) -> Detection | Rejection:
    """Read a candidate by choosing among the stored tags (see the module docstring).

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    quad : Quad
        The candidate (frame pixels).
    first : Rejection
        Its rejection after every other reading (returned, with the model's finding in its
        detail, when this one fails).
    bank : TemplateBank
        The lookup's printed tags.
    params : DetectorParams
        ``model_min_correlation``, ``model_min_gap``, ``model_max_misfit``,
        ``model_max_quiet_misfit``, ``polarities``.
    clock : StageClock
        Charged as ``"model"``.

    Returns
    -------
    Detection or Rejection
        A detection with ``model_correlation`` set, points the stored realization mapped by
        the aligned homography (frame pixels, canonical label order); else ``first``.
    """
    views = _views(quad, params)
    # ECC differentiates its whole input image: it gets the neighbourhood of the quad only
    roi, origin = _neighbourhood(gray, [view.corners for view in views])
    views += _outline_views(roi, origin, views, math.sqrt(quad.area))
    samples: list[_F32] = []
    kept: list[_View] = []
    for view in views:
        to_frame = square_homography(view.corners)
        s = None if to_frame is None else _sample(gray, to_frame, 0.0, 1.0, MODEL_GRID)
        if s is not None:
            samples.append(s.ravel() if view.polarity == "normal" else -s.ravel())
            kept.append(view)
    if not kept:
        clock.lap("model")
        return first
    scores = bank.coarse @ normalized_rows(np.stack(samples)).T  # (templates, views)
    chosen: list[tuple[int, _View, float]] = []
    # the best tags of each reading of the quad (its own polarity; the inverted tag inside a
    # dark quad), so that one reading's many near-misses cannot crowd out the other's match
    for group in ("normal", "inverted"):
        cols = [i for i, v in enumerate(kept) if v.polarity == group]
        if cols:
            chosen += _best_tags(bank, scores[:, cols], [kept[i] for i in cols])
    aligned: list[_Aligned] = []
    unaligned: list[float] = []  # coarse scores of candidates ECC could not align
    for row, view, coarse in chosen:
        a = _align(roi, origin, bank, row, view)
        if a is None:
            unaligned.append(coarse)
        else:
            aligned.append(a)
    clock.lap("model")
    if not aligned:
        return first
    aligned.sort(key=lambda a: -a.correlation)
    top = aligned[0]
    limit, quiet_limit = params.model_max_misfit, params.model_max_quiet_misfit
    # the next best reading of another tag (ID or polarity) that fits as well: a rival that
    # misfits somewhere, or whose quiet zone is not there, is explained away; a candidate ECC
    # lost counts with its coarse score, so that a failed alignment cannot make the winner look
    # unrivalled
    key = (bank.entries[top.row].lambda_text, top.view.polarity)
    rivals = [
        a.correlation
        for a in aligned
        if (bank.entries[a.row].lambda_text, a.view.polarity) != key
        and a.misfit <= limit
        and a.quiet_misfit <= quiet_limit
    ]
    runner_up = max(rivals + unaligned, default=-1.0)
    note = (
        f"{first.detail}; by model: ρ {top.correlation:.2f}, next {runner_up:.2f}, misfit {top.misfit:.2f},"
        f" quiet zone {top.quiet_misfit:.2f}"
    )
    note = note.lstrip("; ")
    if (
        top.correlation < params.model_min_correlation
        or top.correlation - runner_up < params.model_min_gap
        or top.misfit > limit
        or top.quiet_misfit > quiet_limit
    ):
        return Rejection(first.reason, note, first.lambda_text, first.decomposed)
    result = _detection(bank, top, quad)
    clock.lap("model")
    return result if isinstance(result, Detection) else Rejection(first.reason, note, first.lambda_text)


def _best_tags(bank: TemplateBank, scores: _F32, views: list[_View]) -> list[tuple[int, _View, float]]:
    """The ``MODEL_CANDIDATES`` templates of distinct IDs with the highest coarse score over
    ``views`` (columns of ``scores``), each with its best view and that score; none below
    ``_MIN_COARSE``."""
    best_view = scores.argmax(axis=1)
    best = scores[np.arange(len(bank)), best_view]
    chosen: list[tuple[int, _View, float]] = []
    seen: set[str] = set()
    for row in np.argsort(-best)[: 8 * MODEL_CANDIDATES].tolist():
        lam = bank.entries[row].lambda_text
        if best[row] < _MIN_COARSE or lam in seen:
            continue
        seen.add(lam)
        chosen.append((row, views[int(best_view[row])], float(best[row])))
        if len(chosen) == MODEL_CANDIDATES:
            break
    return chosen


def _detection(bank: TemplateBank, top: _Aligned, quad: Quad) -> Detection | Rejection:
    """The detection of an accepted alignment: the stored points mapped into the frame."""
    entry = bank.entries[top.row]
    r = int(bank.realization[top.row])
    real = entry.realizations[r]
    place = placement(entry, r)
    unit = real @ place[:, :2].T + place[:, 2]
    points = apply_homography(top.to_frame, unit)
    corners = apply_homography(top.to_frame, UNIT_SQUARE)
    if not (np.isfinite(points).all() and np.isfinite(corners).all()):
        return Rejection("verification", "by model: the aligned homography is degenerate")
    table, orderings = read_set(points)
    lam = entry.lambda_text
    # a projective map that keeps orientation keeps the order type: anything else is a bad alignment
    if not table.margin > 0 or lambda_text(orderings[0][1]) != lam:
        return Rejection("verification", "by model: the aligned points do not keep the tag's order type", lam)
    member = for_polarity(entry, top.view.polarity, lam)
    if isinstance(member, Rejection):
        return member
    hom = top.to_frame @ np.vstack([place, [0.0, 0.0, 1.0]])
    hom /= hom[2, 2]
    return Detection(
        lam,
        entry.k,
        member.order_type_id,
        member.tag,
        top.view.polarity,
        points,
        real.copy() if entry.unique_min else None,
        corners,
        hom,
        None,
        float(table.margin),
        model_correlation=top.correlation,
    )
