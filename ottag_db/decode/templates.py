"""The printed tags of a lookup as image templates, for reading by model (:mod:`.model_match`).

Every realization the lookup knows in print (its stored layout of triangles and its placement
into the data area) is rasterized once, when a detector is built, into a coarse template of the
data area; a frame's candidate views are scored against all of them by one matrix product.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.lookup import LookupEntry, TagLookup
from ottag_db.decode.placement_check import UNIT_SQUARE, apply_homography, data_area_depths

__all__ = [
    "MODEL_GRID",
    "RANKING_GRID",
    "TemplateBank",
    "contrast_fit",
    "contrast_residual",
    "draw_through",
    "normalized_rows",
    "placement",
    "rasterize",
    "template_bank",
]

_F64 = NDArray[np.float64]
_F32 = NDArray[np.float32]

#: Side of the coarse templates, cells (the data area's side; ~1,000 cells tell the tags of the
#: complete eight-point database apart while a frame's views are scored in a few ms).
MODEL_GRID = 32
#: Side of the ranking templates, cells: enough to tell a tag's triangles from brick, text or
#: foliage, which is all the ranking of candidates for reading by model asks.
RANKING_GRID = 16
#: Supersampling of the coarse templates (the fine ones use :func:`rasterize`'s default, 4): a
#: quarter of the work when the bank is built, and coarse cells are compared unaligned anyway.
_COARSE_SUPERSAMPLING = 2
#: Templates drawn per canvas when the bank is built (a square mosaic of tiles).
_MOSAIC_TILES = 16


@dataclass(frozen=True)
class TemplateBank:
    """Every printed tag of a lookup as a coarse template of its data area.

    Attributes
    ----------
    entries : tuple of LookupEntry
        ``entries[i]``: the lookup entry of template ``i``.
    realization : numpy.ndarray
        ``(N,)`` intp, index of the template's realization in its entry.
    triangles : tuple of numpy.ndarray
        ``triangles[i]``: ``(t, 3, 2)`` the printed triangles in data-area units (x right,
        y down, the data area is [0, 1]²).
    coarse : numpy.ndarray
        ``(N, MODEL_GRID²)`` float32, each row the template (triangles bright) minus its mean,
        divided by its norm: a dot product with a view normalized alike is their correlation.
    ranking : numpy.ndarray
        ``(N, RANKING_GRID²)`` float32, the coarse templates averaged over 2 × 2 cells and
        normalized alike: a quarter of the work to tell which candidates look like a tag
        (:mod:`~ottag_db.decode.model_budget`).
    """

    entries: tuple[LookupEntry, ...]
    realization: NDArray[np.intp]
    triangles: tuple[_F64, ...]
    coarse: _F32
    ranking: _F32

    def __len__(self) -> int:
        return len(self.entries)


def template_bank(lookup: TagLookup, max_templates: int) -> TemplateBank | None:
    """Rasterize every printed tag of ``lookup`` (each realization with a layout and placement).

    Parameters
    ----------
    lookup : TagLookup
        The detector's lookup; it must be iterable (as :class:`~ottag_db.core.lookup.MemoryLookup`
        is) for its tags to be listed.
    max_templates : int
        Bound on the number of templates (memory: ``4 · MODEL_GRID²`` bytes each).

    Returns
    -------
    TemplateBank or None
        None when the lookup cannot be listed, knows no printed tag (e.g. a portable
        dictionary file without layouts), or holds more than ``max_templates`` of them.
    """
    if not isinstance(lookup, Iterable):
        return None
    entries: list[LookupEntry] = []
    rows: list[int] = []
    groups: dict[tuple[int, int], list[int]] = {}  # (points, triangles) → template indices
    for entry in lookup:
        if not isinstance(entry, LookupEntry) or not entry.layouts or not entry.placements:
            continue
        for r, (layout, place) in enumerate(zip(entry.layouts, entry.placements, strict=False)):
            if not layout or place is None:
                continue
            if len(entries) >= max_templates:
                return None
            groups.setdefault((entry.k, len(layout)), []).append(len(entries))
            entries.append(entry)
            rows.append(r)
    if not entries:
        return None
    coarse = np.empty((len(entries), MODEL_GRID * MODEL_GRID), dtype=np.float32)
    triangles: list[_F64] = [np.empty((0, 3, 2))] * len(entries)
    for members in groups.values():
        # one batch per shape: placed points (n, k, 2), then the layout's triangles (n, t, 3, 2)
        real = np.stack([entries[i].realizations[rows[i]] for i in members])
        place = np.stack([placement(entries[i], rows[i]) for i in members])
        labels = np.asarray([entries[i].layouts[rows[i]] for i in members], dtype=np.intp)
        unit = np.einsum("nkj,nij->nki", real, place[:, :, :2]) + place[:, None, :, 2]
        tris = unit[np.arange(len(members))[:, None, None], labels]
        coarse[members] = rasterize(tris, 0.0, 1.0, MODEL_GRID, _COARSE_SUPERSAMPLING).reshape(len(members), -1)
        for j, i in enumerate(members):
            triangles[i] = tris[j]
    g = RANKING_GRID
    ranking = (
        coarse.reshape(len(entries), g, MODEL_GRID // g, g, MODEL_GRID // g).mean(axis=(2, 4)).reshape(len(entries), -1)
    )
    return TemplateBank(
        tuple(entries),
        np.asarray(rows, dtype=np.intp),
        tuple(triangles),
        normalized_rows(coarse),
        normalized_rows(ranking),
    )


def placement(entry: LookupEntry, r: int) -> _F64:
    """The stored placement of realization ``r`` (the bank holds only placed realizations)."""
    place = entry.placements[r]
    if place is None:
        raise ValueError(f"{entry.lambda_text}: realization {r} has no placement")
    return place


def rasterize(polygons: _F64, lo: float, hi: float, size: int, supersampling: int = 4) -> _F32:
    """Area coverage of polygon sets on a square grid, many at once.

    Parameters
    ----------
    polygons : numpy.ndarray
        ``(n, m, v, 2)``: image ``i`` is the ``m`` polygons of ``v`` vertices ``polygons[i]``
        (coordinates in the window's units; polygons of one image must not overlap).
    lo, hi : float
        The window ``[lo, hi]²`` the grid covers.
    size : int
        Grid side, cells.
    supersampling : int
        Polygons are filled at this many times the grid's resolution, then area-averaged.

    Returns
    -------
    numpy.ndarray
        ``(n, size, size)`` float32 in [0, 1]: the covered fraction of each cell (row = y),
        to a supersampled pixel (OpenCV fills the pixels an edge passes through).
    """
    n, m, v = polygons.shape[:3]
    tile = size * supersampling
    out = np.empty((n, size, size), dtype=np.float32)
    per = _MOSAIC_TILES * _MOSAIC_TILES
    scale = tile / (hi - lo)
    for start in range(0, n, per):
        chunk = polygons[start : start + per]
        c = len(chunk)
        cols = min(c, _MOSAIC_TILES)
        nrows = -(-c // cols)
        canvas = np.zeros((nrows * tile, cols * tile), dtype=np.uint8)
        j = np.arange(c)
        offset = np.stack([(j % cols) * tile, (j // cols) * tile], axis=1).astype(np.float64)
        # pixel p of a tile covers [p, p + 1) / scale + lo: its centre is at p + 0.5
        px = (chunk - lo) * scale - 0.5 + offset[:, None, None, :]
        cv2.fillPoly(canvas, list(np.round(px * 16).astype(np.int32).reshape(c * m, v, 1, 2)), 255, cv2.LINE_8, 4)
        small = cv2.resize(canvas, (cols * size, nrows * size), interpolation=cv2.INTER_AREA)
        tiles = np.asarray(small, dtype=np.float32).reshape(nrows, size, cols, size).transpose(0, 2, 1, 3)
        out[start : start + c] = tiles.reshape(-1, size, size)[:c] / 255.0
    return out


#: Supersampled pixel coordinates beyond this are no view of a tag (OpenCV's fixed-point
#: polygon coordinates, 16 × these, stay far inside int32).
_MAX_DRAWN_PX = float(1 << 24)
#: The quiet zone is drawn only where the homography's depth is at least this fraction of the
#: data area's least (see :func:`draw_through`).
_MIN_QUIET_DEPTH = 0.05


def draw_through(
    triangles: _F64, quiet: float, to_pixels: _F64, shape: tuple[int, int], supersampling: int = 4
) -> _F32:
    """A printed tag as a camera would see it through a homography, before the camera's blur.

    The quiet zone (``quiet`` wide around the data area) and the triangles are bright, the
    data area dark (a normal tag; an inverted one is ``1 −`` this); everything else is 0.

    Parameters
    ----------
    triangles : numpy.ndarray
        ``(t, 3, 2)`` printed triangles in data-area units (the data area is [0, 1]²).
    quiet : float
        Width of the quiet zone drawn, data-area units.
    to_pixels : numpy.ndarray
        ``(3, 3)`` homography data-area units → image pixels (pixel centres at integers).
    shape : tuple of int
        ``(H, W)`` of the image.
    supersampling : int
        The polygons are filled at this many times the image's resolution, then area-averaged.

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` float32 in [0, 1], the covered fraction of each pixel. Seen nearly edge-on the
        quiet zone's far edge may lie at or beyond the horizon of the homography: it is drawn up
        to where its depth falls to ``_MIN_QUIET_DEPTH`` of the data area's. All 0 when the data
        area itself reaches the horizon (no view of the tag).
    """
    h, w = shape
    blank: _F32 = np.zeros((h, w), dtype=np.float32)
    # depths of the data area's corners, made positive in front of the camera (the triangles'
    # points lie between them)
    sign = 1.0 if to_pixels[2, 2] >= 0 else -1.0
    depth = sign * data_area_depths(to_pixels)
    if not (depth > 0).all():
        return blank
    row = sign * to_pixels[2]
    q = quiet
    outer = _clip_to_depth(
        np.array([[-q, -q], [1 + q, -q], [1 + q, 1 + q], [-q, 1 + q]]), row, _MIN_QUIET_DEPTH * float(depth.min())
    )
    flat = np.concatenate([outer, UNIT_SQUARE, triangles.reshape(-1, 2)])
    # a pixel's centre p covers [p − 0.5, p + 0.5): supersampled pixel j is centred at (j + 0.5) / s − 0.5
    px = (apply_homography(to_pixels, flat) + 0.5) * supersampling - 0.5
    if not (np.abs(px) < _MAX_DRAWN_PX).all():  # also NaN
        return blank
    fixed = np.round(px * 16).astype(np.int32).reshape(-1, 1, 2)
    m = len(outer)
    canvas = np.zeros((h * supersampling, w * supersampling), dtype=np.uint8)
    cv2.fillPoly(canvas, [fixed[:m]], 255, cv2.LINE_8, 4)
    cv2.fillPoly(canvas, [fixed[m : m + 4]], 0, cv2.LINE_8, 4)
    if len(triangles):
        cv2.fillPoly(canvas, list(fixed[m + 4 :].reshape(-1, 3, 1, 2)), 255, cv2.LINE_8, 4)
    small = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA)
    out: _F32 = np.asarray(small, dtype=np.float32) / np.float32(255.0)
    return out


def _clip_to_depth(poly: _F64, row: _F64, min_depth: float) -> _F64:
    """The part of a convex polygon (tag-plane units) where ``row · (x, y, 1) ≥ min_depth``
    (Sutherland–Hodgman against one line; the polygon itself when it lies there whole)."""
    d = poly @ row[:2] + row[2] - min_depth
    if (d >= 0).all():
        return poly
    out: list[_F64] = []
    for i in range(len(poly)):
        j = (i + 1) % len(poly)
        if d[i] >= 0:
            out.append(poly[i])
        if (d[i] >= 0) != (d[j] >= 0):
            out.append(poly[i] + (poly[j] - poly[i]) * (d[i] / (d[i] - d[j])))
    return np.array(out)


def normalized_rows(rows: NDArray[np.floating]) -> _F32:
    """Rows minus their mean, divided by their norm (a zero row stays zero)."""
    x = np.asarray(rows, dtype=np.float32)
    x = x - x.mean(axis=1, keepdims=True)
    norm = np.sqrt(np.einsum("ij,ij->i", x, x))[:, None]
    out: _F32 = x / np.maximum(norm, np.float32(1e-6))
    return out


def contrast_fit(expected: _F32, seen: _F32) -> _F32:
    """Scale and offset (least squares) that take a drawn tag's values to the frame's.

    Parameters
    ----------
    expected, seen : numpy.ndarray
        1-D float32: the drawn tag's values and the frame's at the same places.

    Returns
    -------
    numpy.ndarray
        ``[scale, offset]`` (float32): the scale is the frame's contrast per unit of the tag's.
    """
    # the normal equations of a line in closed form (float64): np.linalg.lstsq's SVD cost
    # 0.1 ms a call for these two unknowns, and a blurred candidate's fit calls it hundreds of times
    e = expected.astype(np.float64)
    v = seen.astype(np.float64)
    e_mean, v_mean = float(e.mean()), float(v.mean())
    spread = float(((e - e_mean) ** 2).sum())
    if spread > 0.0:
        scale = float(((e - e_mean) * (v - v_mean)).sum()) / spread
        offset = v_mean - scale * e_mean
    else:  # a uniform drawing: the least-norm solution, as lstsq gives it
        scale, offset = e_mean * v_mean / (e_mean**2 + 1.0), v_mean / (e_mean**2 + 1.0)
    return np.array([scale, offset], dtype=np.float32)


def contrast_residual(expected: _F32, seen: _F32) -> float:
    """Mean absolute residual of the frame's values against a drawn tag's under :func:`contrast_fit`.

    Parameters
    ----------
    expected, seen : numpy.ndarray
        As for :func:`contrast_fit`.

    Returns
    -------
    float
        In units of the fitted scale (the frame's contrast).
    """
    scale, offset = contrast_fit(expected, seen)
    return float(np.abs(seen - (scale * expected + offset)).mean() / max(abs(float(scale)), 1e-6))
