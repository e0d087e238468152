"""ECC alignment of a template to the frame around a candidate, in two phases.

OpenCV's ECC (``cv2.findTransformECC``) refines a homography by Gauss-Newton steps until its
correlation changes by less than ``1e-5`` or 60 steps have run. Its correlation settles within
the first few steps: on 978 alignments of reading by model (tags 16–160 px wide, tilted to
86°, sharp and defocused to σ 3.5 px, both polarities) the correlation after :data:`FIRST_STEPS`
steps was within 0.02 of the final one for every alignment that ended at 0.75 or more, and no
alignment under 0.75 after them ended above 0.76. An alignment that has not settled by then
keeps stepping without converging, and on frames without a tag nearly every alignment does:
on scikit-image's photographs 99 % of them stay under 0.75 and cost about 3× the steps of a
converging one. So the first phase runs :data:`FIRST_STEPS` steps; an alignment that reaches
:data:`PROMISING_CORRELATION` goes on to convergence as before, and the caller decides what
the others are worth (:func:`~ottag_db.decode.model_align.align` judges them where they are,
and refines every alignment of a candidate whose sides measured blurred to convergence: the
template is sharp, a blurred tag's alignments correlate low with it until they are judged with
the measured blur, and stopping them lost 6 of 101 inverted tags moved by 17 px in
``benchmarks/decode_degraded.py``'s frames).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography, data_area_depths, square_homography

__all__ = ["FIRST_STEPS", "PROMISING_CORRELATION", "EccResult", "ecc", "to_roi"]

_F64 = NDArray[np.float64]
_F32 = NDArray[np.float32]

#: ECC steps of the first phase. The correlation of an alignment that ends at 0.75 or more is
#: within 0.02 of its final value after 8 steps (see the module docstring); 8 steps cost about
#: a third of a non-converging alignment's 60.
FIRST_STEPS = 8
#: The ECC correlation after :data:`FIRST_STEPS` steps from which an alignment is refined to
#: convergence. A tag read by model is aligned to ECC correlation 0.88 or more (its judged
#: correlation must reach ``DetectorParams.model_min_correlation``, 0.92, and the judged one
#: exceeds ECC's, which compares with an unblurred template); every such alignment, and every
#: one that ended at 0.76 or more, was at 0.75 or more after the first phase.
PROMISING_CORRELATION = 0.75
_SMOOTHING = 1  # ECC's Gaussian kernel (1: none)
#: Steps until convergence (correlation change under 1e-5), at most 60 in all.
_MAX_STEPS = 60
_EPS = 1e-5
#: The factor by which an ECC alignment may change the data area's area from its starting
#: view's: the starting corners (a contour's, or an outline's fit) are within a few pixels of
#: the tag's, which changes the area by well under 2× even at grazing views.
_MAX_AREA_CHANGE = 3.0


@dataclass(frozen=True)
class EccResult:
    """An ECC alignment: data-area units → frame, template pixels → ``roi``, ECC's correlation,
    and whether it ran to convergence (False: stopped after the first phase, unpromising)."""

    to_frame: _F64
    warp: _F64
    correlation: float
    converged: bool


def to_roi(origin: _F64) -> _F64:
    """The translation from frame pixels to those of a neighbourhood whose pixel (0, 0) lies at
    frame position ``origin`` (see :func:`~ottag_db.decode.model_align.neighbourhood`).

    Parameters
    ----------
    origin : numpy.ndarray
        Frame position ``(x, y)`` of the neighbourhood's pixel (0, 0).

    Returns
    -------
    numpy.ndarray
        ``(3, 3)`` homography.
    """
    return np.array([[1.0, 0, -origin[0]], [0, 1.0, -origin[1]], [0, 0, 1.0]])


def _run(
    template: _F32, roi: _F32, warp: NDArray[np.float32], steps: int, mask: NDArray[np.uint8] | None
) -> tuple[float, NDArray[np.float32]] | None:
    """ECC for at most ``steps`` steps from ``warp``; None when it fails."""
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, steps, _EPS)
    try:
        if mask is None:
            # no mask (the stubs do not list a None mask)
            rho, out = cv2.findTransformECC(  # type: ignore[call-overload, unused-ignore]
                template, roi, warp.copy(), cv2.MOTION_HOMOGRAPHY, criteria, None, _SMOOTHING
            )
        else:
            every = np.full(roi.shape, 255, dtype=np.uint8)  # every frame pixel is valid
            rho, out = cv2.findTransformECCWithMask(
                template, roi, mask, every, warp.copy(), cv2.MOTION_HOMOGRAPHY, criteria, _SMOOTHING
            )
    except cv2.error:
        return None  # ECC did not converge (or the warp became singular)
    return float(rho), np.asarray(out, dtype=np.float32)


def ecc(
    roi: _F32,
    origin: _F64,
    template: _F32,
    corners: _F64,
    px_to_unit: _F64,
    template_mask: NDArray[np.uint8] | None = None,
    resume: EccResult | None = None,
) -> EccResult | None:
    """ECC alignment of a template to the frame from the data-area ``corners``.

    Parameters
    ----------
    roi : numpy.ndarray
        float32 frame around the quad; its pixel (0, 0) lies at frame position ``origin``.
    origin : numpy.ndarray
        ``(2,)`` frame position of ``roi``'s pixel (0, 0).
    template : numpy.ndarray
        float32 template.
    corners : numpy.ndarray
        ``(4, 2)`` start corners of the data area, frame pixels, in tag order.
    px_to_unit : numpy.ndarray
        ``(3, 3)`` map of template pixels to data-area units.
    template_mask : numpy.ndarray or None, optional
        Non-zero: template pixels used.
    resume : EccResult or None, optional
        An unpromising first phase of this alignment to refine to convergence.

    Returns
    -------
    EccResult or None
        None when ECC fails, the map sends part of the data area behind the camera, or the
        data area's area changes more than :data:`_MAX_AREA_CHANGE` times.
    """
    start = square_homography(corners)
    if start is None or roi.shape[0] < 4 or roi.shape[1] < 4:
        return None
    frame_to_roi = to_roi(origin)
    if resume is None:
        warp = (frame_to_roi @ start @ px_to_unit).astype(np.float32)
        found = _run(template, roi, warp, FIRST_STEPS, template_mask)
        if found is not None and found[0] >= PROMISING_CORRELATION:
            found = _run(template, roi, found[1], _MAX_STEPS - FIRST_STEPS, template_mask)
            converged = True
        else:
            converged = False
    else:
        found = _run(template, roi, resume.warp.astype(np.float32), _MAX_STEPS - FIRST_STEPS, template_mask)
        converged = True
    if found is None:
        return None
    rho, warp = found
    warp64 = np.asarray(warp, dtype=np.float64)
    to_frame = np.linalg.inv(frame_to_roi) @ warp64 @ np.linalg.inv(px_to_unit)
    to_frame /= to_frame[2, 2]
    if not np.isfinite(to_frame).all() or not math.isfinite(rho):
        return None
    # the data area must stay in front of the camera (depth w > 0 at its corners, 1 at the
    # first): ECC can wander into a map that sends part of it across the horizon, no view of a
    # tag (a rival with ρ 0.94 that way was once drawn from garbage polygons)
    if not (data_area_depths(to_frame) > 0).all():
        return None
    # ... and keep about the size it started from: ECC refines a view, and one that shrinks
    # the data area to a few pixels (a 31 px candidate's to 8 px, on a blurred frame) or
    # swells it has collapsed onto a detail or wandered off, whatever it correlates
    aligned_area = abs(float(cv2.contourArea(apply_homography(to_frame, UNIT_SQUARE).astype(np.float32))))
    start_area = abs(float(cv2.contourArea(corners.astype(np.float32))))
    if not start_area / _MAX_AREA_CHANGE <= aligned_area <= start_area * _MAX_AREA_CHANGE:
        return None
    return EccResult(to_frame, warp64, rho, converged)
