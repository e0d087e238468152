"""A normal tag whose dark data area is joined to dark things outside its quiet zone — a grey bar
from beyond the quiet zone across a side, a grey square over a corner — or whose corner the
frame cuts a few px off: the candidate stage still outlines its data area."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ottag_db.decode import Detector
from ottag_db.decode.outlines import lines_outline, without_spikes
from ottag_db.printing import scenes as sc

_UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _square(centre: tuple[float, float], side: float, angle_deg: float) -> np.ndarray:
    t = np.radians(angle_deg)
    rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    return (_UNIT - 0.5) @ rot.T * side + np.asarray(centre)


def _contours(mask: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    return list(contours), hier[0]


def _nearest_error(quad: np.ndarray, truth: np.ndarray) -> float:
    q = quad.reshape(4, 2).astype(float)
    return float(max(np.linalg.norm(q - t, axis=1).min() for t in truth))


@pytest.mark.parametrize("spike", ["bar", "corner"])
def test_without_spikes_keeps_the_square_of_a_region_with_thin_spikes(spike) -> None:
    """A dark square (60 px, turned 20°) with bright holes, joined to a long, 4 px thin bar or
    to the two edges of a square over a corner, is outlined by the square's corners."""
    mask = np.zeros((240, 320), np.uint8)
    truth = _square((150.0, 120.0), 60.0, 20.0)
    cv2.fillPoly(mask, [np.round(truth * 16).astype(np.int32)], 255, cv2.LINE_8, 4)
    # as the local threshold's mask shows a data area: a band along its border, the uniform
    # interior a hole, split by the band along a triangle's side
    inner = _square((150.0, 120.0), 50.0, 20.0)
    cv2.fillPoly(mask, [np.round(inner * 16).astype(np.int32)], 0, cv2.LINE_8, 4)
    cv2.line(mask, tuple(np.round(inner[0]).astype(int)), tuple(np.round(inner[2]).astype(int)), 255, 3)
    top = 0.5 * (truth[0] + truth[1])  # the middle of one side
    out = top + 3.0 * (top - truth.mean(axis=0))  # far beyond the quiet zone
    if spike == "bar":
        cv2.line(mask, tuple(np.round(top).astype(int)), tuple(np.round(out).astype(int)), 255, 4)
    else:  # an occluder's edges: two thin lines from near a corner, away from the square
        for along, away in ((1, 3), (3, 1)):  # from 6 % along a side, outwards
            start = truth[0] + 0.06 * (truth[along] - truth[0])
            end = start + 1.2 * (truth[0] - truth[away])
            cv2.line(mask, tuple(np.round(start).astype(int)), tuple(np.round(end).astype(int)), 255, 3)
    contours, hier = _contours(mask)
    region = max(range(len(contours)), key=lambda i: len(contours[i]) if hier[i][3] < 0 else 0)
    holes = [contours[i] for i in range(len(contours)) if hier[i][3] == region]
    assert len(holes) >= 2
    assert lines_outline(contours[region], float(len(contours[region])), mask.shape) is None  # too ragged
    quad = without_spikes(contours[region], holes, mask.shape)
    assert quad is not None
    assert _nearest_error(quad, truth) < 2.0


def test_a_corner_cut_a_few_px_by_the_frame_is_outlined_beyond_it() -> None:
    """The frame's edge cuts a corner 3 px deep: a polygon at the usual tolerance rounds the cut
    into one vertex on the edge; the outline is the four sides' lines, that corner beyond it."""
    mask = np.zeros((240, 320), np.uint8)
    truth = _square((100.0, 202.0), 60.0, 32.0)
    low = int(truth[:, 1].argmax())
    truth[:, 1] += 242.0 - truth[low, 1]  # the lowest corner 3 px beyond the last row (239)
    cv2.fillPoly(mask, [np.round(truth * 16).astype(np.int32)], 255, cv2.LINE_8, 4)
    contours, _ = _contours(mask)
    contour = max(contours, key=len)
    quad = lines_outline(contour, float(len(contour)), mask.shape)
    assert quad is not None
    assert _nearest_error(quad, truth) < 1.5
    assert quad.reshape(4, 2)[:, 1].max() > 239.5  # that corner beyond the frame


def _hidden(
    rng: np.random.Generator, tag: sc.DrawableTag, case: str, polarity: str = "normal"
) -> tuple[np.ndarray, np.ndarray]:
    """A tag (125–150 px, tilt ≤ 35°) hidden by a grey bar or corner square reaching from beyond
    its quiet zone 6 % into the data area (dark grey on a normal tag, light grey on an inverted
    one); its frame and data-area corners."""
    spec = sc.posed_spec(tag, rng, rng.uniform(125, 150), rng.uniform(0, 35), polarity)  # type: ignore[arg-type]
    frame = sc.render_scene((480, 640), [spec], rng, blur=0.7, noise=2.0).image
    out = 1.55
    if case == "bar":
        cover = np.array([[0.47, -out], [0.53, -out], [0.53, 0.06], [0.47, 0.06]])
    else:
        cover = np.array([[-out, -out], [0.06, -out], [0.06, 0.06], [-out, 0.06]])
    pts = np.round(sc.project(spec.homography, cover) * 16).astype(np.int32)
    grey = int(rng.integers(95, 125)) if polarity == "normal" else int(rng.integers(140, 170))
    cv2.fillPoly(frame, [pts], grey, lineType=cv2.LINE_AA, shift=4)
    return frame, sc.project(spec.homography, _UNIT)


def _reads_hidden(bundled, case: str, polarity: str, first_seed: int) -> int:
    """Tags read of 8 hidden the ``case`` way (seeds from ``first_seed``); every detection is
    the tag drawn, its corners within 2 % of the side of the truth."""
    lookup, tags = bundled
    drawable = [t for t in tags if t.k == 8 and sc.min_width_px(t.printed_mp_unit) <= 100]
    det = Detector(lookup)
    read = 0
    for seed in range(8):
        rng = np.random.default_rng(first_seed + seed)
        tag = drawable[seed % len(drawable)]
        frame, truth = _hidden(rng, tag, case, polarity)
        dets = det.detect(frame)
        assert [d.lambda_text for d in dets] in ([], [tag.lambda_text])
        if not dets:
            continue
        side = np.sqrt(abs(cv2.contourArea(truth.astype(np.float32))))
        assert np.abs(dets[0].corners - truth).max() < 0.02 * side
        read += 1
    return read


@pytest.mark.parametrize("case", ["bar", "covered corner"])
def test_a_dark_occluder_joined_to_the_data_area_is_cut_off_its_outline(bundled, case) -> None:
    """A dark grey occluder joins a normal data area to the background: the region's outline
    is the data area with spikes (the occluder's edges in the local threshold's mask), which
    :func:`without_spikes` cuts off; the tag reads, its corners within 2 % of the side (before:
    6 of 8 bars and 3 of 8 covered corners read)."""
    read = _reads_hidden(bundled, case, "normal", 100)
    assert read >= {"bar": 7, "covered corner": 6}[case]  # measured: 8 and 7


def test_a_light_cover_over_an_inverted_corner_is_no_side(bundled) -> None:
    """A light grey square over an inverted tag's corner opens its dark quiet zone; the white
    data area's outline runs on along the cover's edge, a run longer than what it supports of
    any side: a run counts only between its side's corners, and the visible sides outline the
    data area (8 of 8 read; before: 6)."""
    assert _reads_hidden(bundled, "covered corner", "inverted", 200) >= 7
