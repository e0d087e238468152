"""Raster drawing of a tag: an anti-aliased grey image and the exact pixel positions in it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ottag_db.errors import ExportError, UsageError
from ottag_db.printing.geometry import TagGeometry

__all__ = ["RasterPositions", "raster_positions", "render_raster"]


@dataclass(frozen=True)
class RasterPositions:
    """Exact positions in a raster made by :func:`render_raster`.

    Continuous pixel coordinates ``(x, y)`` = (column, row): pixel ``[r, c]`` covers
    ``[c, c + 1) × [r, r + 1)``, so its centre is ``(c + 0.5, r + 0.5)`` (subtract 0.5 for
    OpenCV's centre-at-integer convention).

    - ``points``: ``(k, 2)`` the tag points;
    - ``corners``: ``(4, 2)`` data-area corners, top-left, top-right, bottom-right, bottom-left;
    - ``data_px``: data-area side in pixels; ``quiet_px``: quiet-zone width in pixels;
    - ``size``: side of the whole image in pixels (``data_px + 2 · quiet_px``).
    """

    points: NDArray[np.float64]
    corners: NDArray[np.float64]
    data_px: int
    quiet_px: int

    @property
    def size(self) -> int:
        """Image side in pixels."""
        return self.data_px + 2 * self.quiet_px


def raster_positions(geom: TagGeometry, px: int, quiet_px: int | None = None) -> RasterPositions:
    """Pixel positions of points and data-area corners for a raster of data-area side ``px``.

    Parameters
    ----------
    geom : TagGeometry
        The tag.
    px : int
        Data-area side in pixels (≥ 1).
    quiet_px : int, optional
        Quiet-zone width in pixels; default ``round(px · quiet_zone / tag_size)``.

    Returns
    -------
    RasterPositions
        Continuous pixel coordinates (pixel ``[r, c]`` covers ``[c, c + 1) × [r, r + 1)``).

    Raises
    ------
    UsageError
        ``px < 1`` or a negative quiet zone.
    """
    if px < 1:
        raise UsageError(f"the data area needs at least 1 pixel, got {px}")
    q = round(px * geom.quiet_zone / geom.tag_size) if quiet_px is None else int(quiet_px)
    if q < 0:
        raise UsageError(f"quiet zone pixels must be ≥ 0, got {q}")
    pts = q + px * geom.points_array
    corners = np.array([[q, q], [q + px, q], [q + px, q + px], [q, q + px]], dtype=np.float64)
    return RasterPositions(points=pts, corners=corners, data_px=int(px), quiet_px=q)


def _triangle_coverage(tri: NDArray[np.float64], size: int, sub: int) -> tuple[int, int, NDArray[np.float64]]:
    """Area coverage of one triangle on a pixel grid: ``(row0, col0, cov)``.

    ``tri`` ``(3, 2)`` in continuous pixel coordinates; ``cov[r, c]`` is the covered fraction
    of pixel ``(row0 + r, col0 + c)``. Exact along x; along y the pixel is sampled at the
    centres of ``sub`` sub-rows (so the error of a pixel's coverage is below ``1/sub``).
    """
    ys = tri[:, 1]
    r0 = max(int(np.floor(ys.min())), 0)
    r1 = min(int(np.ceil(ys.max())), size)
    c0 = max(int(np.floor(tri[:, 0].min())), 0)
    c1 = min(int(np.ceil(tri[:, 0].max())), size)
    if r1 <= r0 or c1 <= c0:
        return r0, c0, np.zeros((0, 0))
    y = r0 + (np.arange((r1 - r0) * sub) + 0.5) / sub  # sub-row centres
    xl = np.full(y.shape, np.inf)
    xr = np.full(y.shape, -np.inf)
    for e in range(3):
        (ax, ay), (bx, by) = tri[e], tri[(e + 1) % 3]
        if ay == by:
            continue
        lo, hi = min(ay, by), max(ay, by)
        hit = (y >= lo) & (y <= hi)
        x = ax + (y - ay) * (bx - ax) / (by - ay)
        xl = np.where(hit, np.minimum(xl, x), xl)
        xr = np.where(hit, np.maximum(xr, x), xr)
    cols = np.arange(c0, c1, dtype=np.float64)
    cov = np.clip(np.minimum(xr[:, None], cols[None] + 1.0) - np.maximum(xl[:, None], cols[None]), 0.0, 1.0)
    cov = cov.reshape(r1 - r0, sub, c1 - c0).mean(axis=1)
    return r0, c0, cov


def render_raster(
    geom: TagGeometry, px: int, *, quiet_px: int | None = None, supersample: int = 16
) -> NDArray[np.uint8]:
    """Grey ``uint8`` image (square, side ``px + 2 · quiet_px``) of the whole tag.

    The data area is ``px`` pixels wide and aligned to pixel boundaries; positions are given
    by :func:`raster_positions` with the same arguments. Anti-aliased by area coverage:
    each pixel's grey level is the area-weighted mix of the tones, exact along x and
    sampled on ``supersample`` sub-rows along y (vertices are not rounded).

    Parameters
    ----------
    geom : TagGeometry
        The tag.
    px : int
        Data-area side in pixels.
    quiet_px : int, optional
        Quiet-zone width in pixels (default as :func:`raster_positions`).
    supersample : int
        Sub-rows per pixel row for the coverage along y (≥ 1).

    Returns
    -------
    ndarray of uint8
        ``(size, size)`` grey image, 0 black, 255 white.

    Raises
    ------
    UsageError
        Bad sizes or ``supersample``.
    ExportError
        An image above 200 million pixels.
    """
    if supersample < 1:
        raise UsageError(f"supersample must be ≥ 1, got {supersample}")
    pos = raster_positions(geom, px, quiet_px)
    quiet_tone, data_tone, tri_tone = geom.tones()
    size = pos.size
    if size * size > 200_000_000:
        raise ExportError(f"raster of {size} × {size} pixels is too large; lower px")
    coverage = np.zeros((size, size), dtype=np.float64)
    for t in geom.triangles:
        r0, c0, cov = _triangle_coverage(pos.points[list(t)], size, supersample)
        coverage[r0 : r0 + cov.shape[0], c0 : c0 + cov.shape[1]] += cov
    np.clip(coverage, 0.0, 1.0, out=coverage)
    base = np.full((size, size), float(quiet_tone))
    q0, q1 = pos.quiet_px, pos.quiet_px + pos.data_px
    base[q0:q1, q0:q1] = float(data_tone)
    img = base + coverage * (float(tri_tone) - base)
    return np.asarray(np.clip(np.rint(img), 0, 255), dtype=np.uint8)
