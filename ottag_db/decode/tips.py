"""Sharp tips: the apex of a narrow triangle measured from the mass of its cross sections.

A vertex is the intersection of its two side lines. Where the sides meet at a small angle
``θ`` an offset error ``e`` of either line moves the intersection by about ``e / sin(θ / 2)``
along the tip's axis: at 10° a line 0.3 px off puts the vertex 3.4 px from the apex. The side
lines of a sliver are fitted from samples where it is wider than the blur only, so near its
tip they are extrapolated, and a tag seen obliquely (slivers a few px wide) had tips 4–5 px
from where its points lie (the fit of the right order type put them within 1 px).

Across the tip, the grey level integrated over a window wider than the blur (above the dark
level) is the contrast times the sliver's width, whatever the blur: the width grows linearly
from the apex, so the line through these masses along the axis reaches zero at the apex. It
is measured there, on the tip's axis, where the side lines tell it worst; across the axis the
intersection of the lines stands. A drawing uniformly wider than its geometry (ink spread, a
rasterizer that fills every pixel its edges touch) moves that line's zero as it moves the
lines' intersection, by the extra width over ``2 tan(θ / 2)``, 4 px at 7° for a quarter pixel
on either side; its masses then start with a step at the apex, blurred along the axis, and the
apex is where that start fits them.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

from ottag_db.decode.types import PointHypothesis, TriangleLines

__all__ = ["TIP_MAX_ANGLE_DEG", "apices", "with_apices"]

_F64 = NDArray[np.float64]

#: A vertex whose interior angle is under this (degrees) is measured at its apex: at 30° a
#: line 0.3 px off moves the intersection 1.2 px along the axis, about a third of the
#: reprojection bound of small data areas; wider tips are measured well enough by their lines.
TIP_MAX_ANGLE_DEG = 30.0
#: The cross-section window reaches this far (px) beyond the sliver's side lines on both sides:
#: the blur of a sharp camera (σ up to about 1.5 px in a 2× upsampled view) spreads the edge by
#: under 3σ, so nearly all of the tip's light falls inside (the mass is then blur-invariant).
_PAD_PX = 4.0
#: The line through the masses far from the tip takes the sections from this far (px) past the
#: apex the lines put, and past its own zero in later passes: within 2–3σ of the apex the blur
#: also spreads the mass along the axis (and a widened drawing's step is there, see _onset).
_NEAR_PX = 5.0
#: Cross-section spacing along the axis (px) and samples across each.
_STEP_PX = 0.5
_ACROSS = 33
#: A cross section whose outermost samples are brighter than the dark level by this fraction of
#: the contrast crosses another shape (a triangle or the quiet zone) and is left out.
_DARK_FRACTION = 0.2
#: At least this many cross sections over at least this length along the axis (px) measure
#: an apex.
_MIN_SECTIONS = 6
_MIN_SPAN_PX = 3.0
#: The masses' slope must be the contrast times the width's growth the side lines give within
#: this factor (either way): a slope far off means the window took in something else.
_SLOPE_FACTOR = 1.5
#: Cross sections reach this far (px) beyond the apex the lines put, so that the masses'
#: start is seen (a tip whose lines lie outside the sliver ends short of their intersection).
_BEYOND_PX = 6.0
#: The start of the masses is fitted on the sections up to this far (px) past the far line's
#: root: the blurred start (2–3σ) and a stretch of the line beyond it.
_ONSET_REACH_PX = 15.0
#: A drawing may be wider than its geometry by up to this much (px): a rasterizer that fills
#: every pixel its edges touch adds half a pixel on either side, ink spread on a print a
#: fraction of a pixel. The far line's root then lies ``width / (2 tan(θ / 2))`` before the
#: apex; the apex is searched no farther than this widening allows.
_MAX_WIDENING_PX = 1.0
#: Step of that search (px) and the blurs along the axis (σ, px) it tries.
_ONSET_STEP_PX = 0.1
_ONSET_SIGMAS = np.array([0.4, 0.7, 1.0, 1.4, 2.0])


def apices(img: NDArray[np.float32], tris: TriangleLines, level: float) -> dict[int, tuple[float, float]]:
    """The apex of every sharp tip (interior angle under :data:`TIP_MAX_ANGLE_DEG`) that the
    cross sections measure.

    Parameters
    ----------
    img : numpy.ndarray
        float32 grey ROI (triangles bright), as refined.
    tris : TriangleLines
        The refined triangles (ROI pixels).
    level : float
        Grey level halfway between the dark and the bright class.

    Returns
    -------
    dict
        Vertex index ``3t + j`` (vertex j of triangle t) → measured apex ``(x, y)`` (ROI pixels).
    """
    out: dict[int, tuple[float, float]] = {}
    verts = tris.vertices
    if not np.isfinite(verts).all():
        return out
    cos_max = math.cos(math.radians(TIP_MAX_ANGLE_DEG))
    for t in range(len(verts)):
        for j in range(3):
            v, a, b = verts[t, j], verts[t, (j + 1) % 3], verts[t, (j + 2) % 3]
            la, lb = float(np.hypot(*(a - v))), float(np.hypot(*(b - v)))
            if la < 1e-9 or lb < 1e-9:
                continue
            ua, ub = (a - v) / la, (b - v) / lb
            if float(ua @ ub) <= cos_max:
                continue
            apex = _apex(img, v, ua, ub, min(la, lb), level)
            if apex is not None:
                out[3 * t + j] = apex
    return out


def _apex(
    img: NDArray[np.float32], v: _F64, ua: _F64, ub: _F64, length: float, level: float
) -> tuple[float, float] | None:
    """The apex of the tip at ``v`` with sides along ``ua``, ``ub`` (unit), the shorter
    ``length`` px long; None when the cross sections do not measure it."""
    axis = ua + ub
    axis /= float(np.hypot(*axis))
    half = 0.5 * math.acos(float(np.clip(ua @ ub, -1.0, 1.0)))
    tan_half = math.tan(half)
    reach = 0.5 * length * math.cos(half)  # the tip's half: away from the other corners
    s = np.arange(-_BEYOND_PX, reach, _STEP_PX)
    masses = _masses(img, v, axis, s, tan_half, level)
    if masses is None:
        return None
    mass, clean, contrast = masses
    root = 0.0
    slope = offset = 0.0
    for _ in range(3):  # the later passes start past the apex the earlier one measured
        far = clean & (s >= max(root, 0.0) + _NEAR_PX)
        if far.sum() < _MIN_SECTIONS or np.ptp(s[far]) < _MIN_SPAN_PX:
            return None
        slope, offset = _line_fit(s[far], mass[far])
        expected = contrast * 2.0 * tan_half
        if not (expected / _SLOPE_FACTOR <= slope <= expected * _SLOPE_FACTOR):
            return None
        root = -offset / slope
        if abs(root) > 0.5 * reach:
            return None
    near = clean & (s <= root + _ONSET_REACH_PX)
    onset = root
    if near.sum() >= _MIN_SECTIONS:
        onset = _onset(s[near], mass[near], slope, offset, root + _MAX_WIDENING_PX / (2.0 * tan_half))
    return float(v[0] + onset * axis[0]), float(v[1] + onset * axis[1])


def _line_fit(x: _F64, y: _F64) -> tuple[float, float]:
    """Slope and offset of the least-squares line through ``(x, y)`` (``np.polyfit(x, y, 1)``
    in closed form: a tip measures three of them, and polyfit's general solver cost more than
    the rest of the tip)."""
    dx = x - x.mean()
    slope = float((dx * (y - y.mean())).sum() / (dx * dx).sum())
    return slope, float(y.mean() - slope * x.mean())


def _masses(
    img: NDArray[np.float32], v: _F64, axis: _F64, s: _F64, tan_half: float, level: float
) -> tuple[_F64, NDArray[np.bool_], float] | None:
    """The cross-section masses at ``s`` along ``axis`` from ``v`` (grey level above the dark
    level times px), which sections are clean (no other shape in their window) and the contrast;
    None when the window is not darker than ``level``."""
    across = np.array([-axis[1], axis[0]])
    half_w = np.abs(s) * tan_half + _PAD_PX  # (R,)
    frac = np.linspace(-1.0, 1.0, _ACROSS)
    t = half_w[:, None] * frac[None, :]  # (R, A)
    grid = np.empty((len(s), _ACROSS, 2), dtype=np.float32)
    for c in (0, 1):
        grid[..., c] = v[c] + s[:, None] * axis[c] + t * across[c]
    vals = cv2.remap(img, grid, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).astype(np.float64)  # type: ignore[call-overload, unused-ignore]
    ends = np.concatenate([vals[:, :2], vals[:, -2:]], axis=1)
    dark = float(np.median(ends))
    contrast = 2.0 * (level - dark)
    if contrast <= 0:
        return None
    clean = (ends - dark).max(axis=1) < _DARK_FRACTION * contrast
    # trapezoid rule across each section (spacing 2·half_w / (A − 1))
    inner = vals - dark
    mass = (inner.sum(axis=1) - 0.5 * (inner[:, 0] + inner[:, -1])) * (2.0 * half_w / (_ACROSS - 1))
    return mass, clean, contrast


def _onset(s: _F64, mass: _F64, slope: float, offset: float, farthest: float) -> float:
    """Where the masses ``mass`` at ``s`` start: the apex of a wedge drawn wider than its
    geometry, blurred along the axis, whose masses far from the tip lie on ``slope · s + offset``.

    Such a wedge's masses are ``slope · (s − s0) + w`` from its apex ``s0`` on (``w`` the
    extra width times the contrast, ``offset + slope · s0`` for the far line to hold), zero
    before; blurred by a Gaussian of ``σ`` along the axis. ``s0`` is searched from the far
    line's root (no widening) to ``farthest`` and ``σ`` over :data:`_ONSET_SIGMAS`, least squares.
    """
    root = -offset / slope
    s0 = np.arange(root, max(farthest, root) + 1e-9, _ONSET_STEP_PX)[:, None, None]  # (N, 1, 1)
    sigma = _ONSET_SIGMAS[None, :, None]  # (1, G, 1)
    d = s[None, None, :] - s0  # (N, 1, R)
    z = d / sigma
    phi = np.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)
    cdf = ndtr(z)
    model = slope * (d * cdf + sigma * phi) + (offset + slope * s0) * cdf
    err = ((model - mass[None, None, :]) ** 2).sum(axis=2)  # (N, G)
    best = int(np.argmin(err.min(axis=1)))
    return float(s0[best, 0, 0])


def with_apices(hyp: PointHypothesis, measured: dict[int, tuple[float, float]]) -> PointHypothesis:
    """The hypothesis with each point that is one triangle's sharp tip alone (two side lines,
    not merged with another triangle's vertex) at its measured apex.

    Parameters
    ----------
    hyp : PointHypothesis
        Points as intersections of their side lines.
    measured : dict
        :func:`apices` of the same triangles.

    Returns
    -------
    PointHypothesis
        ``hyp`` itself when none of its points is a measured tip.
    """
    if not measured:
        return hyp
    pts = hyp.points
    for i, ids in enumerate(hyp.line_ids):
        if len(ids) != 2:
            continue
        a, b = int(ids[0]), int(ids[1])
        # vertex j of triangle t lies on sides 3t + (j + 2) % 3 and 3t + j
        t, j = divmod(b, 3)
        if a != 3 * t + (j + 2) % 3 or 3 * t + j not in measured:
            continue
        if pts is hyp.points:
            pts = pts.copy()
        pts[i] = measured[3 * t + j]
    return hyp if pts is hyp.points else PointHypothesis(pts, hyp.line_ids)
