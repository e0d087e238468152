"""Calibration accuracy: an Order Type Tag board against an OpenCV ChArUco board on the same views.

Usage: python benchmarks/calibration.py [views] [seed] [--plot PATH]

A 4 × 3 board of 40 mm k = 8 tags (10 mm spacing, A4) is made with ``board create`` from the
bundled data, rasterized from its own PDF (pypdfium2) and photographed by a known camera
(fx = fy = 1000 px, principal point 20 px off the centre of a 1280 × 960 frame, k1 = −0.2,
blur σ 0.7 px, noise σ 2 grey levels) at ``views`` poses tilted 20–45° in every direction.
The PDF is rasterized at 40 px/mm and reduced to 10 px/mm by area averaging (pdfium
snaps filled edges to whole raster rows in y: at 10 px/mm every black square would come out
0.1 mm too tall, a bias of the test print, not of the detector). A ChArUco board of about
the same size (7 × 9 squares of 20 mm, 15 mm DICT_5X5_100 markers: 140 × 180 mm) is
photographed at the same poses with the same degradations.
Ours: ``ottag_db.app.calibration.calibrate_board``; ChArUco: ``cv2.aruco.CharucoDetector`` +
``cv2.calibrateCamera`` with the same model (k1, k2, p1, p2). Both results and their errors
against the true camera are printed side by side; ``--plot PATH`` writes the errors of fx, fy,
cx, cy and the RMS as bars (PNG, matplotlib).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import pypdfium2 as pdfium
from peers import plot_bars  # the benchmarks' plots

from ottag_db.app.boards import create_board, read_board
from ottag_db.app.calibration import calibrate_board
from ottag_db.files.bundled import bundled_point_files
from ottag_db.printing.board import DistortedCamera, calibration_poses
from ottag_db.printing.pdf import MM_TO_PT
from ottag_db.store.db import open_database
from ottag_db.store.importer import import_point_file

TRUE_K = np.array([[1000.0, 0.0, 659.5], [0.0, 1000.0, 499.5], [0.0, 0.0, 1.0]])
TRUE_DIST = np.array([-0.2, 0.0, 0.0, 0.0, 0.0])
SIZE = (1280, 960)
PX_PER_MM = 10.0


def charuco_calibrate(images: list[np.ndarray], board: object) -> tuple[float, np.ndarray, np.ndarray, int]:
    """ChArUco corners → ``cv2.calibrateCamera`` (k3 fixed): RMS, K, distortion, views used."""
    detector = cv2.aruco.CharucoDetector(board)  # type: ignore[attr-defined]
    obj, img = [], []
    for image in images:
        corners, ids, _, _ = detector.detectBoard(image)
        if ids is None or len(ids) < 6:
            continue
        o, i = board.matchImagePoints(corners, ids)  # type: ignore[attr-defined]
        obj.append(o.astype(np.float32))
        img.append(i.astype(np.float32))
    rms, kmat, dist, _, _ = cv2.calibrateCamera(obj, img, SIZE, np.eye(3), np.zeros(5), flags=cv2.CALIB_FIX_K3)
    return float(rms), kmat, dist.ravel(), len(obj)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("views", nargs="?", type=int, default=20)
    parser.add_argument("seed", nargs="?", type=int, default=0)
    parser.add_argument("--plot", default=None, metavar="PATH", help="write the errors as bars (PNG, matplotlib)")
    args = parser.parse_args()
    if args.views < 4:
        parser.error("views must be at least 4")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        db = open_database(folder / "db.sqlite")
        try:
            for file, _k in bundled_point_files():
                import_point_file(db, file, with_mirrors=True)
            _, board_file = create_board(db, folder / "board.pdf", rows=4, cols=3, tag_size_mm=40, spacing_mm=10)
        finally:
            db.close()
        board = read_board(board_file)
        assert board.page_origin_mm is not None
        doc = pdfium.PdfDocument(str(folder / "board.pdf"))
        # pdfium fills shapes up to one raster row too tall (edges snapped to whole pixels in y):
        # rasterize at 4× and reduce by area averaging so the print is exact to 1/40 mm
        page = doc[0].render(scale=4 * PX_PER_MM / MM_TO_PT, grayscale=True).to_numpy()
        doc.close()
        page = np.ascontiguousarray(page[..., 0] if page.ndim == 3 else page)
        page = cv2.resize(page, (page.shape[1] // 4, page.shape[0] // 4), interpolation=cv2.INTER_AREA)
        assert board.page_mm is not None  # pdfium rounds the page up to whole pixels: true scale per axis
        page_scale = (page.shape[1] / board.page_mm[0], page.shape[0] / board.page_mm[1])
        aruco = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100)
        charuco = cv2.aruco.CharucoBoard((7, 9), 20.0, 15.0, aruco)
        charuco_page = charuco.generateImage((1600, 2000), marginSize=100)  # 10 px/mm, 10 mm margin
        cam = DistortedCamera(TRUE_K, TRUE_DIST, (SIZE[1], SIZE[0]), supersampling=2)
        rng = np.random.default_rng(args.seed)
        poses = calibration_poses(board.size_mm, TRUE_K, SIZE, args.views, rng)
        ours_paths, charuco_images = [], []
        for i, (rvec, tvec) in enumerate(poses):
            noise_rng = np.random.default_rng(args.seed * 1000 + i)
            img = cam.render(page, page_scale, board.page_origin_mm, rvec, tvec, noise_rng, blur=0.7, noise=2.0)
            ours_paths.append(folder / f"ott{i:02d}.png")
            cv2.imwrite(str(ours_paths[-1]), img)
            noise_rng = np.random.default_rng(args.seed * 1000 + i)
            charuco_images.append(
                cam.render(charuco_page, PX_PER_MM, (10.0, 10.0), rvec, tvec, noise_rng, blur=0.7, noise=2.0)
            )
        t0 = time.perf_counter()
        ours = calibrate_board(board, ours_paths)
        t_ours = time.perf_counter() - t0
        t0 = time.perf_counter()
        c_rms, c_k, c_dist, c_views = charuco_calibrate(charuco_images, charuco)
        t_charuco = time.perf_counter() - t0
    rows = [
        ("fx (px)", 1000.0, ours.fx, float(c_k[0, 0])),
        ("fy (px)", 1000.0, ours.fy, float(c_k[1, 1])),
        ("cx (px)", 659.5, ours.cx, float(c_k[0, 2])),
        ("cy (px)", 499.5, ours.cy, float(c_k[1, 2])),
        ("k1", -0.2, float(ours.dist_coeffs[0]), float(c_dist[0])),
        ("k2", 0.0, float(ours.dist_coeffs[1]), float(c_dist[1])),
    ]
    used = sum(v.used for v in ours.views)
    print(
        f"{args.views} views of 1280×960, fx = fy = 1000, principal point (659.5, 499.5), k1 = -0.2; seed {args.seed}"
    )
    print(f"{'':10} {'true':>9} {'OTT board':>11} {'error':>9} {'ChArUco':>11} {'error':>9}")
    for name, true, a, b in rows:
        d = 3 if abs(true) > 1 else 4
        print(f"{name:10} {true:9.{d}f} {a:11.{d}f} {a - true:+9.{d}f} {b:11.{d}f} {b - true:+9.{d}f}")
    print(f"{'RMS (px)':10} {'':9} {ours.rms_px:11.3f} {'':9} {c_rms:11.3f}")
    print(f"{'views used':10} {'':9} {used:11d} {'':9} {c_views:11d}")
    print(f"{'time (s)':10} {'':9} {t_ours:11.2f} {'':9} {t_charuco:11.2f}   (detection + calibration)")
    err_ours = max(abs(ours.fx - 1000) / 10, abs(ours.fy - 1000) / 10, abs(ours.cx - 659.5), abs(ours.cy - 499.5))
    err_c = max(abs(c_k[0, 0] - 1000) / 10, abs(c_k[1, 1] - 1000) / 10, abs(c_k[0, 2] - 659.5), abs(c_k[1, 2] - 499.5))
    print(f"largest intrinsics error (focal in 0.1 % units, centre in px): ours {err_ours:.3f}, ChArUco {err_c:.3f}")
    if args.plot:
        groups = {
            name.split()[0]: {"Order Type Tag board": abs(a - true), "ChArUco": abs(b - true)}
            for name, true, a, b in rows[:4]
        }
        groups["RMS"] = {"Order Type Tag board": ours.rms_px, "ChArUco": c_rms}
        plot_bars(
            args.plot,
            f"calibration: |error| against the true camera ({args.views} views, seed {args.seed})",
            "px",
            groups,
        )


if __name__ == "__main__":
    main()
