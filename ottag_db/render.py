"""Tag geometry (placement of a point set in the data area) and raster, SVG and PDF renderers."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal
from xml.sax.saxutils import escape

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ExportError, UsageError
from .geometry import as_point_batch

__all__ = [
    "DEFAULT_INNER_MARGIN",
    "DEFAULT_QUIET_ZONE_RATIO",
    "MM_TO_PT",
    "POLARITIES",
    "Polarity",
    "RasterPositions",
    "TagGeometry",
    "build_tag_geometries",
    "build_tag_geometry",
    "default_quiet_zone",
    "draw_tag_pdf",
    "raster_positions",
    "render_raster",
    "render_svg",
    "tag_placement",
    "tag_placements",
]

Polarity = Literal["normal", "inverted"]
POLARITIES: tuple[Polarity, ...] = ("normal", "inverted")

#: Default quiet zone width as a fraction of the tag size (data-area side), on each side.
DEFAULT_QUIET_ZONE_RATIO = 0.25
#: Default smallest distance between a point and the data-area border, in data-area units.
DEFAULT_INNER_MARGIN = 0.10
#: Points per millimetre (PDF user space unit is 1/72 inch).
MM_TO_PT = 72.0 / 25.4

# Placement search: x' = x + u·y, y' = w·x + r·y (then uniform scale and translation).
_U_RANGE = 0.5
_R_RANGE = 2.0
_MIN_DET = 0.25


def default_quiet_zone(tag_size: float) -> float:
    """Default quiet-zone width (each side) for a data area of side ``tag_size``: 0.25 × size."""
    return DEFAULT_QUIET_ZONE_RATIO * tag_size


# --------------------------------------------------------------------------------------------
# Placement


def _candidate_maps(u: NDArray[np.float64], w: NDArray[np.float64], r: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(..., 2, 2)`` linear maps [[1, u], [w, r]]."""
    a = np.empty((*u.shape, 2, 2))
    a[..., 0, 0] = 1.0
    a[..., 0, 1] = u
    a[..., 1, 0] = w
    a[..., 1, 1] = r
    return a


def _placement_mp(
    pts: NDArray[np.float64], h: NDArray[np.float64], params: NDArray[np.float64], usable: float
) -> NDArray[np.float64]:
    """Printed MP (data-area units) of each set under each candidate map: ``(B, G)``.

    ``pts`` ``(B, k, 2)``; ``h`` ``(B, E)`` = min over third points of |orientation| for the
    edge ``e``; ``params`` ``(B, G, 3)`` or ``(G, 3)`` rows ``(u, w, log r)`` of the map
    ``[[1, u], [w, r]]``. The mapped set is scaled so its bounding box's larger side is
    ``usable``; maps with ``det ≤ 0.25`` score −inf.
    """
    k = pts.shape[1]
    i, j = np.triu_indices(k, 1)
    e = pts[:, j] - pts[:, i]  # (B, E, 2)
    if params.ndim == 2:
        params = np.broadcast_to(params, (pts.shape[0], *params.shape))
    u = params[..., 0, None]  # (B, G, 1)
    w = params[..., 1, None]
    r = np.exp(params[..., 2, None])
    ex, ey = e[:, None, :, 0], e[:, None, :, 1]  # (B, 1, E)
    length = np.hypot(ex + u * ey, w * ex + r * ey)  # (B, G, E)
    det = (r - u * w)[..., 0]  # (B, G)
    mp = 0.5 * det * (h[:, None, :] / length).min(axis=2)
    x, y = pts[:, None, :, 0], pts[:, None, :, 1]  # (B, 1, k)
    qx = x + u * y
    qy = w * x + r * y
    extent = np.maximum(qx.max(axis=2) - qx.min(axis=2), qy.max(axis=2) - qy.min(axis=2))
    result: NDArray[np.float64] = np.where(det > _MIN_DET, mp * usable / extent, -np.inf)
    return result


def tag_placements(points_batch: ArrayLike, inner_margin: float = DEFAULT_INNER_MARGIN) -> NDArray[np.float64]:
    """Affine maps ``(B, 2, 3)`` taking file coordinates to data-area unit coordinates.

    Unit coordinates: x right, y down, origin at the top-left corner of the data area, the
    data area is [0, 1]². A point ``p`` goes to ``M[:, :2] @ p + M[:, 2]``. The map is
    ``s · A`` followed by a translation, with ``A = [[1, u], [w, r]]`` (shear and
    non-uniform scale, ``|u|, |w| ≤ 0.5``, ``0.5 ≤ r ≤ 2``, ``det A > 0.25`` — orientation is
    kept, so the order type is unchanged and not mirrored). ``A`` maximises the printed MP
    (7 × 7 × 7 grid search, then four local 5 × 5 × 5 refinements, batched over sets); ``s``
    makes the larger side of the bounding box ``1 − 2 · inner_margin`` and the box is
    centred, so every point keeps at least ``inner_margin`` from the border.
    """
    if not 0.0 <= inner_margin < 0.5:
        raise UsageError(f"inner margin must be in [0, 0.5) of the data-area side, got {inner_margin}")
    pts, _ = as_point_batch(points_batch)
    b, k, _ = pts.shape
    usable = 1.0 - 2.0 * inner_margin
    i, j = np.triu_indices(k, 1)
    # h[b, e] = min over third points p of |orient(i, j, p)|
    x, y = pts[..., 0], pts[..., 1]
    m = x[:, :, None] * y[:, None, :] - y[:, :, None] * x[:, None, :]
    d = np.abs(m[:, i, j][:, :, None] + (m[:, j, :] - m[:, i, :]))  # (B, E, k)
    d[:, np.arange(len(i)), i] = np.inf
    d[:, np.arange(len(i)), j] = np.inf
    h = d.min(axis=2)
    if np.any(h == 0):
        raise ExportError("cannot place a point set that is not in general position")
    lo = np.array([-_U_RANGE, -_U_RANGE, -np.log(_R_RANGE)])
    hi = -lo
    n_grid = 7
    axes = [np.linspace(lo[c], hi[c], n_grid) for c in range(3)]
    params = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)  # (G, 3)
    chunk = 512
    best = np.empty((b, 3))
    for s in range(0, b, chunk):
        mp = _placement_mp(pts[s : s + chunk], h[s : s + chunk], params, usable)
        best[s : s + chunk] = params[mp.argmax(axis=1)]
    step = (hi - lo) / (n_grid - 1)
    offs = np.stack(np.meshgrid(*([np.linspace(-1.0, 1.0, 5)] * 3), indexing="ij"), axis=-1).reshape(-1, 3)
    for _ in range(4):
        step = step / 2.0
        cand = np.clip(best[:, None, :] + offs[None] * step, lo, hi)  # (B, 125, 3)
        for s in range(0, b, chunk):
            c = cand[s : s + chunk]
            mp = _placement_mp(pts[s : s + chunk], h[s : s + chunk], c, usable)
            best[s : s + chunk] = c[np.arange(len(c)), mp.argmax(axis=1)]
    a = _candidate_maps(best[:, 0], best[:, 1], np.exp(best[:, 2]))  # (B, 2, 2)
    q = np.einsum("bxy,bky->bkx", a, pts)
    lo_q, hi_q = q.min(axis=1), q.max(axis=1)
    scale = usable / (hi_q - lo_q).max(axis=1)
    centre = 0.5 * (lo_q + hi_q)
    out = np.empty((b, 2, 3))
    out[:, :, :2] = scale[:, None, None] * a
    out[:, :, 2] = 0.5 - scale[:, None] * centre
    return out


def tag_placement(points: ArrayLike, inner_margin: float = DEFAULT_INNER_MARGIN) -> NDArray[np.float64]:
    """Affine map ``(2, 3)`` of one ``(k, 2)`` point set; see :func:`tag_placements`."""
    arr = np.asarray(points)
    if arr.ndim != 2:
        raise ValueError(f"tag_placement takes one point set of shape (k, 2), got {arr.shape}")
    return np.asarray(tag_placements(arr[None], inner_margin)[0], dtype=np.float64)


def _mp_units(pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """MP of ``(B, k, 2)`` sets in their own units (½ smallest point-to-line distance)."""
    k = pts.shape[1]
    i, j = np.triu_indices(k, 1)
    x, y = pts[..., 0], pts[..., 1]
    m = x[:, :, None] * y[:, None, :] - y[:, :, None] * x[:, None, :]
    d = np.abs(m[:, i, j][:, :, None] + (m[:, j, :] - m[:, i, :]))
    d[:, np.arange(len(i)), i] = np.inf
    d[:, np.arange(len(i)), j] = np.inf
    length = np.sqrt(((pts[:, j] - pts[:, i]) ** 2).sum(axis=2))
    result: NDArray[np.float64] = 0.5 * (d.min(axis=2) / length).min(axis=1)
    return result


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
    mps = _mp_units(placed)
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
