"""Camera calibration from a board (ottag_db.app.calibration): the board's own PDF rasterized
(pypdfium2) and photographed by a known camera with lens distortion, blur and noise."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from ottag_db.app.boards import Board, create_board, read_board
from ottag_db.app.calibration import CalibrationOptions, calibrate_board, write_camera
from ottag_db.app.decoding import load_camera
from ottag_db.errors import CalibrationError, DecodeError
from ottag_db.printing.board import DistortedCamera, calibration_poses
from ottag_db.printing.pdf import MM_TO_PT
from ottag_db.store.db import open_database

#: The true camera: fx = fy = 1000 px, principal point 20 px right of and below the centre of a
#: 1280 × 960 frame (OpenCV pixel centres: the centre is at 639.5, 479.5), k1 = −0.2.
TRUE_K = np.array([[1000.0, 0.0, 659.5], [0.0, 1000.0, 499.5], [0.0, 0.0, 1.0]])
TRUE_DIST = np.array([-0.2, 0.0, 0.0, 0.0, 0.0])
SIZE = (1280, 960)
PX_PER_MM = 10.0


def rasterize(pdf: Path, px_per_mm: float) -> np.ndarray:
    """The first page of ``pdf`` as a grey uint8 raster: rendered at 4× and reduced by area
    averaging (pdfium snaps filled edges to whole raster rows in y, which would make every
    black square one row too tall)."""
    import pypdfium2 as pdfium

    doc = pdfium.PdfDocument(str(pdf))
    try:
        page = doc[0].render(scale=4 * px_per_mm / MM_TO_PT, grayscale=True).to_numpy()
    finally:
        doc.close()
    page = np.ascontiguousarray(page[..., 0] if page.ndim == 3 else page)
    return np.asarray(cv2.resize(page, (page.shape[1] // 4, page.shape[0] // 4), interpolation=cv2.INTER_AREA))


def page_scale(page: np.ndarray, page_mm: tuple[float, float] | None) -> tuple[float, float]:
    """Pixels per mm of a raster along x and y (pdfium rounds the page up to whole pixels)."""
    assert page_mm is not None
    return page.shape[1] / page_mm[0], page.shape[0] / page_mm[1]


@pytest.fixture(scope="module")
def views(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Board, list[Path]]:
    """A 4 × 3 board of 40 mm tags and 16 views of it by the true camera (blur 0.7 px, noise 2)."""
    folder = tmp_path_factory.mktemp("calib")
    db_path = folder / "db.sqlite"
    shutil.copy(bundled_db_path, db_path)
    db = open_database(db_path)
    try:
        board, board_file = create_board(db, folder / "board.pdf", rows=4, cols=3, tag_size_mm=40, spacing_mm=10)
    finally:
        db.close()
    board = read_board(board_file)
    assert board.page_origin_mm is not None
    page = rasterize(folder / "board.pdf", PX_PER_MM)
    cam = DistortedCamera(TRUE_K, TRUE_DIST, (SIZE[1], SIZE[0]), supersampling=2)
    rng = np.random.default_rng(12)
    paths = []
    for i, (rvec, tvec) in enumerate(calibration_poses(board.size_mm, TRUE_K, SIZE, 16, rng)):
        img = cam.render(
            page, page_scale(page, board.page_mm), board.page_origin_mm, rvec, tvec, rng, blur=0.7, noise=2.0
        )
        path = folder / f"view{i:02d}.png"
        cv2.imwrite(str(path), img)
        paths.append(path)
    return board, paths


def test_calibration_recovers_the_camera(views: tuple[Board, list[Path]], tmp_path: Path) -> None:
    board, paths = views
    result = calibrate_board(board, paths)
    assert result.image_size == SIZE
    assert result.fx == pytest.approx(1000.0, rel=0.005)
    assert result.fy == pytest.approx(1000.0, rel=0.005)
    assert abs(result.cx - 659.5) <= 2.0 and abs(result.cy - 499.5) <= 2.0
    assert abs(result.dist_coeffs[0] + 0.2) <= 0.02
    assert result.rms_px < 0.1  # printed edges fitted: ChArUco's corners reach about 0.06 px here
    assert abs(result.cx - 659.5) <= 0.5 and abs(result.cy - 499.5) <= 0.5
    assert sum(v.used for v in result.views) >= 15
    assert all(len(t.triangles) >= 1 for t in board.tags)
    assert all(v.tags >= 3 for v in result.views)
    # the camera file is what `decode --camera` reads
    out = tmp_path / "camera.json"
    write_camera(result, out)
    cam = load_camera(out)
    np.testing.assert_allclose(cam.matrix, result.camera_matrix)
    np.testing.assert_allclose(cam.dist, result.dist_coeffs)
    data = json.loads(out.read_text())
    assert data["format"] == "ottag-camera/1" and len(data["views"]) == len(paths)


def test_fixed_aspect_and_rational_model(views: tuple[Board, list[Path]]) -> None:
    board, paths = views
    fixed = calibrate_board(board, paths, CalibrationOptions(fix_aspect=True))
    assert fixed.fx == pytest.approx(fixed.fy, rel=1e-9)
    assert fixed.fx == pytest.approx(1000.0, rel=0.005)
    single = calibrate_board(board, paths, CalibrationOptions(refine=False))  # no second, straightened pass
    assert single.fx == pytest.approx(1000.0, rel=0.005) and abs(single.dist_coeffs[0] + 0.2) <= 0.02
    detected = calibrate_board(board, paths, CalibrationOptions(edge_fit=False))  # detector points only
    assert detected.fx == pytest.approx(1000.0, rel=0.005)
    assert fixed.rms_px < detected.rms_px
    rational = calibrate_board(board, paths, CalibrationOptions(model="rational"))
    assert len(rational.dist_coeffs) == 8
    assert rational.rms_px < 0.5


def test_too_few_views_and_views_without_the_board(views: tuple[Board, list[Path]], tmp_path: Path) -> None:
    board, paths = views
    with pytest.raises(CalibrationError, match="at least 4 such views"):
        calibrate_board(board, paths[:3])
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((SIZE[1], SIZE[0]), 128, np.uint8))
    with pytest.raises(CalibrationError, match="none of the 2 image"):
        calibrate_board(board, [blank, blank])
    result = calibrate_board(board, [*paths, blank])  # a view without the board is reported, not fatal
    skipped = [v for v in result.views if not v.used]
    assert [v.image for v in skipped] == [str(blank)] and skipped[0].reason == "no board tag found"
    with pytest.raises(DecodeError, match="no such file"):
        calibrate_board(board, [tmp_path / "missing.png"])
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.full((480, 640), 128, np.uint8))
    with pytest.raises(CalibrationError, match="calibrate one camera resolution at a time"):
        calibrate_board(board, [paths[0], small])


def test_fronto_parallel_views_are_refused(views: tuple[Board, list[Path]], tmp_path: Path) -> None:
    board, _ = views
    assert board.page_origin_mm is not None
    cam = DistortedCamera(TRUE_K, np.zeros(5), (SIZE[1], SIZE[0]), supersampling=1)
    rng = np.random.default_rng(3)
    paths = []
    raster = rasterize(views[1][0].parent / "board.pdf", PX_PER_MM)
    w, h = board.size_mm
    for i, (dx, dy) in enumerate([(-60, -40), (60, -40), (0, 0), (-60, 40), (60, 40)]):
        tvec = np.array([dx - w / 2, dy - h / 2, 420.0 + 10 * i])
        scale = page_scale(raster, board.page_mm)
        img = cam.render(raster, scale, board.page_origin_mm, np.zeros(3), tvec, rng, blur=0.7, noise=2.0)
        path = tmp_path / f"flat{i}.png"
        cv2.imwrite(str(path), img)
        paths.append(path)
    with pytest.raises(CalibrationError, match="fronto-parallel"):
        calibrate_board(board, paths)
