"""The flip graph of order types: neighbours differ by the orientation of exactly one triple (no I/O)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.canonical import canonicalize_lambdas
from ottag_db.core.geometry import as_point_batch, orientation_tensor, triple_indices
from ottag_db.core.types import ProgressCallback

__all__ = ["FlipEdge", "FlipEdges", "flip_edges", "flip_lambdas", "flip_neighbours"]

_Int = TypeVar("_Int", bound=np.integer[Any])

# Sets whose orientation tensor is built at once (k = 9: 2048 × 729 float64 = 12 MB).
_LEFT_CHUNK = 2048


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


@dataclass(frozen=True)
class FlipEdges:
    """Flip edges as arrays (the form for large graphs: k = 9 has millions of edges).

    Edge ``e`` goes from order type ``source[e]`` to ``target[e]`` (indices into the caller's
    list); ``triple[e]`` is ``(a, b, c)``, the canonical labels of ``source`` whose
    orientation the flip changes, ``a < b < c``.
    """

    source: NDArray[np.int64]
    target: NDArray[np.int64]
    triple: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.source.shape[0])


def _left_tensor(pts: NDArray[np.float64]) -> NDArray[np.bool_]:
    """``left[b, i, j, p]``: p left of p_i → p_j, built in chunks to bound the float memory."""
    b, k, _ = pts.shape
    left = np.empty((b, k, k, k), dtype=bool)
    for s in range(0, b, _LEFT_CHUNK):
        left[s : s + _LEFT_CHUNK] = orientation_tensor(pts[s : s + _LEFT_CHUNK]) < 0
    return left


def flip_lambdas(
    lam: NDArray[_Int], a: ArrayLike, b: ArrayLike, c: ArrayLike, c_left_of_ab: ArrayLike
) -> NDArray[_Int]:
    """λ-matrices with the orientation of one triple per matrix reversed.

    ``c`` left of a→b ⇔ ``a`` left of b→c ⇔ ``b`` left of c→a (cyclic), so reversing the
    triple moves λ(a, b), λ(b, c), λ(c, a) by one unit and their transposes by one the other
    way (screen convention, see :mod:`ottag_db.core.geometry`).

    Parameters
    ----------
    lam : ndarray, shape (n, k, k)
        λ-matrices (not modified).
    a, b, c : array_like of int, shape (n,)
        The triple of each matrix (point indices).
    c_left_of_ab : array_like of bool, shape (n,)
        Whether ``c`` is left of a→b before the flip.

    Returns
    -------
    ndarray, shape (n, k, k)
        The flipped λ-matrices (not canonicalized), of the dtype of ``lam``.
    """
    flipped = lam.copy()
    ta, tb, tc = (np.asarray(v, dtype=np.intp) for v in (a, b, c))
    sign = np.where(np.asarray(c_left_of_ab, dtype=bool), 1, -1).astype(lam.dtype)
    rows = np.arange(flipped.shape[0])
    for x, y in ((ta, tb), (tb, tc), (tc, ta)):
        flipped[rows, x, y] -= sign
        flipped[rows, y, x] += sign
    return flipped


def flip_edges(
    canonical_points: ArrayLike,
    texts: Sequence[str],
    index_of: Mapping[str, int] | None = None,
    *,
    sources: ArrayLike | None = None,
    chunk: int = 65536,
    progress: ProgressCallback | None = None,
) -> FlipEdges:
    """Every flip neighbour of every (or every chosen) order type in a complete list of one k.

    ``canonical_points`` is ``(B, k, 2)``: one realization per order type with its rows in
    canonical label order; ``texts`` their canonical IDs. For each source and each triple,
    the triple's orientation is flipped in the chirotope, the λ-matrix rebuilt from the
    flipped orientations and canonicalized; when that ID is in the list, the edge is
    confirmed by comparing all orientations of the flipped chirotope, relabeled by the
    canonical labeling found, with the stored realization's. Flipped chirotopes that are not
    realizable (no realization in the list) yield no edge.

    Parameters
    ----------
    canonical_points : array_like, shape (B, k, 2)
        One realization per order type (any units, screen coordinates), rows in canonical
        label order.
    texts : sequence of str
        Canonical IDs ``k:digits`` of the ``B`` order types, in the same order.
    index_of : mapping of str to int, optional
        ID → index into ``texts``; built from ``texts`` when None.
    sources : array_like of int, optional
        Indices of the order types to flip from (default: all); targets are any in the list.
    chunk : int, optional
        (order type, triple) pairs evaluated per batch (bounds the memory: about 1 kB each
        for k = 9).
    progress : ProgressCallback, optional
        ``progress(done, total)`` in (order type, triple) pairs, after each batch.

    Returns
    -------
    FlipEdges
        Every confirmed edge from the sources, ordered by source (in the order given) then
        triple (the reverse of an edge is found from its target).
    """
    pts, _ = as_point_batch(canonical_points)
    b, k, _ = pts.shape
    lookup = dict(index_of) if index_of is not None else {t: i for i, t in enumerate(texts)}
    left = _left_tensor(pts)
    lam = left.sum(axis=3).astype(np.int8)
    a, bb, c = triple_indices(k)
    m = a.size
    src_all = np.arange(b, dtype=np.intp) if sources is None else np.asarray(sources, dtype=np.intp).ravel()
    total = src_all.size * m
    per = max(1, chunk // m)
    out_s: list[NDArray[np.int64]] = []
    out_t: list[NDArray[np.int64]] = []
    out_x: list[NDArray[np.int64]] = []
    for start in range(0, src_all.size, per):
        part = src_all[start : start + per]
        src = np.repeat(part, m)
        tri = np.tile(np.arange(m), part.size)
        n = src.shape[0]
        ta, tb, tc = a[tri], bb[tri], c[tri]
        canon = canonicalize_lambdas(flip_lambdas(lam[src], ta, tb, tc, left[src, ta, tb, tc]))
        found = np.fromiter((lookup.get(t, -1) for t in canon.texts()), dtype=np.intp, count=n)
        hit = np.flatnonzero(found >= 0)
        if hit.size:
            fl = left[src[hit]]
            h_rows = np.arange(hit.size)
            ha, hb, hc = ta[hit], tb[hit], tc[hit]
            for x, y, z in ((ha, hb, hc), (hb, hc, ha), (hc, ha, hb), (hb, ha, hc), (ha, hc, hb), (hc, hb, ha)):
                fl[h_rows, x, y, z] = ~fl[h_rows, x, y, z]
            q = canon.labelings[hit]
            relabeled = fl[h_rows[:, None, None, None], q[:, :, None, None], q[:, None, :, None], q[:, None, None, :]]
            confirmed = (relabeled == left[found[hit]]).reshape(hit.size, -1).all(axis=1)
            keep = hit[confirmed]
            out_s.append(src[keep].astype(np.int64))
            out_t.append(found[keep].astype(np.int64))
            out_x.append(np.stack([ta[keep], tb[keep], tc[keep]], axis=1).astype(np.int64))
        if progress is not None:
            progress(min((start + per) * m, total), total)
    if not out_s:
        empty = np.zeros(0, dtype=np.int64)
        return FlipEdges(empty, empty.copy(), np.zeros((0, 3), dtype=np.int64))
    return FlipEdges(np.concatenate(out_s), np.concatenate(out_t), np.concatenate(out_x))


def flip_neighbours(
    canonical_points: ArrayLike,
    texts: Sequence[str],
    index_of: Mapping[str, int] | None = None,
    *,
    chunk: int = 4096,
    progress: ProgressCallback | None = None,
) -> list[FlipEdge]:
    """:func:`flip_edges` of every order type in the list, as a list of :class:`FlipEdge`.

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
    e = flip_edges(canonical_points, texts, index_of, chunk=chunk, progress=progress)
    return [
        FlipEdge(int(s), int(t), (int(x[0]), int(x[1]), int(x[2])))
        for s, t, x in zip(e.source.tolist(), e.target.tolist(), e.triple.tolist(), strict=True)
    ]
