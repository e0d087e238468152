"""The compiled kernels (``native/ottag_native``, Cython) compute exactly what their numpy
formulation does, bit for bit: the decoder's readings must not depend on which one ran.

The numpy formulations below are the test's oracle (they were the decoder's code before the
kernels): each step as numpy takes it, in float64.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import ottag_native.blur
import ottag_native.triangles
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.decode import blur
from ottag_db.decode.blur import EdgeBlur, edge_blur
from ottag_db.decode.triangles import triangle_fit_parts
from ottag_db.decode.types import Quad


def _sorted_medians(ordered: np.ndarray, count: np.ndarray) -> np.ndarray:
    at = lambda rank: np.take_along_axis(ordered, np.clip(rank, 0, ordered.shape[1] - 1)[:, None], axis=1)[:, 0]  # noqa: E731
    low, high = at((count - 1) // 2), at(count // 2)
    return np.where(count % 2 == 1, low, (low + high) / 2)


def _edge_blur_numpy(gray: np.ndarray, quad: Quad) -> EdgeBlur:
    """:func:`~ottag_db.decode.blur.edge_blur` in numpy (see its docstring)."""
    along, spread_along = blur._ALONG, blur._ALONG_SPREAD
    corners = quad.corners
    side = math.sqrt(max(quad.area, 1.0))
    reach = min(blur._ACROSS_MAX, max(4.0, 0.2 * side))
    across = np.arange(-reach, reach + 1e-9, blur._ACROSS_STEP)
    centre = corners.mean(axis=0)
    a, b = corners, np.roll(corners, -1, axis=0)
    direction = b - a
    length = np.hypot(direction[:, 0], direction[:, 1])
    normal = np.stack([direction[:, 1], -direction[:, 0]], axis=1) / np.maximum(length, 1e-9)[:, None]
    flip = np.sign(np.einsum("si,si->s", (a + b) / 2 - centre, normal))
    normal = normal * np.where(flip == 0, 1.0, flip)[:, None]
    fractions = (along[:, None] + spread_along[None, :] / np.maximum(length, 1e-9)[:, None, None]).reshape(4, -1)
    starts = a[:, None, :] + fractions[:, :, None] * direction[:, None, :]
    xs = (starts[:, :, 0, None] + across[None, None, :] * normal[:, 0, None, None]).astype(np.float32)
    ys = (starts[:, :, 1, None] + across[None, None, :] * normal[:, 1, None, None]).astype(np.float32)
    shape = (4 * len(along) * len(spread_along), len(across))
    profiles = cv2.remap(gray, xs.reshape(shape), ys.reshape(shape), cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    profile = profiles.reshape(4 * len(along), len(spread_along), len(across)).mean(axis=1)
    third = max(len(across) // 3, 1)
    outer = np.median(profile[:, -third:], axis=1)
    spread = blur._SMOOTHING_PX / blur._ACROSS_STEP
    smooth = cv2.GaussianBlur(profile, (2 * math.ceil(3 * spread) + 1, 1), spread, borderType=cv2.BORDER_REPLICATE)
    steps = np.abs(np.diff(smooth, axis=1))
    steepest = steps.argmax(axis=1)
    rows = np.arange(len(smooth))
    middle = (smooth[rows, steepest] + smooth[rows, steepest + 1]) / 2
    height = 2 * np.abs(outer - middle)
    slope = steps[rows, steepest] / blur._ACROSS_STEP
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = height / (slope * math.sqrt(2 * math.pi))
    sigma = np.sqrt(np.maximum(sigma * sigma - blur._SMOOTHING_PX**2, 0.0))
    least = min(max(blur.STEP_MIN_SHARE * float(np.median(height)), blur._NOISE_HEIGHT), blur._MIN_HEIGHT)
    sigma = np.where((height >= least) & (slope > 0), sigma, np.nan).reshape(4, len(along))
    count = np.isfinite(sigma).sum(axis=1)
    valid = (count >= len(along) // 2) & (length >= 4)
    ordered = np.sort(sigma, axis=1)
    per_side = np.where(valid, _sorted_medians(ordered, count), np.nan)
    rank = lambda f: np.clip(np.rint(f * (count - 1)).astype(np.int64), 0, len(along) - 1)[:, None]  # noqa: E731
    low, high = (np.take_along_axis(ordered, rank(f), axis=1)[:, 0] for f in (0.25, 0.75))
    errors = np.where(valid, 1.2533 * (high - low) / 1.349 / np.sqrt(np.maximum(count, 1)), np.nan)
    where = np.where(np.isfinite(sigma.ravel()), across[steepest] + blur._ACROSS_STEP / 2, np.nan)
    offsets = np.where(valid, _sorted_medians(np.sort(where.reshape(4, -1), axis=1), count), np.nan)
    heights = np.where(np.isfinite(sigma), height.reshape(4, -1), np.nan)
    step_heights = np.where(valid, _sorted_medians(np.sort(heights, axis=1), count), np.nan)
    return EdgeBlur(
        tuple(per_side.tolist()), normal, tuple(offsets.tolist()), tuple(errors.tolist()), tuple(step_heights.tolist())
    )


def _same(a: EdgeBlur, b: EdgeBlur) -> bool:
    fields = ("sides", "normals", "offsets", "errors", "steps")
    return all(np.array_equal(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)), equal_nan=True) for f in fields)


def _scene(seed: int, blur_px: float, noise: float) -> np.ndarray:
    """A grey frame with dark quads (tag-like steps), blurred and noisy."""
    rng = np.random.default_rng(seed)
    image = np.full((120, 160), 200.0)
    for _ in range(3):
        centre = rng.uniform(20, 140, 2)
        pts = centre + rng.uniform(-30, 30, (4, 2))
        cv2.fillConvexPoly(image, cv2.convexHull(pts.astype(np.int32)), float(rng.uniform(10, 120)))
    if blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_px)
    image = image + rng.normal(0, noise, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8)


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    blur_px=st.floats(0.0, 4.0),
    noise=st.floats(0.0, 8.0),
    corners=st.lists(st.tuples(st.floats(-30, 190), st.floats(-30, 150)), min_size=4, max_size=4),
    area=st.floats(0.0, 30_000.0),
)
def test_the_edge_blur_kernel_is_the_numpy_formulation_bit_for_bit(
    seed: int, blur_px: float, noise: float, corners: list[tuple[float, float]], area: float
) -> None:
    gray = _scene(seed, blur_px, noise)
    quad = Quad("normal", np.array(corners, dtype=np.float64), area)
    assert _same(edge_blur(gray, quad), _edge_blur_numpy(gray, quad))


def test_the_edge_blur_kernel_on_a_blurred_square_and_degenerate_quads() -> None:
    image = np.full((100, 100), 210, np.uint8)
    image[30:70, 30:70] = 40
    gray = cv2.GaussianBlur(image, (0, 0), 2.0)
    square = Quad("normal", np.array([[29.5, 29.5], [69.5, 29.5], [69.5, 69.5], [29.5, 69.5]]), 1600.0)
    measured = edge_blur(gray, square)
    assert _same(measured, _edge_blur_numpy(gray, square))
    assert all(1.6 < s < 2.4 for s in measured.sides)  # a defocus of σ 2 measures 2 on every side
    for corners in ([[50, 50]] * 4, [[10, 10], [90, 10], [50, 10], [20, 10]]):  # a point, a line
        quad = Quad("normal", np.array(corners, dtype=np.float64), 0.0)
        assert _same(edge_blur(gray, quad), _edge_blur_numpy(gray, quad))


def test_the_kernels_refuse_arrays_of_the_wrong_shape() -> None:
    out = np.empty((4, 4))
    profile = np.zeros((36, 20))
    with pytest.raises(ValueError, match="36, W"):
        ottag_native.blur.side_blurs(
            np.zeros((35, 20)), profile[:35], np.zeros(20), np.zeros(4), out, 0.5, 1, 0.5, 10, 20
        )
    with pytest.raises(ValueError, match="4 side lengths"):
        ottag_native.blur.side_blurs(profile, profile, np.zeros(20), np.zeros(3), out, 0.5, 1, 0.5, 10, 20)


def _triangle_fit_numpy(pts: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]] | None:
    """:func:`~ottag_db.decode.triangles.triangle_fit_parts` in numpy and plain Python (see its
    comments): the corners and the side chains, or None."""
    n = len(pts)
    if n < 8:
        return None
    c = np.ascontiguousarray(pts.reshape(-1, 2), dtype=np.int32).reshape(-1, 1, 2)
    hull = cv2.convexHull(c, returnPoints=False).ravel()
    if len(hull) < 3:
        return None
    flat = c.reshape(-1, 2).astype(np.float64)
    hp = flat[hull]
    dx, dy = hp[:, 0, None] - hp[None, :, 0], hp[:, 1, None] - hp[None, :, 1]
    ia, ib = divmod(int((dx * dx + dy * dy).argmax()), len(hp))

    def far(p0: int, p1: int) -> list[float]:
        (x0, y0), (x1, y1) = hp[p0].tolist(), hp[p1].tolist()
        return [abs((x1 - x0) * (y - y0) - (y1 - y0) * (x - x0)) for x, y in hp.tolist()]

    vals = far(ia, ib)
    sel = [ia, ib, vals.index(max(vals))]
    for it in range(3):
        changed = False
        for r in range(3):
            if r == 2 and it == 0 and not changed:
                break
            vals = far(sel[(r + 1) % 3], sel[(r + 2) % 3])
            best = vals.index(max(vals))
            if best != sel[r] and vals[best] > vals[sel[r]] + 1e-9:
                sel[r], changed = best, True
        if not changed:
            break
    idx = sorted({int(hull[s]) for s in sel})
    if len(idx) < 3:
        return None
    tri = flat[idx]
    (t0x, t0y), (t1x, t1y), (t2x, t2y) = tri.tolist()
    t_area = 0.5 * abs((t1x - t0x) * (t2y - t0y) - (t1y - t0y) * (t2x - t0x))
    if t_area <= 0 or abs(abs(cv2.contourArea(c)) - t_area) > 0.2 * t_area + 0.25 * cv2.arcLength(c, True):
        return None
    i0, i1, i2 = idx
    segs = (flat[i0 : i1 + 1], flat[i1 : i2 + 1], np.concatenate([flat[i2:], flat[: i0 + 1]]))
    chains, far_count = [], 0
    for seg, (s, q) in zip(segs, ((0, 1), (1, 2), (2, 0)), strict=True):
        m = len(seg)
        ln = math.hypot(*(tri[q] - tri[s]).tolist())
        if ln < 1:
            return None
        if m < 6:
            chains.append(seg[[0, -1]])
            continue
        trim, t10 = max(1, int(0.15 * m)), max(1, int(0.1 * m))
        core = seg[trim : m - trim]
        cx, cy = core[:, 0].sum() / len(core), core[:, 1].sum() / len(core)
        gxx, gxy, gyy = (core[:, 0] ** 2).sum(), (core[:, 0] * core[:, 1]).sum(), (core[:, 1] ** 2).sum()
        sx, sy = core[:, 0].sum(), core[:, 1].sum()
        theta = 0.5 * math.atan2(2 * (gxy - sx * cy), (gxx - sx * cx) - (gyy - sy * cy))
        nx, ny = -math.sin(theta), math.cos(theta)
        dist = np.abs((seg[t10 : m - t10, 0] * nx + seg[t10 : m - t10, 1] * ny) - (nx * cx + ny * cy))
        far_count += int(np.count_nonzero(dist > 1.0 + 0.015 * ln))
        chains.append(core)
    if far_count > max(2, 0.05 * n):
        return None
    return tri, chains


@settings(max_examples=300, deadline=None)
@given(
    corners=st.lists(st.tuples(st.integers(2, 97), st.integers(2, 97)), min_size=3, max_size=6),
    thicken=st.booleans(),
)
def test_the_triangle_fit_kernel_is_the_numpy_formulation(corners: list[tuple[int, int]], thicken: bool) -> None:
    image = np.zeros((100, 100), np.uint8)
    cv2.fillPoly(image, [np.array(corners, np.int32)], 255)
    if thicken:
        image = cv2.dilate(image, np.ones((3, 3), np.uint8))
    contours, _ = cv2.findContours(image, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    for contour in contours:
        pts = contour.reshape(-1, 2)
        fit, expected = triangle_fit_parts(pts), _triangle_fit_numpy(pts)
        assert (fit is None) == (expected is None)
        if fit is not None and expected is not None:
            assert np.array_equal(fit.corners, expected[0])
            assert all(np.array_equal(a, b) for a, b in zip(fit.chains, expected[1], strict=True))


def test_the_triangle_fit_kernel_fits_a_triangle_and_refuses_a_square() -> None:
    image = np.zeros((100, 100), np.uint8)
    cv2.fillPoly(image, [np.array([[10, 10], [90, 20], [30, 85]], np.int32)], 255)
    contour = cv2.findContours(image, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)[0][0].reshape(-1, 2)
    fit = triangle_fit_parts(contour)
    assert fit is not None and len(fit.chains) == 3
    assert sorted(fit.corners.tolist()) == [[10.0, 10.0], [30.0, 85.0], [90.0, 20.0]]
    square = np.zeros((100, 100), np.uint8)
    square[20:80, 20:80] = 255
    contour = cv2.findContours(square, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)[0][0].reshape(-1, 2)
    assert triangle_fit_parts(contour) is None
    with pytest.raises(ValueError, match="hull indices"):
        ottag_native.triangles.fit_triangle(contour.astype(np.float64), np.array([0, 1, 9999], np.int32), 1.0, 1.0)
