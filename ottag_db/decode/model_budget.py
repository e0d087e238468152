"""Reading by model within a budget per candidate pass: a coarse match ranks the candidates.

Reading by model (:mod:`~ottag_db.decode.model_match`) aligns the best few printed tags to the
frame by OpenCV's ECC, some 10–40 ms a candidate. A frame of brick, text or foliage can hold
dozens of dark quads that no other reading decodes, and reading each of them by model made
such a frame cost many times a typical one. Like AprilTag's fixed pipeline, the detector
therefore spends at most ``DetectorParams.model_max_reads`` readings by model per candidate
pass (at most four passes a frame) and gives them to the candidates that look most like a
printed tag: the *coarse match* that starts a reading by model — the candidate's data area in
its four turns, from the contour's corners, correlated with every printed tag — is run for all
of them on a grid of 16² cells instead of 32² (a fraction of a millisecond each), and the
candidates are ranked by their best score. They are read in the detector's order, so that an
outline's refused reading still rivals the later outlines of the same data area.

The functions here sample the frame for that coarse match; :mod:`.model_match` uses them for
its other coarse matches too (outline views, challengers, the print check).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.model_align import INVERTED_QUIET, View
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography, square_homography
from ottag_db.decode.quads import centres_inside
from ottag_db.decode.templates import MODEL_GRID, RANKING_GRID, TemplateBank, normalized_rows
from ottag_db.decode.types import Quad

__all__ = [
    "QUIET_OUTLINE_AREA",
    "around_blurred",
    "coarse_samples",
    "contour_views",
    "rank_for_model",
    "ranking_score",
    "ranking_scores",
    "view_samples",
]

_F64 = NDArray[np.float64]
_F32 = NDArray[np.float32]

#: The range of a data area's area, as a share of the area of a candidate around it, for which
#: that candidate is the outline of its quiet zone (:func:`around_blurred`): the printed quiet
#: zone's outline is (1 + 2 × 0.25)² = 2.25 times the data area (a share of 0.44); a blur moves
#: each threshold's outline by a few px (tags 80–90 px wide moved by 17 px: 0.35–0.41).
QUIET_OUTLINE_AREA = (0.25, 0.7)


def contour_views(quad: Quad, params: DetectorParams) -> list[View]:
    """The candidate's readings as a data area: its four turns in its polarity, and for a dark
    quad also the four of the white data area inside it, as an inverted tag's quiet zone.

    Parameters
    ----------
    quad : Quad
        The candidate (frame pixels).
    params : DetectorParams
        ``polarities``: views of other polarities are left out.

    Returns
    -------
    list of View
    """
    views = [View(np.roll(quad.corners, -r, axis=0), quad.polarity) for r in range(4)]
    if quad.polarity == "normal" and "inverted" in params.polarities:
        outer = square_homography(quad.corners)
        if outer is not None:
            q = INVERTED_QUIET / (1 + 2 * INVERTED_QUIET)
            inner = apply_homography(outer, q + (1 - 2 * q) * UNIT_SQUARE)
            if np.isfinite(inner).all():
                views += [View(np.roll(inner, -r, axis=0), "inverted") for r in range(4)]
    return [v for v in views if v.polarity in params.polarities]


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


def coarse_samples(
    gray: NDArray[np.uint8], framed: list[tuple[View, _F64 | None]], size: int = MODEL_GRID
) -> tuple[list[View], _F32]:
    """The views whose data area samples on a grid of ``size²`` cells and their samples as rows.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    framed : list of (View, numpy.ndarray or None)
        Each view with its homography from data-area units to the frame (None: degenerate).
    size : int, optional
        Cells per side: ``MODEL_GRID`` (the coarse templates) or ``RANKING_GRID``.

    Returns
    -------
    views : list of View
        The views that sampled.
    rows : numpy.ndarray
        ``(len(views), size²)`` float32 normalized rows, triangles bright (an inverted
        view's sample negated): ``bank.coarse @ rows.T`` scores every template. ``(0,
        size²)`` when no view samples.
    """
    samples: list[_F32] = []
    kept: list[View] = []
    for view, to_frame in framed:
        s = None if to_frame is None else _sample(gray, to_frame, 0.0, 1.0, size)
        if s is not None:
            samples.append(s.ravel() if view.polarity == "normal" else -s.ravel())
            kept.append(view)
    if not samples:
        return kept, np.zeros((0, size * size), dtype=np.float32)
    return kept, normalized_rows(np.stack(samples))


def view_samples(gray: NDArray[np.uint8], views: list[View], size: int = MODEL_GRID) -> tuple[list[View], _F32]:
    """:func:`coarse_samples` of views mapped by their corners (:func:`square_homography`),
    each data area sampled once: a view whose corners are another's turned by ``r`` places
    (``np.roll``) in the same polarity samples as that one's sample turned by ``r`` quarter
    turns (the grid of cell centres is symmetric), so :func:`contour_views` and the outline
    views, four turns each, cost one warp per outline instead of four.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    views : list of View
        The views, in any order.
    size : int, optional
        Cells per side.

    Returns
    -------
    views : list of View
        The views that sampled.
    rows : numpy.ndarray
        ``(len(views), size²)`` normalized rows, as :func:`coarse_samples` returns them.
    """
    # (view, its corners as lists, its sample, not negated); the corners compared in plain
    # Python (np.roll and np.array_equal on 8 numbers cost more than the comparison)
    sampled: list[tuple[View, list[list[float]], _F32]] = []
    samples: list[_F32] = []
    kept: list[View] = []
    for view in views:
        s = None
        corners: list[list[float]] = view.corners.tolist()
        for base, base_corners, base_sample in sampled:
            if base.polarity != view.polarity:
                continue
            # the base's corners turned by r places, as np.roll(base.corners, -r, axis=0)
            turns = [r for r in range(1, 4) if corners == base_corners[r:] + base_corners[:r]]
            if turns:
                s = np.rot90(base_sample, turns[0])
                break
        if s is None:
            to_frame = square_homography(view.corners)
            s = None if to_frame is None else _sample(gray, to_frame, 0.0, 1.0, size)
            if s is None:
                continue
            sampled.append((view, corners, s))
        samples.append(s.ravel() if view.polarity == "normal" else -s.ravel())
        kept.append(view)
    if not samples:
        return kept, np.zeros((0, size * size), dtype=np.float32)
    return kept, normalized_rows(np.stack(samples))


def ranking_score(gray: NDArray[np.uint8], quad: Quad, bank: TemplateBank, params: DetectorParams) -> float:
    """How much a candidate looks like a printed tag: the best correlation of any ranking
    template (:attr:`~ottag_db.decode.templates.TemplateBank.ranking`) with any of its contour
    views, sampled on the ranking grid.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    quad : Quad
        The candidate (frame pixels).
    bank : TemplateBank
        The lookup's printed tags.
    params : DetectorParams
        ``polarities``.

    Returns
    -------
    float
        In [-1, 1]; -1 when no view could be sampled.
    """
    return ranking_scores(gray, [quad], bank, params)[0]


def ranking_scores(
    gray: NDArray[np.uint8], quads: list[Quad], bank: TemplateBank, params: DetectorParams
) -> list[float]:
    """:func:`ranking_score` of several candidates, their views scored by one matrix product: a
    pass over brick or foliage queues a hundred candidates, and one product with all their views
    reads the templates once instead of once per candidate (three times less time there).

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    quads : list of Quad
        The candidates (frame pixels).
    bank : TemplateBank
        The lookup's printed tags.
    params : DetectorParams
        ``polarities``.

    Returns
    -------
    list of float
        One score per candidate, as :func:`ranking_score` gives it.
    """
    rows: list[_F32] = []
    owners: list[int] = []
    for i, quad in enumerate(quads):
        kept, sampled = view_samples(gray, contour_views(quad, params), RANKING_GRID)
        rows.append(sampled)
        owners += [i] * len(kept)
    scores = [-1.0] * len(quads)
    if owners:
        best = (bank.ranking @ np.concatenate(rows).T).max(axis=0)
        for i, score in zip(owners, best.tolist(), strict=True):
            scores[i] = max(scores[i], score)
    return scores


def rank_for_model(scores: list[float], budget: int, last: Sequence[bool] = ()) -> tuple[list[int], list[int]]:
    """Which candidates are read by model: the ``budget`` best by :func:`ranking_score`, those
    marked ``last`` only after all others.

    Parameters
    ----------
    scores : list of float
        One per candidate that wants a reading by model, in the detector's order.
    budget : int
        Readings by model the frame has left.
    last : sequence of bool, optional
        Per candidate, whether it ranks after every unmarked one (:func:`around_blurred`);
        empty: none.

    Returns
    -------
    read : list of int
        Indices into ``scores`` to read, in the detector's order (so that an earlier
        outline's refused reading can rival a later one, as without a budget).
    left : list of int
        The others (not read by model: the frame's budget went to better-scoring candidates).
    """
    order = sorted(range(len(scores)), key=lambda i: (bool(last) and last[i], -scores[i]))
    chosen = set(order[: max(budget, 0)])
    return sorted(chosen), [i for i in range(len(scores)) if i not in chosen]


def around_blurred(quads: Sequence[Quad], blurred: Sequence[bool]) -> list[bool]:
    """Per candidate, whether it lies around a blurred candidate of the same pass
    (:attr:`~ottag_db.decode.blur.EdgeBlur.blurred`) as the outline of that data area's quiet
    zone: the blurred one's centre inside it, its area :data:`QUIET_OUTLINE_AREA` of this one's.
    Such an outline reads the same tag only through its blurred quiet zone and ranks after the
    data area itself (:func:`rank_for_model`).

    Parameters
    ----------
    quads : sequence of Quad
        The candidates that want a reading by model, in the detector's order.
    blurred : sequence of bool
        Per candidate, whether its sides measured blurred.

    Returns
    -------
    list of bool
    """
    inner = [q for q, b in zip(quads, blurred, strict=True) if b]
    inside = centres_inside(inner, quads)  # (inner, quads)
    out = []
    for j, quad in enumerate(quads):
        out.append(
            any(
                QUIET_OUTLINE_AREA[0] * quad.area <= q.area <= QUIET_OUTLINE_AREA[1] * quad.area and bool(inside[i, j])
                for i, q in enumerate(inner)
            )
        )
    return out
