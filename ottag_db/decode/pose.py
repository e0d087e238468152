"""Camera pose of a decoded Order Type Tag from its corners and points (planar PnP, IPPE)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.decode.placement_check import apply_homography
from ottag_db.decode.pose_ambiguity import (
    AMBIGUITY_LIMIT,
    AMBIGUITY_MIN_ANGLE_DEG,
    Minimum,
    ippe,
    likelihood_ratio,
    mirrored_minima,
    normal_angle_deg,
)
from ottag_db.decode.types import Detection
from ottag_db.errors import UsageError

__all__ = [
    "AMBIGUITY_LIMIT",
    "AMBIGUITY_MIN_ANGLE_DEG",
    "CORNER_WEIGHT",
    "MEASURED_CORNER_PX",
    "NEXT_TO_UNSEEN_WEIGHT",
    "ROBUST_SCALE_PX",
    "Pose",
    "PoseSolution",
    "estimate_pose",
    "measured_corners",
    "placement_from_detection",
    "tag_object_points",
]

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

    - ``rvec``/``R``/``tvec``: the refined pose (weighted Levenberg–Marquardt on all
      correspondences from each IPPE solution and from their mirrors, the lower weighted error
      kept; see :func:`estimate_pose`);
    - ``reprojection_error_px``: RMS reprojection error of the refined pose over all
      correspondences (4 corners plus the matched points);
    - ``solutions``: both IPPE solutions (``cv2.SOLVEPNP_IPPE``, unrefined, unweighted), lower
      RMS error first;
    - ``n_points``: correspondences used (4 corners + the points when matched);
    - ``alternative``: the mirrored pose of the planar ambiguity (the other minimum, refined like
      the pose; when there is only one minimum, the mirror of the pose as it lies), with its RMS
      error;
    - ``ambiguity``: likelihood of ``alternative`` relative to the pose under the noise model of
      :func:`estimate_pose`, in [0, 1]: near 0 the image tells the two apart, near 1 it cannot;
    - ``ambiguous``: ``ambiguity`` at least :data:`~.pose_ambiguity.AMBIGUITY_LIMIT` and the
      two tag normals more than :data:`~.pose_ambiguity.AMBIGUITY_MIN_ANGLE_DEG` apart: the frame
      alone cannot choose the tilt (see :func:`estimate_pose` for what to do);
    - ``alternative_angle_deg``: angle between the pose's and the alternative's tag normals.
    """

    rvec: _F64
    tvec: _F64
    R: _F64
    reprojection_error_px: float
    solutions: tuple[PoseSolution, ...]
    n_points: int
    alternative: PoseSolution
    ambiguity: float
    ambiguous: bool
    alternative_angle_deg: float

    def swapped(self) -> Pose:
        """The same pose with :attr:`alternative` reported instead (and the pose as its alternative).

        Returns
        -------
        Pose
            ``rvec``/``R``/``tvec``/``reprojection_error_px`` of the alternative; ``ambiguity``,
            ``ambiguous``, ``alternative_angle_deg``, ``solutions`` and ``n_points`` unchanged.
        """
        r_mat, _ = cv2.Rodrigues(self.alternative.rvec)
        return replace(
            self,
            rvec=self.alternative.rvec,
            tvec=self.alternative.tvec,
            R=np.asarray(r_mat, dtype=np.float64),
            reprojection_error_px=self.alternative.reprojection_error_px,
            alternative=PoseSolution(self.rvec, self.tvec, self.reprojection_error_px),
        )

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


#: Weight of a corner not seen where the print puts it (``Detection.corners_seen``: hidden,
#: outside the frame, or measured off) against one vertex: its position is the print's, from the
#: points, so it adds no evidence of its own — the pose comes from what was seen. (Weights 0, 1
#: and 10 flagged 16, 17 and 14 of 479 small far poses ambiguous in benchmarks/pose_flips.py,
#: seeds 1 and 2, none of them flipped unflagged: no measurable difference.)
UNSEEN_CORNER_WEIGHT = 0.0
#: Weight of each data-area corner against one triangle vertex in the final refinement. The
#: corners come from four straight sides fitted over their whole length; the vertices from short
#: sides meeting at acute tips, whose errors are larger and correlated (biased along the sliver).
#: Measured by ``benchmarks/pose_accuracy.py`` (rasterized PDF renders, 30 poses, two noise seeds):
#: weight 1 → mean normal error 0.25°, 3 → 0.15°, 10 → 0.11°, corners only → 0.10°; 10 keeps the
#: vertices' say in the pose (a corner hidden or misplaced by a few pixels is outvoted).
CORNER_WEIGHT = 10.0
#: Scale (px) of the Cauchy reweighting of every correspondence in the final refinement: a point
#: off by ``c`` counts half, so one vertex misplaced at a sliver tip cannot tilt the pose.
ROBUST_SCALE_PX = 0.5


#: Weight of a seen corner next to one not seen (``Detection.corners_seen``), against one vertex.
#: A corner the print puts elsewhere, in a view where the square itself does not place it either
#: (see :data:`MEASURED_CORNER_PX`), had a side measured off — a triangle's edge taken for the
#: border, or an occluder's — and a neighbour on that side (either side of a lone corner not
#: seen; the side between two) is its crossing with another: within the verification bound, it
#: can still lie a pixel off, which at :data:`CORNER_WEIGHT` outweighs the vertices and chose
#: the wrong mirrored pose with confidence (a neighbour 0.9 px off on a 31 px data area, its
#: corner's side run along a triangle's edge); at a vertex's weight it counts as much as one.
NEXT_TO_UNSEEN_WEIGHT = 1.0
#: A corner not seen where the print puts it counts as seen after all when its measured position
#: lies within this distance (px) of where the square, posed by the other corners and the points,
#: puts it (under either mirrored pose). The print's position extrapolates the points'
#: homography (8 unknowns from k points) to the corner: a vertex a pixel or two off at a sharp
#: tip moves it by 1–4 px on data areas 28–40 px wide, so well-measured corners fail that test;
#: a posed square (6 unknowns, the corners' shape known) places the fourth corner from three to
#: within a few tenths of a pixel. On benchmarks/pose_flips.py renders the corners it let back lay
#: within 0.11 px of one of the two poses' corner (their print 1.2–3.6 px off); corners whose
#: side had followed a triangle's edge (before :func:`~ottag_db.decode.refine.refine_lines`
#: searched such sides again) lay 2.1–6.3 px from both. 0.5 px is :data:`ROBUST_SCALE_PX`, the
#: distance at which a corner would count half anyway.
MEASURED_CORNER_PX = 0.5


def measured_corners(detection: Detection) -> _F64 | None:
    """The data-area corners as measured (before the printed position replaced those not seen).

    Parameters
    ----------
    detection : Detection
        A decoded tag.

    Returns
    -------
    numpy.ndarray or None
        ``(4, 2)`` image pixels in the order of ``detection.corners``: ``corners_measured``
        mapped by ``homography`` when the print replaced a corner, else ``corners`` (a corner
        outside the frame, not seen, is where the lines of its sides cross); None when the
        corners measured cannot be mapped.
    """
    if detection.corners_measured is None:
        return np.asarray(detection.corners, dtype=np.float64)
    if detection.homography is None:
        return None
    out = apply_homography(detection.homography, np.asarray(detection.corners_measured, dtype=np.float64))
    return out if np.isfinite(out).all() else None


def _placed_by_square(
    obj4: _F64, measured: _F64, minima: tuple[Minimum, Minimum], k: _F64, dist: _F64 | None
) -> NDArray[np.bool_]:
    """Which measured corners lie within :data:`MEASURED_CORNER_PX` of the corners of either pose."""
    near = np.zeros(4, dtype=bool)
    for m in minima:
        proj, _ = cv2.projectPoints(obj4, m[0], m[1], k, dist)
        near |= np.linalg.norm(proj.reshape(-1, 2) - measured, axis=1) <= MEASURED_CORNER_PX
    return near


def _weigh_unseen(
    detection: Detection, obj: _F64, img: _F64, k: _F64, dist: _F64 | None, weights: _F64, robust_px: float | None
) -> _F64:
    """Weights (set in place) of corners not seen and of their neighbours, and the image points
    with the measured corners the posed square confirms (:data:`MEASURED_CORNER_PX`) back in."""
    unseen = ~np.asarray(detection.corners_seen, dtype=bool)
    corner_weight = float(weights[0])
    weights[:4][unseen] = UNSEEN_CORNER_WEIGHT
    measured = measured_corners(detection)
    if unseen.any() and measured is not None:
        minima = mirrored_minima(obj, img, k, dist, weights, robust_px)
        back = _placed_by_square(obj[:4], measured, minima, k, dist) & unseen
        if back.any():
            img = img.copy()
            img[:4][back] = measured[back]
            weights[:4][back] = corner_weight
            unseen &= ~back
    weights[:4][_next_to_unseen(unseen)] = min(NEXT_TO_UNSEEN_WEIGHT, corner_weight)
    return img


def _next_to_unseen(unseen: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The seen corners on a side suspected of being measured off: a side between two corners
    not seen when there is one (it explains both), else every side through a corner not seen
    (side ``i`` runs from corner ``i`` to corner ``i + 1``)."""
    both = unseen & np.roll(unseen, -1)
    suspect = both if both.any() else unseen | np.roll(unseen, -1)
    out: NDArray[np.bool_] = (suspect | np.roll(suspect, 1)) & ~unseen
    return out


def estimate_pose(
    detection: Detection,
    camera_matrix: ArrayLike,
    dist_coeffs: ArrayLike | None,
    tag_size: float,
    placement: ArrayLike | None = None,
    *,
    corner_weight: float = CORNER_WEIGHT,
    robust_scale_px: float | None = ROBUST_SCALE_PX,
) -> Pose:
    """Pose of a detected tag for a calibrated camera, with the planar ambiguity stated.

    A nearly fronto-parallel tag fits two poses tilted opposite ways about the line of sight
    almost equally (the planar ambiguity: on a data area 28–70 px wide their images differ by
    a tenth of a pixel or so). Both IPPE solutions of all correspondences (4 corners, then the
    matched points; corners not seen, ``Detection.corners_seen``, weigh nothing beside the
    points unless the square posed without them puts them where they were measured,
    :data:`MEASURED_CORNER_PX`; their neighbours weigh :data:`NEXT_TO_UNSEEN_WEIGHT`) are
    refined by a weighted Levenberg–Marquardt, and their mirrors when both end in one minimum
    (:mod:`~ottag_db.decode.pose_ambiguity`). The noise model: each point's
    error is Gaussian with a spread per kind, a corner's ``1/sqrt(corner_weight)`` of a
    vertex's (corners come from four straight sides fitted over their whole length, vertices
    from short sides meeting at sharp tips), with Cauchy tails at ``robust_scale_px`` (a point
    off by a pixel is an outlier, not evidence), its scale estimated from the pose's own
    residuals. The pose is the minimum of lower cost; :attr:`Pose.alternative` is its mirror
    and :attr:`Pose.ambiguity` the mirror's likelihood relative to the pose under that model.

    What to do with it: ``ambiguity`` near 0 means the pose fits clearly better than its
    mirror; near 1, both fit alike. A pose with ``ambiguous`` set is one of two mirrored poses
    its frame cannot tell apart: do not act on its tilt alone. Let other evidence choose
    between it and ``alternative`` — the previous frames on video
    (:class:`ottag_db.app.pose_tracking.PoseTracker` does that), another tag on the same plane,
    the orientation you expect — or drop it. Its position (``tvec``) holds either way (the two
    differ in tilt, hardly in position).

    Parameters
    ----------
    detection : Detection
        A decoded tag (its corners; its points when ``model_points`` is set).
    camera_matrix : array_like, shape (3, 3)
        Intrinsic matrix K (pixels).
    dist_coeffs : array_like or None
        OpenCV distortion coefficients, None for none.
    tag_size : float
        Data-area side in the user's unit (the unit of ``tvec``).
    placement : array_like, shape (2, 3), optional
        Affine map file/grid coordinates → data-area unit square used when the tag was drawn
        (None: estimated, see :func:`placement_from_detection`).
    corner_weight : float, optional
        Weight of each corner against one vertex (> 0; 1 = plain least squares).
    robust_scale_px : float or None, optional
        Cauchy scale in pixels; None for no reweighting.

    Returns
    -------
    Pose
        See :class:`Pose` for the frames and the ambiguity.
    """
    if not tag_size > 0:
        raise UsageError(f"tag_size must be positive, got {tag_size}")
    if not corner_weight > 0:
        raise UsageError(f"corner_weight must be positive, got {corner_weight}")
    if robust_scale_px is not None and not robust_scale_px > 0:
        raise UsageError(f"robust_scale_px must be positive or None, got {robust_scale_px}")
    k = np.asarray(camera_matrix, dtype=np.float64)
    if k.shape != (3, 3):
        raise UsageError(f"camera_matrix must be 3×3, got shape {k.shape}")
    dist = None if dist_coeffs is None else np.asarray(dist_coeffs, dtype=np.float64).ravel()
    obj, img = tag_object_points(detection, tag_size, placement)
    sols = [PoseSolution(rv, tv, _rms(obj, img, rv, tv, k, dist)) for rv, tv in ippe(obj, img, k, dist)]
    sols.sort(key=lambda s: s.reprojection_error_px)
    if not sols:
        raise UsageError("no pose found (degenerate correspondences)")

    weights = np.ones(len(obj))
    weights[:4] = corner_weight
    if detection.corners_seen is not None and len(obj) > 4:
        img = _weigh_unseen(detection, obj, img, k, dist, weights, robust_scale_px)
    best, alt = mirrored_minima(obj, img, k, dist, weights, robust_scale_px)
    rv, tv = best[0], best[1]
    ambiguity = likelihood_ratio(obj, img, k, dist, weights, best, alt)
    angle = normal_angle_deg(best[0], alt[0])
    r_mat, _ = cv2.Rodrigues(rv)
    return Pose(
        rvec=rv,
        tvec=tv,
        R=np.asarray(r_mat, dtype=np.float64),
        reprojection_error_px=_rms(obj, img, rv, tv, k, dist),
        solutions=tuple(sols),
        n_points=len(obj),
        alternative=PoseSolution(alt[0], alt[1], _rms(obj, img, alt[0], alt[1], k, dist)),
        ambiguity=ambiguity,
        ambiguous=ambiguity >= AMBIGUITY_LIMIT and angle > AMBIGUITY_MIN_ANGLE_DEG,
        alternative_angle_deg=angle,
    )
