"""The Order Type Tag detector: orders the decoding stages over the candidates of a frame.

Stages (each a module of :mod:`ottag_db.decode`, data between them in :mod:`.types`)::

    image        to_gray                          image → grey
    candidates   binarize, find_quads             grey → Binarized → Quad (adaptive, then Otsu, then thin quads,
                                                  then holes of the bright mask, then the local
                                                  range for blurred tags; seen_before: a
                                                  foreshortened one outlined anew is read again,
                                                  its first decomposition and by model)
    segmentation segment / decompose              Quad → DataArea → [Decomposition]
    triangles    (triangle fits and splits, inside decompose)
    refine       refine                           Decomposition → TriangleLines (+ quad corners)
    cluster      cluster_hypotheses               TriangleLines → [PointHypothesis]
    identify     identify                         PointHypothesis → ID → LookupEntry
    verify       verify                           → Detection | Rejection
    upsample     (a failed candidate read again at 2×)
    rectify      (a failed candidate read again in a fronto-parallel view of its data area)
    model        (a failed foreshortened candidate: the printed tags aligned to the image)
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.lookup import TagLookup
from ottag_db.decode.binarize import Binarization, searches_at_half_resolution
from ottag_db.decode.blur import BLURRED_MIN_SIDE, BLURRED_MIN_SIGMA, EdgeBlur, edge_blur
from ottag_db.decode.candidates import find_quads
from ottag_db.decode.identify import Catalogue
from ottag_db.decode.image import frame_departure, threshold_offset, to_gray
from ottag_db.decode.model_budget import around_blurred, rank_for_model, ranking_scores
from ottag_db.decode.model_match import NOT_HELD, confirm_by_model, read_model, wants_model
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.profile import StageClock
from ottag_db.decode.quads import (
    Outlined,
    around_detection,
    in_frame_corners,
    outlined_before,
    reading_order,
    same_quad,
    same_tag,
    seen_before,
    within_detection,
)
from ottag_db.decode.reading import read_area, scaled_params
from ottag_db.decode.rectify import read_rectified, wants_rectified
from ottag_db.decode.splitting import FRAME_SEARCH, SearchBudget
from ottag_db.decode.templates import RANKING_GRID, template_bank
from ottag_db.decode.types import Detection, DetectionReport, ModelGuess, Quad, Rejected, Rejection, RejectReason
from ottag_db.errors import UsageError

__all__ = ["DEFAULT_PARAMS", "Detector"]

_F64 = NDArray[np.float64]

#: The default settings (a frozen value, shared safely).
DEFAULT_PARAMS = DetectorParams()

#: Rejections after triangles were found: the reader tries the data area upsampled 2× then.
_RETRY_UPSAMPLED: frozenset[RejectReason] = frozenset(
    {"non_triangle", "point_count", "general_position", "low_margin", "unknown_id", "verification", "quad_inconsistent"}
)
#: Larger data areas (px) are not upsampled (their slivers are wide enough; bounds the cost).
_UPSAMPLE_MAX_SIDE = 640.0
_UPSAMPLE = 2.0


class Detector:
    """Order Type Tag detector, configured once and applied to many frames.

    Pipeline (paper Sec. 4.1.1–4.1.4, extended): grey → dark masks by global Otsu and by
    local mean thresholding → contours with hierarchy; outer contours of dark regions are
    candidate *normal* data areas, hole contours (bright regions inside dark) candidate
    *inverted* ones; convex quadrilaterals above the area threshold are kept. Inside each
    data area a local Otsu threshold separates the triangles; every component must be a
    union of triangles meeting only at vertices (components that touch themselves at a
    shared vertex are split at the pinch, else by a 3×3 opening as in the paper), and each
    triangle side is re-located at sub-pixel precision on the grey image (threshold
    crossings along the side normals, then a least-squares line); vertices are the
    intersections of adjacent sides, shared vertices are clustered. The canonical ID of the
    points is looked up; with ``verify`` every stored realization and every minimal
    labeling is mapped onto the points by a homography and the best fit must stay within
    the reprojection bound (and the data-area corners must map back to a parallelogram).
    With ``verify=False`` the decision is the paper's: the order type alone.

    When a candidate does not read, the reader tries (in this order, all bounded): alternative
    decompositions (the opening, slit cuts, and *strict* fits that also cut at every reflex
    corner of the polygon approximation and do not let a small triangle hanging at a corner
    pass as part of a large one); the data area upsampled 2× (cubic) for slivers and slits
    about a pixel wide; for a candidate tilted beyond about 60°, a fronto-parallel upsampled
    view of its data area (:mod:`~ottag_db.decode.rectify`, ``rectify``); and, for a reading
    whose smallest margin is below ``min_margin_px``,
    soft decoding (:mod:`~ottag_db.decode.soft`): the reading with up to ``soft_max_flips`` of
    its near-collinear triples reversed, each candidate the lookup holds verified, accepted
    only when exactly one verifies, ahead of every other by ``soft_min_fit_gap`` (and, on a
    data area under ``print_check_side_px``, only when the reading by model reads that tag too).
    A foreshortened data area that a later binarization outlines anew is read again with its
    first decomposition and by model, without the alternatives and the upsampled and rectified
    views (:func:`~ottag_db.decode.quads.outlined_before`).

    The detector holds only immutable settings and the lookup: :meth:`detect` keeps no state
    between calls and may run on several threads at once (the lookup must allow concurrent
    reads, as :class:`~ottag_db.core.lookup.MemoryLookup` does).

    Parameters
    ----------
    lookup : TagLookup
        The order types to decode (read per candidate, never written).
    params : DetectorParams
        Settings (see :class:`DetectorParams`).
    """

    def __init__(self, lookup: TagLookup, params: DetectorParams = DEFAULT_PARAMS):
        if not isinstance(params, DetectorParams):
            raise UsageError(f"params must be a DetectorParams, got {type(params).__name__}")
        self._lookup = lookup
        self._params = params
        ks = frozenset(lookup.ks)
        self._catalogue = Catalogue(lookup, ks, params)
        # the 2× re-read measures lengths in upsampled pixels
        self._upsampled = Catalogue(lookup, ks, scaled_params(params, _UPSAMPLE))
        # the printed tags as templates, for reading by model at grazing views
        self._bank = template_bank(lookup, params.model_max_templates) if params.model_match else None

    @property
    def lookup(self) -> TagLookup:
        """The lookup the detector reads."""
        return self._lookup

    @property
    def params(self) -> DetectorParams:
        """The detector's settings."""
        return self._params

    # ------------------------------------------------------------------ public API
    def detect(self, image: object) -> list[Detection]:
        """Decode all tags in an image.

        Parameters
        ----------
        image : array_like
            Any image :func:`~ottag_db.decode.image.to_gray` accepts.

        Returns
        -------
        list of Detection
            In reading order (smaller candidates first, a candidate's pieces right after it,
            adaptive pass before Otsu).
        """
        return self._run(image, StageClock())[0]

    def detect_with_rejections(self, image: object) -> tuple[list[Detection], list[Rejected]]:
        """Decode all tags and also return the rejected candidate data areas with reasons.

        Returns
        -------
        tuple
            ``(detections, rejected)``.
        """
        return self._run(image, StageClock())

    def detect_with_report(self, image: object) -> DetectionReport:
        """Decode all tags; detections, rejected candidates and the time spent per stage.

        Returns
        -------
        DetectionReport
            ``timings`` in seconds per stage name, in pipeline order; ``passes`` in seconds
            per candidate pass that ran.
        """
        clock = StageClock()
        detections, rejected = self._run(image, clock)
        return DetectionReport(detections, rejected, clock.timings(), clock.pass_timings())

    # ------------------------------------------------------------------ stages in order
    def _run(self, image: object, clock: StageClock) -> tuple[list[Detection], list[Rejected]]:
        gray = to_gray(image)
        clock.lap("image")
        rejected: list[Rejected] = []
        detections: list[Detection] = []
        if gray.shape[0] < 8 or gray.shape[1] < 8:
            return detections, rejected
        p = self._params
        passes: list[Binarization] = []
        if p.use_adaptive:
            passes.append("adaptive")
        if p.use_otsu:
            passes.append("otsu")
        if p.use_adaptive:  # after Otsu's: its outlines, seen first, would stand in for Otsu's
            passes.append("adaptive_dim")
        last_resorts = p.use_adaptive and p.last_resort_passes
        if last_resorts and searches_at_half_resolution(gray.shape, p):
            passes.append("adaptive_thin")
        if last_resorts and "normal" in p.polarities:
            passes.append("bright_holes")
        if last_resorts:  # last: a long motion's smeared triangles notch the outlines above
            passes.append("local_range")
        seen: list[Quad] = []
        blurred_seen: list[Quad] = []  # the candidates read by model as blurred tags
        # The best tag of each refused reading by model: a rival of the data area's other
        # outlines (seen_before). An inverted 8-point tag 26 px wide at 80° was refused from the
        # local threshold's outline (a look-alike, ρ 0.926, next 0.922); Otsu's outline then
        # read another look-alike unrivalled (ρ 0.933), now rivalled by the first.
        guesses: list[tuple[Quad, ModelGuess]] = []
        # data areas whose points read an order type the lookup does not hold: their pieces (a
        # triangle outlined as a quad) are not read by model, as a decoded tag's are not
        held_out: list[Quad] = []
        departure: float | None = None
        for kind in passes:
            if kind == "otsu" and p.use_adaptive and detections and not p.otsu_always:
                break  # the global threshold is the fallback of the local one
            edge_on = kind in ("adaptive_thin", "bright_holes")
            if edge_on and detections:
                break  # the last resorts of a frame that read nothing: data areas seen nearly edge-on
            if kind in ("adaptive_dim", "local_range") and detections:
                continue  # the local threshold again (dim or blurred frames) when nothing read
            if kind in ("adaptive_dim", "otsu"):  # how far the frame departs from its surroundings
                departure = frame_departure(gray) if departure is None else departure  # (measured once)
                if kind == "adaptive_dim" and threshold_offset(departure, p.adaptive_c) >= p.adaptive_c:
                    continue  # not a dim frame
            clock.start_pass(kind)
            found = find_quads(gray, kind, p, departure)
            if kind == "local_range":  # a blurred tag outlined anew: its edges' midpoints, not a
                # threshold's notched or shrunk outline; again unless it was read as blurred before
                quads = [q for q in found if not any(same_quad(q, b) for b in blurred_seen)]
            else:
                quads = [q for q in found if not seen_before(q, seen, p.rectify_max_ratio)]
            # A foreshortened data area outlined anew (kept by seen_before) is read again by model
            # only (its first decomposition; no alternatives, upsampled or rectified reading): its
            # new corners can rank the tag seen first there. On 2,000 grazing frames (78-86 deg,
            # tests/support/grazing.py, usual and dark) the other readings of new outlines never
            # read a tag the first outline had not; by model they read 38. An ArUco marker at
            # 76-88 deg spent 17-68 ms in each of up to three outlines' rectified readings
            # (benchmarks/decode_clutter.py: 229-265 -> 155 ms per frame).
            outlined_again = [kind != "local_range" and outlined_before(q, seen) for q in quads]
            seen.extend(quads)
            clock.lap("candidates")
            # read by model after the pass; a blurred one with its blur and coarse match
            by_model: list[tuple[Quad, Rejection, tuple[EdgeBlur, float, Quad] | None]] = []
            # smallest first; a piece of a larger candidate (a triangle's outline inside its data
            # area) after it, and not at all when that one read as a tag
            for i, holder in reading_order(quads):
                quad, again = quads[i], outlined_again[i]
                skip = around_detection(quad, detections) or (holder is not None and within_detection(quad, detections))
                clock.lap("candidates")
                if skip:
                    continue
                # an outline seen again, or inferred from the lines of a partly hidden border (whose
                # reading must show the print anyway), is read once: no alternatives or retries
                once = again or quad.inferred or kind == "local_range"
                if kind == "local_range":
                    # the blurred tags' pass: a quad whose sides are not a blurred tag's is none of
                    # its candidates (the passes before it read the sharp ones), and it is read once
                    blurred = self._blurred_tag(gray, quad)
                    if blurred is None:
                        continue
                result = read_quad(gray, quad, self._catalogue, None if once else FRAME_SEARCH, clock)
                # blurred sides: the points' tips and gaps are gone at every scale (reading by model)
                # (an inferred one too: a long motion smears a data area's corners into no quad)
                if kind != "local_range":
                    blurred = self._blurred_tag(gray, quad) if isinstance(result, Rejection) and not again else None
                if isinstance(result, Rejection) and not once and blurred is None:
                    if result.reason in _RETRY_UPSAMPLED and result.decomposed:
                        result = read_upsampled(gray, quad, result, self._upsampled, p.min_margin_px, clock)
                    if isinstance(result, Rejection) and wants_rectified(quad, result, _RETRY_UPSAMPLED, p):
                        result = read_rectified(gray, quad, result, self._catalogue, clock)
                if isinstance(result, Detection) and self._bank:
                    result = confirm_by_model(gray, quad, result, self._bank, p, clock)
                    if isinstance(result, Rejection):
                        rejected.append(result.at(quad))  # two readings disagree: not read by model again
                        continue
                wanted = isinstance(result, Rejection) and wants_model(
                    quad, result, _RETRY_UPSAMPLED, p, edge_on, blurred is not None
                )
                if isinstance(result, Rejection) and result.reason in NOT_HELD:
                    held_out.append(quad)
                if isinstance(result, Rejection) and self._bank and wanted:
                    by_model.append((quad, result, blurred))
                    if blurred is not None:
                        blurred_seen.append(quad)
                elif isinstance(result, Rejection):
                    rejected.append(result.at(quad))
                elif not any(same_tag(result, d) for d in detections):
                    detections.append(result)
            # last, and only off the tags this pass decoded (pieces of a tag are not tags), within
            # the pass's budget: to the candidates most like a printed tag
            bank = self._bank
            on_tags: list[Outlined] = [*detections, *held_out]
            queue = [entry for entry in by_model if not within_detection(entry[0], on_tags)]
            rejected.extend(first.at(quad) for quad, first, _ in by_model if within_detection(quad, on_tags))
            # ranked only when the pass's candidates outnumber its readings (a coarse match each,
            # measured already for a blurred one)
            ranked = bank is not None and len(queue) > p.model_max_reads
            unmeasured = [q for q, _, measured in queue if measured is None]
            coarse = iter(ranking_scores(gray, unmeasured, bank, p) if bank is not None and ranked else [])
            scores = [
                (measured[1] if measured else next(coarse)) if bank is not None and ranked else 0.0
                for _, _, measured in queue
            ]
            # (the outline of a blurred data area's quiet zone only after the data area)
            last = around_blurred([q for q, _, _ in queue], [m is not None for _, _, m in queue]) if ranked else []
            chosen, passed_over = rank_for_model(scores, p.model_max_reads, last)
            clock.lap("model")
            for i in passed_over:
                quad, first, _ = queue[i]
                note = f"not read by model: the pass's {p.model_max_reads} readings went to candidates more like a tag"
                rejected.append(replace(first, detail=f"{first.detail}; {note}".lstrip("; ")).at(quad))
            for i in chosen:
                quad, first, measured = queue[i]
                if bank is None or within_detection(quad, detections):  # of a tag read by model just now
                    rejected.append(first.at(quad))
                    continue
                rivals = tuple(g for q, g in guesses if same_quad(q, quad))
                blur, read_as = (measured[0], measured[2]) if measured else (None, quad)
                result = read_model(gray, read_as, first, bank, p, clock, rivals, blur)
                if isinstance(result, Rejection):
                    if result.model_best is not None:
                        guesses.append((quad, result.model_best))
                    rejected.append(result.at(quad))
                elif not any(same_tag(result, d) for d in detections):
                    detections.append(result)
        clock.end_passes()
        return [in_frame_corners(d, gray.shape) for d in detections], rejected

    def _blurred_tag(self, gray: NDArray[np.uint8], quad: Quad) -> tuple[EdgeBlur, float, Quad] | None:
        """A candidate the points did not read that looks like a blurred tag — its sides blurred
        alike (:attr:`~ottag_db.decode.blur.EdgeBlur.blurred`), its coarse match like a printed
        tag (:meth:`~ottag_db.decode.blur.EdgeBlur.min_ranking`: lower for a blur that spans a
        cell of the ranking grid) — as its blur, coarse match and
        the outline it is read by model from; else None. The coarse match is taken from the
        threshold's outline and from the outline on its sides' blurred steps
        (:meth:`~ottag_db.decode.blur.EdgeBlur.centred`), the better of the two."""
        if self._bank is None or math.sqrt(quad.area) < BLURRED_MIN_SIDE * BLURRED_MIN_SIGMA:
            return None  # too small to hold a tag blurred that much (blur.BLURRED_MIN_SIDE)
        blur = edge_blur(gray, quad)
        if not blur.blurred:
            return None
        centred = blur.centred(quad)
        outlines = (quad,) if centred is quad else (quad, centred)
        scores = ranking_scores(gray, list(outlines), self._bank, self._params)  # one product for both
        score, best = max((s, i) for i, s in enumerate(scores))
        floor = blur.min_ranking(math.sqrt(quad.area), RANKING_GRID)
        return (blur, score, outlines[best]) if score >= floor else None


def read_quad(
    gray: NDArray[np.uint8],
    quad: Quad,
    catalogue: Catalogue,
    alternatives: SearchBudget | None,
    clock: StageClock,
    print_required: frozenset[str] = frozenset(),
) -> Detection | Rejection:
    """Read one candidate: segmentation → triangles → refinement → clusters → identification.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    quad : Quad
        The candidate (pixels of ``gray``).
    catalogue : Catalogue
        Lookup and settings (lengths in pixels of ``gray``).
    alternatives : SearchBudget or None
        Also try the alternative decompositions (opening, slit cuts, strict fits) within this
        budget when the first does not read (None: not).
    clock : StageClock
        Charged per stage.
    print_required : frozenset of str, optional
        IDs an earlier reading of the candidate refused as not printed
        (:attr:`~ottag_db.decode.types.Rejection.not_printed`).

    Returns
    -------
    Detection or Rejection
        As :func:`~ottag_db.decode.reading.read_area` returns it: the first hypothesis that
        reads with its points within the reprojection bound (else the best-fitting reading),
        else the most telling rejection.
    """
    return read_area(gray, quad, catalogue.params, catalogue, alternatives, clock, print_required=print_required)[0]


def read_upsampled(
    gray: NDArray[np.uint8],
    quad: Quad,
    first: Rejection,
    catalogue: Catalogue,
    min_margin_px: float,
    clock: StageClock,
) -> Detection | Rejection:
    """Read a candidate again on its data area upsampled 2× (cubic), for slivers and slits
    about a pixel wide that the binary mask at the image's own scale merges or loses.

    Parameters
    ----------
    gray : numpy.ndarray
        The frame.
    quad : Quad
        The candidate (frame pixels).
    first : Rejection
        The rejection of the reading at the frame's scale (returned when this one fails).
    catalogue : Catalogue
        Lookup and the settings scaled to upsampled pixels, except ``min_margin_px`` and the
        reprojection floor, which keep their meaning in frame pixels: the reading is checked
        against ``min_margin_px`` after mapping it back.
    min_margin_px : float
        The margin a reading must keep in frame pixels.
    clock : StageClock
        Charged per stage (the resize as ``"upsample"``).

    Returns
    -------
    Detection or Rejection
        The detection in frame pixels, or ``first`` (with the IDs this reading refused as not
        printed in its ``not_printed``).
    """
    side = math.sqrt(quad.area)
    if side > _UPSAMPLE_MAX_SIDE:
        return first
    h, w = gray.shape
    q = quad.corners
    x0 = max(math.floor(q[:, 0].min()) - 6, 0)
    y0 = max(math.floor(q[:, 1].min()) - 6, 0)
    x1 = min(math.ceil(q[:, 0].max()) + 7, w)
    y1 = min(math.ceil(q[:, 1].max()) + 7, h)
    f = _UPSAMPLE
    up: NDArray[np.uint8] = np.asarray(
        cv2.resize(gray[y0:y1, x0:x1], None, fx=f, fy=f, interpolation=cv2.INTER_CUBIC), dtype=np.uint8
    )
    # pixel centres: up pixel u lies at x = x0 + (u + 0.5) / f − 0.5 of the image
    shift = np.array([x0 + 0.5 / f - 0.5, y0 + 0.5 / f - 0.5])
    clock.lap("upsample")
    up_quad = Quad(quad.polarity, (q - shift) * f, quad.area * f * f, quad.inferred)
    res = read_quad(up, up_quad, catalogue, None, clock, first.not_printed)
    if not isinstance(res, Detection):
        return replace(first, not_printed=res.not_printed)  # what this reading refused too
    margin = res.margin_px / f
    if margin < min_margin_px and res.corrected_flips is None:  # soft decoding decided already
        return first
    to_img = np.array([[1 / f, 0, shift[0]], [0, 1 / f, shift[1]], [0, 0, 1.0]])
    hom = None if res.homography is None else to_img @ res.homography
    if hom is not None:
        hom = hom / hom[2, 2]
    return replace(
        res,
        points=res.points / f + shift,
        corners=res.corners / f + shift,
        homography=hom,
        reprojection_error_px=None if res.reprojection_error_px is None else res.reprojection_error_px / f,
        margin_px=margin,
    )
