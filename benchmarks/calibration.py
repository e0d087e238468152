"""Calibration accuracy: an Order Type Tag board against an OpenCV ChArUco board on the same views.

Usage: python benchmarks/calibration.py [views] [seed] [--seed S] [--plot PATH] [--quiet]
       python benchmarks/calibration.py --povray [views] [--seed S] [--cache DIR] [--diagnose] [--quiet]

Warped views (the default). A 4 × 3 board of 40 mm k = 8 tags (10 mm spacing, A4) is made with
``board create`` from the bundled data, rasterized from its own PDF (pypdfium2) and photographed
by a known camera (fx = fy = 1000 px, principal point 20 px off the centre of a 1280 × 960 frame,
k1 = −0.2, blur σ 0.7 px, noise σ 2 grey levels) at ``views`` (default 20) poses tilted 20–45°
in every direction. The PDF is rasterized at 40 px/mm and reduced to 10 px/mm by area averaging
(pdfium snaps filled edges to whole raster rows in y: at 10 px/mm every black square would come
out 0.1 mm too tall, a bias of the test print, not of the detector). A ChArUco board of about
the same size (7 × 9 squares of 20 mm, 15 mm DICT_5X5_100 markers: 140 × 180 mm) is
photographed at the same poses with the same degradations.

Ray-traced views (``--povray``; needs POV-Ray, ``apt-get install povray``). The same page raster
and the same ChArUco board drawn by ``generateImage`` centred on an A4 page (10 px/mm) are
textures on a plane ray-traced by POV-Ray (``benchmarks/povray.py``, ``povray_board.py``) with
an exact pinhole camera: 1280 × 960, f = 1000 px, principal point (639.5, 479.5), no
distortion, lit by a point light and ambient light, adaptive antialiasing; ``views`` (default
15) poses tilted 20–45° in every direction, drawn from ``--seed``, each page at the same pose.
Rendered frames are cached in ``--cache`` (default: a temporary folder); about 2 × ``views``
renders of a few seconds each, at most 2 POV-Ray processes. ``--diagnose`` adds, per view, the
detected points against the true projections (our vertices, our corners, the edge-fit points of
the calibration's second pass, the ChArUco corners: mean offset, RMS, mean outward component),
and the camera fitted by ``cv2.calibrateCamera`` to each kind of our points alone.

Ours: ``ottag_db.app.calibration.calibrate_board``; ChArUco: ``cv2.aruco.CharucoDetector`` +
``cv2.calibrateCamera`` with the same model (k1, k2, p1, p2; k3 fixed). Both results and their
errors against the true camera are printed side by side; ``--plot PATH`` writes the errors of
fx, fy, cx, cy and the RMS as bars (PNG, matplotlib). Progress goes to stderr (not with ``--quiet``).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pypdfium2 as pdfium
from peers import plot_bars  # the benchmarks' plots
from povray import CALIBRATION_CAMERA
from povray_board import Residuals, charuco_board, charuco_page, charuco_residuals, our_residuals, render_views

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


def progress(quiet: bool, text: str, end: str = "\n") -> None:
    """``text`` on stderr unless ``quiet``."""
    if not quiet:
        print(text, end=end, file=sys.stderr, flush=True)


def charuco_calibrate(images: list[np.ndarray], board: Any) -> tuple[float, np.ndarray, np.ndarray, int]:
    """ChArUco corners → ``cv2.calibrateCamera`` (k3 fixed): RMS, K, distortion, views used."""
    detector = cv2.aruco.CharucoDetector(board)
    obj, img = [], []
    for image in images:
        corners, ids, _, _ = detector.detectBoard(image)
        if ids is None or len(ids) < 6:
            continue
        o, i = board.matchImagePoints(corners, ids)
        obj.append(o.astype(np.float32))
        img.append(i.astype(np.float32))
    rms, kmat, dist, _, _ = cv2.calibrateCamera(obj, img, SIZE, np.eye(3), np.zeros(5), flags=cv2.CALIB_FIX_K3)
    return float(rms), kmat, dist.ravel(), len(obj)


def make_board(folder: Path, pdftoppm_dpi: int | None = None) -> tuple[Any, np.ndarray, tuple[float, float]]:
    """Our board (``board create``, bundled data) in ``folder``: the board, its page rasterized from
    its own PDF at 10 px/mm (4× and area averaging) and the raster's true px/mm per axis; with
    ``pdftoppm_dpi``, rasterized by poppler's ``pdftoppm -gray -r DPI`` instead (as issue 38 did)."""
    db = open_database(folder / "db.sqlite")
    try:
        for file, _k in bundled_point_files():
            import_point_file(db, file, with_mirrors=True)
        _, board_file = create_board(db, folder / "board.pdf", rows=4, cols=3, tag_size_mm=40, spacing_mm=10)
    finally:
        db.close()
    board = read_board(board_file)
    assert board.page_origin_mm is not None
    if pdftoppm_dpi is not None:  # the content at DPI exactly, the page rounded to whole pixels
        cmd = ["pdftoppm", "-gray", "-r", str(pdftoppm_dpi), "-singlefile", "-png", "board.pdf", "page"]
        subprocess.run(cmd, cwd=folder, check=True)
        page = cv2.imread(str(folder / "page.png"), cv2.IMREAD_GRAYSCALE)
        return board, np.asarray(page, np.uint8), (pdftoppm_dpi / 25.4, pdftoppm_dpi / 25.4)
    doc = pdfium.PdfDocument(str(folder / "board.pdf"))
    # pdfium fills shapes up to one raster row too tall (edges snapped to whole pixels in y):
    # rasterize at 4× and reduce by area averaging so the print is exact to 1/40 mm
    page = doc[0].render(scale=4 * PX_PER_MM / MM_TO_PT, grayscale=True).to_numpy()
    doc.close()
    page = np.ascontiguousarray(page[..., 0] if page.ndim == 3 else page)
    page = cv2.resize(page, (page.shape[1] // 4, page.shape[0] // 4), interpolation=cv2.INTER_AREA)
    assert board.page_mm is not None  # pdfium rounds the page up to whole pixels: true scale per axis
    page_scale = (page.shape[1] / board.page_mm[0], page.shape[0] / board.page_mm[1])
    return board, page, page_scale


def print_results(
    true: dict[str, float], ours: Any, charuco: tuple[float, np.ndarray, np.ndarray, int], times: tuple[float, float]
) -> list[tuple[str, float, float, float]]:
    """The side-by-side table; its rows (name, true, ours, ChArUco)."""
    c_rms, c_k, c_dist, c_views = charuco
    rows = [
        ("fx (px)", true["fx"], ours.fx, float(c_k[0, 0])),
        ("fy (px)", true["fy"], ours.fy, float(c_k[1, 1])),
        ("cx (px)", true["cx"], ours.cx, float(c_k[0, 2])),
        ("cy (px)", true["cy"], ours.cy, float(c_k[1, 2])),
        ("k1", true["k1"], float(ours.dist_coeffs[0]), float(c_dist[0])),
        ("k2", 0.0, float(ours.dist_coeffs[1]), float(c_dist[1])),
    ]
    used = sum(v.used for v in ours.views)
    print(f"{'':10} {'true':>9} {'OTT board':>11} {'error':>9} {'ChArUco':>11} {'error':>9}")
    for name, t, a, b in rows:
        d = 3 if abs(t) > 1 else 4
        print(f"{name:10} {t:9.{d}f} {a:11.{d}f} {a - t:+9.{d}f} {b:11.{d}f} {b - t:+9.{d}f}")
    print(f"{'RMS (px)':10} {'':9} {ours.rms_px:11.3f} {'':9} {c_rms:11.3f}")
    print(f"{'views used':10} {'':9} {used:11d} {'':9} {c_views:11d}")
    print(f"{'time (s)':10} {'':9} {times[0]:11.2f} {'':9} {times[1]:11.2f}   (detection + calibration)")

    def worst(values: list[float]) -> float:
        e = [abs(v - r[1]) for v, r in zip(values, rows, strict=False)]
        return max(e[0] / true["fx"] * 100, e[1] / true["fy"] * 100, e[2], e[3])

    w_ours, w_ch = worst([r[2] for r in rows[:4]]), worst([r[3] for r in rows[:4]])
    print(f"largest intrinsics error (focal in 0.1 % units, centre in px): ours {w_ours:.3f}, ChArUco {w_ch:.3f}")
    return rows


def warped(args: argparse.Namespace) -> None:
    """The warped views (``DistortedCamera``)."""
    views = args.views or 20
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        board, page, page_scale = make_board(folder)
        aruco = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100)
        charuco = cv2.aruco.CharucoBoard((7, 9), 20.0, 15.0, aruco)
        charuco_page = charuco.generateImage((1600, 2000), marginSize=100)  # 10 px/mm, 10 mm margin
        cam = DistortedCamera(TRUE_K, TRUE_DIST, (SIZE[1], SIZE[0]), supersampling=2)
        rng = np.random.default_rng(args.seed)
        poses = calibration_poses(board.size_mm, TRUE_K, SIZE, views, rng)
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
        progress(args.quiet, f"{views} warped views made; calibrating …")
        t0 = time.perf_counter()
        ours = calibrate_board(board, ours_paths)
        t_ours = time.perf_counter() - t0
        t0 = time.perf_counter()
        c_result = charuco_calibrate(charuco_images, charuco)
        t_charuco = time.perf_counter() - t0
    print(f"{views} views of 1280×960, fx = fy = 1000, principal point (659.5, 499.5), k1 = -0.2; seed {args.seed}")
    true = {"fx": 1000.0, "fy": 1000.0, "cx": 659.5, "cy": 499.5, "k1": -0.2}
    rows = print_results(true, ours, c_result, (t_ours, t_charuco))
    if args.plot:
        groups = {
            name.split()[0]: {"Order Type Tag board": abs(a - t), "ChArUco": abs(b - t)} for name, t, a, b in rows[:4]
        }
        groups["RMS"] = {"Order Type Tag board": ours.rms_px, "ChArUco": c_result[0]}
        plot_bars(
            args.plot, f"calibration: |error| against the true camera ({views} views, seed {args.seed})", "px", groups
        )


def raytraced(args: argparse.Namespace) -> None:
    """The ray-traced views (POV-Ray): both boards on A4 at the same poses, the true camera exact."""
    views = args.views or 15
    cam = CALIBRATION_CAMERA
    kmat, size = cam.matrix, (cam.width, cam.height)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        board, page, scale = make_board(folder, args.pdftoppm)
        assert board.page_mm is not None and board.page_origin_mm is not None
        page_size = (page.shape[1] / scale[0], page.shape[0] / scale[1])  # the raster's extent, mm
        charuco = charuco_board()
        ch_page, ch_origin = charuco_page(charuco)
        poses = calibration_poses(board.size_mm, kmat, size, views, np.random.default_rng(args.seed))
        cache = args.cache if args.cache is not None else folder / "frames"

        def step(done: int, total: int) -> None:
            progress(args.quiet, f"\rrendered {done}/{total}", end="\n" if done == total else "")

        frames = render_views(cache, (page, page_size, board.page_origin_mm), (ch_page, ch_origin), poses, step)
        ours_paths = []
        for i, img in enumerate(frames.ours):
            ours_paths.append(folder / f"ott{i:02d}.png")
            cv2.imwrite(str(ours_paths[-1]), img)
        progress(args.quiet, f"{frames.rendered} frames rendered in {frames.seconds:.0f} s; calibrating …")
        t0 = time.perf_counter()
        ours = calibrate_board(board, ours_paths)
        t_ours = time.perf_counter() - t0
        t0 = time.perf_counter()
        c_result = charuco_calibrate(frames.charuco, charuco)
        t_charuco = time.perf_counter() - t0
        print(
            f"{views} ray-traced views (POV-Ray) of 1280×960, fx = fy = 1000, principal point (639.5, 479.5), "
            f"no distortion; both boards on A4, tilt 20–45°; seed {args.seed}"
        )
        true = {"fx": cam.focal, "fy": cam.focal, "cx": kmat[0, 2], "cy": kmat[1, 2], "k1": 0.0}
        rows = print_results(true, ours, c_result, (t_ours, t_charuco))
        if args.diagnose:
            shift = np.array([ch_origin[0] - board.page_origin_mm[0], ch_origin[1] - board.page_origin_mm[1], 0.0])
            diagnose(board, ours_paths, frames.charuco, charuco, shift, poses, args.quiet)
    if args.plot:
        groups = {
            name.split()[0]: {"Order Type Tag board": abs(a - t), "ChArUco": abs(b - t)} for name, t, a, b in rows[:4]
        }
        groups["RMS"] = {"Order Type Tag board": ours.rms_px, "ChArUco": c_result[0]}
        title = f"calibration, ray-traced: |error| against the true camera ({views} views, seed {args.seed})"
        plot_bars(args.plot, title, "px", groups)


def diagnose(
    board: Any,
    paths: list[Path],
    charuco_images: list[np.ndarray],
    charuco: Any,
    shift: np.ndarray,
    poses: list[tuple[np.ndarray, np.ndarray]],
    quiet: bool,
) -> None:
    """Per view: detected − true points (n, mean offset, RMS, mean outward component; px) of our
    vertices, corners and edge-fit points and of the ChArUco corners; then the camera that
    ``cv2.calibrateCamera`` (k1, k2, p1, p2) fits to each kind of our points alone."""
    kinds = ("vertices", "corners", "edge fit")
    per_kind: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {k: [] for k in kinds}
    table: dict[str, list[Residuals]] = {k: [] for k in (*kinds, "ChArUco")}
    print("\ndetected − true (px): per view n, mean offset (x, y), RMS, mean outward from the tag / square centre")
    print(f"{'view':>4} " + " ".join(f"{k:>34}" for k in table))
    for i, (path, pose) in enumerate(zip(paths, poses, strict=True)):
        progress(quiet, f"\rdiagnosing {i + 1}/{len(paths)}", end="\n" if i + 1 == len(paths) else "")
        res = our_residuals(board, path, pose)
        for k in kinds:
            table[k].append(res[k][0])
            if len(res[k][1]) >= 6:
                per_kind[k].append((res[k][1], res[k][2]))
        table["ChArUco"].append(charuco_residuals(charuco, charuco_images[i], pose, shift))
        cells = [
            f"{r.n:4d} ({r.mean[0]:+.3f},{r.mean[1]:+.3f}) {r.rms:.3f} {r.outward:+.3f}"
            for r in (table[k][-1] for k in table)
        ]
        print(f"{i:4d} " + " ".join(f"{c:>34}" for c in cells))
    cells = []
    for k in table:
        rs = [r for r in table[k] if r.n]
        n = sum(r.n for r in rs)
        mean = np.sum([r.mean * r.n for r in rs], axis=0) / n
        rms = float(np.sqrt(sum(r.rms**2 * r.n for r in rs) / n))
        out = sum(r.outward * r.n for r in rs) / n
        cells.append(f"{n:4d} ({mean[0]:+.3f},{mean[1]:+.3f}) {rms:.3f} {out:+.3f}")
    print(f"{'all':>4} " + " ".join(f"{c:>34}" for c in cells))
    print("\ncv2.calibrateCamera on each kind of our points alone (true 1000, 1000, 639.5, 479.5):")
    for k in kinds:
        obj = [o.astype(np.float32) for o, _ in per_kind[k]]
        img = [p.astype(np.float32) for _, p in per_kind[k]]
        rms, km, _, _, _ = cv2.calibrateCamera(obj, img, SIZE, np.eye(3), np.zeros(5), flags=cv2.CALIB_FIX_K3)
        print(
            f"  {k:9} fx {km[0, 0]:8.2f} fy {km[1, 1]:8.2f} cx {km[0, 2]:7.2f} cy {km[1, 2]:7.2f}  "
            f"RMS {rms:.3f} px, {len(obj)} views"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("views", nargs="?", type=int, default=None, help="views (default 20; --povray: 15)")
    parser.add_argument("seed_pos", nargs="?", type=int, default=None, metavar="seed", help="seed of the poses")
    parser.add_argument("--seed", type=int, default=None, help="seed of the poses (default 0)")
    parser.add_argument("--povray", action="store_true", help="ray-traced views (POV-Ray) instead of warped ones")
    parser.add_argument("--cache", type=Path, default=None, metavar="DIR", help="--povray: folder of rendered frames")
    parser.add_argument("--diagnose", action="store_true", help="--povray: detected points against the truth")
    parser.add_argument(
        "--pdftoppm", type=int, default=None, metavar="DPI", help="--povray: our page rasterized by pdftoppm at DPI"
    )
    parser.add_argument("--plot", default=None, metavar="PATH", help="write the errors as bars (PNG, matplotlib)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    args = parser.parse_args()
    args.seed = args.seed if args.seed is not None else (args.seed_pos or 0)
    if args.views is not None and args.views < 4:
        parser.error("views must be at least 4")
    if args.povray:
        raytraced(args)
    else:
        warped(args)


if __name__ == "__main__":
    main()
