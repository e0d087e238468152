"""Image stage: conversion to grey and the Otsu split."""

from __future__ import annotations

import numpy as np
import pytest

from ottag_db.decode.image import otsu, to_gray
from ottag_db.errors import DecodeError


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
