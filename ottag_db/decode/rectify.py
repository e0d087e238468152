"""Rectified retry: a candidate read again in a fronto-parallel, upsampled view of its data area.

At grazing angles the triangles are slivers a pixel or two wide across the compressed axis of
the data area: the mask at the frame's scale merges or loses them, and their sides are fitted
from a handful of pixels. The four data-area corners give a homography ``R`` from the frame to
a square of ``size`` px (plus a padding band for the quiet zone's edge); warped through it
(cubic interpolation), the slivers are fat again. The same stages run on that view
(segmentation → triangles → refine → cluster), and every point hypothesis is mapped back
to the frame (points by ``R⁻¹``, side lines by ``Rᵀ``, which keeps every incidence exact)
before :func:`~ottag_db.decode.identify.identify` reads it *in frame pixels with the
frame's settings*: the margin, the lookup and the verification against the stored
realizations are exactly those of a direct reading. A projective map keeps the order type,
so nothing of the ID's invariance is given up; the rectified view only measures better.

The first view's ``R`` comes from the candidate's contour corners (whole pixels); the
data-area sides refined at sub-pixel precision in that view (:func:`~ottag_db.decode.refine.refine`
on its grey levels) give the corners, mapped back to the frame, of a second view when the first
does not read: the warp is only a resampling (any error of ``R`` is undone by ``R⁻¹``), but
the better the corners the more fronto-parallel, and the fatter, the slivers. The refined
corners become the detection's corners. The detector runs this stage for a foreshortened
candidate (tilted beyond about 60°) whose direct and 2× upsampled readings failed after the
quad was found (see :func:`wants_rectified`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.identify import Catalogue
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.profile import StageClock
from ottag_db.decode.quads import squeeze
from ottag_db.decode.reading import read_area, scaled_params
from ottag_db.decode.splitting import RECTIFIED_SEARCH
from ottag_db.decode.types import Detection, Quad, Rejection

__all__ = [
    "RECTIFY_MAX_PX",
    "RECTIFY_MIN_PX",
    "RECTIFY_MOVED_PX",
    "RECTIFY_PAD",
    "RECTIFY_PASSES",
    "RECTIFY_UPSAMPLE",
    "RectifiedView",
    "read_rectified",
    "rectified_view",
    "wants_rectified",
]

_F64 = NDArray[np.float64]

#: The rectified square's side is this many times the quad's longest side (px) …
RECTIFY_UPSAMPLE = 1.5
#: … kept within these bounds (px): small enough to bound the cost, large enough that a
#: sliver of the smallest candidates gets a few pixels across.
RECTIFY_MIN_PX = 160.0
RECTIFY_MAX_PX = 400.0
#: Padding around the square, as a fraction of its side: the quiet zone's edge must lie inside
#: the view for the data-area sides to be refined.
RECTIFY_PAD = 0.08
#: At most this many views: each pass after the first warps with the corners refined in the
#: previous view, when they moved by at least RECTIFY_MOVED_PX (frame px).
RECTIFY_PASSES = 2
RECTIFY_MOVED_PX = 0.3


def wants_rectified(quad: Quad, first: Rejection, retry_reasons: frozenset[str], params: DetectorParams) -> bool:
    """Whether a failed candidate is read again rectified.

    Only foreshortened quads are: a flatter view gains nothing the 2× upsampled retry does not
    give, and every retry of a non-tag quad (a marker, text) costs a warp and a segmentation.

    Parameters
    ----------
    quad : Quad
        The candidate.
    first : Rejection
        Its direct reading's rejection.
    retry_reasons : frozenset of str
        Reasons given after the quad was read (the detector's retry set); ``"no_triangles"``
        is retried too (slivers the mask at the frame's scale lost).
    params : DetectorParams
        ``rectify`` (False turns the stage off) and ``rectify_max_ratio``: only quads whose
        :func:`squeeze` is at most this are retried.

    Returns
    -------
    bool
    """
    return (
        params.rectify
        and (first.reason in retry_reasons or first.reason == "no_triangles")
        and squeeze(quad) <= params.rectify_max_ratio
    )


class RectifiedView:
    """A data area warped to a padded square: the view and the maps between it and the frame.

    Attributes
    ----------
    image : numpy.ndarray
        ``(n, n)`` uint8 view, ``n = size · (1 + 2 · pad)`` rounded.
    size : float
        Side of the data area in the view, px; its corners are at ``pad · size`` and
        ``(1 + pad) · size``.
    to_view : numpy.ndarray
        ``(3, 3)`` homography frame pixels → view pixels.
    to_frame : numpy.ndarray
        Its inverse.
    corners : numpy.ndarray
        ``(4, 2)`` the data-area corners in the view (the quad's order).
    """

    __slots__ = ("corners", "image", "size", "to_frame", "to_view")

    def __init__(self, image: NDArray[np.uint8], size: float, to_view: _F64, corners: _F64) -> None:
        self.image = image
        self.size = size
        self.to_view = to_view
        self.to_frame = np.linalg.inv(to_view)
        self.corners = corners

    def points_to_frame(self, pts: _F64) -> _F64:
        """``(m, 2)`` view points in frame pixels."""
        h = np.c_[pts, np.ones(len(pts))] @ self.to_frame.T
        out: _F64 = h[:, :2] / h[:, 2:3]
        return out

    def lines_to_frame(self, normal: _F64, offset: _F64) -> tuple[_F64, _F64]:
        """Lines ``n·x = c`` of the view as unit-normal lines of the frame (``lᵀ·to_view``)."""
        lh = np.c_[normal, -offset] @ self.to_view
        scale = np.maximum(np.hypot(lh[:, 0], lh[:, 1]), 1e-300)
        return lh[:, :2] / scale[:, None], -lh[:, 2] / scale


def rectified_view(gray: NDArray[np.uint8], corners: _F64) -> RectifiedView | None:
    """Warp the data area with corners ``corners`` into a padded, upsampled square.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    corners : numpy.ndarray
        ``(4, 2)`` data-area corners, frame pixels, clockwise on screen.

    Returns
    -------
    RectifiedView or None
        None when the corners do not give a homography (degenerate quad).
    """
    sides = np.hypot(*(np.roll(corners, -1, axis=0) - corners).T)
    size = float(np.clip(RECTIFY_UPSAMPLE * sides.max(), RECTIFY_MIN_PX, RECTIFY_MAX_PX))
    pad = RECTIFY_PAD * size
    dst = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64) * size + pad
    try:
        to_view = np.asarray(
            cv2.getPerspectiveTransform(corners.astype(np.float32), dst.astype(np.float32)), dtype=np.float64
        )
    except cv2.error:
        return None
    if not np.isfinite(to_view).all() or abs(np.linalg.det(to_view)) < 1e-12:
        return None
    n = round(size + 2 * pad)
    img = np.asarray(
        cv2.warpPerspective(gray, to_view, (n, n), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE),
        dtype=np.uint8,
    )
    return RectifiedView(img, size, to_view, dst)


def view_params(p: DetectorParams, f: float) -> DetectorParams:
    """The settings of the rectified view: lengths scaled by ``f`` (view px per frame px); the
    margin and the reprojection bound stay in frame pixels (points are identified there)."""
    return scaled_params(p, f, identification=False)


def read_rectified(
    gray: NDArray[np.uint8],
    quad: Quad,
    first: Rejection,
    catalogue: Catalogue,
    clock: StageClock,
) -> Detection | Rejection:
    """Read a candidate in the rectified view of its data area; identify in frame pixels.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    quad : Quad
        The candidate (frame pixels).
    first : Rejection
        The direct reading's rejection (returned when this one fails).
    catalogue : Catalogue
        The frame's lookup and settings: identification and verification are the direct
        path's, on the mapped-back points.
    clock : StageClock
        Charged per stage (the warp as ``"rectify"``).

    Returns
    -------
    Detection or Rejection
        The detection in frame pixels, or ``first``.
    """
    start = quad.corners
    for _ in range(RECTIFY_PASSES):
        view = rectified_view(gray, start)
        clock.lap("rectify")
        if view is None:
            return first
        result, refined = _read_view(view, quad, catalogue, clock, first.not_printed)
        if isinstance(result, Detection):
            return result
        # the corners refined in this view give a better homography for the next pass
        if refined is None or np.abs(refined - start).max() < RECTIFY_MOVED_PX:
            break
        start = refined
    return first


def _read_view(
    view: RectifiedView, quad: Quad, catalogue: Catalogue, clock: StageClock, print_required: frozenset[str]
) -> tuple[Detection | None, _F64 | None]:
    """The first reading of ``view`` that identifies in frame pixels (or None), and the data-area
    corners refined in the view, mapped to the frame (None when no decomposition was found).
    ``print_required``: the IDs earlier readings of the candidate refused as not printed."""
    vp = view_params(catalogue.params, view.size / math.sqrt(max(quad.area, 1.0)))
    vquad = Quad(quad.polarity, view.corners, view.size * view.size, quad.inferred)
    result, corners = read_area(
        view.image, vquad, vp, catalogue, RECTIFIED_SEARCH, clock, to_frame=view, frame_quad=quad,
        print_required=print_required,
    )  # fmt: skip
    return (result if isinstance(result, Detection) else None), corners
