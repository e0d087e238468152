"""Image stage: conversion to grey and the Otsu split."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ottag_db.decode.candidates import find_quads
from ottag_db.decode.image import frame_has_contrast, otsu, to_gray
from ottag_db.decode.types import DetectorParams
from ottag_db.errors import DecodeError
from tests.support import synthetic_tags as syn


def test_to_gray_keeps_grey_and_scales_other_types() -> None:
    grey = np.tile(np.arange(0, 256, 32, dtype=np.uint8), (4, 1))
    assert to_gray(grey[:, ::2]).flags.c_contiguous
    assert np.array_equal(to_gray(grey), grey)
    assert np.array_equal(
        to_gray(grey.astype(np.int32) * 4), np.round(grey.astype(float) * 4 * 255 / 896).astype(np.uint8)
    )
    assert to_gray(np.full((3, 3), -1.0)).max() == 0  # clipped
    assert to_gray(np.full((3, 3), np.nan)).max() == 0
    assert to_gray(np.zeros((0, 7))).shape == (0, 0)


@pytest.mark.parametrize("bad", [np.zeros((2, 2, 2)), np.zeros(5), np.array(["x"]), None])
def test_to_gray_rejects_non_images(bad: object) -> None:
    with pytest.raises(DecodeError):
        to_gray(bad)


def test_otsu_splits_two_levels() -> None:
    hist = np.zeros(256)
    hist[40] = 300
    hist[200] = 100
    split = otsu(hist)
    assert split is not None
    assert 40 <= split.level < 200
    assert (split.dark, split.bright) == (40.0, 200.0) and split.contrast == 160.0


def test_otsu_needs_two_classes_and_enough_pixels() -> None:
    one = np.zeros(256)
    one[90] = 1000
    assert otsu(one) is None
    few = np.zeros(256)
    few[[10, 250]] = 5
    assert otsu(few) is None


def test_a_blank_frame_of_noise_has_no_contrast_for_the_global_threshold() -> None:
    """A wall or a lens cap with sensor noise: Otsu's classes lie a few grey levels apart and the
    global threshold's pass is not run (it traced some 20,000 specks); a tag gives contrast."""
    rng = np.random.default_rng(0)
    for level, sigma in ((20, 3.0), (128, 2.0), (128, 8.0)):
        blank = np.clip(level + rng.normal(0, sigma, (480, 640)), 0, 255).astype(np.uint8)
        assert not frame_has_contrast(blank, 20.0)
        assert find_quads(blank, "otsu", DetectorParams()) == []
    tag = syn.draw_tags((360, 480), [(60, (200, 150))])
    assert frame_has_contrast(tag, 20.0) and not frame_has_contrast(tag, 400.0)
    quads = find_quads(tag, "otsu", DetectorParams())
    assert len(quads) == 1 and abs(math.sqrt(quads[0].area) - 60) < 3
