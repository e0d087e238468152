"""The binarizations of the candidate stage: one dark mask per pass and its contour hierarchy.

This is the part of a candidate pass that is OpenCV's work alone (thresholds, the half-resolution
resize, the contour traces): a pure function of the frame and the settings, whose result, a
:class:`Binarized`, :func:`~ottag_db.decode.candidates.find_quads` outlines as quads in Python.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.image import DIM_SMOOTHING_PX, frame_departure, threshold_offset
from ottag_db.decode.outlines import holes_at_frame_edge
from ottag_db.decode.params import DetectorParams

__all__ = [
    "HALF_RES_MIN_SIDE",
    "LOCAL_PASSES",
    "Binarization",
    "Binarized",
    "binarize",
    "searches_at_half_resolution",
]

#: How a frame is binarized for the quad search: local mean, global Otsu or local range
#: threshold (see :func:`~ottag_db.decode.candidates.find_quads`).
Binarization = Literal["adaptive", "adaptive_dim", "otsu", "adaptive_thin", "bright_holes", "local_range"]

#: The half-resolution candidate search is used only while the smallest data area keeps at
#: least this side (px) there.
HALF_RES_MIN_SIDE = 6.0
#: The local passes that search the whole frame (at half resolution when it can): they also
#: outline holes cut by the frame's edge.
LOCAL_PASSES = ("adaptive", "adaptive_dim", "local_range")


@dataclass(frozen=True)
class Binarized:
    """One pass's dark mask and its contours (``cv2.RETR_CCOMP``, every point).

    Attributes
    ----------
    kind : Binarization
        The pass.
    mask : numpy.ndarray
        ``(h, w)`` uint8, 255 where dark (for ``"bright_holes"``: where bright), at ``1 / scale``
        of the frame's resolution.
    contours : tuple of numpy.ndarray
        The mask's contours, ``(n, 1, 2)`` int32 each (mask pixels).
    hierarchy : numpy.ndarray or None
        ``(len(contours), 4)`` int32, OpenCV's ``[next, previous, first child, parent]``; None
        when the mask holds no contour.
    scale : int
        Frame pixels per mask pixel (1, or 2 for a search at half resolution).
    min_len : float
        The fewest contour points a candidate's outline has (its sides ``min_quad_side_px``).
    edge_holes : tuple of numpy.ndarray
        For the local passes (with inverted tags and ``outline_by_lines``): the bright regions
        that reach the frame's edge (:func:`~ottag_db.decode.outlines.holes_at_frame_edge`).
    """

    kind: Binarization
    mask: NDArray[np.uint8]
    contours: tuple[NDArray[Any], ...]
    hierarchy: NDArray[np.int32] | None
    scale: int
    min_len: float
    edge_holes: tuple[NDArray[Any], ...]


def binarize(
    gray: NDArray[np.uint8], kind: Binarization, params: DetectorParams, departure: float | None = None
) -> Binarized | None:
    """The dark mask of one candidate pass and its contours (the passes are described at
    :func:`~ottag_db.decode.candidates.find_quads`).

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    kind : Binarization
        The pass.
    params : DetectorParams
        The binarization, polarity and size settings.
    departure : float, optional
        The frame's largest departure (:func:`~ottag_db.decode.image.frame_departure`; measured
        here for the passes that need it when not given).

    Returns
    -------
    Binarized or None
        None for Otsu's pass on a frame that departs nowhere by ``min_contrast`` from its
        surroundings (see :func:`~ottag_db.decode.image.frame_has_contrast`): it has no quads.
    """
    p = params
    h, w = gray.shape
    # The automatic local threshold searches the image at half resolution (a quarter of the
    # pixels to threshold and trace) when even the smallest data area keeps sides of
    # ``HALF_RES_MIN_SIDE`` px there.
    f = 1
    block = p.adaptive_block or max(15, (min(h, w) // 16) | 1)  # local mean window (px)
    if departure is None and kind in ("adaptive_dim", "otsu"):
        departure = frame_departure(gray)
    offset = p.adaptive_c if departure is None or kind != "adaptive_dim" else threshold_offset(departure, p.adaptive_c)
    if kind == "otsu":
        if departure is not None and departure < p.min_contrast:  # (see image.frame_has_contrast)
            return None  # (the mask below keeps OpenCV's threshold of the whole frame)
        _, mask = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
    elif kind == "bright_holes":
        mask = cv2.adaptiveThreshold(gray, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY, block, -p.adaptive_c)
    else:
        src: NDArray[Any] = gray
        if kind in LOCAL_PASSES and searches_at_half_resolution(gray.shape, p):
            f = 2
            src = cv2.resize(gray, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
            block = max(7, (block // 2) | 1)
        if kind == "adaptive_dim":  # a dim frame: its sensor noise nears the lowered offset
            src = cv2.GaussianBlur(src, (0, 0), DIM_SMOOTHING_PX)
        if kind == "local_range":
            mask = _range_mask(src, block, p.min_contrast)
        else:
            mask = cv2.adaptiveThreshold(src, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block, offset)
    min_len = 4 * p.min_quad_side_px / f
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    edge_holes: Sequence[NDArray[Any]] = ()
    if kind in LOCAL_PASSES and "inverted" in p.polarities and p.outline_by_lines:
        edge_holes = holes_at_frame_edge(mask, min_len)
    return Binarized(
        kind, np.asarray(mask), tuple(contours), None if hier is None else hier[0], f, min_len, tuple(edge_holes)
    )


def searches_at_half_resolution(shape: tuple[int, ...], params: DetectorParams) -> bool:
    """Whether the ``"adaptive"`` pass runs at half resolution: with the automatic window, on
    frames of at least 240 px, while the smallest data area keeps sides of
    ``HALF_RES_MIN_SIDE`` px there.

    Parameters
    ----------
    shape : tuple of int
        ``(H, W)`` of the frame.
    params : DetectorParams
        ``adaptive_block`` and ``min_quad_side_px``.

    Returns
    -------
    bool
    """
    return not params.adaptive_block and min(shape[:2]) >= 240 and params.min_quad_side_px >= 2 * HALF_RES_MIN_SIDE


def _range_mask(src: NDArray[Any], block: int, min_range: float) -> NDArray[Any]:
    """The dark mask of AprilTag's threshold: a pixel below the midpoint of the darkest and
    brightest pixel of the ``block`` × ``block`` window about it, where the two differ by
    ``min_range`` grey levels or more (erosion and dilation by the window, in OpenCV)."""
    window = cv2.getStructuringElement(cv2.MORPH_RECT, (block, block))
    darkest, brightest = cv2.erode(src, window), cv2.dilate(src, window)
    midpoint = cv2.addWeighted(darkest, 0.5, brightest, 0.5, 0)
    # (over min_range − 0.5: the range's whole grey levels from min_range on)
    _, contrasted = cv2.threshold(cv2.subtract(brightest, darkest), min_range - 0.5, 255, cv2.THRESH_BINARY)
    return np.asarray(cv2.bitwise_and(cv2.compare(src, midpoint, cv2.CMP_LT), contrasted))
