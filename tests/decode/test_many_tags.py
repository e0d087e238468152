"""Many tags per frame: a board of 20 tags (pairwise flip distance ≥ 2) under perspective, 20/20.

The frame is drawn as ``benchmarks/decode_many.py`` draws it (a 5 × 4 board, 1280×960,
f = 1400 px), at one fixed pose with a 35° tilt, blur, noise and JPEG.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from ottag_db.core.flips import flip_neighbours
from ottag_db.decode import Detector
from ottag_db.printing import scenes as sc
from ottag_db.printing.camera import camera_matrix
from tests.support.tagsynth import scene_data

COLS, ROWS, PITCH = 5, 4, 1.6


def _dictionary(tags: list[sc.DrawableTag], n: int) -> list[sc.DrawableTag]:
    """``n`` tags of k = 8, highest MP first, no two of them flip neighbours."""
    cand = sorted((t for t in tags if len(t.points) == 8), key=lambda t: (-t.printed_mp_unit, t.lambda_text))[:80]
    edges = flip_neighbours(np.stack([t.points for t in cand]), [t.lambda_text for t in cand])
    near: dict[int, set[int]] = {}
    for e in edges:
        near.setdefault(e.source, set()).add(e.target)
        near.setdefault(e.target, set()).add(e.source)
    chosen: list[int] = []
    for i in range(len(cand)):
        if len(chosen) < n and not near.get(i, set()) & set(chosen):
            chosen.append(i)
    assert len(chosen) == n
    return [cand[i] for i in chosen]


def _board() -> np.ndarray:
    """Board plane (data-area sides) → image: tilted 35°, rolled 10°, centred, about 900 px wide."""
    k_mat = camera_matrix(1400.0, 1280, 960)
    r_tilt, _ = cv2.Rodrigues(np.array([math.cos(0.6), math.sin(0.6), 0.0]) * math.radians(35))
    c, s = math.cos(math.radians(10)), math.sin(math.radians(10))
    r_mat = r_tilt @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    t = np.array([0.0, 0.0, 13.0]) - r_mat @ np.array([COLS * PITCH / 2, ROWS * PITCH / 2, 0.0])
    hom = k_mat @ np.column_stack([r_mat[:, 0], r_mat[:, 1], t])
    return hom / hom[2, 2]


@pytest.fixture(scope="module")
def board_scene(bundled_db_path) -> tuple[Detector, sc.Scene]:
    lookup, tags = scene_data(bundled_db_path)
    members = _dictionary(tags, COLS * ROWS)
    board = _board()
    off = (PITCH - 1) / 2
    specs = []
    for i, m in enumerate(members):
        r, c = divmod(i, COLS)
        cell = np.array([[1, 0, c * PITCH + off], [0, 1, r * PITCH + off], [0, 0, 1.0]])
        specs.append(sc.TagSpec(m.points, m.triangles, board @ cell, lambda_text=m.lambda_text, placement=m.placement))
    rng = np.random.default_rng(5)
    scene = sc.render_scene((960, 1280), specs, rng, blur=0.7, noise=3.0, gradient=0.3, jpeg=80)
    return Detector(lookup), scene


def test_twenty_tags_in_one_frame_all_decode_with_their_ids(board_scene) -> None:
    det, scene = board_scene
    unit = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    sides = [math.sqrt(abs(cv2.contourArea(sc.project(s.homography, unit).astype(np.float32)))) for s in scene.tags]
    assert min(sides) > 60 and max(sides) < 160  # the board as intended: small tags, one frame
    dets = det.detect(scene.image)
    assert len(dets) == 20
    for spec, truth in zip(scene.tags, scene.truth_points, strict=True):
        centre = truth.mean(axis=0)
        near = [d for d in dets if np.linalg.norm(d.points.mean(axis=0) - centre) < 10]
        assert [d.lambda_text for d in near] == [spec.lambda_text]
        # every drawn point found (sharp tips of blurred slivers lie up to a few px off)
        gap = np.linalg.norm(near[0].points[:, None, :] - truth[None, :, :], axis=2)
        assert gap.min(axis=0).max() < 3.0
