"""Triangle stage: fit one triangle to a contour, and check fitted triangles against a tag's rules."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from ottag_native.triangles import fit_triangle, triangle_faults

from ottag_db.decode.types import Rejection

__all__ = ["TriangleFit", "bad_triangles", "off_triangle", "strict_chains", "triangle_fit", "triangle_fit_parts"]

_F64 = NDArray[np.float64]
_NEXT3 = np.array([1, 2, 0])


@dataclass(frozen=True)
class TriangleFit:
    """A contour fitted as one triangle: ``chains`` the three side chains (contour points
    without the corner ends; a short side is its chord), ``corners`` ``(3, 2)`` and the whole
    ``contour`` ``(n, 2)`` as float64 (pixels)."""

    chains: list[_F64]
    corners: _F64
    contour: _F64


def triangle_fit(pts: NDArray[Any], strict: float = 0.0) -> list[_F64] | None:
    """Side chains of a closed contour that is one triangle, or None.

    Corners: the two farthest contour points and the point farthest from their line (paper
    Sec. 4.1.2), then grown to the largest-area triangle of hull points. At most 5 % of the
    contour (without the 10 % next to each corner) may lie farther than ``1 px + 1.5 %`` of
    the side from the line fitted to the side's middle, and the contour area must match the
    triangle's.

    Parameters
    ----------
    pts : numpy.ndarray
        ``(n, 2)`` integer contour points (pixels, OpenCV contour order).
    strict : float
        When positive, also reject a contour with more than ``max(3, 2 %)`` of its points
        farther than ``strict`` px from every side (see :func:`off_triangle`): a small
        triangle hanging at a corner, hidden by the corner trims.

    Returns
    -------
    list of numpy.ndarray or None
        The three side chains (float64 ``(m, 2)``), side j from corner j to corner j+1.
    """
    return strict_chains(triangle_fit_parts(pts), strict)


def strict_chains(fit: TriangleFit | None, strict: float) -> list[_F64] | None:
    """The side chains of a fit that passes the strict test of :func:`triangle_fit`.

    Parameters
    ----------
    fit : TriangleFit or None
        :func:`triangle_fit_parts` of a contour.
    strict : float
        As in :func:`triangle_fit` (0: no strict test).

    Returns
    -------
    list of numpy.ndarray or None
        ``fit.chains``, or None when there is no fit or it fails the strict test.
    """
    if fit is None:
        return None
    if strict and off_triangle(fit.contour, fit.corners, strict) > max(3, 0.02 * len(fit.contour)):
        return None  # a small triangle hanging at a corner (hidden by the corner trims below)
    return fit.chains


def triangle_fit_parts(pts: NDArray[Any]) -> TriangleFit | None:
    """:func:`triangle_fit` without the strict test, with the corners and the contour.

    Parameters
    ----------
    pts : numpy.ndarray
        ``(n, 2)`` integer contour points.

    Returns
    -------
    TriangleFit or None
        None when the contour is not one triangle.
    """
    n = len(pts)
    if n < 8:
        return None
    flat_i = np.ascontiguousarray(pts.reshape(-1, 2), dtype=np.int32)
    c = flat_i.reshape(-1, 1, 2)
    hull = cv2.convexHull(c, returnPoints=False).ravel()
    if len(hull) < 3:
        return None
    flat = flat_i.astype(np.float64)
    # compiled (ottag_native.triangles): corners — the two farthest hull points and the hull
    # point farthest from their line (paper Sec. 4.1.2), grown to the largest-area hull
    # triangle (a blunt short side can fool the farthest pair) —, the area test, and per side
    # the chain without 15 % at each end, whose PCA line at most 5 % of the contour (without
    # the 10 % next to each corner) may miss by more than 1 px + 1.5 % of the side; a side of
    # under 6 points (the base of a needle) is its chord, which the grey-level fit refines
    fit = fit_triangle(
        flat, np.ascontiguousarray(hull, dtype=np.int32), abs(float(cv2.contourArea(c))), float(cv2.arcLength(c, True))
    )
    if fit is None:
        return None
    i0, i1, i2, *trims = fit
    segs = (flat[i0 : i1 + 1], flat[i1 : i2 + 1], np.concatenate([flat[i2:], flat[: i0 + 1]]))
    chains = [seg[[0, -1]] if trim < 0 else seg[trim : len(seg) - trim] for seg, trim in zip(segs, trims, strict=True)]
    return TriangleFit(chains, flat[[i0, i1, i2]], flat)


def off_triangle(pts: _F64, tri: _F64, tol_px: float) -> int:
    """How many points lie farther than ``max(tol_px, 0.6 %`` of the longest side) from every
    side segment of the triangle ``tri``.

    Parameters
    ----------
    pts : numpy.ndarray
        ``(n, 2)`` contour points (pixels).
    tri : numpy.ndarray
        ``(3, 2)`` triangle corners.
    tol_px : float
        Distance floor (pixels).

    Returns
    -------
    int
        The number of points off the triangle's outline.
    """
    a = tri
    d = tri[_NEXT3] - a
    ln2 = np.maximum((d * d).sum(axis=1), 1e-12)
    rel = pts[:, None, :] - a[None, :, :]  # (n, 3, 2)
    u = np.clip((rel * d[None]).sum(axis=2) / ln2[None], 0.0, 1.0)
    off = rel - u[..., None] * d[None]
    dist2 = (off * off).sum(axis=2).min(axis=1)
    tol = max(tol_px, 0.006 * math.sqrt(float(ln2.max())))
    return int((dist2 > tol * tol).sum())


def bad_triangles(verts: _F64, quad: _F64, side: float) -> Rejection | None:
    """Why fitted triangles cannot be a tag's, or None if they can.

    The vertices must be finite and inside the data area, and no two triangles may share
    part of a side: tag triangles meet only at shared vertices, while a cut through one
    triangle (a wrong split) leaves two triangles on both sides of one line segment.

    Parameters
    ----------
    verts : numpy.ndarray
        ``(T, 3, 2)`` triangle vertices (pixels).
    quad : numpy.ndarray
        ``(4, 2)`` data-area corners in the same coordinates (convex, either orientation).
    side : float
        Data-area side (√area, pixels): scales the tolerances.

    Returns
    -------
    Rejection or None
        A ``"non_triangle"`` rejection naming the fault.
    """
    # compiled (ottag_native.triangles), as numpy computed it: every vertex on the inner side
    # of every quad side (convex, either orientation) within 1 + 1 % of the side; no side with
    # both ends within max(0.8, 0.8 % of the side) of another triangle's side line whose
    # projections overlap it over a third of the shorter side
    fault = triangle_faults(
        np.ascontiguousarray(verts, dtype=np.float64).reshape(-1, 2), np.ascontiguousarray(quad, dtype=np.float64), side
    )
    return None if fault == 0 else Rejection("non_triangle", _TRIANGLE_FAULTS[fault])


#: The details of :func:`bad_triangles`'s rejections, by the kernel's fault code.
_TRIANGLE_FAULTS = {
    1: "degenerate triangle",
    2: "triangle vertex outside the data area",
    3: "two triangles share part of a side",
}
