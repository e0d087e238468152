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
   its own), from the contour's corners and from corners aligned to a tag's outline
   (:func:`~ottag_db.decode.model_align.outline_views`); one matrix product scores every
   template against every view by normalized correlation.
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
4. **Challenge.** Before it is accepted, the winner must also beat the tags the coarse match
   ranks first once the data area is where the winner's ECC alignment puts it (in its four
   turns), not where the contour's whole-pixel corners put it: the best
   ``MODEL_CHALLENGERS`` of them not yet aligned, and the best ``MODEL_CHALLENGERS`` in the
   winner's own turn, are aligned by ECC and join the decision. On
   small, steep data areas (50–110 px at 70–80°) the first coarse match ranked the tag seen
   11th to 58th, and a look-alike among the few refined won unrivalled (3 wrong IDs in 2,100
   frames of the benchmarks/soft_decoding.py scenes, seeds 2, 4 and 7–11). On smaller ones
   (data areas of 16–23 px at 69–81°) the tag seen ranked 2nd in the winner's own turn but
   behind tags of the other turns, hence the challengers of its own turn (3 wrong IDs in 5,100
   frames of those scenes with tags of 25–60 px at 55–85°).
5. **Check.** A small data area's reading not by model whose points miss the reprojection
   bound (kept when nothing fitted better) stands if the tag read, aligned, fits as printed;
   else, and always when soft-decoded, the candidate is read by model and refused when that
   reads another tag (a soft-decoded one also when it reads none; :func:`confirm_by_model`).

The ID is still an order type: the image only chooses which stored one it shows (not a tag
drawn otherwise). It runs last, for a foreshortened or small candidate no reading decoded
(:func:`wants_model`), after its pass's other readings and off the tags they decoded.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import lambda_text
from ottag_db.core.single_set import read_set
from ottag_db.decode.blur import BLURRED_MIN_NOMINAL_CORRELATION, BLURRED_MIN_SIDE, EdgeBlur, edge_blur
from ottag_db.decode.camera_blur import FrameCamera, measured_blurs, sensor_noise
from ottag_db.decode.identify import for_polarity
from ottag_db.decode.model_align import Aligned, View, align, fit_blur, judge, neighbourhood, outline_views
from ottag_db.decode.model_budget import coarse_samples, contour_views, view_samples
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography
from ottag_db.decode.profile import StageClock
from ottag_db.decode.quads import squeeze
from ottag_db.decode.reading import points_fit
from ottag_db.decode.templates import TemplateBank, placement
from ottag_db.decode.types import Detection, ModelGuess, Quad, Rejection

__all__ = ["MODEL_CANDIDATES", "MODEL_CHALLENGERS", "NOT_HELD", "confirm_by_model", "read_model", "wants_model"]

_F64 = NDArray[np.float64]
_F32 = NDArray[np.float32]

#: Tags (distinct IDs) refined by ECC after the coarse match.
MODEL_CANDIDATES = 3
#: Tags (distinct IDs) ranked again by the coarse match under an accepted reading's alignment
#: and refined by ECC, which it must also beat (see :func:`_challengers`).
MODEL_CHALLENGERS = 3
#: The data area turned by 0, 1, 2 and 3 quarter turns about its centre (data-area units).
_QUARTER_TURNS = tuple(
    np.array([[c, -t, 0.5 - 0.5 * c + 0.5 * t], [t, c, 0.5 - 0.5 * t - 0.5 * c], [0, 0, 1.0]])
    for c, t in ((1, 0), (0, 1), (-1, 0), (0, -1))
)
#: Rejections after which a candidate is not read by model: its points read clearly (margin ≥
#: ``min_margin_px``) an order type the lookup does not hold (or not in that polarity), a tag of
#: another dictionary; by model, which chooses among stored tags only, its look-alike would read.
NOT_HELD: frozenset[str] = frozenset({"unknown_id", "polarity_not_in_dictionary"})
#: A coarse score below this cannot become a detection: the candidate is not refined.
_MIN_COARSE = 0.35


def wants_model(
    quad: Quad,
    first: Rejection,
    retry_reasons: frozenset[str],
    params: DetectorParams,
    edge_on_pass: bool = False,
    blurred: bool = False,
) -> bool:
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
    edge_on_pass : bool, optional
        From a last-resort pass for data areas seen nearly edge-on (``"adaptive_thin"``,
        ``"bright_holes"``): a foreshortened one refused as ``"low_contrast"`` is read by model
        too (a normal data area at 86–87° is 4–6 px thin, dark up to its outline; elsewhere such
        quads are mostly thin dark strips of clutter, 10–90 ms each by model).
    blurred : bool, optional
        A blurred tag's candidate (:attr:`~ottag_db.decode.blur.EdgeBlur.blurred`): read by model
        at any size and view, ``"low_contrast"`` included (blur dims and merges triangles), and
        also when ``quad`` is inferred (a long motion smears a data area's corners).

    Returns
    -------
    bool
        Never after a rejection of :data:`NOT_HELD`.
    """
    if not params.model_match or (quad.inferred and not blurred):  # (an outline no quad: a hidden border)
        return False
    if first.reason in NOT_HELD:
        return False  # the points decide: a tag the lookup does not hold, not one of its look-alikes
    if blurred:
        return first.reason in retry_reasons or first.reason in ("no_triangles", "low_contrast")
    foreshortened = squeeze(quad) <= params.rectify_max_ratio
    if first.reason == "low_contrast":
        return edge_on_pass and foreshortened
    if not (first.reason in retry_reasons or first.reason == "no_triangles"):
        return False
    return foreshortened or math.sqrt(quad.area) < params.model_max_side_px


def confirm_by_model(
    gray: NDArray[np.uint8],
    quad: Quad,
    reading: Detection,
    bank: TemplateBank,
    params: DetectorParams,
    clock: StageClock,
) -> Detection | Rejection:
    """A small data area's loose reading (points off the bound, or soft-decoded), checked by model.

    Points off the bound are kept when nothing fits better (a sharp tip's point slides along
    its bisector, :func:`~ottag_db.decode.reading.points_fit`), but an 8-point tag 36 px wide at
    58° whose vertices merged read so as a 7-point type, and by model as the tag seen. The tag
    read is aligned first (one ECC alignment): fitting as printed (``model_*`` limits) it stands;
    else the candidate is read by model and refused when that reads another tag. A soft-decoded
    reading must be read the same by model: 8-point tags 40 px wide at 64–67° whose tips merged
    were soft-decoded as 7- and 6-point look-alikes (same triangles, placement and print fit).

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    quad : Quad
        The candidate (frame pixels).
    reading : Detection
        Its reading (not by model).
    bank : TemplateBank
        The lookup's printed tags.
    params : DetectorParams
        ``model_match`` and ``verify`` (either False: no check), ``print_check_side_px`` (data areas with a side
        ``√area`` under it are checked), the reprojection bound and the ``model_*`` limits.
    clock : StageClock
        Charged as ``"model"``.

    Returns
    -------
    Detection or Rejection
        ``reading``, or a ``"verification"`` rejection naming both readings (or, for a
        soft-decoded one, why the model read none).
    """
    soft = reading.corrected_flips is not None
    if (
        not params.model_match
        or not params.verify  # the order type alone decides: nothing to dispute
        or reading.model_correlation is not None
        or math.sqrt(quad.area) >= params.print_check_side_px
        or (not soft and points_fit(reading, quad, params))
    ):
        return reading
    if not soft and _shows_own_print(gray, reading, bank, params):
        clock.lap("model")
        return reading  # the tag read fits the image as printed: nothing to dispute
    error = reading.reprojection_error_px
    detail = f"points {error:.2f} px off" if error is not None else "no reprojection error"
    detail = f"soft-decoded ({reading.corrected_flips} flips)" if soft else detail
    check = read_model(gray, quad, Rejection("verification", detail, reading.lambda_text), bank, params, clock)
    if isinstance(check, Rejection):  # the model reads nothing: only a soft reading needed it to
        why = f"{detail} as {reading.lambda_text}; by model: {check.detail}"
        return Rejection("verification", why, reading.lambda_text) if soft else reading
    if (check.lambda_text, check.polarity) == (reading.lambda_text, reading.polarity):
        return reading
    why = f"{detail} as {reading.lambda_text}; by model {check.lambda_text} ({check.polarity})"
    return Rejection("verification", f"{why}, ρ {check.model_correlation:.2f}", reading.lambda_text)


def _shows_own_print(gray: NDArray[np.uint8], reading: Detection, bank: TemplateBank, params: DetectorParams) -> bool:
    """Whether the tag a reading names, aligned by ECC from its corners (the turn and
    realization its coarse score prefers), meets the ``model_*`` limits of an accepted reading
    by model: one alignment instead of a reading by model (on grazing frames the check of loose
    readings cost 20 ms/frame that way, most of them readings of the tag seen)."""
    rows = [i for i, e in enumerate(bank.entries) if e.lambda_text == reading.lambda_text]
    if not rows:
        return False
    turns = [View(np.roll(reading.corners, -r, axis=0), reading.polarity) for r in range(4)]
    views, samples = view_samples(gray, turns)
    if not views:
        return False
    scores = bank.coarse[rows] @ samples.T  # (rows, turns)
    best_row, best_view = divmod(int(np.argmax(scores)), len(views))
    roi, origin = neighbourhood(gray, [views[best_view].corners])
    a = align(roi, origin, bank, rows[best_row], views[best_view])
    return a is not None and _accepted(a, -1.0, params)


def read_model(
    gray: NDArray[np.uint8],
    quad: Quad,
    first: Rejection,
    bank: TemplateBank,
    params: DetectorParams,
    clock: StageClock,
    rivals: tuple[ModelGuess, ...] = (),
    blur: EdgeBlur | None = None,
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
    rivals : tuple of ModelGuess, optional
        The best tags of refused readings by model of the same data area from other outlines
        (:attr:`Rejection.model_best`): rivals of the winner unless they are its tag and polarity
        (each outline's shortlist can miss the tag seen, and a look-alike then wins unrivalled).
    blur : EdgeBlur or None, optional
        The candidate's sides' blur when measured already (:func:`~ottag_db.decode.blur.edge_blur`).

    Returns
    -------
    Detection or Rejection
        A detection with ``model_correlation`` set, points the stored realization mapped by
        the aligned homography (frame pixels, canonical label order); else ``first`` (with
        the best aligned tag in ``model_best`` when one was aligned).
    """
    views = contour_views(quad, params)
    # ECC differentiates its whole input image: it gets the neighbourhood of the quad only
    roi, origin = neighbourhood(gray, [view.corners for view in views])
    views += outline_views(roi, origin, views, math.sqrt(quad.area), quad.polarity, blur is not None)
    kept, rows = view_samples(gray, views)
    if not kept:
        clock.lap("model")
        return first
    scores = bank.coarse @ rows.T  # (templates, views)
    chosen: list[tuple[int, View, float]] = []
    # the best tags of each reading of the quad (its own polarity; the inverted tag inside a
    # dark quad), so that one reading's many near-misses cannot crowd out the other's match
    for group in ("normal", "inverted"):
        cols = [i for i, v in enumerate(kept) if v.polarity == group]
        if cols:
            chosen += _best_tags(bank, scores[:, cols], [kept[i] for i in cols])
    aligned: list[Aligned] = []
    unaligned: list[float] = []  # coarse scores of candidates ECC could not align
    for row, view, score in chosen:
        a = align(roi, origin, bank, row, view, converge=blur is not None)
        if a is None:
            unaligned.append(score)
        else:
            aligned.append(a)
    clock.lap("model")
    if not aligned:
        return first
    top, runner_up = _decide_with_challengers(gray, roi, origin, bank, aligned, unaligned, params, rivals, None)
    blur = edge_blur(gray, quad) if blur is None else blur
    blurred = False
    judged_blurred = (
        blur.blurred
        and blur.width <= math.sqrt(quad.area) / BLURRED_MIN_SIDE
        and top.correlation >= BLURRED_MIN_NOMINAL_CORRELATION
    )
    if not _accepted(top, runner_up, params) and judged_blurred:
        # judged again as a camera with the blur its sides measure would see each tag (the
        # same alignments): the nominal blur misfits a defocused tag's triangles everywhere
        fitted = fit_blur(roi, origin, bank, top, measured_blurs(blur))
        camera = None if fitted is None else FrameCamera(fitted, sensor_noise(roi))  # (for every tag)
        rejudged = [judge(roi, origin, bank, a.row, a.view, a.to_frame, camera) for a in aligned]
        top, runner_up = _decide_with_challengers(gray, roi, origin, bank, rejudged, unaligned, params, rivals, camera)
        blurred = True
    clock.lap("model")
    note = (
        f"{first.detail}; by model: ρ {top.correlation:.2f}, next {runner_up:.2f}, misfit {top.misfit:.2f},"
        f" quiet zone {top.quiet_misfit:.2f}"
    )
    note = note.lstrip("; ")
    best = ModelGuess(bank.entries[top.row].lambda_text, top.view.polarity, top.correlation)
    if not _accepted(top, runner_up, params, blurred):
        return Rejection(first.reason, note, first.lambda_text, first.decomposed, model_best=best)
    result = _detection(bank, top, quad)
    clock.lap("model")
    if isinstance(result, Detection):
        return result
    return Rejection(first.reason, note, first.lambda_text, model_best=best)


def _decide_with_challengers(
    gray: NDArray[np.uint8],
    roi: _F32,
    origin: _F64,
    bank: TemplateBank,
    aligned: list[Aligned],
    unaligned: list[float],
    params: DetectorParams,
    rivals: tuple[ModelGuess, ...],
    camera: FrameCamera | None,
) -> tuple[Aligned, float]:
    """:func:`_decide`, and when the winner is accepted, again with its challengers (judged
    with the candidate's measured ``camera`` too, see :func:`~ottag_db.decode.model_align.judge`)."""
    top, runner_up = _decide(aligned, unaligned, bank, params, rivals)
    if _accepted(top, runner_up, params, camera is not None):
        # Small, steep data areas rank the tag seen as low as 11th–58th by the coarse score
        # from the contour's corners (benchmarks/soft_decoding.py scenes, 50–110 px at
        # 70–80°), and a look-alike among the few refined then wins unrivalled: the winner must
        # also beat the best tags of the coarse match from its own, refined alignment.
        challengers = _challengers(gray, roi, origin, bank, aligned, top, camera)
        if challengers:
            top, runner_up = _decide(aligned + challengers, unaligned, bank, params, rivals)
    return top, runner_up


def _decide(
    aligned: list[Aligned],
    unaligned: list[float],
    bank: TemplateBank,
    params: DetectorParams,
    rivals: tuple[ModelGuess, ...] = (),
) -> tuple[Aligned, float]:
    """The best aligned tag and the correlation of the next best reading of another tag (ID or
    polarity) that fits as well: a rival that misfits somewhere, or whose quiet zone is not
    there, is explained away; a candidate ECC lost counts with its coarse score, so that a
    failed alignment cannot make the winner look unrivalled; ``rivals`` (other outlines) count."""
    aligned.sort(key=lambda a: -a.correlation)
    top = aligned[0]
    key = (bank.entries[top.row].lambda_text, top.view.polarity)
    # a rival's misfit explains it away only when it is also clearly worse than the winner's
    misfit_limit = max(params.model_max_misfit, top.misfit + params.model_misfit_lead)
    others = [
        a.correlation
        for a in aligned
        if (bank.entries[a.row].lambda_text, a.view.polarity) != key
        and a.misfit <= misfit_limit
        and a.quiet_misfit <= params.model_max_quiet_misfit
    ]
    earlier = [r.correlation for r in rivals if (r.lambda_text, r.polarity) != key]
    return top, max(others + unaligned + earlier, default=-1.0)


def _accepted(top: Aligned, runner_up: float, params: DetectorParams, blurred: bool = False) -> bool:
    """Whether the best aligned tag is read (the ``model_*`` limits of :class:`DetectorParams`;
    judged with the candidate's measured blur, ``blurred``, the misfit within
    :attr:`~ottag_db.decode.model_align.Aligned.blurred_misfit_limit`)."""
    limit = min(top.blurred_misfit_limit, params.model_max_misfit) if blurred else params.model_max_misfit
    return (
        top.blurred_correlation >= params.model_min_correlation
        and top.correlation - runner_up >= params.model_min_gap
        and top.misfit <= limit
        and top.quiet_misfit <= params.model_max_quiet_misfit
    )


def _challengers(
    gray: NDArray[np.uint8],
    roi: _F32,
    origin: _F64,
    bank: TemplateBank,
    aligned: list[Aligned],
    top: Aligned,
    camera: FrameCamera | None,
) -> list[Aligned]:
    """The coarse match again, with the data area where the winner's alignment puts it (in its
    four turns: the winner's corner order need not be another tag's): the best
    ``MODEL_CHALLENGERS`` tags of the winner's polarity not yet aligned over all four turns,
    and the best ``MODEL_CHALLENGERS`` of the winner's own turn, aligned by ECC."""
    turned = [top.to_frame @ turn for turn in _QUARTER_TURNS]
    framed: list[tuple[View, _F64 | None]] = [
        (View(apply_homography(to_frame, UNIT_SQUARE), top.view.polarity), to_frame) for to_frame in turned
    ]
    views, rows = coarse_samples(gray, framed)
    if not views:
        return []
    own = [0] if views[0] is framed[0][0] else []  # the column of the winner's own turn
    scores = bank.coarse @ rows.T  # (templates, turns)
    done = frozenset(bank.entries[a.row].lambda_text for a in aligned)
    chosen = _best_tags(bank, scores, views, MODEL_CHALLENGERS, done)
    # A look-alike of the tag seen in the winner's own turn can rank below tags of other turns
    # (an 8-point tag 23 px wide at 69°: 2nd in its turn with 0.78, after three tags of other
    # turns at 0.79-0.81; aligned, ρ 0.996 against the winner's 0.975): that turn's best too.
    if own:
        taken = done | {bank.entries[row].lambda_text for row, _, _ in chosen}
        chosen += _best_tags(bank, scores[:, own], [views[own[0]]], MODEL_CHALLENGERS, taken)
    out: list[Aligned] = []
    for row, view, _ in chosen:
        a = align(roi, origin, bank, row, view, camera, converge=camera is not None)
        if a is not None:
            out.append(a)
    return out


def _best_tags(
    bank: TemplateBank,
    scores: _F32,
    views: list[View],
    count: int = MODEL_CANDIDATES,
    exclude: frozenset[str] = frozenset(),
) -> list[tuple[int, View, float]]:
    """The ``count`` templates of distinct IDs, none in ``exclude``, with the highest coarse score
    over ``views`` (columns of ``scores``), each with its best view and that score; none below
    ``_MIN_COARSE``."""
    best_view = scores.argmax(axis=1)
    best = scores[np.arange(len(bank)), best_view]
    chosen: list[tuple[int, View, float]] = []
    seen: set[str] = set(exclude)
    for row in np.argsort(-best)[: 8 * count + len(exclude)].tolist():
        lam = bank.entries[row].lambda_text
        if best[row] < _MIN_COARSE or lam in seen:
            continue
        seen.add(lam)
        chosen.append((row, views[int(best_view[row])], float(best[row])))
        if len(chosen) == count:
            break
    return chosen


def _detection(bank: TemplateBank, top: Aligned, quad: Quad) -> Detection | Rejection:
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
