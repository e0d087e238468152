"""Clustering stage: triangle vertex estimates → point hypotheses (shared vertices merged)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.types import PointHypothesis, TriangleLines

__all__ = ["cluster_hypotheses", "ls_point"]

_F64 = NDArray[np.float64]


def ls_point(nl: list[list[float]], ol: list[float], ids: Sequence[int]) -> tuple[tuple[float, float] | None, float]:
    """Least-squares intersection of some lines and the largest line distance to it.

    Plain Python: the few lines of one point, no array overhead.

    Parameters
    ----------
    nl : list
        Unit normals ``[nx, ny]`` of all lines.
    ol : list
        Offsets of all lines (n·x = c).
    ids : sequence of int
        The lines to intersect.

    Returns
    -------
    tuple
        The point ``(x, y)`` and its largest distance to the lines (same unit); ``None, inf``
        when the lines are (nearly) parallel.
    """
    a00 = a01 = a11 = b0 = b1 = 0.0
    for i in ids:
        nx, ny = nl[i]
        c = ol[i]
        a00 += nx * nx
        a01 += nx * ny
        a11 += ny * ny
        b0 += nx * c
        b1 += ny * c
    det = a00 * a11 - a01 * a01
    if abs(det) < 1e-9:
        return None, math.inf
    x = (b0 * a11 - a01 * b1) / det
    y = (a00 * b1 - a01 * b0) / det
    return (x, y), max(abs(nl[i][0] * x + nl[i][1] * y - ol[i]) for i in ids)


@dataclass(frozen=True)
class _VertexTable:
    """For ``n`` triangle vertex estimates (vertex j of triangle t at 3t + j): the two side
    lines through each (side j runs from vertex j to j+1) and the ``(n, n)`` mask of pairs
    ``i < j`` of different triangles (read-only)."""

    lines: tuple[tuple[int, int], ...]
    other: NDArray[np.bool_]


def _vertex_table(n: int) -> _VertexTable:
    tri = np.arange(n) // 3
    corner = np.arange(n) % 3
    lines = tuple((int(a), int(b)) for a, b in zip(3 * tri + (corner + 2) % 3, 3 * tri + corner, strict=True))
    other = np.triu(tri[:, None] != tri[None, :], 1)
    other.flags.writeable = False
    return _VertexTable(lines, other)


#: Vertex tables of up to 16 triangles, built once.
_VERTEX_TABLES: tuple[_VertexTable, ...] = tuple(_vertex_table(3 * t) for t in range(17))


def cluster_hypotheses(
    tris: TriangleLines, cap: float, sure: float, tol: float, max_doubtful: int = 4
) -> list[PointHypothesis]:
    """Point hypotheses from the triangle vertex estimates, most merges first.

    Estimates of different triangles may be one shared point when the least-squares
    intersection of all their side lines stays within ``tol`` px of every line (estimates at
    most ``cap`` px apart). Merges of estimates closer than ``sure`` px are always made; up to
    ``max_doubtful`` farther ones (sharp tips give long error ellipses along the bisector) are
    tried in and out, and the decoder keeps the first hypothesis that reads and verifies.

    Parameters
    ----------
    tris : TriangleLines
        Refined side lines and vertices.
    cap, sure, tol : float
        Distances in the unit of the lines (pixels), see above.
    max_doubtful : int
        Doubtful merges tried in and out (2 ** max_doubtful hypotheses at most).

    Returns
    -------
    list of PointHypothesis
        Each point the least-squares intersection of its side lines, with the indices of
        these lines; no two hypotheses with the same grouping.
    """
    v = tris.vertices.reshape(-1, 2)
    n = len(v)
    table = _VERTEX_TABLES[n // 3] if n // 3 < len(_VERTEX_TABLES) else _vertex_table(n)
    lid = table.lines
    nl: list[list[float]] = tris.normal.tolist()
    ol: list[float] = tris.offset.tolist()
    dx, dy = v[:, None, 0] - v[None, :, 0], v[:, None, 1] - v[None, :, 1]  # by coordinate: faster
    d = np.sqrt(dx * dx + dy * dy)
    ii, jj = np.nonzero((d < cap) & table.other)
    order = np.argsort(d[ii, jj], kind="stable")
    sure_pairs: list[tuple[int, int]] = []
    doubtful: list[tuple[int, int]] = []
    for o in order:
        i, j = int(ii[o]), int(jj[o])
        _, res = ls_point(nl, ol, lid[i] + lid[j])
        if res > tol:
            continue
        (sure_pairs if d[i, j] <= sure else doubtful).append((i, j))
    doubtful = doubtful[:max_doubtful]
    subsets = sorted(itertools.product((True, False), repeat=len(doubtful)), key=lambda s: -sum(s))
    out: list[PointHypothesis] = []
    seen: set[tuple[int, ...]] = set()
    for subset in subsets:
        pairs = sure_pairs + [pr for pr, use in zip(doubtful, subset, strict=True) if use]
        groups = _merge(pairs, n, lid, nl, ol, tol)
        key = tuple(sorted(min(g) for g in groups))
        if key in seen:
            continue
        seen.add(key)
        pts = []
        lines = []
        for members in groups:
            id_list = [u for m in members for u in lid[m]]
            xy, _ = ls_point(nl, ol, id_list)
            if xy is None or not (math.isfinite(xy[0]) and math.isfinite(xy[1])):
                break
            pts.append(xy)
            lines.append(np.array(id_list, dtype=np.int64))
        else:
            out.append(PointHypothesis(np.array(pts, dtype=np.float64), tuple(lines)))
    return out


def _merge(
    pairs: list[tuple[int, int]],
    n: int,
    lid: tuple[tuple[int, int], ...],
    nl: list[list[float]],
    ol: list[float],
    tol: float,
) -> list[list[int]]:
    """Greedy union of vertex estimates along ``pairs`` (never two corners of one triangle)."""
    groups: dict[int, list[int]] = {i: [i] for i in range(n)}
    root = list(range(n))
    for i, j in pairs:
        a, b = root[i], root[j]
        if a == b:
            continue
        ga, gb = groups[a], groups[b]
        if {m // 3 for m in ga} & {m // 3 for m in gb}:  # vertex m is a corner of triangle m // 3
            continue
        if len(ga) + len(gb) > 2:
            _, res = ls_point(nl, ol, [u for m in ga + gb for u in lid[m]])
            if res > tol:
                continue
        groups[a] = ga + gb
        for m in gb:
            root[m] = a
        del groups[b]
    return list(groups.values())
