"""Blurred tags under sensor noise: the noise is measured, a tag drawn with its blur may misfit
the frame by what the noise alone leaves, and the sides of a dim tag, whose steps are under 20
grey levels, are measured."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import Detector
from ottag_db.decode.blur import BLURRED_MAX_MISFIT, BLURRED_MAX_MISFIT_NOISY, edge_blur
from ottag_db.decode.camera_blur import Blur, FrameCamera, sensor_noise
from ottag_db.decode.model_align import Aligned, View, judge, neighbourhood
from ottag_db.decode.templates import template_bank
from ottag_db.decode.types import Quad
from ottag_db.printing import scenes as sc
from ottag_db.printing.scenes import DrawableTag

_UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _dim_frame(
    tags: list[DrawableTag], seed: int, size: float, contrast: float, noise: float
) -> tuple[DrawableTag, sc.TagSpec, np.ndarray, np.ndarray]:
    """A tag ``size`` px wide at 1.5 m, tilted up to 40°, defocused by 2.5 px, its contrast
    scaled by ``contrast`` about the frame's mean: the tag, its spec, the frame without noise
    and with Gaussian noise of σ ``noise`` (both uint8)."""
    rng = np.random.default_rng(seed)
    tag = tags[seed % len(tags)]
    spec = sc.posed_spec(tag, rng, size, float(rng.uniform(0, 40)), "normal")
    image = sc.render_scene((480, 640), [spec], rng, blur=2.5).image.astype(np.float64)
    image = image.mean() + contrast * (image - image.mean())
    clean = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    noisy = np.clip(np.rint(image + rng.normal(0, noise, image.shape)), 0, 255).astype(np.uint8)
    return tag, spec, clean, noisy


@pytest.mark.parametrize("noise", [0.0, 2.0, 6.0, 10.0])
def test_the_sensor_noise_is_measured_beside_a_blurred_tag(printed, noise) -> None:
    """Around a defocused tag (its sides and triangles fill part of the neighbourhood), the
    noise's σ is measured within 10 % (and 0.3 grey levels)."""
    _, tags = printed
    for seed in (300, 301, 302):
        _, spec, _, noisy = _dim_frame(tags, seed, 98.0, 0.25, noise)
        roi, _ = neighbourhood(noisy, [sc.project(spec.homography, _UNIT)])
        # rounding to grey levels adds a uniform noise of σ 1/√12 (0.29)
        expected = float(np.hypot(noise, 1 / np.sqrt(12))) if noise else 0.0
        assert abs(sensor_noise(roi) - expected) <= 0.1 * expected + 0.3


def test_a_dim_tag_misfits_its_drawing_by_what_its_noise_leaves(printed, bundled_db_path) -> None:
    """A tag 76 px wide defocused by 2.5 px, its contrast 0.15 (38 grey levels), drawn where it
    lies with its true blur: without noise it misfits its drawing by under 0.03; with noise of
    σ 6 by 0.06–0.13, which ``misfit_noise`` predicts within a third (median), and always
    within ``blurred_misfit_limit`` — where the fixed :data:`BLURRED_MAX_MISFIT` refused one."""
    lookup, tags = printed
    bank = template_bank(lookup, 100_000)
    assert bank is not None
    noisy_misfits, predicted = [], []
    for seed in range(210, 222):
        tag, spec, clean, noisy = _dim_frame(tags, seed, 76.0, 0.15, 6.0)
        row = next(i for i, e in enumerate(bank.entries) if e.lambda_text == tag.lambda_text)
        view = View(sc.project(spec.homography, _UNIT), "normal")
        judged = []
        for gray in (clean, noisy):
            roi, origin = neighbourhood(gray, [view.corners])
            camera = FrameCamera(Blur(2.5), sensor_noise(roi))
            judged.append(judge(roi, origin, bank, row, view, spec.homography, camera))
        assert judged[0].misfit < 0.03
        assert judged[1].misfit <= judged[1].blurred_misfit_limit
        noisy_misfits.append(judged[1].misfit)
        predicted.append(judged[1].misfit_noise)
    assert max(noisy_misfits) > BLURRED_MAX_MISFIT
    assert abs(np.median(predicted) / np.median(noisy_misfits) - 1) < 1 / 3


def test_a_dim_tag_with_steps_under_20_grey_levels_is_measured_and_read(printed) -> None:
    """A defocused tag whose contrast is a tenth (steps of about 25 grey levels) under noise of
    σ 6: every side is measured and judged blurred, and the tag is read by model (under a fixed
    floor of 20 grey levels for a sample's step, which the noise scatters by ±10, 5 of these 8
    tags had a side unmeasured and 2 were read); with the tags drawn taken out of the lookup, no
    other tag is read in their place."""
    lookup, tags = printed
    drawn = {t.lambda_text for t in tags}
    det = Detector(lookup)
    det_without = Detector(MemoryLookup(e for e in lookup if e.lambda_text not in drawn))  # type: ignore[attr-defined]
    read = 0
    for seed in range(300, 308):
        tag, spec, _, noisy = _dim_frame(tags, seed, 98.0, 0.1, 6.0)
        corners = sc.project(spec.homography, _UNIT)
        blur = edge_blur(noisy, Quad("normal", corners, float(cv2.contourArea(corners.astype(np.float32)))))
        assert all(np.isfinite(blur.sides)) and blur.blurred, np.round(blur.sides, 2)
        found = det.detect(noisy)
        assert all(d.lambda_text == tag.lambda_text for d in found)
        read += any(d.lambda_text == tag.lambda_text for d in found)
        assert det_without.detect(noisy) == []
    assert read >= 7


@given(st.floats(0.0, 1.0))
def test_the_noise_widens_the_blurred_limit_in_quadrature_up_to_its_cap(noise: float) -> None:
    """Without noise the limit is :data:`BLURRED_MAX_MISFIT`; it grows with the noise's share
    (never shrinks) and stops at :data:`BLURRED_MAX_MISFIT_NOISY`, where the noise hides a
    look-alike's differing triangle."""
    limit = Aligned(0, View(_UNIT, "normal"), np.eye(3), 0.9, 0.1, 0.1, 0.9, noise).blurred_misfit_limit
    assert BLURRED_MAX_MISFIT <= limit <= BLURRED_MAX_MISFIT_NOISY
    assert limit == pytest.approx(min(float(np.hypot(BLURRED_MAX_MISFIT, noise)), BLURRED_MAX_MISFIT_NOISY))
    if noise == 0.0:
        assert limit == BLURRED_MAX_MISFIT
