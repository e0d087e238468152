"""``decode`` on video files (ottag_db.app.video): an mp4 written here with cv2.VideoWriter, real
OpenCV, real SQLite, the CLI in-process and as a real subprocess for the one-line errors."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from ottag_db.app.decoding import read_image
from ottag_db.app.video import input_kind, read_frames
from ottag_db.cli import cli
from ottag_db.errors import DecodeError
from ottag_db.printing import scenes as sc
from tests.support.paper import TABLE9
from tests.support.tagsynth import scene_data

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)
N_FRAMES = 100
FPS = 25.0
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def dbfile(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("video") / "db.sqlite"
    shutil.copyfile(bundled_db_path, path)
    return path


@pytest.fixture(scope="module")
def clip(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """100 frames (640×480, 25 fps, mp4v) of the paper's Fig. 4 tag moving across the frame,
    turning and tilting, with blur, noise and an illumination gradient."""
    _, tags = scene_data(bundled_db_path, ks=(7,))
    (tag,) = [t for t in tags if t.lambda_text == TABLE9_TEXT]
    out = tmp_path_factory.mktemp("clip") / "clip.mp4"
    writer = cv2.VideoWriter(str(out), cv2.VideoWriter.fourcc(*"mp4v"), FPS, (640, 480), True)
    assert writer.isOpened()
    noise_rng = np.random.default_rng(12)
    for i in range(N_FRAMES):
        s = i / (N_FRAMES - 1)
        center = (150 + 340 * s, 240 + 70 * math.sin(2 * math.pi * s))
        spec = sc.posed_spec(tag, np.random.default_rng(7), 160 + 40 * s, 10 + 30 * s, center_px=center)
        scene = sc.render_scene((480, 640), [spec], noise_rng, gradient=0.2, blur=0.7, noise=2.0)
        writer.write(cv2.cvtColor(scene.image, cv2.COLOR_GRAY2BGR))
    writer.release()
    return out


def _frame_count(path: Path) -> tuple[int, tuple[int, int]]:
    cap = cv2.VideoCapture(str(path))
    assert cap.isOpened(), path
    n, shape = 0, (0, 0)
    while True:
        ok, img = cap.read()
        if not ok:
            break
        n, shape = n + 1, img.shape[:2]
    cap.release()
    return n, shape


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "ottag_db", *args], capture_output=True, text=True, env=env, timeout=300, check=False
    )


def test_every_frame_is_one_json_object_with_the_right_id(
    runner: CliRunner, dbfile: Path, clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    drawn = tmp_path / "annotated.mp4"
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--json", "--draw", str(drawn), str(clip)])
    assert res.exit_code == 0, res.output
    recs = [json.loads(line) for line in res.stdout.splitlines()]
    assert [r["frame"] for r in recs] == list(range(N_FRAMES))
    for r in recs:
        assert r["image"] == str(clip) and {"detections", "rejected", "rejections", "time_s"} <= r.keys()
        assert r["time_s"] == pytest.approx(r["frame"] / FPS, abs=1e-3)
    right = sum(any(d["lambda"] == TABLE9_TEXT for d in r["detections"]) for r in recs)
    wrong = sum(d["lambda"] != TABLE9_TEXT for r in recs for d in r["detections"])
    with capsys.disabled():
        print(f"\nvideo: {right}/{len(recs)} frames with the right ID, {wrong} wrong detection(s)")
    assert right >= 99 and wrong == 0
    det = next(d for r in recs for d in r["detections"])
    assert len(det["points"]) == 7 and len(det["corners"]) == 4 and isinstance(det["number"], int)
    # The progress bar (hidden on a non-terminal: its label only) goes to stderr.
    assert "clip.mp4 (frames)" in res.stderr
    # --draw OUT.mp4: an annotated video OpenCV reopens, every frame at the source's size.
    assert _frame_count(drawn) == (N_FRAMES, (480, 640))


def test_every_nth_frame_and_draw_dir(runner: CliRunner, dbfile: Path, clip: Path, tmp_path: Path) -> None:
    draw = tmp_path / "draw"
    args = ["decode", "--db", str(dbfile), "--json", "--quiet", "--every", "10", "--draw", str(draw), str(clip)]
    res = runner.invoke(cli, args)
    assert res.exit_code == 0, res.output
    assert res.stderr == ""  # --quiet: no progress bar
    recs = [json.loads(line) for line in res.stdout.splitlines()]
    assert [r["frame"] for r in recs] == list(range(0, N_FRAMES, 10))
    assert [r["time_s"] for r in recs] == pytest.approx([f / FPS for f in range(0, N_FRAMES, 10)], abs=1e-3)
    assert all([d["lambda"] for d in r["detections"]] == [TABLE9_TEXT] for r in recs)
    # --draw DIR with a video: DIR/<stem>_decoded.mp4 holds the decoded frames.
    assert _frame_count(draw / "clip_decoded.mp4") == (10, (480, 640))
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--every", "0", str(clip)])
    assert res.exit_code == 2


def test_human_output_summarises_each_video(runner: CliRunner, dbfile: Path, clip: Path, tmp_path: Path) -> None:
    img = tmp_path / "frame.png"
    cap = cv2.VideoCapture(str(clip))
    ok, first = cap.read()
    cap.release()
    assert ok and cv2.imwrite(str(img), first)
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--quiet", "--every", "5", str(clip), str(img)])
    assert res.exit_code == 0, res.output
    lines = res.stdout.splitlines()
    assert lines[0].startswith(f"{clip}: 20 frame(s) decoded, 0.00–3.80 s; ")
    assert lines[1].startswith("  k=7 #") and "in 2" in lines[1] and lines[1].endswith(TABLE9_TEXT)
    assert lines[-2] == f"{img}: 1 tag(s), " + lines[-2].split(", ", 1)[1]
    assert lines[-1].endswith(TABLE9_TEXT)


def test_library_reads_frames_and_tells_videos_from_images(clip: Path, tmp_path: Path) -> None:
    frames = list(read_frames(clip, every=25))
    assert [f.index for f in frames] == [0, 25, 50, 75] and frames[0].image.shape == (480, 640, 3)
    assert frames[0].fps == pytest.approx(FPS)
    done: list[tuple[int, int]] = []
    assert len(list(read_frames(clip, every=50, progress=lambda d, t: done.append((d, t))))) == 2
    assert done[-1] == (N_FRAMES, N_FRAMES) and len(done) == N_FRAMES
    png = tmp_path / "a.png"
    cv2.imwrite(str(png), np.zeros((8, 8), np.uint8))
    assert input_kind(clip) == "video" and input_kind(png) == "image" and input_kind(tmp_path / "no.mp4") == "image"
    with pytest.raises(DecodeError, match="cannot open the video"):
        list(read_frames(png.with_suffix(".mp4")))


def test_unreadable_video_is_one_line_exit_1(dbfile: Path, clip: Path, tmp_path: Path) -> None:
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(clip.read_bytes()[:4000])  # the index (moov) is at the end: cannot be opened
    res = _run("decode", "--db", str(dbfile), str(cut))
    assert res.returncode == 1 and res.stdout == ""
    assert res.stderr.splitlines() == [
        f"error: {cut}: cannot open the video (damaged file or a codec OpenCV's FFmpeg lacks)"
    ]
    notes = tmp_path / "notes.txt"
    notes.write_text("not a picture")
    res = _run("decode", "--db", str(dbfile), "--json", str(notes))
    assert res.returncode == 1
    assert json.loads(res.stdout) == {"image": str(notes), "error": res.stderr.strip().removeprefix("error: ")}
    assert len(res.stderr.splitlines()) == 1 and "neither an image nor a video" in res.stderr


def test_a_file_named_as_an_image_is_refused_as_an_image(dbfile: Path, tmp_path: Path) -> None:
    # FFmpeg opens a text file named .png and finds no frame: the message spoke of a video
    fake = tmp_path / "notes.png"
    fake.write_text("not a picture")
    assert input_kind(fake) == "image"
    res = _run("decode", "--db", str(dbfile), str(fake))
    assert res.returncode == 1 and res.stdout == ""
    assert res.stderr.splitlines() == [
        f"error: {fake}: not an image OpenCV can read, or a damaged one (PNG, JPEG, TIFF, BMP, …)"
    ]


def test_truncated_images_are_errors_not_warnings(dbfile: Path, clip: Path, tmp_path: Path) -> None:
    cap = cv2.VideoCapture(str(clip))
    ok, frame = cap.read()
    cap.release()
    assert ok
    whole_jpg, whole_png = tmp_path / "whole.jpg", tmp_path / "whole.png"
    assert cv2.imwrite(str(whole_jpg), frame) and cv2.imwrite(str(whole_png), frame)
    cut_jpg, cut_png = tmp_path / "cut.jpg", tmp_path / "cut.png"
    cut_jpg.write_bytes(whole_jpg.read_bytes()[: whole_jpg.stat().st_size * 2 // 3])
    cut_png.write_bytes(whole_png.read_bytes()[: whole_png.stat().st_size * 2 // 3])
    assert read_image(whole_jpg).shape == (480, 640, 3)
    with pytest.raises(DecodeError, match="truncated JPEG"):
        read_image(cut_jpg)
    with pytest.raises(DecodeError, match="truncated PNG"):
        read_image(cut_png)
    # JPEG data after the end-of-image marker (some cameras append some) is fine.
    tail = tmp_path / "tail.jpg"
    tail.write_bytes(whole_jpg.read_bytes() + b"\0" * 64)
    assert read_image(tail).shape == (480, 640, 3)
    res = _run("decode", "--db", str(dbfile), str(cut_jpg))
    assert res.returncode == 1 and res.stdout == ""
    assert len(res.stderr.splitlines()) == 1 and "truncated JPEG" in res.stderr and str(cut_jpg) in res.stderr
    res = _run("decode", "--db", str(dbfile), "--json", str(whole_jpg), str(cut_jpg), str(cut_png))
    assert res.returncode == 1
    recs = [json.loads(line) for line in res.stdout.splitlines()]
    assert [("error" in r) for r in recs] == [False, True, True]
    assert "Premature end" not in res.stderr and "libpng" not in res.stderr
    assert res.stderr.splitlines()[-1] == "error: 2 of 3 file(s) could not be read"


def test_draw_video_needs_one_video_input(runner: CliRunner, dbfile: Path, clip: Path, tmp_path: Path) -> None:
    png = tmp_path / "a.png"
    cv2.imwrite(str(png), np.zeros((8, 8), np.uint8))
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--draw", str(tmp_path / "o.mp4"), str(png)])
    assert res.exit_code == 2 and "exactly one video input" in res.stderr
    res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--draw", str(tmp_path / "o.webm"), str(clip)])
    assert res.exit_code == 2 and "annotated videos are written as" in res.stderr


def test_decode_video_json_says_how_each_pose_was_chosen(dbfile: Path, clip: Path, tmp_path: Path) -> None:
    cam = tmp_path / "cam.json"
    cam.write_text(json.dumps({"fx": 700, "fy": 700, "cx": 319.5, "cy": 239.5}))
    res = CliRunner().invoke(
        cli,
        [
            "decode",
            "--db",
            str(dbfile),
            "--json",
            "--every",
            "10",
            "--camera",
            str(cam),
            "--tag-size",
            "5cm",
            str(clip),
        ],
    )
    assert res.exit_code == 0, res.output
    poses = [d["pose"] for line in res.stdout.splitlines() for d in json.loads(line)["detections"]]
    assert poses
    for p in poses:
        assert p["chosen_by"] in ("frame", "previous_frames") and isinstance(p["ambiguous"], bool)
        assert 0 <= p["ambiguity"] <= 1 and len(p["alternative"]["rvec"]) == 3
