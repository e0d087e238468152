"""Blurred candidates under noise and long motion: the sides' pair test allows each side's
measured scatter, and the coarse match a blurred candidate needs falls with a blur that spans a
cell of the ranking grid."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import Detector
from ottag_db.decode.blur import (
    BLURRED_MIN_RANKING,
    BLURRED_MIN_RANKING_SMEARED,
    EdgeBlur,
    edge_blur,
)
from ottag_db.decode.templates import RANKING_GRID
from ottag_db.decode.types import Quad
from tests.decode.test_blur import _frame

_NORMALS = np.eye(2)[[0, 1, 0, 1]]


def test_noisy_sides_scatter_and_their_scatter_lets_a_pair_differ(printed) -> None:
    """In dim light (contrast a quarter, noise σ 6) a defocused data area's sides scatter by
    more than in good light: the standard errors the sides measure. Opposite sides of 1.4 and
    3.4 px pass the pair test with such errors, not with the small ones of consistent edges
    (clutter sharp on one side and soft on the other), nor when the sharp side is consistent."""
    _, tags = printed
    dim, clean = [], []
    for seed in range(200, 204):
        for errors, is_dim in ((dim, True), (clean, False)):
            _, image, corners = _frame(tags, seed, "normal", defocus=2.5, dim=is_dim)
            quad = Quad("normal", corners, float(cv2.contourArea(corners.astype(np.float32))))
            blur = edge_blur(image, quad)
            assert all(math.isfinite(e) and e >= 0 for e in blur.errors)
            errors.extend(blur.errors)
    assert float(np.median(dim)) > 1.5 * float(np.median(clean))
    noisy = EdgeBlur((2.0, 1.4, 2.2, 3.4), _NORMALS, errors=(0.2, 0.4, 0.2, 0.5))
    consistent = EdgeBlur((2.0, 1.4, 2.2, 3.4), _NORMALS, errors=(0.05, 0.05, 0.05, 0.05))
    assert noisy.blurred and not consistent.blurred
    assert not EdgeBlur((2.0, 0.8, 2.2, 3.4), _NORMALS, errors=(0.2, 0.05, 0.2, 0.5)).blurred


def test_the_floor_falls_from_a_quarter_of_a_ranking_cell_to_half_a_cell() -> None:
    side = 96.0
    cell = side / RANKING_GRID

    def floor(sigma: float) -> float:
        return EdgeBlur((sigma, sigma, sigma, sigma), _NORMALS).min_ranking(side, RANKING_GRID)

    assert floor(0.1 * cell) == pytest.approx(BLURRED_MIN_RANKING) == floor(0.25 * cell)
    assert floor(0.375 * cell) == pytest.approx((BLURRED_MIN_RANKING + BLURRED_MIN_RANKING_SMEARED) / 2)
    assert floor(0.5 * cell) == pytest.approx(BLURRED_MIN_RANKING_SMEARED) == floor(2.0 * cell)


@pytest.mark.parametrize("polarity", ["normal", "inverted"])
def test_tags_moved_by_17_px_read_and_no_look_alike_reads_in_their_place(printed, polarity) -> None:
    """A tag 98 px wide moved by 17 px correlates under 0.7 with its printed tag on the ranking
    grid (the normal tag of seed 200: before, not read by model); read now. With the tags drawn
    taken out of the lookup, no other tag is read in their place."""
    lookup, tags = printed
    drawn = {t.lambda_text for t in tags}
    without = MemoryLookup(e for e in lookup if e.lambda_text not in drawn)  # type: ignore[attr-defined]
    det, det_without = Detector(lookup), Detector(without)
    read = []
    for seed in range(200, 206):
        tag, image, _ = _frame(tags, seed, polarity, motion=17)
        found = det.detect(image)
        assert all(d.lambda_text == tag.lambda_text for d in found)
        if any(d.lambda_text == tag.lambda_text for d in found):
            read.append(seed)
        assert det_without.detect(image) == []
    assert len(read) == 6, read
