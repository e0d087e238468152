"""Camera calibration from images of a calibration board (``ottag-db calibrate``).

Every image is decoded with a detector whose lookup holds only the board's tags (built from
the board file: no database). Each detected tag gives k point and 4 corner correspondences
(board mm ↔ image px). ``cv2.calibrateCamera`` fits the intrinsics; views whose RMS error is
far above the others, and single correspondences far off, are dropped and the camera is
fitted again. The result is written as a camera file that ``decode --camera`` reads.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ottag_db.app.board_refine import Straightening, refine_tag, tag_edges
from ottag_db.app.boards import Board, board_lookup
from ottag_db.app.decoding import read_image
from ottag_db.core.types import ProgressCallback
from ottag_db.decode import Detector, DetectorParams
from ottag_db.decode.image import to_gray
from ottag_db.errors import CalibrationError, ExportError, UsageError

__all__ = [
    "CAMERA_FORMAT",
    "CalibrationOptions",
    "CalibrationResult",
    "ViewResult",
    "calibrate_board",
    "calibration_json",
    "write_camera",
]

#: The ``format`` value of the camera files written by calibration.
CAMERA_FORMAT = "ottag-camera/1"

_F64 = NDArray[np.float64]
_MODELS = ("standard", "rational")


@dataclass(frozen=True)
class CalibrationOptions:
    """How to calibrate.

    - ``model``: ``"standard"`` = k1, k2, p1, p2 (k3 fixed at 0; 5 coefficients written),
      ``"rational"`` = OpenCV's rational model (k1 … k6, p1, p2; 8 coefficients);
    - ``fix_aspect``: fx = fy;
    - ``min_views``: usable views needed; ``min_tags``: board tags a view must show;
    - ``outlier_view_factor``: a view is dropped when its RMS error exceeds this many times
      the median view RMS (and 0.5 px); ``outlier_point_sigma``: a correspondence is dropped
      when its error exceeds this many robust standard deviations (and 1 px);
    - ``min_tilt``: a view counts as tilted when the board's depth varies by more than this
      fraction across the seen tags; the focal length needs at least two tilted views;
    - ``refine``: after the first fit, decode every view again with the lens distortion of
      that fit removed (straight edges for the line fits; the points are mapped back to the
      original frame) and fit once more;
    - ``edge_fit``: in that second pass, replace each tag's detected points by the board
      positions mapped through a homography fitted to the tag's printed edges (data-area and
      triangle sides, :mod:`ottag_db.app.board_refine`).
    """

    model: str = "standard"
    fix_aspect: bool = False
    min_views: int = 4
    min_tags: int = 3
    outlier_view_factor: float = 3.0
    outlier_point_sigma: float = 5.0
    min_tilt: float = 0.03
    refine: bool = True
    edge_fit: bool = True

    def __post_init__(self) -> None:
        if self.model not in _MODELS:
            raise UsageError(f"--model must be standard or rational, got {self.model!r}")
        if self.min_views < 3 or self.min_tags < 1:
            raise UsageError("calibration needs at least 3 views and 1 tag per view")


@dataclass(frozen=True)
class ViewResult:
    """One image: how many board tags and correspondences it gave, its RMS error (px) and
    whether the final fit used it (``reason`` says why not)."""

    image: str
    tags: int
    points: int
    rms_px: float | None
    used: bool
    reason: str = ""
    dropped_points: int = 0


@dataclass(frozen=True)
class CalibrationResult:
    """Camera intrinsics (pixels, OpenCV conventions), distortion, RMS (px) and per-view errors."""

    image_size: tuple[int, int]
    camera_matrix: _F64
    dist_coeffs: _F64
    rms_px: float
    model: str
    views: tuple[ViewResult, ...]
    std_intrinsics: _F64

    @property
    def fx(self) -> float:
        """Focal length along x, px."""
        return float(self.camera_matrix[0, 0])

    @property
    def fy(self) -> float:
        """Focal length along y, px."""
        return float(self.camera_matrix[1, 1])

    @property
    def cx(self) -> float:
        """Principal point x, px."""
        return float(self.camera_matrix[0, 2])

    @property
    def cy(self) -> float:
        """Principal point y, px."""
        return float(self.camera_matrix[1, 2])


@dataclass(frozen=True)
class _View:
    image: str
    tags: int
    obj: _F64  # (n, 3) board mm
    img: _F64  # (n, 2) px


def _view_correspondences(
    detector: Detector, board: Board, path: Path, straight: Straightening | None = None, edge_fit: bool = False
) -> tuple[tuple[int, int], _F64, _F64, int]:
    """Image size, board points, image points and number of board tags seen in one image
    (detected in the straightened frame when ``straight`` is given, reported in the original;
    ``edge_fit``: there, points from each tag's homography fitted to its printed edges)."""
    import cv2

    image = read_image(path)
    h, w = image.shape[:2]
    frame = image if straight is None else straight.straighten(image)
    detections = detector.detect(frame)
    gray = to_gray(frame).astype(np.float32)
    seen: dict[int, int] = {}
    for d in detections:
        if d.tag is not None:
            seen[d.tag] = seen.get(d.tag, 0) + 1
    obj: list[_F64] = []
    img: list[_F64] = []
    tags = 0
    for d in detections:
        if d.tag is None or seen[d.tag] > 1:  # a tag seen twice is not this board's: skip it
            continue
        if d.corners_seen is not None and not all(d.corners_seen):
            continue  # partly hidden or cut by the frame's edge: its points are read at the frame's rim
        tags += 1
        t = board.tags[d.tag]
        n_before = len(obj)
        obj.append(board.object_points(d.tag)[: t.k])
        img.append(np.asarray(d.points, dtype=np.float64))
        if d.homography is not None:
            # corners in the printed order, checked against the tag frame mapped by the homography
            s = board.tag_size_mm
            local = np.array([[0, 0, 1], [s, 0, 1], [s, s, 1], [0, s, 1]], dtype=np.float64) @ d.homography.T
            predicted = local[:, :2] / local[:, 2:3]
            (ax, ay), (bx, by) = predicted[2] - predicted[0], predicted[3] - predicted[1]
            side = math.sqrt(abs(float(ax * by - ay * bx)) / 2)
            if np.all(np.linalg.norm(predicted - d.corners, axis=1) < 0.1 * side):
                obj.append(board.object_points(d.tag)[t.k :])
                img.append(np.asarray(d.corners, dtype=np.float64))
        if edge_fit and straight is not None:
            o, i = np.concatenate(obj[n_before:]), np.concatenate(img[n_before:])
            h0, _ = cv2.findHomography(o[:, :2], i, 0)
            fitted = (
                None
                if h0 is None
                else refine_tag(gray, np.asarray(h0, np.float64), tag_edges(t.corners_mm, t.points_mm, t.triangles))
            )
            if fitted is not None:
                q = np.c_[o[:, :2], np.ones(len(o))] @ fitted.T
                img[n_before:] = [q[:, :2] / q[:, 2:3]]
                obj[n_before:] = [o]
    if not obj:
        return (w, h), np.zeros((0, 3)), np.zeros((0, 2)), 0
    pixels = np.concatenate(img)
    return (w, h), np.concatenate(obj), pixels if straight is None else straight.to_frame(pixels), tags


def _tilt(view: _View) -> float:
    """Relative variation of depth across the seen board part (0 for a fronto-parallel view),
    from the board → image homography (lens distortion ignored)."""
    import cv2

    hmat, _ = cv2.findHomography(view.obj[:, :2], view.img, 0)
    if hmat is None:
        return 0.0
    w = np.c_[view.obj[:, :2], np.ones(len(view.obj))] @ hmat[2]
    if np.any(w <= 0):
        return 1.0
    return float(w.max() / w.min() - 1.0)


def _flags(options: CalibrationOptions) -> int:
    import cv2

    flags = 0
    if options.model == "standard":
        flags |= cv2.CALIB_FIX_K3
    else:
        flags |= cv2.CALIB_RATIONAL_MODEL
    if options.fix_aspect:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO
    return flags


def _fit(
    views: Sequence[_View], size: tuple[int, int], options: CalibrationOptions
) -> tuple[float, _F64, _F64, list[_F64], _F64]:
    """One ``calibrateCameraExtended`` run: RMS, K, distortion, per-view residuals (n, 2), std."""
    import cv2

    obj = [v.obj.astype(np.float32) for v in views]
    img = [v.img.astype(np.float32).reshape(-1, 1, 2) for v in views]
    k0 = np.eye(3)
    rms, kmat, dist, rvecs, tvecs, std, _, _ = cv2.calibrateCameraExtended(
        obj, img, size, k0, np.zeros(5 if options.model == "standard" else 8), flags=_flags(options)
    )
    residuals = []
    for v, r, t in zip(views, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(v.obj, r, t, kmat, dist)
        residuals.append(proj.reshape(-1, 2) - v.img)
    k_out = np.asarray(kmat, dtype=np.float64)
    d_out = np.asarray(dist, dtype=np.float64).ravel()
    s_out = np.asarray(std, dtype=np.float64).ravel()
    return float(rms), k_out, d_out, residuals, s_out


def calibrate_board(
    board: Board,
    images: Sequence[str | os.PathLike[str]],
    options: CalibrationOptions | None = None,
    *,
    progress: ProgressCallback | None = None,
) -> CalibrationResult:
    """Calibrate a camera from images of ``board``.

    Parameters
    ----------
    board : Board
        The board (see :func:`ottag_db.app.boards.read_board`).
    images : sequence of str or PathLike
        Image files, all of the same size, each showing the board (best: 15 or more views,
        tilted 20–45° in different directions, covering the whole frame).
    options : CalibrationOptions, optional
        Model, aspect and outlier settings.
    progress : ProgressCallback, optional
        ``progress(done, total)`` in images while decoding.

    Returns
    -------
    CalibrationResult
        Intrinsics (px), distortion coefficients (OpenCV order), RMS reprojection error (px)
        of the final fit and every view's figures.

    Raises
    ------
    DecodeError
        An image is missing or unreadable.
    CalibrationError
        Images of different sizes, too few views with enough board tags, or views that leave
        the focal length undetermined (all nearly fronto-parallel).
    """
    opts = options or CalibrationOptions()
    if not images:
        raise CalibrationError("no images given: pass the photos of the board")
    # Only tags whose whole outline is seen: the lines of a partial border are straight where
    # the lens bends the sides at the frame's rim (benchmarks/calibration.py 20 S, seeds 0-2: the
    # largest intrinsics error 0.140 / 0.105 / 0.051 with them, 0.121 / 0.088 / 0.058 without).
    detector = Detector(board_lookup(board), DetectorParams(outline_by_lines=False))
    size: tuple[int, int] | None = None
    views: list[_View] = []
    skipped: list[ViewResult] = []
    for i, path in enumerate(images):
        p = Path(path)
        view_size, obj, img, tags = _view_correspondences(detector, board, p)
        if size is None:
            size = view_size
        elif view_size != size:
            raise CalibrationError(
                f"{p}: {view_size[0]}×{view_size[1]} px, but the first image is {size[0]}×{size[1]} px; "
                "calibrate one camera resolution at a time"
            )
        if tags < opts.min_tags:
            why = "no board tag found" if tags == 0 else f"only {tags} board tag(s), {opts.min_tags} needed"
            skipped.append(ViewResult(str(p), tags, len(obj), None, False, why))
        else:
            views.append(_View(str(p), tags, obj, img))
        if progress is not None:
            progress(i + 1, len(images) * (2 if opts.refine else 1))
    assert size is not None
    if not views and len(images) > 0:
        raise CalibrationError(
            f"none of the {len(images)} image(s) shows at least {opts.min_tags} tags of this board; "
            "check that the images show the printed board of this board file"
        )
    if len(views) < opts.min_views:
        raise CalibrationError(
            f"only {len(views)} of {len(images)} image(s) show at least {opts.min_tags} board tags; calibration "
            f"needs at least {opts.min_views} such views (better 15 or more, tilted in different directions)"
        )
    tilted = sum(_tilt(v) > opts.min_tilt for v in views)
    if tilted < 2:
        raise CalibrationError(
            f"{len(views)} views but {tilted} tilted: nearly fronto-parallel views leave the focal length "
            "undetermined; add views with the board tilted 20–45° in different directions"
        )
    first = _calibrate(views, skipped, size, opts)
    if not opts.refine:
        return first
    straight = Straightening.of(first.camera_matrix, first.dist_coeffs, size)
    refined: list[_View] = []
    for j, v in enumerate(views):
        _, obj, img, tags = _view_correspondences(detector, board, Path(v.image), straight, opts.edge_fit)
        refined.append(_View(v.image, tags, obj, img) if tags >= opts.min_tags else v)
        if progress is not None:
            progress(len(images) + j + 1, 2 * len(images))
    if progress is not None:
        progress(2 * len(images), 2 * len(images))
    return _calibrate(refined, skipped, size, opts)


def _calibrate(
    views: list[_View], skipped: list[ViewResult], size: tuple[int, int], opts: CalibrationOptions
) -> CalibrationResult:
    """Fit, drop outlying views and correspondences, fit again (up to three rounds)."""
    active = list(views)
    dropped_views: dict[str, str] = {}
    dropped_points: dict[str, int] = {}
    rms, kmat, dist, residuals, std = _fit(active, size, opts)
    for _ in range(3):
        errs = [np.linalg.norm(r, axis=1) for r in residuals]
        view_rms = np.array([math.sqrt(float(np.mean(e**2))) for e in errs])
        limit = max(opts.outlier_view_factor * float(np.median(view_rms)), 0.5)
        sigma = 1.4826 * float(np.median(np.concatenate(errs)))
        keep: list[_View] = []
        n_dropped = 0
        for v, e, vr in zip(active, errs, view_rms, strict=True):
            if vr > limit and len(active) - n_dropped - 1 >= opts.min_views:
                dropped_views[v.image] = f"RMS {vr:.2f} px above {limit:.2f} px (outlying view)"
                n_dropped += 1
                continue
            bad = e > max(opts.outlier_point_sigma * sigma, 1.0)
            if bad.any() and (~bad).sum() >= 8:
                dropped_points[v.image] = dropped_points.get(v.image, 0) + int(bad.sum())
                v = _View(v.image, v.tags, v.obj[~bad], v.img[~bad])
            keep.append(v)
        if len(keep) == len(active) and all(len(a.obj) == len(b.obj) for a, b in zip(keep, active, strict=True)):
            break
        active = keep
        rms, kmat, dist, residuals, std = _fit(active, size, opts)
    fx_std = float(std[0]) if len(std) else 0.0
    if not math.isfinite(fx_std) or fx_std > 0.05 * abs(float(kmat[0, 0])):
        raise CalibrationError(
            f"the views leave the focal length undetermined (fx = {kmat[0, 0]:.0f} ± {fx_std:.0f} px); add views "
            "with the board tilted 20–45° in different directions and covering the frame"
        )
    fitted = {v.image: (v, r) for v, r in zip(active, residuals, strict=True)}
    out: list[ViewResult] = []
    for v in views:
        if v.image in fitted:
            fv, r = fitted[v.image]
            vr = math.sqrt(float(np.mean(np.sum(r**2, axis=1))))
            out.append(ViewResult(v.image, v.tags, len(fv.obj), vr, True, "", dropped_points.get(v.image, 0)))
        else:
            out.append(ViewResult(v.image, v.tags, len(v.obj), None, False, dropped_views.get(v.image, "dropped")))
    order = {s.image: s for s in skipped}
    views_all = tuple(out) + tuple(order.values())
    n_coef = 5 if opts.model == "standard" else 8
    return CalibrationResult(
        image_size=size,
        camera_matrix=kmat,
        dist_coeffs=dist[:n_coef],
        rms_px=rms,
        model=opts.model,
        views=views_all,
        std_intrinsics=std[: 4 + n_coef],
    )


def calibration_json(result: CalibrationResult) -> dict[str, Any]:
    """The result as JSON (``calibrate --json``; also the content of the camera file).

    Parameters
    ----------
    result : CalibrationResult
        The calibration.

    Returns
    -------
    dict
        ``format``, ``image_size`` [w, h], ``camera_matrix`` (3×3), ``dist_coeffs`` (OpenCV
        order), ``fx``, ``fy``, ``cx``, ``cy`` (px), ``model``, ``rms_px`` and ``views``
        (``image``, ``tags``, ``points``, ``rms_px``, ``used``, ``reason``, ``dropped_points``).
        :func:`ottag_db.app.decoding.load_camera` reads it.
    """
    return {
        "format": CAMERA_FORMAT,
        "image_size": list(result.image_size),
        "camera_matrix": result.camera_matrix.tolist(),
        "dist_coeffs": result.dist_coeffs.tolist(),
        "fx": result.fx,
        "fy": result.fy,
        "cx": result.cx,
        "cy": result.cy,
        "model": result.model,
        "rms_px": result.rms_px,
        "std_intrinsics": result.std_intrinsics.tolist(),
        "views": [
            {
                "image": v.image,
                "tags": v.tags,
                "points": v.points,
                "rms_px": v.rms_px,
                "used": v.used,
                "reason": v.reason,
                "dropped_points": v.dropped_points,
            }
            for v in result.views
        ],
    }


def write_camera(result: CalibrationResult, path: str | os.PathLike[str]) -> None:
    """Write the camera file (JSON of :func:`calibration_json`) that ``decode --camera`` reads.

    Parameters
    ----------
    result : CalibrationResult
        The calibration.
    path : str or PathLike
        The JSON file.

    Raises
    ------
    ExportError
        The file cannot be written.
    """
    p = Path(path)
    try:
        p.write_text(json.dumps(calibration_json(result), indent=1) + "\n", encoding="utf-8")
    except OSError as exc:
        raise ExportError(f"cannot write the camera file {p}: {exc.strerror or exc}") from exc
