"""Enumerate all order types of 3 … 8 points from scratch and build the bundled point-set files."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .canonical import canonical_batch, canonicalize_lambdas, mirror_lambdas
from .errors import UsageError
from .pointfile import file_sha256, write_point_file

__all__ = [
    "MP_THRESHOLDS",
    "GenerationReport",
    "Progress",
    "Realization",
    "enumerate_order_types",
    "generate_database",
    "insertion_candidates",
    "mirror_points",
    "normalize_unit",
    "relative_mp",
]

#: Progress callback ``(stage name, done, total)``.
Progress = Callable[[str, int, int], None]

#: MP thresholds (grid units) of the summary table, as in the paper's Table 7.
MP_THRESHOLDS: tuple[float, ...] = tuple(0.5 * i for i in range(1, 19))

#: Candidates whose distance to a line of the arrangement is below this fraction of the
#: set's extent are dropped (they are numerically on the line).
_CLEARANCE_TOL = 1e-9
#: Distance (in units of the set's extent, which is 1 after normalization) at which points
#: are placed in unbounded cells.
_FAR = 1.5
#: Candidate sets canonicalized per batch (bounds the memory to a few hundred MB).
_CHUNK_SETS = 200_000


@dataclass(frozen=True)
class Realization:
    """One order type with a float realization.

    - ``text``: canonical ID ``k:digits`` of ``points``;
    - ``mirror_text``: canonical ID of the reflected set (equal to ``text`` if achiral);
    - ``points``: ``(k, 2)`` float64 coordinates, scaled into the unit square [0, 1]²
      (screen convention, unitless).
    """

    text: str
    mirror_text: str
    points: NDArray[np.float64]

    @property
    def k(self) -> int:
        """Number of points."""
        return int(self.points.shape[0])

    @property
    def representative(self) -> bool:
        """True for the chirality whose ID text is the smaller one of its reflection pair."""
        return self.text <= self.mirror_text


# --------------------------------------------------------------------------------------------
# Small batched helpers
# --------------------------------------------------------------------------------------------


def normalize_unit(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Translate and uniformly scale each ``(B, n, 2)`` set so its bounding box is in [0, 1]²."""
    lo = points.min(axis=1, keepdims=True)
    span = (points.max(axis=1, keepdims=True) - lo).max(axis=2, keepdims=True)
    out: NDArray[np.float64] = (points - lo) / span
    return out


def mirror_points(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Reflect ``(B, n, 2)`` sets in a vertical line (x → −x, then back into [0, 1]²)."""
    out = points.copy()
    out[..., 0] *= -1.0
    return normalize_unit(out)


def _triple_index(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    a, b, c = (np.asarray(v, dtype=np.intp) for v in zip(*_combinations3(n), strict=True))
    return a, b, c


def _combinations3(n: int) -> list[tuple[int, int, int]]:
    return [(a, b, c) for a in range(n) for b in range(a + 1, n) for c in range(b + 1, n)]


def relative_mp(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """MP of each ``(B, n, 2)`` set divided by the larger side of its bounding box (unitless).

    MP is half the smallest distance from a point to a line through two others; for a
    triangle the smallest of its three heights is twice its area over its longest side.
    """
    n = points.shape[1]
    a, b, c = _triple_index(n)
    pa, pb, pc = points[:, a], points[:, b], points[:, c]
    ab = pb - pa
    ac = pc - pa
    bc = pc - pb
    area2 = np.abs(ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0])
    longest = np.sqrt(np.maximum(np.maximum((ab * ab).sum(-1), (ac * ac).sum(-1)), (bc * bc).sum(-1)))
    with np.errstate(divide="ignore", invalid="ignore"):
        heights = np.where(longest > 0, area2 / longest, 0.0)
    extent = (points.max(axis=1) - points.min(axis=1)).max(axis=1)
    out: NDArray[np.float64] = 0.5 * heights.min(axis=1) / extent
    return out


# --------------------------------------------------------------------------------------------
# Insertion of one point into every cell of the line arrangement
# --------------------------------------------------------------------------------------------


def _vertex_layout(m: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Pairs ``(i, j)`` (the lines) and pairs of disjoint lines ``(l1, l2)`` (crossing vertices)."""
    first, second = np.triu_indices(m, 1)
    n_lines = first.size
    l1, l2 = np.triu_indices(n_lines, 1)
    disjoint = (
        (first[l1] != first[l2]) & (first[l1] != second[l2]) & (second[l1] != first[l2]) & (second[l1] != second[l2])
    )
    return first.astype(np.intp), second.astype(np.intp), l1[disjoint].astype(np.intp), l2[disjoint].astype(np.intp)


def insertion_candidates(base: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Points in the cells of the arrangement of lines through all pairs of each base set.

    ``base`` is ``(N, m, 2)`` (sets in general position, coordinates of order 1). Every
    cell of an arrangement of non-parallel lines has a vertex, and the cells around a
    vertex are the angular sectors between consecutive lines through it. For every vertex
    (the m input points, where m − 1 lines meet, and the crossings of two lines through
    four distinct points) and every sector, a candidate is put on the bisector halfway to
    the first line the bisecting ray meets (at distance ``_FAR`` when it meets none).

    Returns ``(candidates (N, C, 2), clearance (N, C))`` where ``clearance`` is the
    smallest distance from the candidate to any line (same units as ``base``).
    """
    n_sets, m, _ = base.shape
    first, second, l1, l2 = _vertex_layout(m)
    n_lines = first.size
    pi = base[:, first]
    pj = base[:, second]
    u = pj - pi
    u /= np.linalg.norm(u, axis=2, keepdims=True)
    normal = np.stack([-u[..., 1], u[..., 0]], axis=2)  # (N, P, 2)
    offset = -(normal * pi).sum(axis=2)  # (N, P)

    # (a) Vertices at the input points: 2(m − 1) rays, bisect consecutive ones.
    others = np.array([[j for j in range(m) if j != i] for i in range(m)], dtype=np.intp)  # (m, m−1)
    d = base[:, others] - base[:, :, None, :]  # (N, m, m−1, 2)
    ang = np.arctan2(d[..., 1], d[..., 0])
    ang = np.concatenate([ang, ang + np.pi], axis=2)
    ang = np.mod(ang, 2.0 * np.pi)
    ang.sort(axis=2)
    nxt = np.concatenate([ang[..., 1:], ang[..., :1] + 2.0 * np.pi], axis=2)
    mid = 0.5 * (ang + nxt)  # (N, m, S)
    dirs_a = np.stack([np.cos(mid), np.sin(mid)], axis=3)  # (N, m, S, 2)
    verts_a = base
    incident_a = (first[None, :] == np.arange(m)[:, None]) | (second[None, :] == np.arange(m)[:, None])  # (m, P)

    # (b) Crossings of two lines through four distinct points: 4 sectors each.
    n1, n2 = normal[:, l1], normal[:, l2]
    c1, c2 = offset[:, l1], offset[:, l2]
    det = n1[..., 0] * n2[..., 1] - n1[..., 1] * n2[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        vx = (-c1 * n2[..., 1] + c2 * n1[..., 1]) / det
        vy = (-n1[..., 0] * c2 + n2[..., 0] * c1) / det
    verts_b = np.stack([vx, vy], axis=2)  # (N, Q, 2)
    u1, u2 = u[:, l1], u[:, l2]
    s_dir = u1 + u2
    d_dir = u1 - u2
    s_dir /= np.linalg.norm(s_dir, axis=2, keepdims=True)
    d_dir /= np.linalg.norm(d_dir, axis=2, keepdims=True)
    dirs_b = np.stack([s_dir, -s_dir, d_dir, -d_dir], axis=2)  # (N, Q, 4, 2)
    line_ids = np.arange(n_lines)
    incident_b = (line_ids[None, :] == l1[:, None]) | (line_ids[None, :] == l2[:, None])  # (Q, P)

    out: list[NDArray[np.float64]] = []
    for verts, dirs, incident in ((verts_a, dirs_a, incident_a), (verts_b, dirs_b, incident_b)):
        side = (normal[:, None, :, :] * verts[:, :, None, :]).sum(axis=3) + offset[:, None, :]  # (N, V, P)
        rate = np.einsum("nvsd,npd->nvsp", dirs, normal)  # (N, V, S, P)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -side[:, :, None, :] / rate
        t = np.where((t > 0) & ~incident[None, :, None, :] & np.isfinite(t), t, np.inf)
        step = np.minimum(0.5 * t.min(axis=3), _FAR)  # (N, V, S)
        out.append((verts[:, :, None, :] + dirs * step[..., None]).reshape(n_sets, -1, 2))
    cand = np.concatenate(out, axis=1)
    dist = np.abs((normal[:, None, :, :] * cand[:, :, None, :]).sum(axis=3) + offset[:, None, :])
    clearance = dist.min(axis=2)
    clearance = np.where(np.isfinite(clearance), clearance, 0.0)
    return cand, clearance


def _insert_points(base: NDArray[np.float64]) -> dict[str, tuple[NDArray[np.float64], float]]:
    """All order types obtained by adding one point to a base set: ID → (best set, quality).

    Candidates in the same cell of the same base set are merged first (by their sign
    vector with respect to all lines); of the sets with the same canonical ID the one with
    the largest :func:`relative_mp` is kept (normalized into [0, 1]²).
    """
    n_sets, m, _ = base.shape
    k = m + 1
    found: dict[str, tuple[NDArray[np.float64], float]] = {}
    per_set = max(1, _CHUNK_SETS // max(1, (m * 2 * (m - 1) + 4 * _vertex_layout(m)[2].size)))
    for start in range(0, n_sets, per_set):
        chunk = base[start : start + per_set]
        cand, clearance = insertion_candidates(chunk)
        nb, nc, _ = cand.shape
        first, second = np.triu_indices(m, 1)
        pi = chunk[:, first][:, None]
        pj = chunk[:, second][:, None]
        cross = (pj[..., 0] - pi[..., 0]) * (cand[:, :, None, 1] - pi[..., 1]) - (pj[..., 1] - pi[..., 1]) * (
            cand[:, :, None, 0] - pi[..., 0]
        )  # (nb, nc, P)
        bits = (cross < 0).astype(np.int64) << np.arange(first.size, dtype=np.int64)
        code = bits.sum(axis=2)
        ok = clearance > _CLEARANCE_TOL
        set_idx = np.broadcast_to(np.arange(nb)[:, None], (nb, nc))
        # One candidate per (base set, cell): the one farthest from all lines.
        order = np.lexsort((-clearance.ravel(), code.ravel(), set_idx.ravel()))
        order = order[ok.ravel()[order]]
        keys = set_idx.ravel()[order] * (1 << 40) + code.ravel()[order]
        _, first_pos = np.unique(keys, return_index=True)
        pick = order[first_pos]
        sets = np.concatenate([chunk[set_idx.ravel()[pick]], cand.reshape(-1, 2)[pick][:, None, :]], axis=1)
        quality = relative_mp(sets)
        texts = canonical_batch(sets).texts()
        best: dict[str, int] = {}
        for idx, text in enumerate(texts):
            prev = best.get(text)
            if prev is None or quality[idx] > quality[prev]:
                best[text] = idx
        for text, idx in best.items():
            q = float(quality[idx])
            old = found.get(text)
            if old is None or q > old[1]:
                found[text] = (sets[idx], q)
    del k
    return {t: (normalize_unit(p[None])[0], q) for t, (p, q) in found.items()}


def _mirror_texts(points: NDArray[np.float64]) -> list[str]:
    lam = canonical_batch(points).lambdas
    return canonicalize_lambdas(mirror_lambdas(lam)).texts()


def _subsets(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """All ``(B·k, k − 1, 2)`` subsets obtained by dropping one point of each ``(B, k, 2)`` set."""
    k = points.shape[1]
    keep = np.array([[j for j in range(k) if j != i] for i in range(k)], dtype=np.intp)
    out: NDArray[np.float64] = points[:, keep].reshape(-1, k - 1, 2)
    return out


def enumerate_order_types(max_k: int = 8, progress: Progress | None = None) -> dict[int, list[Realization]]:
    """All order types of ``k = 3 … max_k`` points in general position, both chiralities.

    Starts from a triangle; the types of ``k`` points come from inserting a point into
    every cell of the line arrangement of a realization of each type of ``k − 1`` points,
    then (since the cells depend on the coordinates) into every ``(k − 1)``-subset of the
    new ``k``-point realizations, until a pass finds nothing new. Mirror images are added
    by reflection. Deterministic. Returns ``{k: [Realization, …]}`` sorted by ID text; the
    points are in [0, 1]² and, of all candidates seen, the one with the largest relative
    MP is kept.
    """
    if not 3 <= max_k <= 8:
        raise UsageError(f"max_k must be between 3 and 8, got {max_k}")
    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]])
    tri_text = canonical_batch(tri).texts()[0]
    result: dict[int, list[Realization]] = {3: [Realization(tri_text, _mirror_texts(tri)[0], tri[0])]}
    for k in range(4, max_k + 1):
        reps = [r for r in result[k - 1] if r.representative]
        base = np.stack([r.points for r in reps])
        found: dict[str, tuple[NDArray[np.float64], float]] = {}
        passes = 0
        while base.shape[0]:
            passes += 1
            if progress is not None:
                progress(f"enumerate k={k} pass {passes}", 0, 1)
            new = _insert_points(base)
            fresh: list[str] = []
            for text, (pts, q) in new.items():
                old = found.get(text)
                if old is None:
                    fresh.append(text)
                if old is None or q > old[1]:
                    found[text] = (pts, q)
            # Close under reflection; the reflected sets need not be extended (their
            # extensions are the reflections of the extensions of the originals).
            direct = sorted(fresh)
            if fresh:
                fresh_pts = np.stack([found[t][0] for t in fresh])
                mirrored = mirror_points(fresh_pts)
                for text, pts, q in zip(
                    canonical_batch(mirrored).texts(), mirrored, relative_mp(mirrored), strict=True
                ):
                    if text not in found:
                        found[text] = (pts, float(q))
                        fresh.append(text)
            if progress is not None:
                progress(f"enumerate k={k} pass {passes}", 1, 1)
            if not direct:
                break
            base = _subsets(np.stack([found[t][0] for t in direct]))
        texts = sorted(found)
        pts_all = np.stack([found[t][0] for t in texts])
        mirrors = _mirror_texts(pts_all)
        result[k] = [Realization(t, mt, p) for t, mt, p in zip(texts, mirrors, pts_all, strict=True)]
    return result
