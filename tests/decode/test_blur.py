"""Blurred frames: the blur measured on a candidate's sides, the camera blurs a tag is judged
with, and defocused or moving tags read by model without misreading a look-alike."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ottag_db.core.lookup import MemoryLookup
from ottag_db.core.types import Polarity
from ottag_db.decode import Detector
from ottag_db.decode.blur import BLURRED_MAX_MISFIT, NOMINAL_BLURS_PX, EdgeBlur, edge_blur
from ottag_db.decode.camera_blur import Blur, FrameCamera, measured_blurs, motion_kernel, refined_blur, sensor_noise
from ottag_db.decode.model_align import View, fit_blur, judge, neighbourhood
from ottag_db.decode.templates import template_bank
from ottag_db.decode.types import Quad
from ottag_db.printing import scenes as sc
from ottag_db.printing.scenes import DrawableTag

_UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _motion(image: np.ndarray, length: int, angle: float) -> np.ndarray:
    return np.asarray(cv2.filter2D(image, -1, motion_kernel(length, angle), borderType=cv2.BORDER_REPLICATE))


def _frame(
    tags: list[DrawableTag], seed: int, polarity: Polarity, defocus: float = 0.0, motion: int = 0, dim: bool = False
) -> tuple[DrawableTag, np.ndarray, np.ndarray]:
    """A tag 98 px wide at 1.5 m, tilted up to 40°, defocused (Gaussian σ px) or moved (px, a
    random direction), with sensor noise (``dim``: the contrast a quarter, the noise σ 6): the
    tag, the frame and its data area's corners."""
    rng = np.random.default_rng(seed)
    tag = tags[seed % len(tags)]
    spec = sc.posed_spec(tag, rng, 98.0, float(rng.uniform(0, 40)), polarity)
    image = sc.render_scene((480, 640), [spec], rng, blur=max(defocus, 0.5)).image.astype(np.float64)
    if motion:
        image = _motion(image, motion, float(rng.uniform(0, 180)))
    if dim:
        image = image.mean() + 0.25 * (image - image.mean())
    noisy = np.clip(np.rint(image + rng.normal(0, 6.0 if dim else 2.0, image.shape)), 0, 255).astype(np.uint8)
    return tag, noisy, sc.project(spec.homography, _UNIT)


@pytest.mark.parametrize("sigma", [0.5, 1.5, 2.5, 3.5])
def test_the_sides_measure_the_defocus(printed, sigma) -> None:
    """Every side of a defocused data area measures the Gaussian's σ within 25 % (and a sharp
    one under the nominal blurs' largest, plus the measurement's own smoothing)."""
    _, tags = printed
    _, image, corners = _frame(tags, 3, "normal", defocus=sigma)
    blur = edge_blur(image, Quad("normal", corners, float(cv2.contourArea(corners.astype(np.float32)))))
    assert all(math.isfinite(s) for s in blur.sides)
    if sigma < NOMINAL_BLURS_PX[-1]:
        assert blur.largest < NOMINAL_BLURS_PX[-1]
    else:
        assert all(abs(s - sigma) <= 0.25 * sigma for s in blur.sides), blur.sides


def test_motion_widens_the_sides_across_it_and_the_measured_blurs_draw_it(printed) -> None:
    """A 13 px motion along the data area's first side widens the two sides across it, not the
    two along it; the measured blurs then include that motion (its length within 30 %, its
    direction within 10° of the side's, up to the mirror image)."""
    _, tags = printed
    rng = np.random.default_rng(5)
    tag = tags[0]
    spec = sc.posed_spec(tag, rng, 98.0, 0.0, "normal")
    image = sc.render_scene((480, 640), [spec], rng, blur=0.5).image
    corners = sc.project(spec.homography, _UNIT)
    side = corners[1] - corners[0]
    angle = math.degrees(math.atan2(side[1], side[0]))
    moved = _motion(image, 13, angle)
    blur = edge_blur(moved, Quad("normal", corners, float(cv2.contourArea(corners.astype(np.float32)))))
    along, across = max(blur.sides[0], blur.sides[2]), min(blur.sides[1], blur.sides[3])
    assert across > 2.5 * along
    motions = [b for b in measured_blurs(blur) if b.length > 0]
    assert motions
    best = min(motions, key=lambda b: abs(b.length - 13))
    assert abs(best.length - 13) <= 0.3 * 13
    turn = min(abs((b.angle_deg - angle) % 180.0) for b in motions)
    assert min(turn, 180.0 - turn) <= 10.0


@given(st.floats(1.5, 25.0), st.floats(0.0, 360.0))
def test_a_motion_kernel_is_normalized_and_symmetric(length: float, angle: float) -> None:
    kernel = motion_kernel(length, angle)
    assert kernel.shape[0] == kernel.shape[1] and kernel.shape[0] % 2 == 1
    assert math.isclose(float(kernel.sum()), 1.0, rel_tol=1e-5)
    np.testing.assert_allclose(kernel, kernel[::-1, ::-1], atol=1e-6)  # a motion has no direction sign


def test_a_sharp_candidate_is_judged_with_the_nominal_blurs_only() -> None:
    sharp = EdgeBlur((0.8, 0.7, math.nan, 0.9), np.eye(2)[[0, 1, 0, 1]])
    assert sharp.largest <= NOMINAL_BLURS_PX[-1] and not sharp.blurred
    assert measured_blurs(sharp) == () == measured_blurs(None)


@pytest.mark.parametrize("polarity", ["normal", "inverted"])
@pytest.mark.parametrize("shift", [-2.0, 2.0])
def test_a_blurred_outline_is_centred_on_its_steps(printed, polarity, shift) -> None:
    """An outline a threshold put 2 px inside or outside a data area defocused by 3 px is moved
    onto its sides' blurred steps: its corners within 1 px of the data area's."""
    _, tags = printed
    _, image, corners = _frame(tags, 7, polarity, defocus=3.0)
    centre = corners.mean(axis=0)
    side = math.sqrt(float(cv2.contourArea(corners.astype(np.float32))))
    moved = centre + (corners - centre) * (1 + 2 * shift / side)  # each side about `shift` px out
    quad = Quad(polarity, moved, float(cv2.contourArea(moved.astype(np.float32))))
    centred = edge_blur(image, quad).centred(quad)
    assert np.linalg.norm(moved - corners, axis=1).max() > 1.5
    assert np.linalg.norm(centred.corners - corners, axis=1).max() < 1.0


def test_the_refined_blur_reaches_a_motion_the_sides_placed_off() -> None:
    """The pattern search from measured motions 30 % short and 25° off reaches the best-fitting
    one (a misfit least at 15 px along 60°) within 0.5 px and 2°; a defocus wins when it fits best."""

    def misfit(b: Blur) -> float:
        turn = min(abs(b.angle_deg - 60.0) % 180.0, 180.0 - abs(b.angle_deg - 60.0) % 180.0)
        return (b.length - 15.0) ** 2 / 4 + (turn / 5) ** 2 + (b.sigma - 0.7) ** 2 + 0.5

    measured = (Blur(3.0), Blur(4.0), *(Blur(0.7, 10.5 * f, 35.0) for f in (0.85, 1.0, 1.15)))
    best = refined_blur(misfit, measured)
    assert best is not None and abs(best.length - 15.0) < 0.5
    assert min(abs(best.angle_deg - 60.0), 180 - abs(best.angle_deg - 60.0)) < 2.0
    defocus = refined_blur(lambda b: abs(b.sigma - 3.3) + b.length, measured)
    assert defocus is not None and defocus.length == 0.0 and abs(defocus.sigma - 3.3) < 0.15
    assert refined_blur(misfit, ()) is None


def test_the_refined_blur_sweeps_the_directions_at_every_measured_length() -> None:
    """Measured 60 % long (27 px for a 17 px motion along 149°), the directions fit best at
    86° at that length: swept at the shortest measured length too, the search reaches the
    motion within 1 px and 3°."""

    def turn(angle: float, to: float) -> float:
        return min(abs(angle - to) % 180.0, 180.0 - abs(angle - to) % 180.0)

    def misfit(b: Blur) -> float:
        if b.length <= 1.0:
            return 6.0  # no defocus fits
        towards = 149.0 if b.length < 22.0 else 86.0  # a long smear fits another direction best
        return 2.4 + (b.length - 17.0) ** 2 / 8 + (turn(b.angle_deg, towards) / 10) ** 2

    measured = tuple(Blur(0.7, 26.8 * f, a) for a in (76.0, 86.0, 96.0) for f in (0.7, 0.85, 1.0, 1.15, 1.3))
    best = refined_blur(misfit, measured)
    assert best is not None and abs(best.length - 17.0) < 1.0 and turn(best.angle_deg, 149.0) < 3.0, best


def test_the_refined_blur_reaches_a_motion_the_sides_measured_short() -> None:
    """Measured about half long (8–10 px for a 17 px motion along 40°: a triangle smeared
    across the sides lowers their steps), the directions fit best 60° off at those lengths:
    swept beyond the longest measured length too, the search reaches the motion within 1 px
    and 3°."""

    def turn(angle: float, to: float) -> float:
        return min(abs(angle - to) % 180.0, 180.0 - abs(angle - to) % 180.0)

    def misfit(b: Blur) -> float:
        if b.length <= 1.0:
            return 6.0  # no defocus fits
        towards = 40.0 if b.length > 12.0 else 100.0  # a short smear fits another direction best
        return 2.4 + (b.length - 17.0) ** 2 / 8 + (turn(b.angle_deg, towards) / 10) ** 2

    measured = tuple(Blur(0.7, 9.0 * f, a) for a in (95.0, 100.0, 105.0) for f in (0.9, 1.0, 1.1))
    best = refined_blur(misfit, measured)
    assert best is not None and abs(best.length - 17.0) < 1.0 and turn(best.angle_deg, 40.0) < 3.0, best


def test_a_side_whose_step_is_a_smeared_triangle_is_left_out_of_the_pair_test() -> None:
    """A 15 px motion across a data area's left and right sides, a bright triangle smeared
    along the right one inside: that side's step (from the smear's grey to the quiet zone) is
    under a third of the others', and its slope measures no motion, where the left side
    measures it; the pair is left out of the test, and the sides are a blurred tag's."""
    image = np.full((300, 300), 100.0)
    image[60:240, 60:240] = 170.0  # the quiet zone
    image[90:210, 90:210] = 15.0  # the data area
    image[95:205, 180:208] = 120.0  # a triangle smeared along its right side
    gray = np.clip(np.rint(cv2.GaussianBlur(_motion(image, 15, 0.0), (0, 0), 0.7)), 0, 255).astype(np.uint8)
    corners = np.array([[89.5, 89.5], [209.5, 89.5], [209.5, 209.5], [89.5, 209.5]])
    blur = edge_blur(gray, Quad("normal", corners, 120.0**2))
    assert blur.sides[1] < 1.5 < 4.0 < blur.sides[3], blur.sides
    assert blur.steps[1] < 0.35 * min(blur.steps[0], blur.steps[2], blur.steps[3]), blur.steps
    assert blur.blurred


@pytest.mark.parametrize("sigma", [1.5, 2.0])
def test_sensor_noise_does_not_sharpen_the_sides(printed, sigma) -> None:
    """In dim light (contrast a quarter, noise σ 6) the sides of tags defocused by 1.5–2 px
    measure the defocus within 8 % (median of 8 tags' sides): the noise steepens a single
    profile's steepest slope, and measured so they read 11–14 % short."""
    _, tags = printed
    sides = []
    for seed in range(20, 28):
        _, image, corners = _frame(tags, seed, "normal", defocus=sigma, dim=True)
        blur = edge_blur(image, Quad("normal", corners, float(cv2.contourArea(corners.astype(np.float32)))))
        sides += blur.sides
    assert abs(float(np.nanmedian(sides)) - sigma) <= 0.08 * sigma, np.round(sides, 2)


@pytest.mark.parametrize(
    ("defocus", "motion", "dim"), [(2.5, 0, False), (3.0, 0, False), (0.0, 11, False), (2.5, 0, True)]
)
@pytest.mark.parametrize("polarity", ["normal", "inverted"])
def test_blurred_tags_read_and_no_look_alike_reads_in_their_place(printed, defocus, motion, dim, polarity) -> None:
    """At a defocus of 2.5–3 px, or a motion of 11 px, also in dim light, the points' tips and
    gaps are gone: the tag is read by model, judged with the blur its sides measure (before:
    none of these read). With the tags drawn taken out of the lookup, no other tag is read in
    their place."""
    lookup, tags = printed
    drawn = {t.lambda_text for t in tags}
    without = MemoryLookup(e for e in lookup if e.lambda_text not in drawn)  # type: ignore[attr-defined]
    det, det_without = Detector(lookup), Detector(without)
    read = 0
    for seed in range(200, 206):
        tag, image, _ = _frame(tags, seed, polarity, defocus=defocus, motion=motion, dim=dim)
        found = det.detect(image)
        assert all(d.lambda_text == tag.lambda_text for d in found)
        read += any(d.lambda_text == tag.lambda_text for d in found)
        assert det_without.detect(image) == []
    assert read >= 4


@pytest.mark.parametrize("seed", [210, 211, 212])
def test_the_blur_fitted_in_a_dim_noisy_frame_is_the_defocus(printed, seed) -> None:
    """A tag defocused by 2.5 px in dim light (contrast a quarter, noise σ 6), judged where it
    lies: the blur fitted to its view is within 12 % of the defocus and its drawing with it
    fits the view within the blurred misfit limit (a fit in units of each drawing's own scale
    drifted to blurs a fifth too large there, and misfit by 0.13)."""
    lookup, tags = printed
    rng = np.random.default_rng(seed)
    tag = tags[seed % len(tags)]
    spec = sc.posed_spec(tag, rng, 98.0, float(rng.uniform(0, 40)), "normal")
    image = sc.render_scene((480, 640), [spec], rng, blur=2.5).image.astype(np.float64)
    image = image.mean() + 0.25 * (image - image.mean()) + rng.normal(0, 6.0, image.shape)
    gray = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    bank = template_bank(lookup, 100_000)
    assert bank is not None
    row = next(i for i, e in enumerate(bank.entries) if e.lambda_text == tag.lambda_text)
    corners = sc.project(spec.homography, _UNIT)
    roi, origin = neighbourhood(gray, [corners])
    view = View(corners, "normal")
    seen = judge(roi, origin, bank, row, view, spec.homography)
    assert seen.correlation > 0.8  # the tag where it lies
    fitted = fit_blur(roi, origin, bank, seen, (Blur(2.0), Blur(2.7), Blur(3.4)))
    assert fitted is not None and abs(fitted.sigma - 2.5) <= 0.12 * 2.5, fitted
    camera = FrameCamera(fitted, sensor_noise(roi))
    assert judge(roi, origin, bank, row, view, spec.homography, camera).misfit <= BLURRED_MAX_MISFIT
