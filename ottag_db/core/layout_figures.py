"""What the layout search measures: index tables of triangle covers and per-set figures.

Index-level tables depend on ``k`` (and the number of triangles ``m``) only; per-set
figures (emptiness, crossings, angles, sides, gaps) are batched over ``B`` sets of ``k``
points. Lengths are in the units of the points (grid units for file coordinates), angles in
degrees; orientations follow the screen convention of :mod:`ottag_db.core.geometry`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.geometry import orientation_tensor, triple_indices

__all__ = [
    "SCORE_REFERENCES",
    "CoverTable",
    "IndexTables",
    "SetGeometry",
    "cover_figures",
    "cover_table",
    "index_tables",
    "layout_score",
]

#: Reference values of the score terms (see :class:`ottag_db.core.layout.Layout`): an angle
#: of 30°, a side of a quarter of the diameter, a gap of a tenth of the diameter and an
#: angular gap of 30° score 1.
SCORE_REFERENCES: dict[str, float] = {
    "angle_deg": 30.0,
    "side_rel": 0.25,
    "gap_rel": 0.10,
    "shared_gap_deg": 30.0,
}

# --------------------------------------------------------------------------------------------
# Index-level tables (depend on k and m only)


@dataclass(frozen=True)
class IndexTables:
    """Index tables of ``k`` points: triangles, edges and the edges of each triangle."""

    k: int
    tris: NDArray[np.intp]  # (T, 3) all index triples i < j < l
    edges: NDArray[np.intp]  # (E, 2) all index pairs i < j
    tri_edges: NDArray[np.intp]  # (T, 3) edge ids of each triangle


# Pure constant tables of k (and m): cached because every batch of the search needs them;
# they hold no state and the search never writes into them.
@cache
def index_tables(k: int) -> IndexTables:
    """Index tables of ``k`` points.

    Parameters
    ----------
    k : int
        Number of points.

    Returns
    -------
    IndexTables
        ``tris`` ``(T, 3)``: all triples ``i < j < l`` in lexicographic order; ``edges``
        ``(E, 2)``: all pairs ``i < j``; ``tri_edges`` ``(T, 3)``: edge ids of the sides
        ``(i, j)``, ``(j, l)``, ``(i, l)`` of each triangle.
    """
    tris = np.stack(triple_indices(k), axis=1)
    edges = np.array(list(combinations(range(k), 2)), dtype=np.intp)
    eid = np.full((k, k), -1, dtype=np.intp)
    eid[edges[:, 0], edges[:, 1]] = np.arange(len(edges))
    eid[edges[:, 1], edges[:, 0]] = np.arange(len(edges))
    tri_edges = np.stack(
        [eid[tris[:, 0], tris[:, 1]], eid[tris[:, 1], tris[:, 2]], eid[tris[:, 0], tris[:, 2]]], axis=1
    )
    return IndexTables(k=k, tris=tris, edges=edges, tri_edges=tri_edges)


@dataclass(frozen=True)
class CoverTable:
    """Candidate covers of ``k`` points by ``m`` triangles (index level, see :func:`cover_table`)."""

    cands: NDArray[np.intp]  # (C, m) triangle ids
    pairs: NDArray[np.intp]  # (P, 2) distinct triangle-id pairs used by candidates
    cand_pairs: NDArray[np.intp]  # (C, m(m-1)/2) pair ids
    pair_shared: NDArray[np.intp]  # (P,) shared vertex or -1 when vertex-disjoint


@cache
def cover_table(k: int, m: int) -> CoverTable:
    """All sets of ``m`` triangles covering ``0 … k-1`` in which no two share two vertices.

    Parameters
    ----------
    k : int
        Number of points.
    m : int
        Number of triangles.

    Returns
    -------
    CoverTable
        ``cands`` ``(C, m)``: triangle ids (into :attr:`IndexTables.tris`) of each cover,
        ascending; ``pairs`` ``(P, 2)``: the distinct triangle pairs used by the covers;
        ``cand_pairs`` ``(C, m(m−1)/2)``: pair ids of each cover; ``pair_shared``
        ``(P,)``: the vertex two triangles share, −1 when vertex-disjoint.
    """
    tb = index_tables(k)
    t = len(tb.tris)
    masks = (1 << tb.tris).sum(axis=1)
    common = np.array([[bin(int(a) & int(b)).count("1") for b in masks] for a in masks])
    ok_pair = common <= 1
    full = (1 << k) - 1
    combos = np.arange(t, dtype=np.intp)[:, None]
    cover = masks.copy()
    for level in range(1, m):
        last = combos[:, -1]
        allowed = np.ones((len(combos), t), dtype=bool)
        for c in range(level):
            allowed &= ok_pair[combos[:, c]]
        allowed &= np.arange(t)[None, :] > last[:, None]
        rows, nxt = np.nonzero(allowed)
        new_cover = cover[rows] | masks[nxt]
        remaining = m - level - 1
        uncovered = np.array([k - bin(int(v)).count("1") for v in new_cover], dtype=np.intp)
        keep = uncovered <= 3 * remaining
        combos = np.concatenate([combos[rows[keep]], nxt[keep, None]], axis=1)
        cover = new_cover[keep]
    combos = combos[cover == full]
    pair_list = list(combinations(range(m), 2))
    if pair_list:
        raw = np.stack([combos[:, [a, b]] for a, b in pair_list], axis=1)  # (C, Q, 2)
        flat = raw[:, :, 0] * t + raw[:, :, 1]
        uniq, inv = np.unique(flat, return_inverse=True)
        pairs = np.stack([uniq // t, uniq % t], axis=1).astype(np.intp)
        cand_pairs = inv.reshape(flat.shape).astype(np.intp)
    else:
        pairs = np.zeros((0, 2), dtype=np.intp)
        cand_pairs = np.zeros((len(combos), 0), dtype=np.intp)
    shared = np.full(len(pairs), -1, dtype=np.intp)
    for p, (a, b) in enumerate(pairs):
        s = set(tb.tris[a].tolist()) & set(tb.tris[b].tolist())
        if s:
            shared[p] = s.pop()
    return CoverTable(cands=combos, pairs=pairs, cand_pairs=cand_pairs, pair_shared=shared)


# --------------------------------------------------------------------------------------------
# Per-set figures (batched)


def layout_score(
    angle: NDArray[np.float64],
    side_rel: NDArray[np.float64],
    gap_rel: NDArray[np.float64],
    shared: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Score ``min(q) + 0.1 · mean(q)`` of layouts from their four figures (broadcast).

    Parameters
    ----------
    angle : ndarray of float64
        Smallest interior angle, degrees.
    side_rel : ndarray of float64
        Shortest side divided by the set's diameter.
    gap_rel : ndarray of float64
        Smallest gap between vertex-disjoint triangles divided by the diameter (inf when
        none).
    shared : ndarray of float64
        Smallest angular gap at a shared vertex, degrees (inf when none).

    Returns
    -------
    ndarray of float64
        Scores in [0, 1.1]; each term ``q`` is its figure over :data:`SCORE_REFERENCES`,
        capped at 1 (so an inapplicable term, inf, counts 1).
    """
    r = SCORE_REFERENCES
    q = np.stack(
        [
            np.minimum(angle / r["angle_deg"], 1.0),
            np.minimum(side_rel / r["side_rel"], 1.0),
            np.minimum(gap_rel / r["gap_rel"], 1.0),  # inf → 1
            np.minimum(shared / r["shared_gap_deg"], 1.0),
        ],
        axis=-1,
    )
    result: NDArray[np.float64] = q.min(axis=-1) + 0.1 * q.mean(axis=-1)
    return result


class SetGeometry:
    """Triangle and pair figures of a batch of ``B`` sets of ``k`` points.

    Parameters
    ----------
    pts : ndarray of float64, shape (B, k, 2)
        The sets (any units; screen coordinates).

    Every figure keeps the set axis **last** (index tables lead, so gathers by triangle or
    edge copy contiguous rows of ``B`` values and reductions over them are elementwise):
    ``empty`` ``(T, B)`` no other point inside or on (``T`` triangles, ``E`` edges of
    :func:`index_tables`); ``cross`` ``(E, E, B)`` proper crossing of two edges with four
    distinct endpoints; ``diameter`` ``(B,)``; ``tri_side`` and ``tri_angle`` ``(T, B)``
    shortest side and smallest angle (degrees); ``pt_seg`` ``(k, E, B)`` point-to-segment
    distances; ``direction`` ``(k, k, B)`` angle of ``v → p`` in degrees.
    """

    def __init__(self, pts: NDArray[np.float64]) -> None:
        b, k, _ = pts.shape
        tb = index_tables(k)
        self.pts = pts
        self.tables = tb
        d = np.ascontiguousarray(np.moveaxis(orientation_tensor(pts), 0, -1))  # (k, k, k, B)
        tris = tb.tris
        a, bb, c = tris[:, 0], tris[:, 1], tris[:, 2]
        e = tb.edges
        ea, eb = e[:, 0], e[:, 1]
        side = d[ea, eb]  # (E, k, B): orientation of every point against every edge i < j
        sign = np.sign(side)
        s1 = sign[tb.tri_edges[:, 0]]  # (T, k, B): edge (a, b)
        s2 = sign[tb.tri_edges[:, 1]]  # edge (b, c)
        s3 = np.sign(d[c, a])
        inside = (s1 == s2) & (s2 == s3) & (s1 != 0)
        vert = np.zeros((len(tris), k), dtype=bool)
        vert[np.arange(len(tris))[:, None], tris] = True
        inside &= ~vert[:, :, None]
        self.empty = ~inside.any(axis=1)  # (T, B)
        # proper crossings of edges with four distinct endpoints: edge i separates the ends of
        # edge j (sep[i, j]) and edge j those of edge i (the transpose)
        sep = side[:, ea] * side[:, eb] < 0  # (E, E, B)
        distinct = (
            (ea[:, None] != ea[None, :])
            & (ea[:, None] != eb[None, :])
            & (eb[:, None] != ea[None, :])
            & (eb[:, None] != eb[None, :])
        )
        self.cross = sep & sep.transpose(1, 0, 2) & distinct[:, :, None]  # (E, E, B)
        # side lengths and angles
        px = np.ascontiguousarray(pts[:, :, 0].T)  # (k, B)
        py = np.ascontiguousarray(pts[:, :, 1].T)
        self._px, self._py = px, py
        dx = px[:, None] - px[None, :]  # (k, k, B): p_i − p_j
        dy = py[:, None] - py[None, :]
        dist = np.sqrt(dx**2 + dy**2)
        self.diameter = dist.reshape(k * k, b).max(axis=0)
        self.tri_side = np.minimum(np.minimum(dist[a, bb], dist[bb, c]), dist[a, c])  # (T, B)
        self.tri_angle = np.minimum(np.minimum(self._angle(a, bb, c), self._angle(bb, c, a)), self._angle(c, a, bb))
        # point-to-segment distances (k, E, B)
        s0x, s0y = px[ea][None], py[ea][None]  # (1, E, B)
        svx, svy = (px[eb] - px[ea])[None], (py[eb] - py[ea])[None]
        qx, qy = px[:, None], py[:, None]  # (k, 1, B)
        t = ((qx - s0x) * svx + (qy - s0y) * svy) / (svx**2 + svy**2)
        t = np.clip(t, 0.0, 1.0)
        self.pt_seg = np.sqrt((qx - (s0x + t * svx)) ** 2 + (qy - (s0y + t * svy)) ** 2)
        # direction angle of v → p, degrees in [0, 360)
        self.direction = np.degrees(np.arctan2(-dy, -dx)) % 360.0  # (v, p, B)

    def _angle(self, at: NDArray[np.intp], u: NDArray[np.intp], w: NDArray[np.intp]) -> NDArray[np.float64]:
        px, py = self._px, self._py
        v1x, v1y = px[u] - px[at], py[u] - py[at]
        v2x, v2y = px[w] - px[at], py[w] - py[at]
        cross = np.abs(v1x * v2y - v1y * v2x)
        dot = v1x * v2x + v1y * v2y
        result: NDArray[np.float64] = np.degrees(np.arctan2(cross, dot))
        return result

    def pair_figures(
        self, pairs: NDArray[np.intp], shared: NDArray[np.intp]
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]:
        """Figures of triangle pairs on every set (the set axis last).

        Parameters
        ----------
        pairs : ndarray of intp, shape (P, 2)
            Triangle ids (into :attr:`IndexTables.tris`).
        shared : ndarray of intp, shape (P,)
            The vertex each pair shares, −1 when vertex-disjoint.

        Returns
        -------
        compatible : ndarray of bool, shape (P, B)
            No edge of one triangle properly crosses an edge of the other.
        gap : ndarray of float64, shape (P, B)
            Smallest vertex-to-side distance of vertex-disjoint pairs (units of the
            points), inf for pairs sharing a vertex.
        angle : ndarray of float64, shape (P, B)
            Smallest angle (degrees) between the sides of the two triangles at the shared
            vertex, inf for vertex-disjoint pairs.
        """
        tb = self.tables
        b = self.pts.shape[0]
        n = len(pairs)
        te1 = tb.tri_edges[pairs[:, 0]]  # (P, 3)
        te2 = tb.tri_edges[pairs[:, 1]]
        crossing = self.cross[te1[:, :, None], te2[:, None, :]].reshape(n, 9, b).any(axis=1)
        compat = ~crossing
        gap = np.full((n, b), np.inf)
        ang = np.full((n, b), np.inf)
        dis = shared < 0
        if dis.any():
            pr = pairs[dis]
            v1 = tb.tris[pr[:, 0]]
            v2 = tb.tris[pr[:, 1]]
            e1 = tb.tri_edges[pr[:, 0]]
            e2 = tb.tri_edges[pr[:, 1]]
            g1 = self.pt_seg[v1[:, :, None], e2[:, None, :]].reshape(len(pr), 9, b).min(axis=1)
            g2 = self.pt_seg[v2[:, :, None], e1[:, None, :]].reshape(len(pr), 9, b).min(axis=1)
            gap[dis] = np.minimum(g1, g2)
        sh = ~dis
        if sh.any():
            pr = pairs[sh]
            v = shared[sh]
            o1 = np.sort(np.where(tb.tris[pr[:, 0]] == v[:, None], 1 << 20, tb.tris[pr[:, 0]]), axis=1)[:, :2]
            o2 = np.sort(np.where(tb.tris[pr[:, 1]] == v[:, None], 1 << 20, tb.tris[pr[:, 1]]), axis=1)[:, :2]
            d1 = self.direction[v[:, None], o1]  # (P', 2, B)
            d2 = self.direction[v[:, None], o2]
            delta = np.abs(d1[:, :, None] - d2[:, None, :]) % 360.0
            delta = np.minimum(delta, 360.0 - delta)
            ang[sh] = delta.reshape(len(pr), 4, b).min(axis=1)
        return compat, gap, ang


def cover_figures(
    geo: SetGeometry, cov: CoverTable
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Validity and figures of every candidate cover on every set.

    Parameters
    ----------
    geo : SetGeometry
        Figures of ``B`` sets.
    cov : CoverTable
        ``C`` candidate covers of the same ``k``.

    Returns
    -------
    valid, angle, side, gap, shared : ndarray, shape (B, C) each
        Whether the cover is a layout (triangles empty, pairwise compatible), its smallest
        angle (degrees), shortest side, smallest vertex-disjoint gap (units of the points,
        inf when none) and smallest angular gap at a shared vertex (degrees, inf when none).
    """
    cands = cov.cands
    valid = geo.empty[cands].all(axis=1)  # (C, B)
    angle = geo.tri_angle[cands].min(axis=1)
    side = geo.tri_side[cands].min(axis=1)
    if cov.pairs.shape[0]:
        compat, gap, ang = geo.pair_figures(cov.pairs, cov.pair_shared)
        valid &= compat[cov.cand_pairs].all(axis=1)
        cgap = gap[cov.cand_pairs].min(axis=1)
        cang = ang[cov.cand_pairs].min(axis=1)
    else:
        shape = (len(cands), geo.pts.shape[0])
        cgap = np.full(shape, np.inf)
        cang = np.full(shape, np.inf)
    return valid.T, angle.T, side.T, cgap.T, cang.T
