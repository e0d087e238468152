"""Tag geometry (placement of a point set in the data area) and raster, SVG and PDF renderers."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any
from xml.sax.saxutils import escape

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import as_point_batch, maximal_perturbations
from ottag_db.errors import ExportError, UsageError

__all__ = [
    "DEFAULT_QUIET_ZONE_RATIO",
    "MM_TO_PT",
    "RasterPositions",
    "TagGeometry",
    "build_tag_geometries",
    "build_tag_geometry",
    "default_quiet_zone",
    "draw_tag_pdf",
    "raster_positions",
    "render_raster",
    "render_svg",
]

from ottag_db.core.placement import DEFAULT_INNER_MARGIN, tag_placements
from ottag_db.core.types import POLARITIES, Polarity

#: Default quiet zone width as a fraction of the tag size (data-area side), on each side.
DEFAULT_QUIET_ZONE_RATIO = 0.25
#: Points per millimetre (PDF user space unit is 1/72 inch).
MM_TO_PT = 72.0 / 25.4


def default_quiet_zone(tag_size: float) -> float:
    """Default quiet-zone width (each side) for a data area of side ``tag_size``: 0.25 × size."""
    return DEFAULT_QUIET_ZONE_RATIO * tag_size


# --------------------------------------------------------------------------------------------
# Geometry


@dataclass(frozen=True)
class TagGeometry:
    """Everything needed to draw one tag, independent of the output medium.

    - ``points``: the k points in data-area unit coordinates (x right, y down, origin the
      top-left corner of the data area, which is [0, 1]²);
    - ``triangles``: index triples into ``points`` (the layout);
    - ``polarity``: ``"normal"`` = white quiet zone, black data area, white triangles;
      ``"inverted"`` = black quiet zone, white data area, black triangles;
    - ``tag_size``: side of the data area (the square users measure), mm for vector output;
    - ``quiet_zone``: width of the quiet zone on each side of the data area, same unit;
    - ``mp_unit``: MP of ``points`` in data-area units (printed MP = ``mp_unit · tag_size``);
    - ``transform``: the ``(2, 3)`` affine map from the source (file) coordinates to ``points``.
    """

    points: tuple[tuple[float, float], ...]
    triangles: tuple[tuple[int, int, int], ...]
    polarity: Polarity
    tag_size: float
    quiet_zone: float
    mp_unit: float
    transform: tuple[tuple[float, float, float], tuple[float, float, float]]

    @property
    def k(self) -> int:
        """Number of points."""
        return len(self.points)

    @property
    def mp_mm(self) -> float:
        """Printed MP in the unit of ``tag_size`` (mm for vector output)."""
        return self.mp_unit * self.tag_size

    @property
    def total_size(self) -> float:
        """Side of the whole tag, quiet zone included: ``tag_size + 2 · quiet_zone``."""
        return self.tag_size + 2.0 * self.quiet_zone

    @property
    def inverted(self) -> bool:
        """True for the inverted polarity."""
        return self.polarity == "inverted"

    @property
    def points_array(self) -> NDArray[np.float64]:
        """``(k, 2)`` float64 copy of ``points`` (unit coordinates)."""
        return np.array(self.points, dtype=np.float64).reshape(-1, 2)

    def resized(self, tag_size: float, quiet_zone: float | None = None) -> TagGeometry:
        """The same tag with another data-area side (and quiet zone, default 0.25 × size)."""
        q = default_quiet_zone(tag_size) if quiet_zone is None else quiet_zone
        _check_sizes(tag_size, q)
        return dataclasses.replace(self, tag_size=float(tag_size), quiet_zone=float(q))

    def with_polarity(self, polarity: Polarity) -> TagGeometry:
        """The same tag in the other (or same) polarity."""
        _check_polarity(polarity)
        return dataclasses.replace(self, polarity=polarity)

    def tones(self) -> tuple[int, int, int]:
        """Grey levels (0 black, 255 white) of quiet zone, data area and triangles."""
        return (0, 255, 0) if self.inverted else (255, 0, 255)


def _check_polarity(polarity: str) -> None:
    if polarity not in POLARITIES:
        raise UsageError(f"polarity must be 'normal' or 'inverted', got {polarity!r}")


def _check_sizes(tag_size: float, quiet_zone: float) -> None:
    if not np.isfinite(tag_size) or tag_size <= 0:
        raise UsageError(f"tag size must be positive, got {tag_size}")
    if not np.isfinite(quiet_zone) or quiet_zone < 0:
        raise UsageError(f"quiet zone must be zero or positive, got {quiet_zone}")


def build_tag_geometries(
    points_batch: ArrayLike,
    triangles_batch: Sequence[Sequence[Sequence[int]]],
    *,
    polarity: Polarity = "normal",
    tag_size: float = 50.0,
    quiet_zone: float | None = None,
    inner_margin: float = DEFAULT_INNER_MARGIN,
) -> list[TagGeometry]:
    """Tag geometries of ``B`` point sets ``(B, k, 2)`` (file coordinates) and their layouts.

    Placement by :func:`tag_placements` (batched); ``quiet_zone`` defaults to
    :func:`default_quiet_zone`. Sizes are in mm for vector output.
    """
    _check_polarity(polarity)
    q = default_quiet_zone(tag_size) if quiet_zone is None else quiet_zone
    _check_sizes(tag_size, q)
    pts, _ = as_point_batch(points_batch)
    if len(triangles_batch) != pts.shape[0]:
        raise ValueError(f"{pts.shape[0]} point sets but {len(triangles_batch)} layouts")
    maps = tag_placements(pts, inner_margin)
    placed = np.einsum("bxy,bky->bkx", maps[:, :, :2], pts) + maps[:, None, :, 2]
    mps = maximal_perturbations(placed)
    k = pts.shape[1]
    out: list[TagGeometry] = []
    for n in range(pts.shape[0]):
        tris = tuple(tuple(sorted(int(i) for i in t)) for t in triangles_batch[n])
        if not tris or any(len(t) != 3 or not all(0 <= i < k for i in t) for t in tris):
            raise ExportError(f"set {n}: layout {triangles_batch[n]!r} does not fit {k} points")
        out.append(
            TagGeometry(
                points=tuple((float(px), float(py)) for px, py in placed[n]),
                triangles=tris,  # type: ignore[arg-type]
                polarity=polarity,
                tag_size=float(tag_size),
                quiet_zone=float(q),
                mp_unit=float(mps[n]),
                transform=(
                    (float(maps[n, 0, 0]), float(maps[n, 0, 1]), float(maps[n, 0, 2])),
                    (float(maps[n, 1, 0]), float(maps[n, 1, 1]), float(maps[n, 1, 2])),
                ),
            )
        )
    return out


def build_tag_geometry(
    points: ArrayLike,
    triangles: Sequence[Sequence[int]],
    *,
    polarity: Polarity = "normal",
    tag_size: float = 50.0,
    quiet_zone: float | None = None,
    inner_margin: float = DEFAULT_INNER_MARGIN,
) -> TagGeometry:
    """Tag geometry of one ``(k, 2)`` point set; see :func:`build_tag_geometries`."""
    arr = np.asarray(points)
    if arr.ndim != 2:
        raise ValueError(f"build_tag_geometry takes one point set of shape (k, 2), got {arr.shape}")
    return build_tag_geometries(
        arr[None],
        [triangles],
        polarity=polarity,
        tag_size=tag_size,
        quiet_zone=quiet_zone,
        inner_margin=inner_margin,
    )[0]


# --------------------------------------------------------------------------------------------
# Raster


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

    ``quiet_px`` defaults to ``round(px · quiet_zone / tag_size)``.
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


# --------------------------------------------------------------------------------------------
# SVG


def _f(v: float) -> str:
    text = f"{v:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def render_svg(geom: TagGeometry, *, title: str | None = None) -> str:
    """Standalone SVG document of the whole tag; user units are mm (``viewBox`` in mm).

    y grows downwards as in the unit coordinates, so points are not flipped. Triangles are
    one ``<path>``; ``title`` becomes the SVG ``<title>``.
    """
    t = geom.total_size
    q = geom.quiet_zone
    s = geom.tag_size
    quiet, data, tri = (("#000000" if v == 0 else "#ffffff") for v in geom.tones())
    pts = geom.points_array
    d = " ".join(
        "M{} {} L{} {} L{} {} Z".format(*(_f(q + s * c) for i in tri_idx for c in pts[i])) for tri_idx in geom.triangles
    )
    parts = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{_f(t)}mm" height="{_f(t)}mm" '
        f'viewBox="0 0 {_f(t)} {_f(t)}">',
    ]
    if title:
        parts.append(f"<title>{escape(title)}</title>")
    parts += [
        f'<rect x="0" y="0" width="{_f(t)}" height="{_f(t)}" fill="{quiet}"/>',
        f'<rect x="{_f(q)}" y="{_f(q)}" width="{_f(s)}" height="{_f(s)}" fill="{data}"/>',
        f'<path d="{d}" fill="{tri}" stroke="none"/>',
        "</svg>",
        "",
    ]
    return "\n".join(parts)


# --------------------------------------------------------------------------------------------
# PDF


def draw_tag_pdf(canvas: Any, geom: TagGeometry, x_mm: float, y_mm: float, *, quiet_zone: bool = True) -> None:
    """Draw the tag on a reportlab canvas with its lower-left corner at (``x_mm``, ``y_mm``).

    Positions are page coordinates in mm from the page's lower-left corner (PDF y-up); the
    whole tag, quiet zone included, covers ``total_size`` mm. Points are flipped (unit
    y down → PDF y up) so the printed tag reads like the raster and the SVG. Three fills:
    quiet-zone square (skipped with ``quiet_zone=False`` — e.g. white on white paper), data
    square (a ``re`` of side ``tag_size``), and one path with all triangles.
    """
    quiet_tone, data_tone, tri_tone = geom.tones()
    k = MM_TO_PT
    total = geom.total_size * k
    x0, y0 = x_mm * k, y_mm * k
    q = geom.quiet_zone * k
    s = geom.tag_size * k
    if quiet_zone and geom.quiet_zone > 0:
        canvas.setFillGray(quiet_tone / 255.0)
        canvas.rect(x0, y0, total, total, stroke=0, fill=1)
    canvas.setFillGray(data_tone / 255.0)
    canvas.rect(x0 + q, y0 + q, s, s, stroke=0, fill=1)
    dx, dy = x0 + q, y0 + q + s
    pts = [(dx + s * u, dy - s * v) for u, v in geom.points]
    path = canvas.beginPath()
    for a, b, c in geom.triangles:
        path.moveTo(*pts[a])
        path.lineTo(*pts[b])
        path.lineTo(*pts[c])
        path.close()
    canvas.setFillGray(tri_tone / 255.0)
    canvas.drawPath(path, stroke=0, fill=1)
