"""Alignment stage of reading by model: a stored tag aligned to the frame by ECC and judged
against the frame as a camera would see it (:mod:`~ottag_db.decode.model_match` decides).

A tag is aligned from a view of the candidate (data-area corners in tag order, polarity) with a
refinement template of its data area and a band of its quiet zone (:func:`fine_template`,
:func:`ecc`); :func:`judge` then draws the tag into the frame through a homography, blurs it
like a camera image and samples it back like the frame, and scores correlation, local misfit
and the quiet band (:class:`Aligned`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.types import QUIET_ZONE, Polarity
from ottag_db.decode.blur import BLURRED_MAX_MISFIT, BLURRED_MAX_MISFIT_NOISY, NOMINAL_BLURS_PX
from ottag_db.decode.camera_blur import Blur, FrameCamera, refined_blur
from ottag_db.decode.ecc import ecc, to_roi
from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography
from ottag_db.decode.templates import (
    TemplateBank,
    contrast_fit,
    contrast_residual,
    draw_through,
    normalized_rows,
    rasterize,
)

__all__ = [
    "INVERTED_QUIET",
    "Aligned",
    "View",
    "align",
    "align_outline",
    "ecc",
    "fine_template",
    "judge",
    "neighbourhood",
    "outline_views",
    "to_roi",
]

_F64 = NDArray[np.float64]
_F32 = NDArray[np.float32]

#: Side of the refinement templates, px, and the quiet-zone band they include (data-area
#: units on each side; within the 0.25 quiet zone ``export`` prints).
_FINE_GRID = 48
_FINE_BAND = 0.12
#: The refinement template's cells inside the data area (a cell's width off its edge).
_FINE_INSIDE = slice(
    math.ceil(_FINE_BAND / (1 + 2 * _FINE_BAND) * _FINE_GRID) + 1,
    math.floor((1 + _FINE_BAND) / (1 + 2 * _FINE_BAND) * _FINE_GRID) - 1,
)
#: Refinement-template pixels (centres) → data-area units.
_FINE_STEP = (1 + 2 * _FINE_BAND) / _FINE_GRID
_FINE_PX_TO_UNIT = np.array(
    [[_FINE_STEP, 0, -_FINE_BAND + _FINE_STEP / 2], [0, _FINE_STEP, -_FINE_BAND + _FINE_STEP / 2], [0, 0, 1.0]]
)
#: The refinement template's cells of the quiet band (the outer 3 of its 4.6 on each side).
_FINE_BAND_CELLS = np.ones((_FINE_GRID, _FINE_GRID), dtype=bool)
_FINE_BAND_CELLS[3:-3, 3:-3] = False
#: The quiet zone assumed when a dark quad is read as an inverted tag's quiet zone (data-area
#: units, :data:`~ottag_db.core.types.QUIET_ZONE`; ECC corrects a mismatch).
INVERTED_QUIET = QUIET_ZONE
#: The outline template (:func:`align_outline`): the printed quiet zone all round
#: (:data:`INVERTED_QUIET` wide) and a rim of the data area inside the points' inner margin
#: (:data:`~ottag_db.core.placement.DEFAULT_INNER_MARGIN`, 0.10), where no triangle is printed;
#: the rest of the data area, where the triangles lie, is masked out of the alignment.
_OUTLINE_BAND = INVERTED_QUIET
_OUTLINE_RIM = 0.09
_OUTLINE_STEP = (1 + 2 * _OUTLINE_BAND) / _FINE_GRID
_OUTLINE_PX_TO_UNIT = np.array(
    [
        [_OUTLINE_STEP, 0, -_OUTLINE_BAND + _OUTLINE_STEP / 2],
        [0, _OUTLINE_STEP, -_OUTLINE_BAND + _OUTLINE_STEP / 2],
        [0, 0, 1.0],
    ]
)
_OUTLINE_UNITS = -_OUTLINE_BAND + _OUTLINE_STEP * (np.arange(_FINE_GRID) + 0.5)  # cell centres
_OUTLINE_CORE = (_OUTLINE_UNITS > _OUTLINE_RIM) & (_OUTLINE_UNITS < 1 - _OUTLINE_RIM)
_OUTLINE_MASK = np.full((_FINE_GRID, _FINE_GRID), 255, dtype=np.uint8)
_OUTLINE_MASK[np.ix_(_OUTLINE_CORE, _OUTLINE_CORE)] = 0
_OUTLINE_MASK.flags.writeable = False
#: The refinement template's cells of the outline (the quiet band and the data area's rim
#: inside :data:`_OUTLINE_RIM`, where no triangle is printed): the same for every tag.
_FINE_UNITS = -_FINE_BAND + _FINE_STEP * (np.arange(_FINE_GRID) + 0.5)  # cell centres
_FINE_RIM = (_FINE_UNITS < _OUTLINE_RIM) | (_FINE_UNITS > 1 - _OUTLINE_RIM)
_FINE_OUTLINE = _FINE_RIM[:, None] | _FINE_RIM[None, :]
_FINE_OUTLINE.flags.writeable = False
#: Side of the window (refinement-template cells, 1/10 of the data area) over which the
#: aligned tag's local misfit is averaged (see :class:`Aligned`).
_MISFIT_WINDOW = 4
#: The Gaussian (σ, in refinement-template cells) that averages the frame and the drawn tag
#: about each cell before a blurred candidate's misfit and correlation with its measured blur
#: are taken (:func:`judge`): a cell sampled bilinearly takes the noise of about one pixel, and
#: in a dim frame (contrast a quarter, noise σ 6) a tag defocused by 2.5 px, drawn with its
#: true blur, misfit by 0.09–0.14 of its contrast that way — over
#: :data:`~ottag_db.decode.blur.BLURRED_MAX_MISFIT`, where the same frame without the noise
#: leaves 0.02–0.04 — and by 0.05–0.08 averaged so; a triangle that differs is several cells
#: wide and keeps its patch.
_CELL_AVERAGE = 0.5
#: The standard deviation of the mean, over a misfit window (:data:`_MISFIT_WINDOW` cells of
#: 1 px, each averaged by :data:`_CELL_AVERAGE`), of white noise of σ 1: the Gaussians' sum of
#: the noise's correlations between the window's cells (divide by the cell's side in px).
_WINDOW_NOISE_GAIN = float(
    np.exp(
        -(np.subtract.outer(np.arange(_MISFIT_WINDOW), np.arange(_MISFIT_WINDOW)) ** 2) / (4 * _CELL_AVERAGE**2)
    ).sum()
    / _MISFIT_WINDOW**2
    / math.sqrt(4 * math.pi * _CELL_AVERAGE**2)
)
#: How many of those standard deviations the largest window mean of the noise alone reaches
#: over a data area (:attr:`Aligned.misfit_noise`): simulated on the 39² cells inside it, the
#: largest absolute mean of the sliding windows lies 3.7 standard deviations out in the median
#: (4.6 in the 95th percentile).
_NOISE_WINDOWS_SD = 3.7
#: The quiet zone drawn around the tag when it is judged (data-area units, :data:`INVERTED_QUIET`).
_DRAWN_QUIET = INVERTED_QUIET
#: An alignment whose ECC first phase stayed unpromising (:data:`~ottag_db.decode.ecc.PROMISING_CORRELATION`)
#: is refined on only when the tag judged there correlates this well (or better) with the
#: frame. A reading needs ``model_min_correlation`` (0.92) and a lead of ``model_min_gap`` (0.08)
#: over every rival, so a rival under 0.84 never refuses it; 0.05 below that covers what the
#: rest of ECC's steps could still add (the ECC correlation moves by under 0.02 after the first
#: phase). Others count as not aligned: by their coarse score, like an alignment ECC lost.
_UNREFINED_MAX_CORRELATION = 0.79


@dataclass(frozen=True)
class View:
    """One interpretation of a candidate: data-area corners in tag order and the polarity."""

    corners: _F64
    polarity: Polarity


@dataclass(frozen=True)
class Aligned:
    """A refined candidate: template row, view, homography data-area units → frame, the
    correlation of the aligned tag with the frame inside the data area, and its largest local
    misfit there. Both compare the frame with the tag as the camera would see it: drawn into
    the frame through the aligned homography, blurred and sampled back like the frame. The
    correlation takes the first of :data:`~ottag_db.decode.blur.NOMINAL_BLURS_PX`. The misfit is the mean absolute
    residual of the frame against the view with the blur that fits the outline best (the quiet
    band and the data area's rim, :data:`_FINE_OUTLINE`: the frame's own blur, measured where
    every tag looks the same, so that it cannot favour one tag), scaled to the frame's contrast
    by least squares, over a window of ``_MISFIT_WINDOW`` cells, in units of that contrast: a
    tag that resembles the one seen fits well overall but leaves a patch where a triangle
    differs. The quiet misfit is the mean absolute residual over the quiet band around the
    data area, with the scale and offset fitted inside it: the band must be as bright or dark
    as the reading's polarity prints it. ``blurred_correlation``: the correlation with the blur
    measured on a blurred candidate (:func:`fit_blur`; each cell averaged over the pixels about
    it, :data:`_CELL_AVERAGE`, as for its misfit) when it is judged with it, else
    ``correlation``; it must reach the minimum correlation, while
    the gap to the other tags is judged on ``correlation``. ``misfit_noise``: with a measured
    blur, the misfit the frame's sensor noise (:func:`~ottag_db.decode.camera_blur.sensor_noise`)
    alone would leave on a tag that fits exactly (:data:`_NOISE_WINDOWS_SD`), else 0."""

    row: int
    view: View
    to_frame: _F64
    correlation: float
    misfit: float
    quiet_misfit: float
    blurred_correlation: float
    misfit_noise: float = 0.0

    @property
    def blurred_misfit_limit(self) -> float:
        """The largest misfit of a tag read with its measured blur: :data:`~ottag_db.decode.blur.BLURRED_MAX_MISFIT`
        and :attr:`misfit_noise` added in quadrature (the drawing's own error and the noise are
        independent, and their largest windows seldom coincide), at most
        :data:`~ottag_db.decode.blur.BLURRED_MAX_MISFIT_NOISY`."""
        return min(math.hypot(BLURRED_MAX_MISFIT, self.misfit_noise), BLURRED_MAX_MISFIT_NOISY)


def _quiet_ring(b: float) -> _F32:
    """A band ``b`` wide around the data area (1) and the data area (0), on the template grid
    covering ``[-b, 1 + b]²``."""
    ring = np.array(
        [
            [[-b, -b], [1 + b, -b], [1 + b, 0], [-b, 0]],
            [[-b, 1], [1 + b, 1], [1 + b, 1 + b], [-b, 1 + b]],
            [[-b, 0], [0, 0], [0, 1], [-b, 1]],
            [[1, 0], [1 + b, 0], [1 + b, 1], [1, 1]],
        ]
    )
    out: _F32 = rasterize(ring[None], -b, 1 + b, _FINE_GRID)[0]
    return out


#: The refinement templates' band of quiet zone (constant: built once at import).
_FINE_RING = _quiet_ring(_FINE_BAND)


def fine_template(triangles: _F64, polarity: Polarity) -> _F32:
    """The refinement template: data area with its triangles and a band of quiet zone, 0 … 1,
    bright where the print is bright."""
    b = _FINE_BAND
    img = _FINE_RING.copy()
    if len(triangles):
        img += rasterize(triangles[None], -b, 1 + b, _FINE_GRID)[0]
    out: _F32 = img if polarity == "normal" else 1.0 - img
    return out


def neighbourhood(gray: NDArray[np.uint8], corners: list[_F64]) -> tuple[_F32, _F64]:
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


#: The outline templates of :func:`align_outline` and the blank tags it aligns a data area read
#: inside a quad of the other polarity to, per polarity (constant: built once at import).
_OUTLINE_TEMPLATES: dict[Polarity, _F32] = {
    "normal": _quiet_ring(_OUTLINE_BAND),
    "inverted": np.float32(1.0) - _quiet_ring(_OUTLINE_BAND),
}
_BLANK_TEMPLATES: dict[Polarity, _F32] = {
    "normal": fine_template(np.zeros((0, 3, 2)), "normal"),
    "inverted": fine_template(np.zeros((0, 3, 2)), "inverted"),
}


def align_outline(
    roi: _F32, origin: _F64, polarity: Polarity, corners: _F64, inside: bool = False, converge: bool = False
) -> _F64 | None:
    """The data area's outline aligned by ECC, whatever tag it holds.

    The template is the printed quiet zone around a rim of the data area inside the points'
    inner margin, the rest of the data area masked out (its triangles are not known yet). At a
    grazing view the contour's whole-pixel corners miss the data area by a large part of its
    short side (6.6 % of the data area, median, on benchmarks/decode_polarity.py scenes at
    84–87°). A blank template of the whole data area made that worse (7.9 %: the triangles it
    does not show pull the alignment); this one gives 4.0 % for normal tags and 1.5 % for
    inverted ones, whose dark quiet zone stands out from a light background.

    A data area read *inside* a quad of the other polarity (a dark quad as the quiet zone of an
    inverted tag whose white data area was not found as a quad) is aligned to the blank tag
    instead: the whole data area bright inside a band of dark quiet zone. The masked outline
    fits a dark area with a bright rim anywhere, also inside a normal tag's dark data area: a
    normal tag at 84° whose order type the lookup lacked was read as an inverted look-alike
    (ρ 0.95) from there; with the blank tag that reading stays at ρ 0.89.

    Parameters
    ----------
    roi : numpy.ndarray
        float32 frame around the candidate (see :func:`neighbourhood`).
    origin : numpy.ndarray
        Frame position ``(x, y)`` of ``roi`` pixel (0, 0).
    polarity : {"normal", "inverted"}
        Normal: bright quiet zone, dark data area; inverted the other way round.
    corners : numpy.ndarray
        ``(4, 2)`` start corners of the data area, frame pixels, in tag order.
    inside : bool, optional
        The data area is read inside a quad of the other polarity (blank template).
    converge : bool, optional
        Refine an unpromising alignment to convergence too (a candidate whose sides measured
        blurred: see :func:`align`).

    Returns
    -------
    numpy.ndarray or None
        ``(3, 3)`` homography data-area units → frame pixels, or None when ECC fails.
    """
    if inside:
        template, px_to_unit, mask = _BLANK_TEMPLATES[polarity], _FINE_PX_TO_UNIT, None
    else:
        template, px_to_unit, mask = _OUTLINE_TEMPLATES[polarity], _OUTLINE_PX_TO_UNIT, _OUTLINE_MASK
    # an unpromising alignment (see ottag_db.decode.ecc) is used where its first phase left it:
    # its correlation has settled, and the outline only starts the tags' own alignments
    found = ecc(roi, origin, template, corners, px_to_unit, mask)
    if found is not None and converge and not found.converged:
        found = ecc(roi, origin, template, corners, px_to_unit, mask, resume=found)
    return None if found is None else found.to_frame


def outline_views(
    roi: _F32, origin: _F64, views: list[View], side: float, quad_polarity: Polarity, converge: bool = False
) -> list[View]:
    """The candidate's views again, with corners aligned to a tag's outline.

    At a grazing view the contour's whole-pixel corners are off by a large part of the data
    area's short side, and the coarse match then ranks the tag seen below look-alikes.

    Parameters
    ----------
    roi, origin : numpy.ndarray
        The frame around the candidate and the frame position of its pixel (0, 0)
        (:func:`neighbourhood`).
    views : list of View
        The candidate's views; the first of each polarity is aligned (:func:`align_outline`,
        a view of the other polarity than the quad's as read inside it).
    side : float
        The data area's side (√area, px): an alignment that moved a corner farther than a
        quarter of it (+ 3 px) wandered off the quad and is dropped.
    quad_polarity : {"normal", "inverted"}
        The candidate quad's polarity.
    converge : bool, optional
        As in :func:`align_outline`.

    Returns
    -------
    list of View
        The four turns of each aligned view.
    """
    out: list[View] = []
    for polarity in ("normal", "inverted"):
        first = next((v for v in views if v.polarity == polarity), None)
        if first is None:
            continue
        to_frame = align_outline(roi, origin, polarity, first.corners, polarity != quad_polarity, converge)
        if to_frame is None:
            continue
        corners = apply_homography(to_frame, UNIT_SQUARE)
        # an alignment that wandered off the quad is no better start
        if not np.isfinite(corners).all() or np.abs(corners - first.corners).max() > 0.25 * side + 3:
            continue
        out += [View(np.roll(corners, -r, axis=0), polarity) for r in range(4)]
    return out


def align(
    roi: _F32,
    origin: _F64,
    bank: TemplateBank,
    row: int,
    view: View,
    camera: FrameCamera | None = None,
    converge: bool = False,
) -> Aligned | None:
    """ECC alignment of template ``row`` to the frame from the view's corners
    (:func:`~ottag_db.decode.ecc.ecc`), judged against the tag as the camera would see it there
    (``camera``: see :func:`judge`); None when ECC fails, or when its first phase stayed
    unpromising and the tag judged there correlates under :data:`_UNREFINED_MAX_CORRELATION`
    (unless ``converge``: a candidate whose sides measured blurred, judged again with its blur
    later, whose sharp template correlates low with it until ECC has run its course)."""
    template = fine_template(bank.triangles[row], view.polarity)
    found = ecc(roi, origin, template, view.corners, _FINE_PX_TO_UNIT)
    if found is not None and not found.converged:
        judged = judge(roi, origin, bank, row, view, found.to_frame, camera)
        if not converge and max(judged.correlation, judged.blurred_correlation) < _UNREFINED_MAX_CORRELATION:
            return None  # can neither be read nor rival a reading: counted as not aligned
        found = ecc(roi, origin, template, view.corners, _FINE_PX_TO_UNIT, resume=found)
    if found is None:
        return None
    return judge(roi, origin, bank, row, view, found.to_frame, camera)


def _drawn(roi: _F32, origin: _F64, bank: TemplateBank, row: int, view: View, to_frame: _F64) -> _F32:
    """Template ``row`` drawn into the frame's ``roi`` through ``to_frame`` (unblurred; the
    data area's tones in ``[0, 1]``, triangles bright in a normal view)."""
    drawn = draw_through(bank.triangles[row], _DRAWN_QUIET, to_roi(origin) @ to_frame, (roi.shape[0], roi.shape[1]))
    return np.float32(1.0) - drawn if view.polarity == "inverted" else drawn


def fit_blur(roi: _F32, origin: _F64, bank: TemplateBank, aligned: Aligned, blurs: tuple[Blur, ...]) -> Blur | None:
    """The blur under which the aligned tag fits its whole view best (the quiet band, the rim
    and the triangles: a motion's direction is known from the sides only up to its mirror
    image, and only the triangles' smear tells the two apart): the best of ``blurs``, refined
    (:func:`~ottag_db.decode.camera_blur.refined_blur`).

    Parameters
    ----------
    roi, origin : numpy.ndarray
        The frame around the candidate and the frame position of its pixel (0, 0).
    bank : TemplateBank
        The printed tags.
    aligned : Aligned
        The tag that best explains the candidate with the nominal blurs.
    blurs : tuple of Blur
        The candidate's measured blurs (:func:`~ottag_db.decode.camera_blur.measured_blurs`).

    Returns
    -------
    Blur or None
        None when ``blurs`` is empty.
    """
    if not blurs:
        return None
    warp = to_roi(origin) @ aligned.to_frame @ _FINE_PX_TO_UNIT
    size = (_FINE_GRID, _FINE_GRID)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    seen = np.asarray(cv2.warpPerspective(roi, warp, size, flags=flags, borderMode=cv2.BORDER_REPLICATE), np.float32)
    drawn = _drawn(roi, origin, bank, aligned.row, aligned.view, aligned.to_frame)

    def residual(kind: Blur) -> float:
        # in the view's own grey levels, the same for every blur tried: in units of each
        # drawing's fitted scale, a blurrier drawing (of less variance, so fitted with a larger
        # scale) divides the sensor noise's share of the residual by more, and the fit drifted
        # to blurs a fifth too large in a dim frame (contrast a quarter, noise σ 6), where the
        # tag seen then misfit its drawing by half as much again
        view = np.asarray(
            cv2.warpPerspective(kind.apply(drawn), warp, size, flags=flags, borderMode=cv2.BORDER_REPLICATE), np.float32
        ).ravel()
        scale, offset = contrast_fit(view, seen.ravel())
        return float(np.abs(seen.ravel() - (scale * view + offset)).mean())

    return refined_blur(residual, blurs)


def judge(
    roi: _F32,
    origin: _F64,
    bank: TemplateBank,
    row: int,
    view: View,
    to_frame: _F64,
    camera: FrameCamera | None = None,
) -> Aligned:
    """Template ``row`` judged against the frame under the homography ``to_frame`` (data-area
    units → frame), as the camera would see it there (see :class:`Aligned`); ``camera``: the
    blur a blurred candidate's sides and best tag measure (:func:`fit_blur`), which the misfits
    and ``blurred_correlation`` then take, for every tag alike, and the noise around it, which
    gives ``misfit_noise``."""
    warp = to_roi(origin) @ to_frame @ _FINE_PX_TO_UNIT
    size = (_FINE_GRID, _FINE_GRID)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    seen = np.asarray(cv2.warpPerspective(roi, warp, size, flags=flags, borderMode=cv2.BORDER_REPLICATE), np.float32)
    # The tag drawn into the frame through the aligned homography and blurred like a camera
    # image, then sampled back like the frame: at a grazing view each pixel averages a long
    # strip of the data area, which a template blurred in data-area units does not model (the
    # correct tag's sliver tips then misfit like a different tag's triangle).
    drawn = _drawn(roi, origin, bank, row, view, to_frame)
    kinds = [Blur(sigma) for sigma in NOMINAL_BLURS_PX] + ([] if camera is None else [camera.blur])
    applied = [kind.apply(drawn) for kind in kinds]
    blurred = [
        np.asarray(cv2.warpPerspective(im, warp, size, flags=flags, borderMode=cv2.BORDER_REPLICATE), dtype=np.float32)
        for im in applied
    ]
    # judged inside the data area only: the quiet band that anchors the alignment looks the
    # same for every tag and would lift every candidate's score alike
    inside = _FINE_INSIDE
    s_in = seen[inside, inside]
    # The misfits with the frame's own blur: against the nominal blur the correct tag's sliver
    # edges in a blurrier frame misfit like a look-alike's triangle (at 84°, 0.29-0.31 over the
    # limit of 0.28: normal tags 3 points behind inverted ones, benchmarks/decode_sweeps.py)
    s_outline = seen[_FINE_OUTLINE]
    expected = min(blurred, key=lambda e: contrast_residual(e[_FINE_OUTLINE], s_outline))
    if camera is not None:  # the blur measured on the candidate, for every tag alike
        expected = blurred[-1]
    pair = normalized_rows(np.stack([blurred[0][inside, inside].ravel(), s_in.ravel()]))
    # on a blurred candidate also with the blur that fits its outline: a tag blurred by 3.5 px
    # correlates 0.89 with its nominal drawing (its look-alikes 0.4-0.8), 1.00 with its blurred
    # one (and the look-alikes 0.97-0.98: blur compresses the gaps, which the nominal one keeps)
    fitted = pair[0] @ pair[1]
    e_in = expected[inside, inside]
    coef = contrast_fit(e_in.ravel(), s_in.ravel())
    resid = s_in - (coef[0] * e_in + coef[1])
    noise = 0.0
    if camera is None:
        resid = np.abs(resid)
    else:
        # each cell the mean of the frame's pixels about it (and of the tag's): the correlation
        # with the measured blur and the misfit (:data:`_CELL_AVERAGE`)
        area = abs(float(cv2.contourArea(apply_homography(to_frame, UNIT_SQUARE).astype(np.float32))))
        sigma = _CELL_AVERAGE * _FINE_STEP * math.sqrt(area)
        s_av, e_av = (
            np.asarray(
                cv2.warpPerspective(
                    cv2.GaussianBlur(im, (0, 0), sigma), warp, size, flags=flags, borderMode=cv2.BORDER_REPLICATE
                ),
                dtype=np.float32,
            )[inside, inside]
            for im in (roi, applied[-1])
        )
        both = normalized_rows(np.stack([e_av.ravel(), s_av.ravel()]))
        fitted = both[0] @ both[1]
        resid = s_av - (coef[0] * e_av + coef[1])
        noise = _NOISE_WINDOWS_SD * _WINDOW_NOISE_GAIN * camera.noise / (_FINE_STEP * math.sqrt(area))
    # with a measured blur, the signed residual is averaged: a differing triangle leaves a patch
    # of one sign, while the sensor noise of a dim, blurred frame averages out (its absolute
    # value alone filled a quarter of the strict limit, blur.BLURRED_MAX_MISFIT)
    local = np.abs(cv2.boxFilter(resid, -1, (_MISFIT_WINDOW, _MISFIT_WINDOW), borderType=cv2.BORDER_REPLICATE))
    misfit = float(local.max() / max(abs(float(coef[0])), 1e-6))
    # the quiet band under the same scale and offset: as bright (normal) or dark (inverted) as
    # the print, where the data area alone can pass for the other polarity's
    band = _FINE_BAND_CELLS
    quiet = np.abs(seen[band] - (coef[0] * expected[band] + coef[1]))
    quiet_misfit = float(quiet.mean() / max(abs(float(coef[0])), 1e-6))
    contrast = max(abs(float(coef[0])), 1e-6)
    return Aligned(row, view, to_frame, float(pair[0] @ pair[1]), misfit, quiet_misfit, float(fitted), noise / contrast)
