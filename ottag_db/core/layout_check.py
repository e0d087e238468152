"""Independent checker of tag layouts: plain Python, polygon clipping for overlaps.

Deliberately independent of :mod:`ottag_db.core.layout` and :mod:`ottag_db.core.geometry`
(its own scalar orientation test, Sutherland–Hodgman clipping): it verifies the search's
results, so it must not share the search's code paths.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["validate_layout"]


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

    Parameters
    ----------
    points : array_like, shape (k, 2)
        The point set (any units; screen coordinates).
    triangles : sequence of sequence of int
        Index triples into ``points``.

    Returns
    -------
    list of str
        One sentence per violated rule, naming the triangles and points; empty when the
        layout is valid.
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
