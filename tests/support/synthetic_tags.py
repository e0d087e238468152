"""Small synthetic Order Type Tags for the decoder's stage tests (no database, no reference files).

A tag of :data:`POINTS` (6 points, grid coordinates 0…255): two white triangles on a black data
area, the data area axis-aligned (or mapped by a homography) on a white frame, drawn 4×
supersampled and reduced with area averaging, so edges are anti-aliased.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import canonical_form
from ottag_db.core.lookup import LookupEntry, MemoryLookup

#: Six points in general position (grid units): triangle (0, 1, 2) and triangle (3, 4, 5).
POINTS = np.array([[20, 30], [110, 20], [60, 120], [150, 140], [240, 170], [170, 235]], dtype=np.float64)
TRIANGLES = ((0, 1, 2), (3, 4, 5))
SS = 4


def placement(side_px: float, origin: tuple[float, float]) -> NDArray[np.float64]:
    """``(3, 3)`` map grid → image: the data area ``[0, 1]²`` (grid 0…255 at 0.1…0.9) to a square
    of ``side_px`` at ``origin`` (image pixels)."""
    s = side_px * 0.8 / 255
    return np.array([[s, 0, origin[0] + 0.1 * side_px], [0, s, origin[1] + 0.1 * side_px], [0, 0, 1.0]])


def _map(h: NDArray[np.float64], pts: NDArray[np.float64]) -> NDArray[np.float64]:
    ph = np.c_[pts, np.ones(len(pts))] @ h.T
    out: NDArray[np.float64] = ph[:, :2] / ph[:, 2:3]
    return out


def square_to_image(side_px: float, origin: tuple[float, float]) -> NDArray[np.float64]:
    """``(3, 3)`` map unit square → image of the data area drawn by :func:`draw_tags`."""
    return np.array([[side_px, 0, origin[0]], [0, side_px, origin[1]], [0, 0, 1.0]])


def draw_tags(
    shape: tuple[int, int], tags: list[tuple[float, tuple[float, float]]], inverted: bool = False
) -> NDArray[np.uint8]:
    """A white frame with one tag per ``(side_px, origin)``; tones swapped when ``inverted``."""
    h, w = shape
    canvas = np.full((h * SS, w * SS), 255, np.uint8)
    for side, origin in tags:
        sq = _map(square_to_image(side, origin), np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]))
        cv2.fillPoly(canvas, [np.round((sq + 0.5) * SS - 0.5).astype(np.int32)], 0)
        img_pts = _map(placement(side, origin), POINTS)
        for tri in TRIANGLES:
            cv2.fillPoly(canvas, [np.round((img_pts[list(tri)] + 0.5) * SS - 0.5).astype(np.int32)], 255)
    out = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA)
    return (255 - out) if inverted else out


def image_points(side_px: float, origin: tuple[float, float]) -> NDArray[np.float64]:
    """The tag's points in the image (input order of :data:`POINTS`)."""
    return _map(placement(side_px, origin), POINTS)


def lookup(extra: dict[str, object] | None = None, realization: NDArray[np.float64] | None = None) -> MemoryLookup:
    """A lookup holding the order type of :data:`POINTS` (id 7, tag 3), realized by
    ``realization`` (default :data:`POINTS`) in canonical order."""
    form = canonical_form(POINTS)
    real = (POINTS if realization is None else realization)[list(form.labeling)]
    entry = LookupEntry(form.text, 6, 7, form.unique_min, (real,), 3, extra or {})
    return MemoryLookup([entry])


def lambda_text() -> str:
    """The ID of :data:`POINTS`."""
    return canonical_form(POINTS).text
