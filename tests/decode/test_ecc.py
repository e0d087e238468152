"""ECC in two phases: a tag's alignment runs to convergence, one on a frame without it stops early."""

from __future__ import annotations

import numpy as np

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode.ecc import FIRST_STEPS, PROMISING_CORRELATION, ecc
from ottag_db.decode.model_align import _FINE_PX_TO_UNIT, fine_template, neighbourhood
from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography
from ottag_db.printing import clutter
from ottag_db.printing import scenes as sc
from ottag_db.printing.scenes import DrawableTag


def _triangles(tag: DrawableTag) -> np.ndarray:
    """The tag's triangles in data-area units, ``(T, 3, 2)``."""
    placed = tag.points @ tag.placement[:, :2].T + tag.placement[:, 2]
    return placed[np.array(tag.triangles)]


def test_a_tags_alignment_runs_to_convergence(printed: tuple[MemoryLookup, list[DrawableTag]]) -> None:
    """From corners 1.5 px off, the tag's own template aligns to its true corners."""
    _, tags = printed
    rng = np.random.default_rng(3)
    tag = tags[0]
    spec = sc.posed_spec(tag, rng, 120.0, 40.0)
    frame = sc.render_scene((480, 640), [spec], rng, blur=0.6, noise=2.0).image
    truth = sc.project(spec.homography, UNIT_SQUARE)
    start = truth + rng.uniform(-1.5, 1.5, truth.shape)
    roi, origin = neighbourhood(frame, [start])
    found = ecc(roi, origin, fine_template(_triangles(tag), "normal"), start, _FINE_PX_TO_UNIT)
    assert found is not None and found.converged
    assert found.correlation >= 0.9
    assert np.abs(apply_homography(found.to_frame, UNIT_SQUARE) - truth).max() < 0.5


def test_an_alignment_on_a_frame_without_the_tag_stops_after_the_first_phase(
    printed: tuple[MemoryLookup, list[DrawableTag]],
) -> None:
    """On clutter the correlation stays low and ECC stops after ``FIRST_STEPS``; resumed to
    convergence, it stays unpromising (the rest of the steps do not make a match of it)."""
    _, tags = printed
    rng = np.random.default_rng(5)
    template = fine_template(_triangles(tags[1]), "normal")
    corners = np.array([[300.0, 200.0], [360.0, 204.0], [356.0, 262.0], [298.0, 258.0]])
    stopped = 0
    for frame in clutter.clutter_frames(rng, 6):
        roi, origin = neighbourhood(frame, [corners])
        first = ecc(roi, origin, template, corners, _FINE_PX_TO_UNIT)
        if first is None:
            continue  # ECC lost it within the first steps
        assert first.converged == (first.correlation >= PROMISING_CORRELATION)
        if first.converged:
            continue
        stopped += 1
        resumed = ecc(roi, origin, template, corners, _FINE_PX_TO_UNIT, resume=first)
        if resumed is not None:
            assert resumed.converged
            assert resumed.correlation < PROMISING_CORRELATION + 0.05
    assert stopped >= 1, f"no alignment stopped after {FIRST_STEPS} steps"
