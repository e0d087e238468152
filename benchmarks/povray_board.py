"""Ray-traced calibration views: an Order Type Tag board and a ChArUco board on the same A4 page pose.

The helper of ``benchmarks/calibration.py --povray``. Both boards are textures of a whole A4
page (210 × 297 mm, 10 px/mm) mapped onto a plane by POV-Ray (``benchmarks/povray.py``: its
exact pinhole camera :data:`povray.CALIBRATION_CAMERA`, 1280×960, f = 1000 px, principal point
(639.5, 479.5), no distortion; a point light above and left of the camera (:data:`LAMP`) and
ambient light, adaptive antialiasing). A pose
is that of our board (``calibration_poses``: board → camera, mm, the board's top-left corner as
origin); the ChArUco page takes the same place, so both pages are seen from the same viewpoints.

Besides the frames, the true image positions of every board point (our tags' vertices and
corners, the ChArUco chessboard corners) are projected by the true camera, so that
:func:`our_residuals` and :func:`charuco_residuals` can measure what the detectors find against
the truth (``calibration.py --povray --diagnose``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray
from povray import CALIBRATION_CAMERA, Renderer, Scene

from ottag_db.app.board_refine import Straightening
from ottag_db.app.boards import Board, board_lookup
from ottag_db.app.calibration import _view_correspondences  # the points calibrate_board fits (diagnosis only)
from ottag_db.decode import Detector, DetectorParams

_U8 = NDArray[np.uint8]
_F64 = NDArray[np.float64]
Pose = tuple[_F64, _F64]

#: The lamp (POV-Ray's frame: x right, y up, z forward; m): above and left of the camera, a little behind
#: it (the pages are 0.2–0.4 m away).
LAMP = (-0.15, 0.25, -0.05)
#: The page of both boards (mm) and the raster of the ChArUco page (px/mm).
A4_MM = (210.0, 297.0)
CHARUCO_PX_PER_MM = 10.0
#: The ChArUco board of the warped views (7 × 9 squares of 20 mm, 15 mm DICT_5X5_100 markers), centred on A4.
CHARUCO_SQUARES, CHARUCO_SQUARE_MM, CHARUCO_MARKER_MM = (7, 9), 20.0, 15.0


def charuco_board() -> cv2.aruco.CharucoBoard:
    """The ChArUco board (board units: mm)."""
    aruco = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100)
    return cv2.aruco.CharucoBoard(CHARUCO_SQUARES, CHARUCO_SQUARE_MM, CHARUCO_MARKER_MM, aruco)


def charuco_page(board: cv2.aruco.CharucoBoard) -> tuple[_U8, tuple[float, float]]:
    """An A4 page (10 px/mm) with ``board`` drawn by ``generateImage`` at its centre, and the board's
    origin (top-left outer corner) on the page, mm."""
    s = CHARUCO_PX_PER_MM
    bw, bh = (round(n * CHARUCO_SQUARE_MM * s) for n in CHARUCO_SQUARES)
    pw, ph = round(A4_MM[0] * s), round(A4_MM[1] * s)
    page = np.full((ph, pw), 255, np.uint8)
    x0, y0 = (pw - bw) // 2, (ph - bh) // 2
    page[y0 : y0 + bh, x0 : x0 + bw] = board.generateImage((bw, bh), marginSize=0)
    return page, (x0 / s, y0 / s)


def page_scene(texture: _U8, page_mm: tuple[float, float], origin_mm: tuple[float, float], pose: Pose) -> Scene:
    """The page ``texture`` (``page_mm`` wide and high) at ``pose`` (of a board whose top-left corner
    lies at ``origin_mm`` on the page; mm), as a POV-Ray scene in metres."""
    rvec, tvec = pose
    r_mat, _ = cv2.Rodrigues(np.asarray(rvec, np.float64))
    centre = np.array([page_mm[0] / 2 - origin_mm[0], page_mm[1] / 2 - origin_mm[1], 0.0])
    t = (r_mat @ centre + np.asarray(tvec, np.float64)) / 1000.0
    return Scene(texture, np.asarray(r_mat, np.float64), t, page_mm[0] / 1000.0, page_mm[1] / 1000.0, LAMP)


@dataclass(frozen=True)
class Views:
    """The rendered frames of both boards at the same poses."""

    ours: list[_U8]
    charuco: list[_U8]
    rendered: int  # frames rendered now (not read from the cache)
    seconds: float  # wall time of the renders


def render_views(
    cache: Path,
    ours: tuple[_U8, tuple[float, float], tuple[float, float]],
    charuco: tuple[_U8, tuple[float, float]],
    poses: Sequence[Pose],
    progress: Callable[[int, int], None] | None = None,
) -> Views:
    """Render our page (raster, page size mm, board origin mm) and the ChArUco page (raster, board
    origin on it, mm) at ``poses`` of our board, 2 POV-Ray processes, frames cached in ``cache``."""
    renderer = Renderer(cache, camera=CALIBRATION_CAMERA)
    our_page, our_page_mm, our_origin = ours
    ch_page, ch_origin = charuco
    # the ChArUco page lies where ours does: its board origin shifted by the difference of the origins
    shift = np.array([ch_origin[0] - our_origin[0], ch_origin[1] - our_origin[1], 0.0])
    scenes = [page_scene(our_page, our_page_mm, our_origin, p) for p in poses]
    for rvec, tvec in poses:
        r_mat, _ = cv2.Rodrigues(np.asarray(rvec, np.float64))
        moved = (r_mat @ shift + np.asarray(tvec, np.float64), np.asarray(rvec, np.float64))
        scenes.append(page_scene(ch_page, A4_MM, ch_origin, (moved[1], moved[0])))
    frames = renderer.render(scenes, progress)
    images = [f.image for f in frames]
    n = len(poses)
    return Views(images[:n], images[n:], renderer.rendered, renderer.seconds)


def _project(points_mm: _F64, pose: Pose) -> _F64:
    """Pixels of board points (mm, z = 0 plane of the pose's board) seen by the true camera."""
    obj = np.asarray(points_mm, np.float64).reshape(-1, 1, 3)
    pix, _ = cv2.projectPoints(obj, pose[0], pose[1], CALIBRATION_CAMERA.matrix, None)
    return np.asarray(pix, np.float64).reshape(-1, 2)


@dataclass(frozen=True)
class Residuals:
    """Detected − true image points of one kind in one view: the count, the mean vector (px), the RMS
    (px) and the mean component away from the centre of the point's tag or square (px; + outward)."""

    n: int
    mean: _F64
    rms: float
    outward: float

    @staticmethod
    def of(found: _F64, truth: _F64, centres: _F64) -> Residuals:
        """The figures of ``found`` against ``truth`` (rows paired), outward from ``centres``."""
        if len(found) == 0:
            return Residuals(0, np.zeros(2), float("nan"), float("nan"))
        d = found - truth
        away = truth - centres
        away /= np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-9)
        return Residuals(
            len(d), d.mean(axis=0), float(np.sqrt(np.mean(np.sum(d**2, axis=1)))), float(np.mean(np.sum(d * away, 1)))
        )


def our_residuals(board: Board, path: Path, pose: Pose) -> dict[str, tuple[Residuals, _F64, _F64]]:
    """Our detector's vertices and corners (first pass of ``calibrate_board``) and the edge-fit points
    of its second pass (the frame "straightened" by the true camera, i.e. as is) in the frame at
    ``path`` against the truth: per kind the residuals, the board points (mm) and the image points."""
    detector = Detector(board_lookup(board), DetectorParams(outline_by_lines=False))
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise RuntimeError(f"cannot read {path}")
    found: dict[str, list[_F64]] = {"vertices": [], "corners": []}
    objs: dict[str, list[_F64]] = {"vertices": [], "corners": []}
    truth: dict[str, list[_F64]] = {"vertices": [], "corners": []}
    centres: dict[str, list[_F64]] = {"vertices": [], "corners": []}
    for d in detector.detect(image):
        if d.tag is None or (d.corners_seen is not None and not all(d.corners_seen)):
            continue
        t = board.tags[d.tag]
        obj = board.object_points(d.tag)
        true_px = _project(obj, pose)
        centre = true_px[t.k :].mean(axis=0)  # the tag's four corners
        for kind, pts, sl in (("vertices", d.points, slice(0, t.k)), ("corners", d.corners, slice(t.k, None))):
            true = true_px[sl]
            objs[kind].append(obj[sl])
            found[kind].append(np.asarray(pts, np.float64))
            truth[kind].append(true)
            centres[kind].append(np.repeat(centre[None], len(true), axis=0))
    out = {}
    for kind in found:
        arrays = [np.concatenate(v[kind]) if v[kind] else np.zeros((0, 2)) for v in (found, truth, centres)]
        o = np.concatenate(objs[kind]) if objs[kind] else np.zeros((0, 3))
        out[kind] = (Residuals.of(*arrays), o, arrays[0])
    straight = Straightening.of(CALIBRATION_CAMERA.matrix, np.zeros(5), (image.shape[1], image.shape[0]))
    _, obj, img, _ = _view_correspondences(detector, board, path, straight, True)
    true_px = _project(obj, pose)
    s, g = board.tag_size_mm, board.tag_size_mm + board.spacing_mm
    col, row = np.floor(obj[:, 0] / g), np.floor(obj[:, 1] / g)
    tag_centres = _project(np.column_stack([col * g + s / 2, row * g + s / 2, np.zeros(len(obj))]), pose)
    out["edge fit"] = (Residuals.of(img, true_px, tag_centres), obj, img)
    return out


def charuco_residuals(board: cv2.aruco.CharucoBoard, image: _U8, pose: Pose, origin_shift: _F64) -> Residuals:
    """ChArUco corners found by ``CharucoDetector`` against the truth (``origin_shift``: the ChArUco
    board's origin in our board's coordinates, mm)."""
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(image)
    if ids is None:
        return Residuals.of(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)))
    chess = np.asarray(board.getChessboardCorners(), np.float64)[ids.ravel()]
    true_px = _project(chess + origin_shift, pose)
    # centre of the square to the corner's lower right: outward then is the diagonal (sign is arbitrary)
    sq = CHARUCO_SQUARE_MM
    centre_px = _project(chess + origin_shift - np.array([sq / 2, sq / 2, 0.0]), pose)
    return Residuals.of(np.asarray(corners, np.float64).reshape(-1, 2), true_px, centre_px)
