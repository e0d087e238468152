"""Tests of the decode command and ottag_db.app.decoding (real images, real OpenCV, real SQLite)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from ottag_db.app.decoding import load_camera
from ottag_db.app.detector import open_detector
from ottag_db.cli import cli
from ottag_db.errors import UsageError
from tests.support.paper import TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)


@pytest.fixture(scope="module")
def dbfile(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("decode") / "db.sqlite"
    shutil.copyfile(bundled_db_path, path)
    return path


@pytest.fixture(scope="module")
def fig4_png(dbfile: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("img") / "fig4.png"
    res = CliRunner().invoke(cli, ["render", "--db", str(dbfile), TABLE9_TEXT, str(out), "--px", "240"])
    assert res.exit_code == 0, res.output
    return out


def test_decode_json_contract(runner: CliRunner, dbfile: Path, fig4_png: Path, tmp_path: Path) -> None:
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--json", "--draw", str(tmp_path / "draw"), str(fig4_png)])
    assert res.exit_code == 0, res.output
    lines = res.stdout.strip().splitlines()
    assert len(lines) == 1
    rec = json.loads(lines[0])
    assert rec["image"] == str(fig4_png) and isinstance(rec["rejected"], int)
    (det,) = rec["detections"]
    for key in ("lambda", "k", "order_type", "tag", "polarity", "points", "corners", "homography", "margin_px"):
        assert key in det
    assert det["lambda"] == TABLE9_TEXT and det["k"] == 7 and det["polarity"] == "normal"
    assert len(det["points"]) == 7 and len(det["corners"]) == 4 and np.array(det["homography"]).shape == (3, 3)
    assert det["margin_px"] > 1.0 and isinstance(det["number"], int)
    assert (tmp_path / "draw" / "fig4_decoded.png").exists()


def test_decode_inverted_and_pose(runner: CliRunner, dbfile: Path, tmp_path: Path) -> None:
    img = tmp_path / "inv.png"
    assert (
        runner.invoke(cli, ["render", "--db", str(dbfile), TABLE9_TEXT, str(img), "--polarity", "inverted"]).exit_code
        == 0
    )
    cam = tmp_path / "cam.json"
    cam.write_text(json.dumps({"fx": 800, "fy": 800, "cx": 300, "cy": 300}))
    res = runner.invoke(
        cli, ["decode", "--db", str(dbfile), "--json", "--camera", str(cam), "--tag-size", "5cm", str(img)]
    )
    assert res.exit_code == 0, res.output
    (det,) = json.loads(res.stdout)["detections"]
    assert det["polarity"] == "inverted"
    pose = det["pose"]
    assert len(pose["solutions"]) >= 1 and len(pose["tvec"]) == 3
    # Rendered head-on: the tag plane faces the camera, at z = f * size / pixels (fronto-parallel).
    assert pose["tvec"][2] > 0
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--camera", str(cam), str(img)])
    assert res.exit_code == 2 and "go together" in res.stderr


def test_decode_bad_inputs(runner: CliRunner, dbfile: Path, fig4_png: Path, tmp_path: Path) -> None:
    text = tmp_path / "notes.png"
    text.write_text("not an image")
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    one = tmp_path / "one.png"
    cv2.imwrite(str(one), np.zeros((1, 1), np.uint8))
    deep = tmp_path / "deep.png"
    g = cv2.imread(str(fig4_png), cv2.IMREAD_GRAYSCALE)
    cv2.imwrite(str(deep), g.astype(np.uint16) * 257)
    rgba = tmp_path / "rgba.png"
    cv2.imwrite(str(rgba), cv2.cvtColor(g, cv2.COLOR_GRAY2BGRA))
    args = ["decode", "--db", str(dbfile), "--json", str(text), str(empty), str(one), str(deep), str(rgba)]
    res = runner.invoke(cli, [*args, str(tmp_path / "missing.png"), str(tmp_path)])
    assert res.exit_code == 1
    recs = [json.loads(x) for x in res.stdout.strip().splitlines()]
    assert len(recs) == 7
    by = {Path(r["image"]).name: r for r in recs}
    assert "error" in by["notes.png"] and "error" in by["empty.png"] and "error" in by["missing.png"]
    assert "is a directory" in by[tmp_path.name]["error"]
    assert by["one.png"]["detections"] == []
    assert [d["lambda"] for d in by["deep.png"]["detections"]] == [TABLE9_TEXT]
    assert [d["lambda"] for d in by["rgba.png"]["detections"]] == [TABLE9_TEXT]
    assert "4 of 7 file(s) could not be read" in res.stderr


def test_open_detector_and_camera_files(dbfile: Path, fig4_png: Path, tmp_path: Path) -> None:
    det = open_detector(str(dbfile))
    found = det.detect(cv2.imread(str(fig4_png)))
    assert [d.lambda_text for d in found] == [TABLE9_TEXT]
    assert found[0].model_points is not None
    yml = tmp_path / "cam.yml"
    fs = cv2.FileStorage(str(yml), cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]))
    fs.write("distortion_coefficients", np.zeros((1, 5)))
    fs.release()
    cam = load_camera(yml)
    assert cam.matrix[0, 0] == 500
    bad = tmp_path / "bad.json"
    bad.write_text('{"fx": 1}')
    with pytest.raises(UsageError, match="fx, fy, cx, cy"):
        load_camera(bad)


# ----------------------------------------------------------------------------- issue 11, item 8
def _damage_jpeg(src: Path, dst: Path) -> None:
    """Flip 8 bytes in the middle of the entropy-coded data of a JPEG written by cv2.imwrite."""
    data = bytearray(src.read_bytes())
    sos = data.index(b"\xff\xda")
    start = sos + 2 + int.from_bytes(data[sos + 2 : sos + 4], "big")
    end = data.rindex(b"\xff\xd9")
    mid = (start + end) // 2
    for i in range(mid, mid + 8):
        data[i] ^= 0x5A
    dst.write_bytes(bytes(data))


def test_jpeg_damaged_in_the_middle_is_an_error(dbfile: Path, fig4_png: Path, tmp_path: Path) -> None:
    import subprocess
    import sys

    from ottag_db.app.decoding import read_image
    from ottag_db.errors import DecodeError

    good = tmp_path / "good.jpg"
    assert cv2.imwrite(str(good), cv2.imread(str(fig4_png)), [cv2.IMWRITE_JPEG_QUALITY, 95])
    bad = tmp_path / "bad.jpg"
    _damage_jpeg(good, bad)
    # Precondition: OpenCV alone returns an image and only libjpeg's warning says it is damaged.
    shape = read_image(good).shape
    probe = "import cv2, sys; print(cv2.imread(sys.argv[1]).shape)"
    raw = subprocess.run([sys.executable, "-c", probe, str(bad)], capture_output=True, text=True, check=True)
    assert raw.stdout.strip() == str(shape) and "Corrupt JPEG data" in raw.stderr
    with pytest.raises(DecodeError, match=r"bad\.jpg: damaged JPEG \(.+\).*copy or export the file again"):
        read_image(bad)

    cmd = [sys.executable, "-m", "ottag_db", "decode", "--db", str(dbfile)]
    res = subprocess.run([*cmd, str(bad)], capture_output=True, text=True, timeout=300)
    assert res.returncode == 1 and res.stdout == ""
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {bad}: damaged JPEG"), res.stderr
    assert "Corrupt JPEG data" not in res.stderr  # our line replaces libjpeg's raw text
    # In a batch the other files still decode, the damaged one is a record with "error".
    res = subprocess.run([*cmd, "--json", str(good), str(bad)], capture_output=True, text=True, timeout=300)
    assert res.returncode == 1
    recs = [json.loads(x) for x in res.stdout.strip().splitlines()]
    assert [d["lambda"] for d in recs[0]["detections"]] == [TABLE9_TEXT]
    assert "damaged JPEG" in recs[1]["error"] and recs[1]["detections"] == []
    assert "Corrupt JPEG data" not in res.stderr and "1 of 2 file(s) could not be read" in res.stderr


def test_a_three_point_tag_says_why_it_is_not_verified(runner: CliRunner, dbfile: Path, tmp_path: Path) -> None:
    """A 3-point tag's points lie on 6 side lines, too few for a homography: the rejection says so
    and names the way to read it; without verification the order type alone reads it."""
    img = tmp_path / "k3.png"
    assert runner.invoke(cli, ["render", "--db", str(dbfile), "3:010001100", str(img)]).exit_code == 0
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--json", str(img)])
    assert res.exit_code == 0, res.output
    rec = json.loads(res.stdout)
    assert rec["detections"] == []
    (why,) = [r for r in rec["rejections"] if r["lambda"] == "3:010001100"]
    assert why["reason"] == "verification" and "3-point reading cannot be verified" in why["detail"]
    assert "--no-verify" in why["detail"]
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--json", "--no-verify", str(img)])
    assert res.exit_code == 0, res.output
    assert [d["lambda"] for d in json.loads(res.stdout)["detections"]] == ["3:010001100"]
