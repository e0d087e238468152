"""Camera pose of a decoded Order Type Tag from its corners and points (planar PnP, IPPE)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.decode.types import Detection
from ottag_db.errors import UsageError

__all__ = ["Pose", "PoseSolution", "estimate_pose", "placement_from_detection", "tag_object_points"]

_F64 = NDArray[np.float64]


@dataclass(frozen=True)
class PoseSolution:
    """One pose candidate: ``rvec`` (3,) Rodrigues, ``tvec`` (3,), RMS reprojection error (px)."""

    rvec: _F64
    tvec: _F64
    reprojection_error_px: float


@dataclass(frozen=True)
class Pose:
    """Pose of the tag frame in the camera frame: ``X_cam = R @ X_tag + tvec``.

    Tag frame: origin at the data area's top-left corner, x along its top side (to the
    top-right corner), y along its left side (to the bottom-left corner), z = x × y pointing
    *into* the tag (away from a camera that sees the printed side); the data area is
    ``[0, s] × [0, s] × {0}`` with ``s = tag_size`` in the user's unit, which is also the unit
    of ``tvec``. Camera frame: OpenCV's (x right, y down, z forward).

    - ``rvec``/``R``/``tvec``: the refined pose (Levenberg–Marquardt on all correspondences,
      started from the better IPPE solution);
    - ``reprojection_error_px``: RMS reprojection error of the refined pose over all
      correspondences (4 corners plus the matched points);
    - ``solutions``: both IPPE solutions (``cv2.SOLVEPNP_IPPE``), best first, each with its RMS
      error; a ratio of their errors near 1 flags the planar pose ambiguity;
    - ``n_points``: correspondences used (4 corners + the points when matched).
    """

    rvec: _F64
    tvec: _F64
    R: _F64
    reprojection_error_px: float
    solutions: tuple[PoseSolution, ...]
    n_points: int

    @property
    def distance(self) -> float:
        """Distance from the camera centre to the tag-frame origin (top-left corner), user units."""
        return float(np.linalg.norm(self.tvec))


def placement_from_detection(detection: Detection) -> _F64:
    """Affine ``(2, 3)`` file/grid coordinates → data-area unit square, estimated from a detection.

    The corners (top-left, top-right, bottom-right, bottom-left) are mapped back to the tag
    plane through ``detection.homography`` and the affine map taking them to ``(0,0), (1,0),
    (1,1), (0,1)`` is fitted by least squares. Needs a homography (a verified detection).
    """
    if detection.homography is None:
        raise UsageError("the detection has no homography (unknown or unverified order type)")
    hinv = np.linalg.inv(detection.homography)
    ph = np.c_[detection.corners, np.ones(4)] @ hinv.T
    g = ph[:, :2] / ph[:, 2:3]
    unit = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64)
    a = np.c_[g, np.ones(4)]
    sol, *_ = np.linalg.lstsq(a, unit, rcond=None)
    out: _F64 = np.asarray(sol.T, dtype=np.float64)
    return out


def tag_object_points(detection: Detection, tag_size: float, placement: ArrayLike | None = None) -> tuple[_F64, _F64]:
    """3-D tag-frame points and their image points: the 4 corners, then the matched points.

    The points are used only when the detection carries ``model_points`` (unique minimal
    ordering); they are placed by ``placement`` (``(2, 3)`` affine grid → unit square, None =
    :func:`placement_from_detection`) and scaled by ``tag_size``.
    """
    s = float(tag_size)
    obj = [np.array([[0, 0, 0], [s, 0, 0], [s, s, 0], [0, s, 0]], dtype=np.float64)]
    img = [np.asarray(detection.corners, dtype=np.float64)]
    if detection.model_points is not None and detection.homography is not None:
        aff = placement_from_detection(detection) if placement is None else np.asarray(placement, float)
        if aff.shape != (2, 3):
            raise UsageError(f"placement must be a (2, 3) affine matrix, got shape {aff.shape}")
        unit = np.c_[detection.model_points, np.ones(len(detection.model_points))] @ aff.T
        obj.append(np.c_[unit * s, np.zeros(len(unit))])
        img.append(np.asarray(detection.points, dtype=np.float64))
    return np.concatenate(obj), np.concatenate(img)


def _rms(obj: _F64, img: _F64, rvec: _F64, tvec: _F64, k: _F64, dist: _F64 | None) -> float:
    proj, _ = cv2.projectPoints(obj, rvec, tvec, k, dist)
    return float(math.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))


def estimate_pose(
    detection: Detection,
    camera_matrix: ArrayLike,
    dist_coeffs: ArrayLike | None,
    tag_size: float,
    placement: ArrayLike | None = None,
) -> Pose:
    """Pose of a detected tag for a calibrated camera.

    ``camera_matrix`` is the 3×3 intrinsic matrix K (pixels), ``dist_coeffs`` OpenCV
    distortion coefficients or None, ``tag_size`` the data-area side in the user's unit,
    ``placement`` the ``(2, 3)`` affine map file/grid coordinates → data-area unit square
    used when the tag was drawn (None: estimated, see :func:`placement_from_detection`).
    Uses the 4 corners and, when matched, the k points (see :class:`Pose` for the frames).
    """
    if not tag_size > 0:
        raise UsageError(f"tag_size must be positive, got {tag_size}")
    k = np.asarray(camera_matrix, dtype=np.float64)
    if k.shape != (3, 3):
        raise UsageError(f"camera_matrix must be 3×3, got shape {k.shape}")
    dist = None if dist_coeffs is None else np.asarray(dist_coeffs, dtype=np.float64).ravel()
    obj, img = tag_object_points(detection, tag_size, placement)
    n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, k, dist, flags=cv2.SOLVEPNP_IPPE)
    sols = []
    for i in range(int(n)):
        rv = np.asarray(rvecs[i], dtype=np.float64).reshape(3)
        tv = np.asarray(tvecs[i], dtype=np.float64).reshape(3)
        sols.append(PoseSolution(rv, tv, _rms(obj, img, rv, tv, k, dist)))
    sols.sort(key=lambda s: s.reprojection_error_px)
    if not sols:
        raise UsageError("no pose found (degenerate correspondences)")
    rvec = sols[0].rvec.reshape(3, 1).copy()
    tvec = sols[0].tvec.reshape(3, 1).copy()
    ref_r, ref_t = cv2.solvePnPRefineLM(obj, img, k, dist, rvec, tvec)
    rv = np.asarray(ref_r, dtype=np.float64).reshape(3)
    tv = np.asarray(ref_t, dtype=np.float64).reshape(3)
    r_mat, _ = cv2.Rodrigues(rv)
    return Pose(
        rvec=rv,
        tvec=tv,
        R=np.asarray(r_mat, dtype=np.float64),
        reprojection_error_px=_rms(obj, img, rv, tv, k, dist),
        solutions=tuple(sols),
        n_points=len(obj),
    )
