"""The compiled kernels of a data area's reading give exactly what their numpy formulation
gives, bit for bit: the chain moments of :func:`~ottag_db.decode.refine.fit_chains` on chains of
2 to 400 points, and the sample grid, level crossings, crossing moments and inward sides of
:func:`~ottag_db.decode.refine.refine_lines` (both ``ottag_native.refine``) on random triangles
(touching ones and a side of zero length among them), with and without a data area around them,
on blurred grey levels, and the crossings of one data-area side searched again over the first
search's offsets or the wide ones; Otsu's split of :func:`~ottag_db.decode.image.otsu`
(``ottag_native.histogram``) on histograms of two classes and of one grey level; the checks of
:func:`~ottag_db.decode.triangles.bad_triangles` (``ottag_native.triangles``) on triangles that
share part of a side, leave the data area, or are degenerate.

The numpy formulations below are the test's oracles (they were the decoder's code before the
kernels).
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import ottag_native.refine
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from ottag_db.decode import refine
from ottag_db.decode.image import otsu
from ottag_db.decode.triangles import bad_triangles

_F64 = NDArray[np.float64]


def _inward(normal: _F64, offset: _F64, quad: _F64) -> NDArray[np.bool_]:
    """Whether each line's normal points into the quad (towards its centre), as numpy computed it."""
    out: NDArray[np.bool_] = normal @ quad.mean(axis=0) - offset > 0
    return out


def _falls(above: NDArray[np.bool_], inward: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``(R, O - 1)``: where a row crosses the border's way (falling along the normal when it
    points inward, rising when it points out), as numpy computed it."""
    out: NDArray[np.bool_] = (above[:, :-1] & ~above[:, 1:]) == inward[:, None]
    return out


def _fit_samples(px: _F64, py: _F64, w: _F64, cnt: _F64) -> tuple[_F64, _F64]:
    """Weighted least-squares lines of the ``(S, M)`` points, ``cnt = w.sum(axis=1)``, as numpy computed them."""
    cnt_safe = np.maximum(cnt, 1)
    mx_ = (w * px).sum(axis=1) / cnt_safe
    my_ = (w * py).sum(axis=1) / cnt_safe
    qx = px - mx_[:, None]
    qy = py - my_[:, None]
    wdx = w * qx
    return refine.lines_from_moments(
        mx_, my_, (wdx * qx).sum(axis=1), (wdx * qy).sum(axis=1), (w * qy * qy).sum(axis=1)
    )


def _grid_numpy(a: _F64, sd: _F64, normal: _F64, st_: int) -> tuple[Any, ...]:
    """The samples, their widths, the wide flags and the remap grid, as numpy computed them."""
    s = len(a)
    base = [a[:, c, None] + refine._REFINE_FR[None, :] * sd[:, c, None] for c in (0, 1)]
    bx, by = base[0][:, :, None], base[1][:, :, None]
    ax, ay = a[:st_, 0], a[:st_, 1]
    dx, dy = sd[:st_, 0], sd[:st_, 1]
    ln2 = np.maximum(dx * dx + dy * dy, 1e-12)
    rx = bx - ax
    ry = by - ay
    u = (rx * dx + ry * dy) / ln2
    np.clip(u, 0.0, 1.0, out=u)
    rx -= u * dx
    ry -= u * dy
    gap = rx * rx + ry * ry
    gap[np.arange(st_), :, np.arange(st_)] = np.inf
    width = np.sqrt(gap.min(axis=2, initial=np.inf))
    m_fr = len(refine._REFINE_FR)
    wide = np.ones((s, m_fr), dtype=bool)
    wide[:st_] = width[:st_] >= np.minimum(3.0, 0.6 * width[:st_].max(axis=1, initial=0.0))[:, None]
    offs = refine._REFINE_OFFS
    samp32 = np.empty((s, m_fr, len(offs), 2), dtype=np.float32)
    for c in (0, 1):
        shift = offs[None, :] * normal[:, c, None]
        np.add(base[c][:, :, None], shift[:, None, :], out=samp32[..., c], casting="same_kind")
    return base[0], base[1], width, wide, samp32


def _crossings_numpy(
    vals32: NDArray[np.float32], level: float, st_: int, inward: NDArray[np.bool_] | None, base: tuple[_F64, _F64],
    normal: _F64, wide: NDArray[np.bool_],
) -> tuple[_F64, _F64, NDArray[np.bool_]]:  # fmt: skip
    """The crossing nearest each side per row of samples, as numpy computed it."""
    s, m_fr = wide.shape
    offs = refine._REFINE_OFFS
    vals = vals32.reshape(s * m_fr, len(offs)).astype(np.float64)
    vals -= level
    above = vals > 0
    change = above[:, 1:] != above[:, :-1]
    if inward is not None:
        change[st_ * m_fr :] &= _falls(above[st_ * m_fr :], np.repeat(inward, m_fr))
    j = np.where(change, refine._REFINE_MID, np.inf).argmin(axis=1)
    rows = np.arange(len(vals))
    v0 = vals[rows, j]
    den = v0 - vals[rows, j + 1]
    step = den != 0
    o = offs[j] + np.where(step, v0 / np.where(step, den, 1.0), 0.5) * (offs[1] - offs[0])
    valid = (change.any(axis=1) & wide.ravel()).reshape(s, -1)
    o2 = o.reshape(s, -1)
    return base[0] + o2 * normal[:, 0, None], base[1] + o2 * normal[:, 1, None], valid


def _compiled(a: _F64, sd: _F64, normal: _F64, st_: int) -> tuple[Any, ...]:
    s, m_fr, n_o = len(a), len(refine._REFINE_FR), len(refine._REFINE_OFFS)
    base_x, base_y, width = (np.empty((s, m_fr)) for _ in range(3))
    wide = np.empty((s, m_fr), dtype=np.uint8)
    samp32 = np.empty((s, m_fr, n_o, 2), dtype=np.float32)
    ottag_native.refine.sample_grid(
        a, sd, normal, st_, refine._REFINE_FR, refine._REFINE_OFFS, base_x, base_y, width, wide, samp32
    )
    return base_x, base_y, width, wide.view(bool), samp32


def _sides(rng: np.random.Generator, triangles: int, with_quad: bool) -> tuple[_F64, _F64, _F64, _F64 | None]:
    """Random triangles (and a data area around them): side starts, vectors and unit normals."""
    verts = rng.uniform(5, 55, size=(triangles, 3, 2))
    a = verts.reshape(-1, 2)
    b = np.roll(verts, -1, axis=1).reshape(-1, 2)
    quad = None
    if with_quad:
        quad = np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 60.0], [0.0, 60.0]]) + rng.normal(0, 2, (4, 2))
        a = np.concatenate([a, quad])
        b = np.concatenate([b, np.roll(quad, -1, axis=0)])
    sd = b - a
    normal = np.stack([-sd[:, 1], sd[:, 0]], axis=1)
    normal /= np.maximum(np.hypot(normal[:, 0], normal[:, 1]), 1e-12)[:, None]
    if triangles > 1:  # a degenerate side (zero length) and touching triangles occur in practice
        sd[1] = 0.0
        a[3] = a[1]
    return np.ascontiguousarray(a), np.ascontiguousarray(sd), normal, quad


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), triangles=st.integers(1, 5), with_quad=st.booleans(), level=st.floats(20, 230))
def test_the_kernels_compute_what_numpy_computed(seed: int, triangles: int, with_quad: bool, level: float) -> None:
    rng = np.random.default_rng(seed)
    a, sd, normal, quad = _sides(rng, triangles, with_quad)
    st_ = 3 * triangles
    expected = _grid_numpy(a, sd, normal, st_)
    got = _compiled(a, sd, normal, st_)
    for e, g in zip(expected, got, strict=True):
        assert np.array_equal(e, g), "the sample grid differs from numpy's"
    # grey levels: a bright blob in a dark square, blurred, with sample values at the level itself
    img = np.full((70, 70), 40, np.float32)
    cv2.circle(img, (int(rng.integers(15, 55)), int(rng.integers(15, 55))), int(rng.integers(5, 25)), 220.0, -1)
    blurred = np.asarray(cv2.GaussianBlur(img, (0, 0), float(rng.uniform(0.5, 2.0))), dtype=np.float32)
    vals32 = cv2.remap(blurred, expected[4].reshape(1, -1, 2), None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    vals32 = np.asarray(vals32, dtype=np.float32).reshape(len(a) * len(refine._REFINE_FR), -1)
    vals32[::7, 3] = np.float32(level)  # a sample exactly at the level: no crossing of it there
    offset = (normal * a).sum(axis=1)  # the lines through the sides' first ends
    inward = None if quad is None else _inward(normal[st_:], offset[st_:], quad)
    want = _crossings_numpy(vals32, level, st_, inward, (expected[0], expected[1]), normal, expected[3])
    s, m_fr = expected[3].shape
    px, py = np.empty((s, m_fr)), np.empty((s, m_fr))
    valid = np.empty((s, m_fr), dtype=np.uint8)
    ottag_native.refine.level_crossings(
        vals32, level, st_, np.empty(0, np.uint8) if inward is None else inward.astype(np.uint8),
        refine._REFINE_OFFS, refine._REFINE_MID, got[0], got[1], normal, got[3].view(np.uint8), px, py, valid,
    )  # fmt: skip
    assert np.array_equal(want[0], px) and np.array_equal(want[1], py), "the crossings differ from numpy's"
    assert np.array_equal(want[2], valid.view(bool)), "the found crossings differ from numpy's"


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 20), scale=st.floats(0.01, 500.0))
def test_the_moments_and_the_inward_sides_are_numpys(seed: int, rows: int, scale: float) -> None:
    rng = np.random.default_rng(seed)
    m = len(refine._REFINE_FR)
    px = rng.normal(size=(rows, m)) * scale + rng.uniform(-300, 300)
    py = rng.normal(size=(rows, m)) * scale + rng.uniform(-300, 300)
    valid = rng.random((rows, m)) > rng.uniform(0, 1)
    got = [np.empty(rows) for _ in range(6)]
    ottag_native.refine.crossing_moments(px, py, valid.view(np.uint8), *got)
    w = valid.astype(np.float64)
    assert np.array_equal(got[5], w.sum(axis=1))
    # the lines of the moments are those of the numpy fit, bit for bit
    want = _fit_samples(px, py, w, w.sum(axis=1))
    lines = refine.lines_from_moments(*got[:5])
    assert np.array_equal(want[0], lines[0]) and np.array_equal(want[1], lines[1]), "the moments differ from numpy's"
    quad = np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 60.0], [0.0, 60.0]]) * scale / 100 + rng.normal(0, 1, (4, 2))
    normal = rng.normal(size=(rows, 2))
    normal /= np.hypot(normal[:, 0], normal[:, 1])[:, None]
    offset = (normal * quad[rng.integers(0, 4, rows)]).sum(axis=1)  # lines through the corners
    inward = np.empty(rows, dtype=np.uint8)
    ottag_native.refine.inward_sides(normal, offset, quad, inward)
    assert np.array_equal(_inward(normal, offset, quad), inward.view(bool))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), wide_search=st.booleans(), level=st.floats(20, 230))
def test_a_data_area_side_searched_again_crosses_as_numpy_found(seed: int, wide_search: bool, level: float) -> None:
    # refine._recentre_quad_sides: one data-area side (st = 0), its crossings over the first
    # search's offsets or the wide ones, as numpy found them
    rng = np.random.default_rng(seed)
    offs = refine._WIDE_OFFS if wide_search else refine._REFINE_OFFS
    m = len(refine._REFINE_FR)
    ramp = np.clip((offs[None, :] + rng.normal(0, 2, (m, 1))) * rng.uniform(-60, 60), -120, 120) + 128
    vals32 = np.asarray(ramp + rng.normal(0, 3, ramp.shape), dtype=np.float32)
    vals32[::5, 4] = np.float32(level)  # a sample exactly at the level
    quad = np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 60.0], [0.0, 60.0]]) + rng.normal(0, 2, (4, 2))
    n = rng.normal(size=2)
    n /= np.hypot(n[0], n[1])
    c = float(n @ quad[int(rng.integers(0, 4))])
    base = rng.uniform(0, 60, (m, 2))
    # numpy, as the side was searched again before the kernel
    vals = vals32.astype(np.float64) - level
    above = vals > 0
    inward = np.repeat(_inward(n[None], np.array([c]), quad), m)
    change = (above[:, 1:] != above[:, :-1]) & _falls(above, inward)
    j = np.where(change, np.abs(0.5 * (offs[1:] + offs[:-1])), np.inf).argmin(axis=1)
    rows = np.arange(m)
    v0 = vals[rows, j]
    den = v0 - vals[rows, j + 1]
    step = den != 0
    o = offs[j] + np.where(step, v0 / np.where(step, den, 1.0), 0.5) * (offs[1] - offs[0])
    found = change.any(axis=1)
    want = base[found] + o[found, None] * n[None, :]
    # the kernel, as refine._recentre_quad_sides calls it
    got_in = np.empty(1, dtype=np.uint8)
    ottag_native.refine.inward_sides(n[None], np.array([c]), quad, got_in)
    px, py, valid = np.empty((1, m)), np.empty((1, m)), np.empty((1, m), dtype=np.uint8)
    ottag_native.refine.level_crossings(
        vals32, level, 0, got_in, offs, np.abs(0.5 * (offs[1:] + offs[:-1])),
        np.ascontiguousarray(base[:, 0])[None, :], np.ascontiguousarray(base[:, 1])[None, :], n[None],
        np.ones((1, m), dtype=np.uint8), px, py, valid,
    )  # fmt: skip
    kept = valid[0].view(bool)
    assert np.array_equal(kept, found), "the found crossings differ from numpy's"
    assert np.array_equal(px[0][kept], want[:, 0]) and np.array_equal(py[0][kept], want[:, 1])


def _otsu_numpy(hist: NDArray[Any]) -> tuple[int, float, float] | None:
    """Otsu's split and its class means, as numpy computed them (the oracle of ``otsu``)."""
    levels = np.arange(256, dtype=np.float64)
    w0 = np.cumsum(hist, dtype=np.float64)
    total = float(w0[-1])
    if total < 16:
        return None
    s0 = np.cumsum(hist * levels)
    s_all = float(s0[-1])
    num = total * s0 - s_all * w0
    den = w0 * (total - w0)
    between = num * num / np.where(den > 0, den, np.inf)
    t = int(between.argmax())
    w0t = float(w0[t])
    if w0t <= 0 or total - w0t <= 0:
        return None
    s0t = float(s0[t])
    return t, s0t / w0t, (s_all - s0t) / (total - w0t)


@settings(max_examples=100, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    pixels=st.integers(0, 200_000),
    spread=st.floats(0.5, 60.0),
    one_level=st.booleans(),
)
def test_otsus_split_is_numpys(seed: int, pixels: int, spread: float, one_level: bool) -> None:
    rng = np.random.default_rng(seed)
    dark, bright = rng.uniform(0, 255, 2)
    grey = np.concatenate([rng.normal(dark, spread, pixels // 2), rng.normal(bright, spread, pixels - pixels // 2)])
    roi = np.clip(np.rint(grey), 0, 255).astype(np.uint8).reshape(1, -1)
    if one_level:  # a uniform patch: one class is empty at every split
        roi[:] = roi[0, 0] if roi.size else 0
    hist = cv2.calcHist([roi], [0], None, [256], [0, 256]).ravel() if roi.size else np.zeros(256, np.float32)
    want = _otsu_numpy(hist)
    got = otsu(hist)
    assert (got is None) == (want is None)
    if got is not None and want is not None:
        assert (got.level, got.dark, got.bright) == want  # exactly: the same operations in float64


def _bad_triangles_numpy(verts: _F64, quad: _F64, side: float) -> str | None:
    """Why the triangles cannot be a tag's, as numpy computed it (the oracle of ``bad_triangles``)."""
    if not np.isfinite(verts).all():
        return "degenerate triangle"
    v = verts.reshape(-1, 2)
    a = quad
    d = np.roll(quad, -1, axis=0) - a
    cross = d[None, :, 0] * (v[:, None, 1] - a[None, :, 1]) - d[None, :, 1] * (v[:, None, 0] - a[None, :, 0])
    cross /= np.hypot(d[:, 0], d[:, 1])[None, :]
    slack = 1.0 + 0.01 * side
    if not ((cross >= -slack).all(axis=1).all() or (cross <= slack).all(axis=1).all()):
        return "triangle vertex outside the data area"
    if len(verts) < 2:
        return None
    near = max(0.8, 0.008 * side)
    sa = verts.reshape(-1, 2)
    sb = verts[:, [1, 2, 0]].reshape(-1, 2)
    sd = sb - sa
    ln = np.maximum(np.hypot(sd[:, 0], sd[:, 1]), 1e-9)
    ux, uy = (sd[:, 0] / ln)[:, None], (sd[:, 1] / ln)[:, None]
    nx = -uy
    rax, ray = sa[None, :, 0] - sa[:, None, 0], sa[None, :, 1] - sa[:, None, 1]
    rbx, rby = sb[None, :, 0] - sa[:, None, 0], sb[None, :, 1] - sa[:, None, 1]
    off_a = np.abs(rax * nx + ray * ux)
    off_b = np.abs(rbx * nx + rby * ux)
    pa = rax * ux + ray * uy
    pb = rbx * ux + rby * uy
    overlap = np.minimum(np.maximum(pa, pb), ln[:, None]) - np.maximum(np.minimum(pa, pb), 0.0)
    tri = np.arange(len(sa)) // 3
    own = tri[:, None] == tri[None, :]
    shared = (off_a < near) & (off_b < near) & (overlap > np.minimum(ln[:, None], ln[None, :]) / 3) & ~own
    return "two triangles share part of a side" if shared.any() else None


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    triangles=st.integers(1, 14),
    fault=st.sampled_from(["none", "shared", "outside", "nan", "degenerate"]),
    reverse=st.booleans(),
)
def test_the_triangle_checks_are_numpys(seed: int, triangles: int, fault: str, reverse: bool) -> None:
    rng = np.random.default_rng(seed)
    side = float(rng.uniform(20, 200))
    quad = np.array([[0.0, 0.0], [side, 0.0], [side, side], [0.0, side]]) + rng.normal(0, 0.02 * side, (4, 2))
    if reverse:
        quad = quad[::-1].copy()
    verts = rng.uniform(0.05 * side, 0.95 * side, size=(triangles, 3, 2))
    if fault == "shared" and triangles > 1:  # triangle 1 has a side along part of triangle 0's
        t = rng.uniform(0.1, 0.5)
        verts[1, 0] = verts[0, 0] + t * (verts[0, 1] - verts[0, 0]) + rng.normal(0, 0.3, 2)
        verts[1, 1] = verts[0, 0] + (t + rng.uniform(0.1, 0.5)) * (verts[0, 1] - verts[0, 0]) + rng.normal(0, 0.3, 2)
    elif fault == "outside":
        verts[-1, 2] = quad[0] + rng.uniform(-0.05, 0.05, 2) * side
    elif fault == "nan":
        verts[-1, 1, 0] = np.nan if rng.random() < 0.5 else np.inf
    elif fault == "degenerate":  # a side of zero length; a vertex shared by two triangles
        verts[0, 1] = verts[0, 0]
        if triangles > 1:
            verts[1, 0] = verts[0, 2]
    got = bad_triangles(verts, quad, side)
    assert (None if got is None else got.detail) == _bad_triangles_numpy(verts, quad, side)


def _fit_chains_numpy(chains: list[_F64]) -> tuple[_F64, _F64]:
    """The least-squares lines of point chains, as numpy computed them (the oracle of ``fit_chains``)."""
    lens = np.array([len(c) for c in chains])
    allp = np.concatenate(chains)
    starts = np.concatenate([[0], np.cumsum(lens)[:-1]])
    sx = np.add.reduceat(allp[:, 0], starts)
    sy = np.add.reduceat(allp[:, 1], starts)
    mx, my = sx / lens, sy / lens
    rep = np.repeat(np.arange(len(chains)), lens)
    dx = allp[:, 0] - mx[rep]
    dy = allp[:, 1] - my[rep]
    return refine.lines_from_moments(
        mx, my, np.add.reduceat(dx * dx, starts), np.add.reduceat(dx * dy, starts), np.add.reduceat(dy * dy, starts)
    )


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), lengths=st.lists(st.integers(2, 400), min_size=1, max_size=12))
def test_the_chain_lines_are_numpys(seed: int, lengths: list[int]) -> None:
    rng = np.random.default_rng(seed)
    chains = []
    for n in lengths:  # points along a line with pixel noise, some integer, some sub-pixel
        t = np.linspace(0, rng.uniform(2, 300), n)
        angle = rng.uniform(0, np.pi)
        pts = (
            rng.uniform(0, 640, 2) + t[:, None] * np.array([np.cos(angle), np.sin(angle)]) + rng.normal(0, 0.7, (n, 2))
        )
        chains.append(np.rint(pts) if rng.random() < 0.5 else pts)
    want, got = _fit_chains_numpy(chains), refine.fit_chains(chains)
    assert np.array_equal(want[0], got[0]) and np.array_equal(want[1], got[1])
