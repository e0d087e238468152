"""``DetectorParams(last_resort_passes=False)`` and ``ottag-db decode --fast``: a frame without a tag
runs the first candidate passes only, a tag those passes read reads the same, and a tag only a
last-resort pass reads is given up (real renders, real OpenCV, the bundled database)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from ottag_db.cli import cli
from ottag_db.decode import Detector, DetectorParams
from ottag_db.printing import scenes as sc
from tests.support import synthetic_tags as syn

FIRST_PASSES = {"adaptive", "otsu", "adaptive_dim"}
LAST_RESORTS = {"adaptive_thin", "bright_holes", "local_range"}
FAST = DetectorParams(last_resort_passes=False)

#: A normal 8-point tag at 86° (21 cm at 1.5 m, the tilt sweep of benchmarks/decode_sweeps.py)
#: that only the pass over the bright quiet zone's holes outlines (tests/decode/test_edge_on.py).
EDGE_ON_PREFIX = "8:06543210001645321505432120103654322304"
EDGE_ON_HOM = [[54.570271, -102.38266, 343.301434], [42.77418, 13.438711, 242.327915], [0.150519, 0.008177, 1]]


def _edge_on_frame(bundled) -> tuple[str, np.ndarray]:
    """The edge-on tag's ID and its render (blur 0.58 px, noise 0.59, gradient 0.04, JPEG 85)."""
    _, records = bundled
    tag = next(t for t in records if t.lambda_text.startswith(EDGE_ON_PREFIX))
    spec = sc.TagSpec(tag.points, tag.triangles, np.array(EDGE_ON_HOM), "normal", placement=tag.placement)
    rng = np.random.default_rng(0)
    image = sc.render_scene((480, 640), [spec], rng, blur=0.58, noise=0.59, gradient=0.04, jpeg=85).image
    return tag.lambda_text, image


def test_a_frame_without_a_tag_runs_the_first_passes_only() -> None:
    """Texture reads nothing either way; the default runs the last-resort passes on it, the
    setting none of them."""
    texture = np.clip(np.random.default_rng(1).normal(128, 40, (300, 400)), 0, 255).astype(np.uint8)
    lookup = syn.lookup()
    default = Detector(lookup).detect_with_report(texture)
    fast = Detector(lookup, FAST).detect_with_report(texture)
    assert default.detections == [] and fast.detections == []
    assert {name for name, _ in default.passes} >= LAST_RESORTS
    assert {name for name, _ in fast.passes} <= FIRST_PASSES


def test_a_tag_the_first_passes_read_reads_the_same() -> None:
    """Two tags read in the first pass: the same IDs, corners and points with the setting."""
    lookup = syn.lookup()
    frame = syn.draw_tags((300, 560), [(200, (40, 50)), (190, (320, 60))])
    default = Detector(lookup).detect(frame)
    fast = Detector(lookup, FAST).detect(frame)
    assert len(default) == 2
    assert [d.lambda_text for d in fast] == [d.lambda_text for d in default]
    for a, b in zip(fast, default, strict=True):
        np.testing.assert_array_equal(a.corners, b.corners)
        np.testing.assert_array_equal(a.points, b.points)


def test_a_tag_only_a_last_resort_pass_reads_is_given_up(bundled) -> None:
    """The edge-on tag reads by default and not with the setting, and nothing reads in its place."""
    lookup, _ = bundled
    lam, image = _edge_on_frame(bundled)
    assert [d.lambda_text for d in Detector(lookup).detect(image)] == [lam]
    assert Detector(lookup, FAST).detect(image) == []


@pytest.fixture(scope="module")
def dbfile(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("fast") / "db.sqlite"
    shutil.copyfile(bundled_db_path, path)
    return path


def test_decode_fast_on_the_command_line(bundled, dbfile: Path, tmp_path: Path) -> None:
    """``decode --fast`` reads a rendered tag as ``decode`` does and gives up the edge-on one,
    with the same JSON keys."""
    runner = CliRunner()
    tag_png = tmp_path / "tag.png"
    lam = "7:0543210002543113043222010543312005442310055432100"
    assert runner.invoke(cli, ["render", "--db", str(dbfile), lam, str(tag_png), "--px", "240"]).exit_code == 0
    edge_lam, edge = _edge_on_frame(bundled)
    edge_png = tmp_path / "edge_on.png"
    assert cv2.imwrite(str(edge_png), edge)

    def decoded(*extra: str) -> list[dict]:
        res = runner.invoke(cli, ["decode", "--db", str(dbfile), "--json", *extra, str(tag_png), str(edge_png)])
        assert res.exit_code == 0, res.output
        return [json.loads(line) for line in res.stdout.splitlines()]

    default, fast = decoded(), decoded("--fast")
    assert [[d["lambda"] for d in rec["detections"]] for rec in default] == [[lam], [edge_lam]]
    assert [[d["lambda"] for d in rec["detections"]] for rec in fast] == [[lam], []]
    assert fast[0]["detections"] == default[0]["detections"]
    assert fast[0].keys() == default[0].keys()
