"""``ottag-db board create|show`` and ``ottag-db calibrate`` end to end (real subprocesses for
the exit codes, real SQLite, PDF and images)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from ottag_db.printing.board import DistortedCamera, calibration_poses
from tests.app.test_calibration import PX_PER_MM, SIZE, TRUE_DIST, TRUE_K, page_scale, rasterize


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "ottag_db", *args], capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def cli_board(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("cliboard")
    db = folder / "db.sqlite"
    shutil.copy(bundled_db_path, db)
    proc = run(
        "board",
        "create",
        str(folder / "b.pdf"),
        "--rows",
        "4",
        "--cols",
        "3",
        "--tag-size",
        "40mm",
        "--spacing",
        "10mm",
        "--db",
        str(db),
        "--quiet",
    )
    assert proc.returncode == 0, proc.stderr
    assert "4 × 3 board, 12 tags" in proc.stdout and "b.board.json" in proc.stdout
    return folder, db


def test_create_and_show(cli_board: tuple[Path, Path]) -> None:
    folder, _ = cli_board
    assert (folder / "b.pdf").read_bytes().startswith(b"%PDF")
    proc = run("board", "show", str(folder / "b.board.json"))
    assert proc.returncode == 0, proc.stderr
    assert "4 rows × 3 columns, 12 tags (k = 8; normal)" in proc.stdout
    assert "tag size 40 mm, spacing 10 mm" in proc.stdout
    assert len([ln for ln in proc.stdout.splitlines() if ln.strip().startswith(("0 ", "1 ", "2 ", "3 "))]) == 12
    data = json.loads(run("board", "show", str(folder / "b.board.json"), "--json").stdout)
    assert data["format"] == "ottag-board/1" and len(data["tags"]) == 12


def test_board_that_does_not_fit(cli_board: tuple[Path, Path]) -> None:
    folder, db = cli_board
    proc = run("board", "create", str(folder / "x.pdf"), "--rows", "5", "--cols", "4", "--db", str(db))
    assert proc.returncode == 1
    assert proc.stderr.startswith("error: ") and "4 rows × 3 columns" in proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    proc = run(
        "board", "create", str(folder / "x.pdf"), "--rows", "2", "--cols", "2", "--tag-size", "40", "--db", str(db)
    )
    assert proc.returncode == 2 and "needs a unit" in proc.stderr


def test_bad_board_file_is_one_line_exit_1(tmp_path: Path) -> None:
    bad = tmp_path / "x.board.json"
    bad.write_text(json.dumps({"format": "something-else"}))
    for args in (["board", "show", str(bad)], ["calibrate", str(bad), str(bad)]):
        proc = run(*args)
        assert proc.returncode == 1
        assert proc.stderr.strip().splitlines()[-1].startswith("error: ")
        assert "not an ottag-board/1 board file" in proc.stderr and "Traceback" not in proc.stderr


def test_calibrate_command(cli_board: tuple[Path, Path], tmp_path: Path) -> None:
    folder, db = cli_board
    board = json.loads((folder / "b.board.json").read_text())
    page = rasterize(folder / "b.pdf", PX_PER_MM)
    cam = DistortedCamera(TRUE_K, TRUE_DIST, (SIZE[1], SIZE[0]), supersampling=1)
    rng = np.random.default_rng(5)
    w = board["cols"] * 40 + (board["cols"] - 1) * 10
    h = board["rows"] * 40 + (board["rows"] - 1) * 10
    images = []
    for i, (r, t) in enumerate(calibration_poses((w, h), TRUE_K, SIZE, 8, rng)):
        scale = page_scale(page, tuple(board["page_mm"]))
        img = cam.render(page, scale, tuple(board["page_origin_mm"]), r, t, rng, blur=0.7, noise=2.0)
        images.append(tmp_path / f"v{i}.png")
        cv2.imwrite(str(images[-1]), img)
    out = tmp_path / "camera.json"
    proc = run("calibrate", str(folder / "b.board.json"), *map(str, images), "-o", str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert "fx = " in proc.stdout and "k1 = " in proc.stdout and "RMS reprojection error" in proc.stdout
    assert len([ln for ln in proc.stdout.splitlines() if "v" in ln and ".png" in ln]) == 8
    data = json.loads(out.read_text())
    assert abs(data["fx"] - 1000) < 10 and abs(data["dist_coeffs"][0] + 0.2) < 0.05
    proc = run("calibrate", str(folder / "b.board.json"), *map(str, images), "--json", "--fix-aspect", "-q")
    res = json.loads(proc.stdout)
    assert res["fx"] == pytest.approx(res["fy"]) and len(res["views"]) == 8
    # the camera file works with decode --camera
    proc = run("decode", str(images[0]), "--camera", str(out), "--tag-size", "40mm", "--json", "--db", str(db))
    assert proc.returncode == 0, proc.stderr
    dets = json.loads(proc.stdout.splitlines()[0])["detections"]
    assert dets and all("pose" in d for d in dets)
    # images without the board: one line, exit 1
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((960, 1280), 128, np.uint8))
    proc = run("calibrate", str(folder / "b.board.json"), str(blank), "-q")
    assert proc.returncode == 1 and "none of the 1 image(s) shows" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
