"""Refinement stage: triangle and data-area sides as sub-pixel lines on the grey image."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray
from ottag_native.refine import chain_moments, crossing_moments, inward_sides, level_crossings, sample_grid

from ottag_db.decode.types import Decomposition, TriangleLines

__all__ = [
    "fit_chains",
    "intersect",
    "lines_from_moments",
    "lines_through",
    "polygon_vertices",
    "refine",
    "refine_lines",
    "triangle_vertices",
]

_F64 = NDArray[np.float64]
_NEXT4 = np.array([1, 2, 3, 0])

#: Side tables below are built once for polygons with up to this many sides in all.
_TABLE_SIDES = 64


def _side_table(s: int, m: int, step: int) -> NDArray[np.intp]:
    i = np.arange(s)
    out: NDArray[np.intp] = i - i % m + (i + step) % m
    out.flags.writeable = False
    return out


#: ``_PREV[m][s]`` / ``_NEXT[m][s]``: index of side j−1 / j+1 of the same polygon for every side
#: of ``s / m`` polygons of ``m`` sides (triangles and the data-area quad).
_PREV: dict[int, tuple[NDArray[np.intp], ...]] = {
    m: tuple(_side_table(s, m, -1) for s in range(_TABLE_SIDES)) for m in (3, 4)
}
_NEXT: dict[int, tuple[NDArray[np.intp], ...]] = {
    m: tuple(_side_table(s, m, 1) for s in range(_TABLE_SIDES)) for m in (3, 4)
}


def _prev_index(s: int, m: int) -> NDArray[np.intp]:
    return _PREV[m][s] if m in _PREV and s < _TABLE_SIDES else _side_table(s, m, -1)


def _next_index(s: int, m: int) -> NDArray[np.intp]:
    return _NEXT[m][s] if m in _NEXT and s < _TABLE_SIDES else _side_table(s, m, 1)


def refine(
    img: NDArray[np.float32], decomposition: Decomposition, level: float, quad: _F64 | None = None
) -> tuple[TriangleLines, _F64 | None]:
    """Sub-pixel side lines and vertices of a decomposition's triangles (and of the quad).

    The side chains are fitted by least squares, then every line is moved to the ``level``
    crossings of the grey image along its normals (:func:`refine_lines`).

    Parameters
    ----------
    img : numpy.ndarray
        float32 grey ROI (triangles bright).
    decomposition : Decomposition
        Side chains in ROI pixels.
    level : float
        Grey level of the edges (halfway between the dark and bright class).
    quad : numpy.ndarray or None
        ``(4, 2)`` data-area corners (ROI pixels) to refine in the same pass.

    Returns
    -------
    tuple
        The refined :class:`TriangleLines` and the refined ``(4, 2)`` quad corners (None
        without ``quad``; the corners may be non-finite when two quad sides are parallel).
    """
    n_t, c_t = fit_chains(list(decomposition.chains))
    verts = triangle_vertices(n_t, c_t)
    corners: _F64 | None = None
    if quad is not None:
        qn, qc = lines_through(quad)
        n_all, c_all = refine_lines(img, np.concatenate([n_t, qn]), np.concatenate([c_t, qc]), verts, level, quad=quad)
        st = len(c_t)
        n_t, c_t = n_all[:st], c_all[:st]
        corners = polygon_vertices(n_all[st:], c_all[st:], 4)
    else:
        n_t, c_t = refine_lines(img, n_t, c_t, verts, level)
    return TriangleLines(n_t, c_t, triangle_vertices(n_t, c_t)), corners


def fit_chains(chains: list[_F64]) -> tuple[_F64, _F64]:
    """Least-squares lines of point chains.

    Parameters
    ----------
    chains : list of numpy.ndarray
        ``(m, 2)`` point chains (pixels), at least two points each.

    Returns
    -------
    tuple of numpy.ndarray
        Unit normals ``(S, 2)`` and offsets ``(S,)`` with n·x = c.
    """
    # compiled (ottag_native.refine), as numpy computed it: each chain's mean and central
    # second moments, summed as np.add.reduceat sums a chain of the chains stacked
    s = len(chains)
    mx, my, sxx, sxy, syy = (np.empty(s) for _ in range(5))
    chain_moments([np.asarray(c, dtype=np.float64) for c in chains], mx, my, sxx, sxy, syy)
    return lines_from_moments(mx, my, sxx, sxy, syy)


def lines_from_moments(mx: _F64, my: _F64, sxx: _F64, sxy: _F64, syy: _F64) -> tuple[_F64, _F64]:
    """Lines through the means ``(mx, my)`` along the direction of largest spread.

    Parameters
    ----------
    mx, my : numpy.ndarray
        ``(S,)`` means of each point set.
    sxx, sxy, syy : numpy.ndarray
        ``(S,)`` central second moments.

    Returns
    -------
    tuple of numpy.ndarray
        Unit normals ``(S, 2)`` and offsets ``(S,)`` (n·x = c).
    """
    theta = 0.5 * np.arctan2(2 * sxy, sxx - syy)  # direction of largest spread
    # filled by column: np.stack costs more than the trigonometry for a few dozen lines
    normal = np.empty((len(theta), 2))
    np.sin(theta, out=normal[:, 0])
    np.negative(normal[:, 0], out=normal[:, 0])
    np.cos(theta, out=normal[:, 1])
    offset = normal[:, 0] * mx + normal[:, 1] * my
    return normal, offset


def lines_through(poly: _F64) -> tuple[_F64, _F64]:
    """Lines of the sides of one closed polygon (side i from vertex i to i+1).

    Parameters
    ----------
    poly : numpy.ndarray
        ``(m, 2)`` vertices.

    Returns
    -------
    tuple of numpy.ndarray
        Unit normals ``(m, 2)`` (the side direction turned by +90°) and offsets ``(m,)``.
    """
    a = poly
    b = poly[_next_index(len(poly), len(poly))]
    d = b - a
    normal = np.empty_like(d)  # filled by column (np.stack and np.linalg.norm cost more here)
    np.negative(d[:, 1], out=normal[:, 0])
    normal[:, 1] = d[:, 0]
    normal /= np.sqrt(normal[:, 0] * normal[:, 0] + normal[:, 1] * normal[:, 1])[:, None]
    return normal, normal[:, 0] * a[:, 0] + normal[:, 1] * a[:, 1]


def intersect(n1: _F64, c1: _F64, n2: _F64, c2: _F64) -> _F64:
    """Intersections of line pairs ``n1·x = c1`` and ``n2·x = c2`` (row by row).

    Returns
    -------
    numpy.ndarray
        ``(S, 2)``; NaN for parallel lines.
    """
    det = n1[:, 0] * n2[:, 1] - n1[:, 1] * n2[:, 0]
    det[det == 0] = np.nan  # parallel lines: no intersection (NaN, without a warning)
    out: _F64 = np.empty((len(det), 2))
    out[:, 0] = (c1 * n2[:, 1] - c2 * n1[:, 1]) / det
    out[:, 1] = (n1[:, 0] * c2 - n2[:, 0] * c1) / det
    return out


def polygon_vertices(normal: _F64, offset: _F64, m: int) -> _F64:
    """Vertices of polygons of ``m`` sides each: vertex j = side j−1 ∩ side j.

    Returns
    -------
    numpy.ndarray
        ``(S / m, m, 2)``, or ``(4, 2)`` for one quad (``m = 4``).
    """
    prev = _prev_index(len(offset), m)
    v = intersect(normal[prev], offset[prev], normal, offset)
    return v.reshape(-1, m, 2) if m != 4 else v.reshape(-1, 2)


def triangle_vertices(normal: _F64, offset: _F64) -> _F64:
    """``(T, 3, 2)`` vertices of triangles given by 3 consecutive side lines each.

    Side j of a triangle runs from vertex j to vertex j+1, so vertex j = side j−1 ∩ side j.
    """
    return polygon_vertices(normal, offset, 3).reshape(-1, 3, 2)


_REFINE_FR = np.linspace(0.08, 0.92, 16)
_REFINE_OFFS = np.linspace(-3.0, 3.0, 13)
_REFINE_MID = np.abs(0.5 * (_REFINE_OFFS[1:] + _REFINE_OFFS[:-1]))
_NONE_INWARD = np.empty(0, dtype=np.uint8)  # (no data-area sides)

#: A data-area side sample within this distance (px) of a triangle side is suspect: the
#: crossing search reaches 3 px either side of the rough line, which can itself lie a pixel or
#: two off the border, so the ``level`` crossing nearest the line may be the triangle's edge
#: rather than the border's. Such crossings sat 3.6-3.9 px from the rough triangle sides on
#: data areas 28-34 px wide; 4 px caught only some of them, 6 px did no better than 5.
_QUAD_NEAR_PX = 5.0
#: ... and it is dropped when its crossing lies farther than this (px) from the side's first
#: fit (a border crossing scatters by a tenth of a pixel under noise; one at a triangle's edge
#: lay 2-5 px off). Dropping every sample near a triangle instead, without this test, made the
#: result hinge on the distance (3.5 px: hardly any effect, 4.5 px: a flip not flagged) and fit
#: sides with as few as 3 clustered samples.
_QUAD_OUTLIER_PX = 1.0


def _fitted_lines(px: _F64, py: _F64, valid: NDArray[np.uint8]) -> tuple[_F64, _F64, _F64]:
    """The least-squares line of each row's valid points of ``(S, M)`` (``M`` ≤ 128) and how
    many there were: normals ``(S, 2)``, offsets and counts ``(S,)`` (compiled: the sums as
    numpy adds them)."""
    rows = len(px)
    mx, my, sxx, sxy, syy, count = (np.empty(rows) for _ in range(6))
    crossing_moments(px, py, valid, mx, my, sxx, sxy, syy, count)
    normal, offset = lines_from_moments(mx, my, sxx, sxy, syy)
    return normal, offset, count


def refine_lines(
    img: NDArray[np.float32],
    normal: _F64,
    offset: _F64,
    tri_verts: _F64,
    level: float,
    quad: _F64 | None = None,
) -> tuple[_F64, _F64]:
    """Move each side line to the ``level`` crossings of the grey image along its normals.

    The lines are the sides of the triangles ``tri_verts`` ``(T, 3, 2)`` (side j runs from
    vertex j to j+1; vertex j lies on lines j−1 and j), followed, when ``quad`` ``(4, 2)`` is
    given, by the 4 sides of the data area through its corners: one pass (one ``remap``)
    refines both. Samples 16 positions on the middle 84 % of each side, 13 offsets in ±3 px
    (bilinear), takes the crossing nearest the line and refits by least squares. Sides with
    fewer than 3 crossings keep their line.

    A triangle sample counts only where the shape is wide enough: its distance to every other
    triangle side must be at least ``min(3 px, 0.6 × the side's widest sample)``. Across a
    sliver narrower than the blur the grey level never reaches the bright level and the
    crossings move inward, which would make needle tips overshoot along their axis.

    A data-area side takes only crossings the border's way (bright outside, dark inside; a
    triangle's edge next to the border is crossed the other way) and is fitted twice: its
    samples within :data:`_QUAD_NEAR_PX` of a triangle side whose crossing lies over
    :data:`_QUAD_OUTLIER_PX` from the first fit (the crossing found was the triangle's edge, not
    the border) are left out of the second. A side left with fewer than 3 samples keeps its
    first fit. A side that found no crossing at some samples, or one off its fit, is searched
    again around the line most of its crossings agree on (:data:`_CONSENSUS_PX`).

    Returns
    -------
    tuple of numpy.ndarray
        The refined unit normals ``(S, 2)`` (orientation kept) and offsets ``(S,)``.
    """
    at = tri_verts.reshape(-1, 2)
    st = len(at)
    if quad is not None:
        a = np.concatenate([at, quad])
        b = np.concatenate([at[_next_index(st, 3)], quad[_NEXT4]])
    else:
        a = at
        b = at[_next_index(st, 3)]
    s = len(a)
    finite: NDArray[np.bool_] | bool = True
    if not np.isfinite(at).all():  # parallel lines: those sides keep their line
        finite = np.asarray(np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1), dtype=bool)
        a = np.where(finite[:, None], a, 0.0)
        b = np.where(finite[:, None], b, 0.0)
    sd = b - a
    m_fr, n_o = len(_REFINE_FR), len(_REFINE_OFFS)
    # compiled (ottag_native.refine), as numpy computed it: the samples on the middle of each
    # side, each sample's distance to the nearest other triangle side (a triangle sample counts
    # only where the shape is wide enough), and the grid across the sides for remap (float32)
    base_x, base_y, width = (np.empty((s, m_fr)) for _ in range(3))
    wide = np.empty((s, m_fr), dtype=np.uint8)
    samp32 = np.empty((s, m_fr, n_o, 2), dtype=np.float32)
    normal = np.ascontiguousarray(normal, dtype=np.float64)
    a, sd = np.ascontiguousarray(a), np.ascontiguousarray(sd)
    sample_grid(a, sd, normal, st, _REFINE_FR, _REFINE_OFFS, base_x, base_y, width, wide, samp32)
    # One row of samples (remap takes under 32,767 per row): OpenCV splits a remap by rows
    # among its threads, and waking them for a few thousand samples cost more than the
    # sampling. With 2 threads 70 µs per frame as (S·M, O) rows against 20 µs as one row
    # (benchmarks/decode_speed.py, idle machine; up to 0.8 ms under load).
    map_rows = 1 if samp32.size < 2 * 32_000 else s * m_fr
    vals32 = cv2.remap(img, samp32.reshape(map_rows, -1, 2), None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)  # type: ignore[call-overload, unused-ignore]
    # the crossing of ``level`` nearest each side on each row of samples across it (a
    # data-area side's only the border's way: bright outside, dark inside)
    inward = _NONE_INWARD
    if quad is not None:
        inward = np.empty(s - st, dtype=np.uint8)
        inward_sides(
            normal[st:],
            np.ascontiguousarray(offset[st:], dtype=np.float64),
            np.ascontiguousarray(quad, dtype=np.float64),
            inward,
        )
    px, py = np.empty((s, m_fr)), np.empty((s, m_fr))
    valid8 = np.empty((s, m_fr), dtype=np.uint8)
    level_crossings(
        np.asarray(vals32, dtype=np.float32).reshape(s * m_fr, n_o), level, st, inward, _REFINE_OFFS, _REFINE_MID,
        base_x, base_y, normal, wide, px, py, valid8,
    )  # fmt: skip
    valid = valid8.view(bool)
    n2, c2, cnt = _fitted_lines(px, py, valid8)
    good = (cnt >= 3) & finite
    if quad is not None:  # the data-area sides again, without crossings at a triangle's edge
        qn, qc = n2[st:], c2[st:]
        res = np.abs(qn[:, 0, None] * px[st:] + qn[:, 1, None] * py[st:] - qc[:, None])  # (4, M)
        drop = valid[st:] & (width[st:] < _QUAD_NEAR_PX) & (res > _QUAD_OUTLIER_PX)
        if drop.any():
            kept = (valid[st:] & ~drop).view(np.uint8)
            nq, cq_off, cq = _fitted_lines(px[st:], py[st:], kept)
            redo = drop.any(axis=1) & (cq >= 3)
            n2[st:] = np.where(redo[:, None], nq, qn)
            c2[st:] = np.where(redo, cq_off, qc)
        redone = _recentre_quad_sides(
            img, level, (px[st:], py[st:], valid[st:]), (n2[st:], c2[st:]), (normal[st:], offset[st:]),
            (a[st:], b[st:]), quad,
        )  # fmt: skip
        good[st:] |= redone & (finite if isinstance(finite, bool) else finite[st:])
    # keep the orientation of the old normal
    flip = (n2 * normal).sum(axis=1) < 0
    n2[flip] *= -1
    c2[flip] *= -1
    return np.where(good[:, None], n2, normal), np.where(good, c2, offset)


#: A data-area side is searched again around the line most of its crossings agree on (within
#: this distance, px: border crossings scatter by about a tenth of a pixel) when the first
#: search found no crossing at some of its samples or one over :data:`_QUAD_OUTLIER_PX` from its
#: fit: its rough line lay so far off the border (1.5–2 px in the image, 3–4 px in a 2×
#: upsampled view of a data area 28–40 px wide) that the ±3 px search missed the border over
#: part of the side and found a triangle's edge there, or nothing. The new line is the one most
#: crossings of the second search agree on.
_CONSENSUS_PX = 0.5
#: ... when at least this many crossings agree on it.
_CONSENSUS_MIN = 4
#: Offsets (px) searched along a data-area side's normal when fewer than :data:`_CONSENSUS_MIN`
#: of its first crossings agree (the border lay beyond the first search over most of the side):
#: twice the first search's reach, at its step.
_WIDE_OFFS = np.linspace(-6.0, 6.0, 25)


def _consensus(x: _F64, y: _F64) -> tuple[_F64, float] | None:
    """The least-squares line of the largest set of the points ``(x, y)`` lying within
    :data:`_CONSENSUS_PX` of a line through two of them (None: fewer than :data:`_CONSENSUS_MIN`)."""
    if len(x) < _CONSENSUS_MIN:
        return None
    i, j = np.triu_indices(len(x), 1)
    dx, dy = x[j] - x[i], y[j] - y[i]
    ln = np.maximum(np.hypot(dx, dy), 1e-9)
    nx, ny = -dy / ln, dx / ln
    dist = np.abs(nx[:, None] * (x[None, :] - x[i][:, None]) + ny[:, None] * (y[None, :] - y[i][:, None]))
    inside = dist <= _CONSENSUS_PX
    count = inside.sum(axis=1)
    best = int(np.lexsort((np.where(inside, dist, 0.0).sum(axis=1), -count))[0])
    if count[best] < _CONSENSUS_MIN:
        return None
    keep = inside[best]
    n, c, _ = _fitted_lines(x[keep][None, :], y[keep][None, :], np.ones((1, int(keep.sum())), dtype=np.uint8))
    return n[0], float(c[0])


def _recentre_quad_sides(
    img: NDArray[np.float32],
    level: float,
    crossings: tuple[_F64, _F64, NDArray[np.bool_]],
    lines: tuple[_F64, _F64],
    rough: tuple[_F64, _F64],
    ends: tuple[_F64, _F64],
    quad: _F64,
) -> NDArray[np.bool_]:
    """The data-area sides searched again around the line their crossings agree on (see
    :data:`_CONSENSUS_PX`), or over :data:`_WIDE_OFFS` around the rough line when too few agree.

    Parameters
    ----------
    img, level
        As for :func:`refine_lines`.
    crossings : tuple of numpy.ndarray
        The first search's ``(4, M)`` crossing coordinates ``px``, ``py`` and whether each was found.
    lines : tuple of numpy.ndarray
        The sides' fitted normals ``(4, 2)`` and offsets ``(4,)``, updated in place.
    rough : tuple of numpy.ndarray
        The rough sides' normals and offsets.
    ends : tuple of numpy.ndarray
        The rough sides' first and last ends, ``(4, 2)`` each.
    quad : numpy.ndarray
        The rough corners ``(4, 2)``.

    Returns
    -------
    numpy.ndarray
        ``(4,)`` bool: the sides given a new line (at least :data:`_CONSENSUS_MIN` crossings of
        the second search agree on it); the others keep theirs.
    """
    px, py, valid = crossings
    normal, offset = lines
    a, b = ends
    res = np.abs(normal[:, 0, None] * px + normal[:, 1, None] * py - offset[:, None])
    doubt = (~valid).any(axis=1) | (valid & (res > _QUAD_OUTLIER_PX)).any(axis=1)
    redone = np.zeros(4, dtype=bool)
    for q in np.flatnonzero(doubt & np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)):
        line = _consensus(px[q][valid[q]], py[q][valid[q]])
        n, c = (rough[0][q], float(rough[1][q])) if line is None else line
        offs = _WIDE_OFFS if line is None else _REFINE_OFFS
        if n @ rough[0][q] < 0:
            n, c = -n, -c
        # the rough side's ends projected onto the line, sampled as before
        e0, e1 = (p - (n @ p - c) * n for p in (a[q], b[q]))
        base = e0[None, :] + _REFINE_FR[:, None] * (e1 - e0)[None, :]  # (M, 2)
        grid = (base[:, None, :] + offs[None, :, None] * n[None, None, :]).astype(np.float32)
        vals = cv2.remap(img, grid, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)  # type: ignore[call-overload, unused-ignore]
        # the border's crossings as refine_lines finds them: one data-area side (st = 0)
        side = np.ascontiguousarray(n, dtype=np.float64)[None, :]
        inward = np.empty(1, dtype=np.uint8)
        inward_sides(side, np.array([c], dtype=np.float64), np.ascontiguousarray(quad, dtype=np.float64), inward)
        m = len(base)
        bx, by = np.ascontiguousarray(base[:, 0])[None, :], np.ascontiguousarray(base[:, 1])[None, :]
        cx, cy, found = np.empty((1, m)), np.empty((1, m)), np.empty((1, m), dtype=np.uint8)
        level_crossings(
            np.asarray(vals, dtype=np.float32), level, 0, inward, offs, np.abs(0.5 * (offs[1:] + offs[:-1])),
            bx, by, side, np.ones((1, m), dtype=np.uint8), cx, cy, found,
        )  # fmt: skip
        kept = found[0].view(bool)
        again = _consensus(cx[0][kept], cy[0][kept])
        if again is None:
            continue
        nf, cf = again
        sign = 1.0 if nf @ normal[q] >= 0 else -1.0
        normal[q], offset[q] = sign * nf, sign * cf
        redone[q] = True
    return redone
