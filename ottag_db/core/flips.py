"""The flip graph of order types: neighbours differ by the orientation of exactly one triple (no I/O)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ottag_db.core.canonical import canonicalize_lambdas
from ottag_db.core.geometry import as_point_batch, orientation_tensor, triple_indices
from ottag_db.core.types import ProgressCallback

__all__ = ["FlipEdge", "flip_neighbours"]


@dataclass(frozen=True)
class FlipEdge:
    """``source`` and ``target`` are indices into the caller's list of order types.

    ``triple`` holds the canonical labels (of ``source``) of the three points whose
    orientation differs: moving one of them across the line through the other two turns
    ``source`` into ``target``.
    """

    source: int
    target: int
    triple: tuple[int, int, int]


def flip_neighbours(
    canonical_points: ArrayLike,
    texts: Sequence[str],
    index_of: Mapping[str, int] | None = None,
    *,
    chunk: int = 4096,
    progress: ProgressCallback | None = None,
) -> list[FlipEdge]:
    """Every flip neighbour of every order type in a complete list of one k.

    ``canonical_points`` is ``(B, k, 2)``: one realization per order type with its rows in
    canonical label order; ``texts`` their canonical IDs. For each order type and each
    triple, the triple's orientation is flipped in the chirotope, the λ-matrix rebuilt
    from the flipped orientations and canonicalized; when that ID is in the list, the edge
    is confirmed by comparing all orientations of the flipped chirotope, relabeled by the
    canonical labeling found, with the stored realization's. Flipped chirotopes that are
    not realizable (no realization in the list) yield no edge.

    Parameters
    ----------
    canonical_points : array_like, shape (B, k, 2)
        One realization per order type (any units, screen coordinates), rows in canonical
        label order.
    texts : sequence of str
        Canonical IDs ``k:digits`` of the ``B`` order types, in the same order.
    index_of : mapping of str to int, optional
        ID → index into ``texts``; built from ``texts`` when None.
    chunk : int, optional
        (order type, triple) pairs evaluated per batch (bounds the memory).
    progress : ProgressCallback, optional
        ``progress(done, total)`` in (order type, triple) pairs, after each batch.

    Returns
    -------
    list of FlipEdge
        Every confirmed edge, ordered by source then triple (the reverse of an edge is
        found from its target).
    """
    pts, _ = as_point_batch(canonical_points)
    b, k, _ = pts.shape
    lookup = dict(index_of) if index_of is not None else {t: i for i, t in enumerate(texts)}
    left = orientation_tensor(pts) < 0  # (B, k, k, k)
    lam = left.sum(axis=3).astype(np.int8)
    a, bb, c = triple_indices(k)
    m = a.size
    edges: list[FlipEdge] = []
    pairs = [(s, t) for s in range(b) for t in range(m)]
    for start in range(0, len(pairs), chunk):
        src = np.array([p[0] for p in pairs[start : start + chunk]], dtype=np.intp)
        tri = np.array([p[1] for p in pairs[start : start + chunk]], dtype=np.intp)
        n = src.shape[0]
        ta, tb, tc = a[tri], bb[tri], c[tri]
        rows = np.arange(n)
        # c left of a→b ⇒ also a left of b→c and b left of c→a (cyclic); a flip moves one unit.
        sign = np.where(left[src, ta, tb, tc], 1, -1).astype(np.int8)
        flipped = lam[src].copy()
        for x, y in ((ta, tb), (tb, tc), (tc, ta)):
            flipped[rows, x, y] -= sign
            flipped[rows, y, x] += sign
        canon = canonicalize_lambdas(flipped)
        found = np.array([lookup.get(t, -1) for t in canon.texts()], dtype=np.intp)
        hit = np.flatnonzero(found >= 0)
        if hit.size:
            fl = left[src[hit]].copy()
            h_rows = np.arange(hit.size)
            ha, hb, hc = ta[hit], tb[hit], tc[hit]
            for x, y, z in ((ha, hb, hc), (hb, hc, ha), (hc, ha, hb), (hb, ha, hc), (ha, hc, hb), (hc, hb, ha)):
                fl[h_rows, x, y, z] = ~fl[h_rows, x, y, z]
            q = canon.labelings[hit]
            relabeled = fl[h_rows[:, None, None, None], q[:, :, None, None], q[:, None, :, None], q[:, None, None, :]]
            confirmed = (relabeled == left[found[hit]]).reshape(hit.size, -1).all(axis=1)
            for i in np.flatnonzero(confirmed):
                j = hit[i]
                edges.append(FlipEdge(int(src[j]), int(found[j]), (int(ta[j]), int(tb[j]), int(tc[j]))))
        if progress is not None:
            progress(min(start + chunk, len(pairs)), len(pairs))
    return edges
