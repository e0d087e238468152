"""The compiled clustering stage (``ottag_native.cluster``) gives exactly the hypotheses of its
numpy and plain-Python formulation, bit for bit: on triangles that share vertices (measured
with noise), whose vertices lie near each other without being shared (doubtful merges), and
whose side lines are parallel.

The formulation below is the test's oracle (it was the decoder's code before the kernel).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from ottag_db.decode.cluster import cluster_hypotheses
from ottag_db.decode.refine import fit_chains, triangle_vertices
from ottag_db.decode.types import PointHypothesis, TriangleLines

_F64 = NDArray[np.float64]


def _ls_point(nl: list[list[float]], ol: list[float], ids: Sequence[int]) -> tuple[tuple[float, float] | None, float]:
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


def _cluster_numpy(
    tris: TriangleLines, cap: float, sure: float, tol: float, max_doubtful: int = 4
) -> list[PointHypothesis]:
    """``cluster_hypotheses`` as it was (see its docstring)."""
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
        _, res = _ls_point(nl, ol, lid[i] + lid[j])
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
            xy, _ = _ls_point(nl, ol, id_list)
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
            _, res = _ls_point(nl, ol, [u for m in ga + gb for u in lid[m]])
            if res > tol:
                continue
        groups[a] = ga + gb
        for m in gb:
            root[m] = a
        del groups[b]
    return list(groups.values())


def _lines(tris: _F64, rng: np.random.Generator, noise: float) -> TriangleLines:
    """Side lines fitted to noisy points along each triangle's sides."""
    chains = [
        np.linspace(t[j], t[(j + 1) % 3], 10)[1:-1] + rng.normal(0, noise, (8, 2)) for t in tris for j in range(3)
    ]
    normal, offset = fit_chains(chains)
    return TriangleLines(normal, offset, triangle_vertices(normal, offset))


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    triangles=st.integers(1, 9),
    shared=st.integers(0, 8),
    noise=st.floats(0.0, 1.5),
    tol=st.floats(0.2, 6.0),
    parallel=st.booleans(),
)
def test_the_kernel_gives_the_formulations_hypotheses(
    seed: int, triangles: int, shared: int, noise: float, tol: float, parallel: bool
) -> None:
    rng = np.random.default_rng(seed)
    tris = rng.uniform(0, 120, size=(triangles, 3, 2))
    for _ in range(shared if triangles > 1 else 0):  # a vertex shared (or nearly) by two triangles
        a, b = rng.choice(triangles, 2, replace=False)
        tris[b, rng.integers(3)] = tris[a, rng.integers(3)] + rng.normal(0, rng.choice([0.0, 1.0, 4.0]), 2)
    lines = _lines(tris, rng, noise)
    if parallel:  # two sides of one triangle on parallel lines: its vertex between them is lost
        normal, offset = lines.normal.copy(), lines.offset.copy()
        normal[1] = normal[0]
        offset[1] = offset[0] + 5.0
        lines = TriangleLines(normal, offset, triangle_vertices(normal, offset))
    cap, sure = 15.0, float(rng.uniform(0.5, 3.0))
    want = _cluster_numpy(lines, cap, sure, tol)
    got = cluster_hypotheses(lines, cap, sure, tol)
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        assert np.array_equal(g.points, w.points) and g.points.dtype == w.points.dtype
        assert len(g.line_ids) == len(w.line_ids)
        assert all(np.array_equal(a, b) and a.dtype == b.dtype for a, b in zip(g.line_ids, w.line_ids, strict=True))
