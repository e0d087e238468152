"""Triangle layouts of order-type tags: fewest empty, disjoint triangles covering every point."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import as_point_batch, check_general_position, orientation_tensor
from ottag_db.core.types import ProgressCallback
from ottag_db.errors import ExportError

__all__ = [
    "LAYOUT_MAX_K",
    "LAYOUT_MIN_K",
    "SCORE_REFERENCES",
    "Layout",
    "compute_layout",
    "compute_layouts",
    "layout_quality",
    "layout_supported",
    "validate_layout",
]

#: Smallest and largest number of points a layout is computed for (k = 4 is refused, see below).
LAYOUT_MIN_K = 3
LAYOUT_MAX_K = 8

#: Reference values of the score terms (see :class:`Layout`): an angle of 30°, a side of a
#: quarter of the diameter, a gap of a tenth of the diameter and an angular gap of 30° score 1.
SCORE_REFERENCES: dict[str, float] = {
    "angle_deg": 30.0,
    "side_rel": 0.25,
    "gap_rel": 0.10,
    "shared_gap_deg": 30.0,
}

Triangle = tuple[int, int, int]

_K4_MESSAGE = (
    "order types with 4 points cannot be drawn as tags: any two triangles on 4 points share an "
    "edge (convex position), or the only triangle holding all points is not empty (one point "
    "inside), so no layout satisfies the tag rules (use k = 3 or 5 … 8)"
)


@dataclass(frozen=True)
class Layout:
    """Triangles drawn for one point set and their quality figures.

    ``triangles`` are index triples into the point set, each sorted ascending, the tuple
    sorted lexicographically. Figures are measured on the points the layout was computed
    for (file / grid units for lengths):

    - ``min_angle_deg``: smallest interior angle of any triangle, degrees;
    - ``min_side``: shortest triangle side, coordinate units;
    - ``min_gap``: smallest distance between two triangles sharing no vertex, coordinate
      units (None when every pair of triangles shares a vertex, e.g. one triangle);
    - ``min_shared_gap_deg``: smallest angle, at a shared vertex, between two triangles
      meeting there (None when no vertex is shared);
    - ``diameter``: largest distance between two points (coordinate units);
    - ``score``: ``min(q) + 0.1 · mean(q)`` over the four terms, each capped at 1,
      ``q_angle = min_angle_deg / 30``, ``q_side = min_side / (0.25 · diameter)``,
      ``q_gap = min_gap / (0.10 · diameter)``, ``q_shared = min_shared_gap_deg / 30``
      (a term that does not apply counts 1); so the score is scale-free and in [0, 1.1].
      The references are :data:`SCORE_REFERENCES`.

    Validity (emptiness, disjointness, no shared edge) is affine-invariant, so a layout
    stays valid under the placement map of the renderer; the figures are not.
    """

    triangles: tuple[Triangle, ...]
    min_angle_deg: float
    min_side: float
    min_gap: float | None
    min_shared_gap_deg: float | None
    diameter: float
    score: float

    @property
    def size(self) -> int:
        """Number of triangles."""
        return len(self.triangles)


def layout_supported(k: int) -> bool:
    """True when point sets of ``k`` points get a layout (k = 3 and 5 … 8)."""
    return LAYOUT_MIN_K <= k <= LAYOUT_MAX_K and k != 4


def _check_k(k: int) -> None:
    if k == 4:
        raise ExportError(_K4_MESSAGE)
    if not LAYOUT_MIN_K <= k <= LAYOUT_MAX_K:
        raise ExportError(f"tag layouts are computed for 3 ≤ k ≤ {LAYOUT_MAX_K} points (k ≠ 4); got k = {k}")


# --------------------------------------------------------------------------------------------
# Index-level tables (depend on k and m only)


@dataclass(frozen=True)
class _Tables:
    k: int
    tris: NDArray[np.intp]  # (T, 3) all index triples i < j < l
    edges: NDArray[np.intp]  # (E, 2) all index pairs i < j
    tri_edges: NDArray[np.intp]  # (T, 3) edge ids of each triangle


@cache
def _tables(k: int) -> _Tables:
    tris = np.array(list(combinations(range(k), 3)), dtype=np.intp)
    edges = np.array(list(combinations(range(k), 2)), dtype=np.intp)
    eid = np.full((k, k), -1, dtype=np.intp)
    eid[edges[:, 0], edges[:, 1]] = np.arange(len(edges))
    eid[edges[:, 1], edges[:, 0]] = np.arange(len(edges))
    tri_edges = np.stack(
        [eid[tris[:, 0], tris[:, 1]], eid[tris[:, 1], tris[:, 2]], eid[tris[:, 0], tris[:, 2]]], axis=1
    )
    return _Tables(k=k, tris=tris, edges=edges, tri_edges=tri_edges)


@dataclass(frozen=True)
class _Covers:
    cands: NDArray[np.intp]  # (C, m) triangle ids
    pairs: NDArray[np.intp]  # (P, 2) distinct triangle-id pairs used by candidates
    cand_pairs: NDArray[np.intp]  # (C, m(m-1)/2) pair ids
    pair_shared: NDArray[np.intp]  # (P,) shared vertex or -1 when vertex-disjoint


@cache
def _covers(k: int, m: int) -> _Covers:
    """All sets of ``m`` triangles covering ``0 … k-1`` in which no two share two vertices."""
    tb = _tables(k)
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
    return _Covers(cands=combos, pairs=pairs, cand_pairs=cand_pairs, pair_shared=shared)


# --------------------------------------------------------------------------------------------
# Per-set geometry (batched)


def _score(
    angle: NDArray[np.float64],
    side_rel: NDArray[np.float64],
    gap_rel: NDArray[np.float64],
    shared: NDArray[np.float64],
) -> NDArray[np.float64]:
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


class _SetGeometry:
    """Triangle and pair figures of a batch of ``B`` sets of ``k`` points."""

    def __init__(self, pts: NDArray[np.float64]) -> None:
        b, k, _ = pts.shape
        tb = _tables(k)
        self.pts = pts
        self.tables = tb
        d = orientation_tensor(pts)  # (B, k, k, k)
        self.orient = d
        tris = tb.tris
        a, bb, c = tris[:, 0], tris[:, 1], tris[:, 2]
        s1 = np.sign(d[:, a, bb, :])
        s2 = np.sign(d[:, bb, c, :])
        s3 = np.sign(d[:, c, a, :])
        inside = (s1 == s2) & (s2 == s3) & (s1 != 0)
        vert = np.zeros((len(tris), k), dtype=bool)
        vert[np.arange(len(tris))[:, None], tris] = True
        inside &= ~vert[None]
        self.empty = ~inside.any(axis=2)  # (B, T)
        # proper crossings of edges with four distinct endpoints
        e = tb.edges
        ea, eb = e[:, 0], e[:, 1]
        o1 = d[:, ea[:, None], eb[:, None], ea[None, :]]
        o2 = d[:, ea[:, None], eb[:, None], eb[None, :]]
        o3 = d[:, ea[None, :], eb[None, :], ea[:, None]]
        o4 = d[:, ea[None, :], eb[None, :], eb[:, None]]
        distinct = (
            (ea[:, None] != ea[None, :])
            & (ea[:, None] != eb[None, :])
            & (eb[:, None] != ea[None, :])
            & (eb[:, None] != eb[None, :])
        )
        self.cross = (o1 * o2 < 0) & (o3 * o4 < 0) & distinct[None]  # (B, E, E)
        # side lengths and angles
        diff = pts[:, :, None, :] - pts[:, None, :, :]
        dist = np.sqrt((diff**2).sum(axis=3))  # (B, k, k)
        self.diameter = dist.reshape(b, -1).max(axis=1)
        self.tri_side = np.minimum(np.minimum(dist[:, a, bb], dist[:, bb, c]), dist[:, a, c])  # (B, T)
        self.tri_angle = np.minimum(np.minimum(self._angle(a, bb, c), self._angle(bb, c, a)), self._angle(c, a, bb))
        # point-to-segment distances (B, k, E)
        p = pts[:, :, None, :]
        s0 = pts[:, ea][:, None]
        sv = (pts[:, eb] - pts[:, ea])[:, None]
        t = ((p - s0) * sv).sum(axis=3) / (sv**2).sum(axis=3)
        t = np.clip(t, 0.0, 1.0)
        proj = s0 + t[..., None] * sv
        self.pt_seg = np.sqrt(((p - proj) ** 2).sum(axis=3))
        # direction angle of v → p, degrees in [0, 360)
        self.direction = np.degrees(np.arctan2(-diff[..., 1], -diff[..., 0])) % 360.0  # (B, v, p)

    def _angle(self, at: NDArray[np.intp], u: NDArray[np.intp], w: NDArray[np.intp]) -> NDArray[np.float64]:
        p = self.pts
        v1 = p[:, u] - p[:, at]
        v2 = p[:, w] - p[:, at]
        cross = np.abs(v1[..., 0] * v2[..., 1] - v1[..., 1] * v2[..., 0])
        dot = (v1 * v2).sum(axis=-1)
        result: NDArray[np.float64] = np.degrees(np.arctan2(cross, dot))
        return result

    def pair_figures(
        self, pairs: NDArray[np.intp], shared: NDArray[np.intp]
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]:
        """For triangle pairs: compatible, vertex-disjoint gap (inf else), shared-vertex gap (inf else)."""
        tb = self.tables
        b = self.pts.shape[0]
        te1 = tb.tri_edges[pairs[:, 0]]  # (P, 3)
        te2 = tb.tri_edges[pairs[:, 1]]
        crossing = self.cross[:, te1[:, :, None], te2[:, None, :]].reshape(b, len(pairs), 9).any(axis=2)
        compat = ~crossing
        gap = np.full((b, len(pairs)), np.inf)
        ang = np.full((b, len(pairs)), np.inf)
        dis = shared < 0
        if dis.any():
            pr = pairs[dis]
            v1 = tb.tris[pr[:, 0]]
            v2 = tb.tris[pr[:, 1]]
            e1 = tb.tri_edges[pr[:, 0]]
            e2 = tb.tri_edges[pr[:, 1]]
            g1 = self.pt_seg[:, v1[:, :, None], e2[:, None, :]].reshape(b, len(pr), 9).min(axis=2)
            g2 = self.pt_seg[:, v2[:, :, None], e1[:, None, :]].reshape(b, len(pr), 9).min(axis=2)
            gap[:, dis] = np.minimum(g1, g2)
        sh = ~dis
        if sh.any():
            pr = pairs[sh]
            v = shared[sh]
            o1 = np.sort(np.where(tb.tris[pr[:, 0]] == v[:, None], 1 << 20, tb.tris[pr[:, 0]]), axis=1)[:, :2]
            o2 = np.sort(np.where(tb.tris[pr[:, 1]] == v[:, None], 1 << 20, tb.tris[pr[:, 1]]), axis=1)[:, :2]
            d1 = self.direction[:, v[:, None], o1]  # (B, P', 2)
            d2 = self.direction[:, v[:, None], o2]
            delta = np.abs(d1[:, :, :, None] - d2[:, :, None, :]) % 360.0
            delta = np.minimum(delta, 360.0 - delta)
            ang[:, sh] = delta.reshape(b, len(pr), 4).min(axis=2)
        return compat, gap, ang


def _figures_for(
    geo: _SetGeometry, cov: _Covers
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Validity and figures ``(B, C)`` of every candidate cover."""
    cands = cov.cands
    valid = geo.empty[:, cands].all(axis=2)
    angle = geo.tri_angle[:, cands].min(axis=2)
    side = geo.tri_side[:, cands].min(axis=2)
    if cov.pairs.shape[0]:
        compat, gap, ang = geo.pair_figures(cov.pairs, cov.pair_shared)
        valid &= compat[:, cov.cand_pairs].all(axis=2)
        cgap = gap[:, cov.cand_pairs].min(axis=2)
        cang = ang[:, cov.cand_pairs].min(axis=2)
    else:
        shape = (geo.pts.shape[0], len(cands))
        cgap = np.full(shape, np.inf)
        cang = np.full(shape, np.inf)
    return valid, angle, side, cgap, cang


def _make_layout(
    tris: NDArray[np.intp], angle: float, side: float, gap: float, shared: float, diameter: float
) -> Layout:
    score = float(_score(np.array(angle), np.array(side / diameter), np.array(gap / diameter), np.array(shared)))
    triangles = tuple(sorted(tuple(sorted(int(i) for i in t)) for t in tris))
    return Layout(
        triangles=triangles,  # type: ignore[arg-type]
        min_angle_deg=float(angle),
        min_side=float(side),
        min_gap=None if math.isinf(gap) else float(gap),
        min_shared_gap_deg=None if math.isinf(shared) else float(shared),
        diameter=float(diameter),
        score=score,
    )


def _solve_more(pts: NDArray[np.float64], m_start: int) -> list[Layout]:
    """Layouts of sets that have none with fewer than ``m_start`` triangles."""
    b, k, _ = pts.shape
    geo = _SetGeometry(pts)
    tb = geo.tables
    result: list[Layout | None] = [None] * b
    todo = np.arange(b)
    m = m_start
    while todo.size:
        if m > k:
            raise ExportError("no triangle layout exists for a point set of this batch")
        cov = _covers(k, m)
        if len(cov.cands) == 0:
            m += 1
            continue
        sub = _SetGeometry(pts[todo])
        valid, angle, side, gap, shared = _figures_for(sub, cov)
        diam = sub.diameter[:, None]
        score = np.where(valid, _score(angle, side / diam, gap / diam, shared), -np.inf)
        best = score.argmax(axis=1)
        found = valid[np.arange(len(todo)), best]
        for row in np.flatnonzero(found):
            c = int(best[row])
            result[int(todo[row])] = _make_layout(
                tb.tris[cov.cands[c]],
                float(angle[row, c]),
                float(side[row, c]),
                float(gap[row, c]),
                float(shared[row, c]),
                float(sub.diameter[row]),
            )
        todo = todo[~found]
        m += 1
    return [r for r in result if r is not None]


def compute_layouts(
    points_batch: ArrayLike, progress: ProgressCallback | None = None, *, chunk: int = 256
) -> list[Layout]:
    """Best layout of each of ``B`` point sets given as ``(B, k, 2)`` (3 ≤ k ≤ 8, k ≠ 4).

    Exhaustive over covers of ``m = ⌈k/3⌉, ⌈k/3⌉ + 1, …`` empty triangles (vertex-level
    candidate covers are tabulated once per (k, m); per set only emptiness, crossings and
    the figures are evaluated, batched over ``chunk`` sets). Among valid covers with the
    fewest triangles the highest :attr:`Layout.score` wins; ties go to the lexicographically
    first cover, so results are deterministic. ``progress(done, total)`` is called after each
    chunk. Raises :class:`ExportError` for k = 4 or k outside 3 … 8 and
    :class:`~ottag_db.errors.GeneralPositionError` for a degenerate set.
    """
    pts, _ = as_point_batch(points_batch)
    b, k, _ = pts.shape
    _check_k(k)
    layouts: list[Layout] = []
    for start in range(0, b, chunk):
        part = pts[start : start + chunk]
        check_general_position(part, record_offset=start)
        layouts.extend(_solve_more(part, -(-k // 3)))
        if progress is not None:
            progress(min(start + chunk, b), b)
    if b == 0 and progress is not None:
        progress(0, 0)
    return layouts


def compute_layout(points: ArrayLike) -> Layout:
    """Best layout of one ``(k, 2)`` point set; see :func:`compute_layouts`."""
    arr = np.asarray(points)
    if arr.ndim != 2:
        raise ValueError(f"compute_layout takes one point set of shape (k, 2), got {arr.shape}")
    return compute_layouts(arr[None])[0]


def layout_quality(points: ArrayLike, triangles: Sequence[Sequence[int]]) -> Layout:
    """Figures and score of a given (assumed valid) layout on ``points`` — e.g. placed points."""
    pts, _ = as_point_batch(np.asarray(points)[None])
    k = pts.shape[1]
    tris = [tuple(sorted(int(i) for i in t)) for t in triangles]
    tb = _tables(k)
    index = {tuple(int(v) for v in t): n for n, t in enumerate(tb.tris)}
    ids = np.array([index[t] for t in tris], dtype=np.intp)
    geo = _SetGeometry(pts)
    angle = float(geo.tri_angle[0, ids].min())
    side = float(geo.tri_side[0, ids].min())
    pairs = np.array(list(combinations(ids.tolist(), 2)), dtype=np.intp).reshape(-1, 2)
    shared = np.array(
        [next(iter(set(tb.tris[a].tolist()) & set(tb.tris[b].tolist())), -1) for a, b in pairs],
        dtype=np.intp,
    )
    gap = shared_gap = math.inf
    if len(pairs):
        _, g, a = geo.pair_figures(pairs, shared)
        gap, shared_gap = float(g.min()), float(a.min())
    return _make_layout(tb.tris[ids], angle, side, gap, shared_gap, float(geo.diameter[0]))


# --------------------------------------------------------------------------------------------
# Independent checker


def _orient(p: Sequence[float], q: Sequence[float], r: Sequence[float]) -> float:
    return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])


def _clip(
    poly: list[tuple[float, float]], a: tuple[float, float], b: tuple[float, float], sign: float
) -> list[tuple[float, float]]:
    """Keep the part of ``poly`` on the side ``sign`` of the line a → b (Sutherland–Hodgman)."""
    out: list[tuple[float, float]] = []
    n = len(poly)
    for i in range(n):
        cur, nxt = poly[i], poly[(i + 1) % n]
        oc, on = sign * _orient(a, b, cur), sign * _orient(a, b, nxt)
        if oc >= 0:
            out.append(cur)
        if (oc > 0 > on) or (oc < 0 < on):
            t = oc / (oc - on)
            out.append((cur[0] + t * (nxt[0] - cur[0]), cur[1] + t * (nxt[1] - cur[1])))
    return out


def _area(poly: list[tuple[float, float]]) -> float:
    s = 0.0
    for i in range(len(poly)):
        x1, y1 = poly[i]
        x2, y2 = poly[(i + 1) % len(poly)]
        s += x1 * y2 - x2 * y1
    return abs(s) / 2.0


def _overlap_area(t1: list[tuple[float, float]], t2: list[tuple[float, float]]) -> float:
    sign = 1.0 if _orient(*t2) > 0 else -1.0
    poly = list(t1)
    for i in range(3):
        poly = _clip(poly, t2[i], t2[(i + 1) % 3], sign)
        if not poly:
            return 0.0
    return _area(poly)


def _segments_cross(p1: Sequence[float], p2: Sequence[float], q1: Sequence[float], q2: Sequence[float]) -> bool:
    d1, d2 = _orient(p1, p2, q1), _orient(p1, p2, q2)
    d3, d4 = _orient(q1, q2, p1), _orient(q1, q2, p2)
    return ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4))


def validate_layout(points: ArrayLike, triangles: Sequence[Sequence[int]]) -> list[str]:
    """Violated tag-layout rules of ``triangles`` on ``points`` (``(k, 2)``); empty when valid.

    Checked geometrically, independently of :func:`compute_layouts` (plain Python, polygon
    clipping for overlaps): indices valid and distinct, triangles not degenerate and not
    repeated; every point a vertex; no two triangles sharing an edge; no point inside or on
    a triangle it is not a vertex of; no crossing edges; interiors pairwise disjoint
    (overlap area zero); at least ⌈k/3⌉ triangles. Minimality is not checked.
    """
    pts = [(float(x), float(y)) for x, y in np.asarray(points, dtype=np.float64).reshape(-1, 2)]
    k = len(pts)
    errors: list[str] = []
    tris: list[tuple[int, int, int]] = []
    for t in triangles:
        idx = tuple(int(i) for i in t)
        if len(idx) != 3:
            errors.append(f"triangle {idx} does not have 3 vertices")
            continue
        if any(not 0 <= i < k for i in idx):
            errors.append(f"triangle {idx} has a vertex index outside 0 … {k - 1}")
            continue
        if len(set(idx)) != 3:
            errors.append(f"triangle {idx} repeats a vertex")
            continue
        tris.append((idx[0], idx[1], idx[2]))
    if not tris:
        errors.append("no triangles")
        return errors
    seen: set[frozenset[int]] = set()
    for t in tris:
        key = frozenset(t)
        if key in seen:
            errors.append(f"triangle {t} appears twice")
        seen.add(key)
        if _orient(pts[t[0]], pts[t[1]], pts[t[2]]) == 0:
            errors.append(f"triangle {t} is degenerate (collinear vertices)")
    if len(tris) < -(-k // 3):
        errors.append(f"{len(tris)} triangles cannot cover {k} points")
    used = {i for t in tris for i in t}
    missing = sorted(set(range(k)) - used)
    if missing:
        errors.append(f"points {missing} are not a vertex of any triangle")
    for t in tris:
        a, b, c = (pts[i] for i in t)
        for p in range(k):
            if p in t:
                continue
            o1, o2, o3 = _orient(a, b, pts[p]), _orient(b, c, pts[p]), _orient(c, a, pts[p])
            if (o1 >= 0 and o2 >= 0 and o3 >= 0) or (o1 <= 0 and o2 <= 0 and o3 <= 0):
                errors.append(f"point {p} lies inside or on triangle {t}")
    scale = max((abs(x) for p in pts for x in p), default=1.0) or 1.0
    for i in range(len(tris)):
        for j in range(i + 1, len(tris)):
            t1, t2 = tris[i], tris[j]
            common = set(t1) & set(t2)
            if len(common) >= 2 and frozenset(t1) != frozenset(t2):
                errors.append(f"triangles {t1} and {t2} share the edge {sorted(common)}")
            for e1 in ((t1[0], t1[1]), (t1[1], t1[2]), (t1[0], t1[2])):
                for e2 in ((t2[0], t2[1]), (t2[1], t2[2]), (t2[0], t2[2])):
                    if set(e1) & set(e2):
                        continue
                    if _segments_cross(pts[e1[0]], pts[e1[1]], pts[e2[0]], pts[e2[1]]):
                        errors.append(f"edge {e1} of triangle {t1} crosses edge {e2} of triangle {t2}")
            area = _overlap_area([pts[v] for v in t1], [pts[v] for v in t2])
            if area > 1e-9 * scale * scale:
                errors.append(f"triangles {t1} and {t2} overlap (common area {area:.6g})")
    return errors
