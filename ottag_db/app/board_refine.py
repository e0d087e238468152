"""Model-based refinement of a board tag's correspondences (calibration's last pass).

The detector locates each point from the triangles around it; calibration knows more: the
printed geometry of the whole tag (data-area square and triangle sides, in board mm). In a
frame without lens distortion a flat tag is a homography of its print, so every printed
straight edge is a straight image edge. :func:`refine_tag` samples the grey image across every
printed edge where no other edge is near (sub-pixel edge position of the blurred step by the
area method, along the edge normal), and fits the tag's board → image homography to all those
edge samples (iteratively reweighted linear least squares on the point-on-line constraints).
The refined correspondences are the board points mapped by it: hundreds of edge samples per
tag instead of the few pixels around each vertex.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.geometry import segment_distances

__all__ = ["Straightening", "refine_tag", "tag_edges"]

_F64 = NDArray[np.float64]

#: Half-length of an edge profile, px; other printed edges must be farther than ``_CLEAR`` px.
_HALF = 3.0
_STEP = 0.25
_CLEAR = 4.0
_MIN_CONTRAST = 30.0


def tag_edges(
    corners_mm: Sequence[tuple[float, float]],
    points_mm: Sequence[tuple[float, float]],
    triangles: Sequence[tuple[int, int, int]],
) -> list[tuple[_F64, _F64]]:
    """The printed straight edges of a tag: data-area sides, then triangle sides.

    Parameters
    ----------
    corners_mm : sequence of (float, float)
        Data-area corners in board mm, in order around the square.
    points_mm : sequence of (float, float)
        The tag's points in board mm (label order).
    triangles : sequence of (int, int, int)
        The printed triangles as label triples (may be empty: square sides only).

    Returns
    -------
    list of (ndarray, ndarray)
        Segments ``(a, b)``, end points in board mm.
    """
    c = np.asarray(corners_mm, dtype=np.float64)
    p = np.asarray(points_mm, dtype=np.float64)
    segs = [(c[i], c[(i + 1) % 4]) for i in range(4)]
    for t in triangles:
        segs += [(p[t[i]], p[t[(i + 1) % 3]]) for i in range(3)]
    return segs


def _apply(h: _F64, pts: _F64) -> _F64:
    q = np.c_[pts, np.ones(len(pts))] @ h.T
    out: _F64 = q[:, :2] / q[:, 2:3]
    return out


def _edge_samples(gray: NDArray[np.float32], h: _F64, segs: list[tuple[_F64, _F64]]) -> tuple[_F64, _F64]:
    """Image edge points (n, 2) and the board lines (n, 3: unit normal, −offset) they lie on."""
    import cv2

    offs = np.arange(-_HALF, _HALF + 1e-9, _STEP)
    scale = math.sqrt(abs(float(np.linalg.det(h[:2, :2] - np.outer(h[:2, 2], h[2, :2])))))  # ~px per mm
    lines: list[_F64] = []
    points: list[_F64] = []
    for si, (a, b) in enumerate(segs):
        ends = _apply(h, np.array([a, b]))
        n = max(int(np.linalg.norm(ends[1] - ends[0]) / 1.5), 2)
        mp = a + ((np.arange(n) + 0.5) / n)[:, None] * (b - a)
        ok = np.ones(n, dtype=bool)
        for sj, (c, d) in enumerate(segs):
            if sj != si:
                ok &= segment_distances(mp, c[None], d[None])[:, 0] * scale > _CLEAR
        if ok.sum() < 2:
            continue
        mp = mp[ok]
        tangent = (b - a) / np.linalg.norm(b - a)
        x0 = _apply(h, mp)
        tv = _apply(h, mp + 1e-3 * tangent) - x0
        tv /= np.linalg.norm(tv, axis=1, keepdims=True)
        nv = np.c_[-tv[:, 1], tv[:, 0]]
        grid = x0[:, None, :] + offs[None, :, None] * nv[:, None, :]
        prof = cv2.remap(
            gray,
            grid[..., 0].astype(np.float32),
            grid[..., 1].astype(np.float32),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        ).astype(np.float64)
        lo, hi = prof[:, :3].mean(axis=1), prof[:, -3:].mean(axis=1)
        good = np.abs(hi - lo) > _MIN_CONTRAST
        frac = (prof - lo[:, None]) / np.where(good, hi - lo, 1.0)[:, None]
        # a step at offset e: the integral of frac over [−HALF, HALF] is HALF − e (trapezoids)
        e = _HALF - (frac.sum(axis=1) - 0.5 * (frac[:, 0] + frac[:, -1])) * _STEP
        good &= np.abs(e) < _HALF - 1.0
        if good.sum() < 2:
            continue
        normal = np.array([-tangent[1], tangent[0]])
        points.append(x0[good] + e[good, None] * nv[good])
        lines.append(np.tile(np.r_[normal, -float(normal @ a)], (int(good.sum()), 1)))
    if not points:
        return np.zeros((0, 2)), np.zeros((0, 3))
    return np.concatenate(points), np.concatenate(lines)


def refine_tag(
    gray: NDArray[np.float32], homography: _F64, segs: list[tuple[_F64, _F64]], iterations: int = 3
) -> _F64 | None:
    """Fit a tag's board → image homography to its printed edges in a distortion-free frame.

    Parameters
    ----------
    gray : ndarray of float32
        ``(h, w)`` grey frame without lens distortion (pixel centres at integers).
    homography : ndarray
        ``(3, 3)`` first estimate, board mm → frame px (e.g. from the detected points).
    segs : list of (ndarray, ndarray)
        The printed edges (:func:`tag_edges`), board mm.
    iterations : int
        Rounds of sampling the edges and refitting.

    Returns
    -------
    ndarray or None
        The refined ``(3, 3)`` homography (``H[2, 2] = 1``); None when too few edges were
        found (keep the first estimate).
    """
    h = np.asarray(homography, dtype=np.float64)
    corners = np.array([a for a, _ in segs[:4]])
    centre = corners.mean(axis=0)
    size = float(np.linalg.norm(corners[1] - corners[0]))
    tm = np.array([[1 / size, 0, -centre[0] / size], [0, 1 / size, -centre[1] / size], [0, 0, 1]])
    for _ in range(iterations):
        xs, ls = _edge_samples(gray, h, segs)
        if len(xs) < 24:
            return None
        m = xs.mean(axis=0)
        s = float(xs.std()) or 1.0
        ti = np.array([[1 / s, 0, -m[0] / s], [0, 1 / s, -m[1] / s], [0, 0, 1]])
        ln = ls @ np.linalg.inv(tm)
        ln /= np.linalg.norm(ln[:, :2], axis=1, keepdims=True)
        xn = np.c_[(xs - m) / s, np.ones(len(xs))]
        g = tm @ np.linalg.inv(h) @ np.linalg.inv(ti)  # frame → board, normalised
        for _ in range(3):
            # l·(G x) / (G x)_z is the board-plane distance of the sample from its line
            a = (ln[:, :, None] * xn[:, None, :]).reshape(len(xs), 9) / (xn @ g[2])[:, None]
            new = np.linalg.svd(a, full_matrices=False)[2][-1].reshape(3, 3)
            g = new if float(np.sum(new * g)) > 0 else -new
        h = np.linalg.inv(np.linalg.inv(tm) @ g @ ti)
        h /= h[2, 2]
    return h


@dataclass(frozen=True)
class Straightening:
    """Remap tables that remove the lens distortion of a first camera estimate from a frame
    (straight board edges for the detector's line fits), and the pinhole camera of the
    straightened frame (same focal length, wider canvas so nothing is cut off)."""

    mapx: NDArray[np.float32]
    mapy: NDArray[np.float32]
    new_k: _F64
    kmat: _F64
    dist: _F64

    @classmethod
    def of(cls, kmat: _F64, dist: _F64, size: tuple[int, int]) -> Straightening:
        import cv2

        w, h = size
        xs, ys = np.linspace(0, w - 1, 64), np.linspace(0, h - 1, 48)
        border = np.concatenate(
            [
                np.c_[xs, np.zeros_like(xs)],
                np.c_[xs, np.full_like(xs, h - 1)],
                np.c_[np.zeros_like(ys), ys],
                np.c_[np.full_like(ys, w - 1), ys],
            ]
        )
        und = cv2.undistortPoints(border.reshape(-1, 1, 2), kmat, dist, None, None, kmat).reshape(-1, 2)
        lo = np.maximum(und.min(axis=0), [-0.5 * w, -0.5 * h])
        hi = np.minimum(und.max(axis=0), [1.5 * w, 1.5 * h])
        new_k = kmat.copy()
        new_k[0, 2] -= lo[0]
        new_k[1, 2] -= lo[1]
        out = (math.ceil(float(hi[0] - lo[0])) + 1, math.ceil(float(hi[1] - lo[1])) + 1)
        mapx, mapy = cv2.initUndistortRectifyMap(kmat, dist, None, new_k, out, cv2.CV_32FC1)
        return cls(np.asarray(mapx), np.asarray(mapy), new_k, kmat, dist)

    def straighten(self, image: NDArray[Any]) -> NDArray[Any]:
        """The frame without lens distortion."""
        import cv2

        return np.asarray(cv2.remap(image, self.mapx, self.mapy, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE))

    def to_frame(self, pts: _F64) -> _F64:
        """Straightened-frame pixels → pixels of the original (distorted) frame."""
        import cv2

        n = (pts - self.new_k[[0, 1], [2, 2]]) / self.new_k[[0, 1], [0, 1]]
        proj, _ = cv2.projectPoints(np.c_[n, np.ones(len(n))], np.zeros(3), np.zeros(3), self.kmat, self.dist)
        out: _F64 = np.asarray(proj, dtype=np.float64).reshape(-1, 2)
        return out
