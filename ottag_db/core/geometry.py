"""Batched plane geometry of point sets: orientations, λ-matrices, hulls and MP (no I/O)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.errors import GeneralPositionError

__all__ = [
    "as_point_batch",
    "check_general_position",
    "general_position_mask",
    "hull_size",
    "hull_sizes",
    "lambda_matrices",
    "lambda_matrix",
    "maximal_perturbation",
    "maximal_perturbations",
    "orientation_tensor",
]


def as_point_batch(points: ArrayLike) -> tuple[NDArray[np.float64], bool]:
    """Return ``points`` as a float64 ``(B, n, 2)`` array and whether the input was one set.

    Integer coordinates up to 16 bits are represented exactly; every orientation computed
    from them below is exact too (products stay below 2**53).
    """
    arr = np.asarray(points)
    single = arr.ndim == 2
    if single:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[-1] != 2:
        raise ValueError(f"expected points of shape (n, 2) or (B, n, 2), got {arr.shape}")
    if arr.shape[1] < 3:
        raise ValueError(f"a point set needs at least 3 points, got {arr.shape[1]}")
    return np.ascontiguousarray(arr, dtype=np.float64), single


def orientation_tensor(points: ArrayLike) -> NDArray[np.float64]:
    """Signed orientation ``D[b, i, j, p] = (xj−xi)(yp−yi) − (yj−yi)(xp−xi)``.

    Screen convention (x right, y down): ``p`` is *left* of the directed line
    ``p_i → p_j`` when ``D < 0``. Computed as ``M[i,j] + M[j,p] + M[p,i]`` with
    ``M[a,b] = xa·yb − ya·xb``, which is exact for integer coordinates below 2**16.
    Returns a ``(B, n, n, n)`` float64 array (a single set gives ``B = 1``).
    """
    pts, _ = as_point_batch(points)
    x = pts[..., 0]
    y = pts[..., 1]
    m = x[:, :, None] * y[:, None, :] - y[:, :, None] * x[:, None, :]
    # D[i,j,p] = M[i,j] + M[j,p] + M[p,i]
    d: NDArray[np.float64] = m[:, :, :, None] + m[:, None, :, :] + m.transpose(0, 2, 1)[:, :, None, :]
    return d


def _upper_orientations(pts: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.intp]]:
    """``D[b, q, p]`` for the pairs ``q = (i, j)``, ``i < j`` (from ``np.triu_indices``)."""
    n = pts.shape[1]
    x = pts[..., 0]
    y = pts[..., 1]
    m = x[:, :, None] * y[:, None, :] - y[:, :, None] * x[:, None, :]
    first, second = np.triu_indices(n, 1)
    # D[i,j,p] = M[i,j] + M[j,p] − M[i,p]  (M is antisymmetric)
    d: NDArray[np.float64] = m[:, first, second][:, :, None] + (m[:, second, :] - m[:, first, :])
    return d, first, second


def _lambda_from_upper(
    d: NDArray[np.float64], first: NDArray[np.intp], second: NDArray[np.intp], n: int
) -> NDArray[np.int8]:
    upper = (d < 0).sum(axis=2, dtype=np.int8)
    lam = np.zeros((d.shape[0], n, n), dtype=np.int8)
    lam[:, first, second] = upper
    lam[:, second, first] = (n - 2) - upper
    return lam


@dataclass(frozen=True)
class PointSetAnalysis:
    """One pass over a batch: λ-matrices, general-position flags and MP (see the functions)."""

    lambdas: NDArray[np.int8]
    general_position: NDArray[np.bool_]
    mp: NDArray[np.float64]


def analyse_point_sets(points: ArrayLike) -> PointSetAnalysis:
    """λ-matrices, general-position mask and MP of a ``(B, n, 2)`` batch from one orientation pass.

    Cheaper than calling :func:`lambda_matrices`, :func:`general_position_mask` and
    :func:`maximal_perturbations` separately (the importer's hot path). λ is only
    meaningful where ``general_position`` is True.
    """
    pts, _ = as_point_batch(points)
    n = pts.shape[1]
    d, first, second = _upper_orientations(pts)
    lam = _lambda_from_upper(d, first, second, n)
    ad = np.abs(d)
    # Every triple (i < j, p ∉ {i, j}) appears here; D = 0 for p ∈ {i, j} is masked.
    idx = np.arange(n)
    own = (idx[None, :] == first[:, None]) | (idx[None, :] == second[:, None])
    ad[:, own] = np.inf
    diff = pts[:, first, :] - pts[:, second, :]
    lengths = np.sqrt((diff * diff).sum(axis=2))
    ok = (ad.min(axis=(1, 2)) > 0) & (lengths.min(axis=1) > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        mp = 0.5 * (ad.min(axis=2) / lengths).min(axis=1)
    return PointSetAnalysis(lambdas=lam, general_position=np.asarray(ok, dtype=bool), mp=np.where(ok, mp, 0.0))


def lambda_matrices(points: ArrayLike) -> NDArray[np.int8]:
    """λ-matrices ``L[b, i, j]`` = number of points left of ``p_i → p_j`` (diagonal 0).

    ``points`` is ``(B, n, 2)``; returns ``(B, n, n)`` int8. Assumes general position
    (see :func:`check_general_position`). Only pairs ``i < j`` are evaluated: in general
    position ``L[j, i] = n − 2 − L[i, j]``.
    """
    pts, _ = as_point_batch(points)
    d, first, second = _upper_orientations(pts)
    return _lambda_from_upper(d, first, second, pts.shape[1])


def lambda_matrix(points: ArrayLike) -> NDArray[np.int8]:
    """λ-matrix of one point set given as ``(n, 2)``; returns ``(n, n)`` int8."""
    pts = np.asarray(points)
    if pts.ndim != 2:
        raise ValueError("lambda_matrix takes one point set of shape (n, 2)")
    single: NDArray[np.int8] = lambda_matrices(pts[None])[0]
    return single


def hull_sizes(lam: NDArray[np.integer]) -> NDArray[np.int64]:
    """Number of convex-hull vertices of each set, from its ``(B, n, n)`` λ-matrices.

    A point is a hull vertex exactly when the line to one of its neighbours has all
    other ``n − 2`` points on its left.
    """
    n = lam.shape[-1]
    on_hull = (lam == n - 2).any(axis=2)
    counts: NDArray[np.int64] = on_hull.sum(axis=1).astype(np.int64)
    return counts


def hull_size(points: ArrayLike) -> int:
    """Number of convex-hull vertices of one ``(n, 2)`` point set in general position."""
    return int(hull_sizes(lambda_matrix(points)[None])[0])


def _pair_lengths(pts: NDArray[np.float64]) -> NDArray[np.float64]:
    diff = pts[:, :, None, :] - pts[:, None, :, :]
    lengths: NDArray[np.float64] = np.sqrt((diff * diff).sum(axis=3))
    return lengths


def maximal_perturbations(points: ArrayLike) -> NDArray[np.float64]:
    """MP of each set: half the smallest distance from a point to a line through two others.

    In the units of the coordinates (grid units for file coordinates). Moving every point
    by less than MP cannot change the order type (paper Sec. 5.3). ``(B, n, 2)`` → ``(B,)``.
    """
    pts, _ = as_point_batch(points)
    n = pts.shape[1]
    d = np.abs(orientation_tensor(pts))
    lengths = _pair_lengths(pts)
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = d / lengths[:, :, :, None]
    idx = np.arange(n)
    invalid = (
        (idx[:, None, None] == idx[None, :, None])
        | (idx[:, None, None] == idx[None, None, :])
        | (idx[None, :, None] == idx[None, None, :])
    )
    dist[:, invalid] = np.inf
    result: NDArray[np.float64] = 0.5 * dist.reshape(dist.shape[0], -1).min(axis=1)
    return result


def maximal_perturbation(points: ArrayLike) -> float:
    """MP of one ``(n, 2)`` point set, in coordinate units."""
    return float(maximal_perturbations(np.asarray(points)[None])[0])


def general_position_mask(points: ArrayLike, *, tolerance: float = 0.0) -> NDArray[np.bool_]:
    """``(B,)`` bool: True where a set has no repeated point and no collinear triple.

    ``tolerance`` is the smallest accepted ``|D|`` (twice the triangle area); 0 means exact.
    """
    pts, _ = as_point_batch(points)
    n = pts.shape[1]
    d = np.abs(orientation_tensor(pts))
    a, b, c = _triples(n)
    ok: NDArray[np.bool_] = np.asarray((d[:, a, b, c] > tolerance).all(axis=1), dtype=bool)
    return ok


def _triples(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    idx = np.arange(n)
    a, b, c = np.meshgrid(idx, idx, idx, indexing="ij")
    keep = (a < b) & (b < c)
    return a[keep], b[keep], c[keep]


def check_general_position(points: ArrayLike, *, record_offset: int = 0) -> None:
    """Raise :class:`GeneralPositionError` naming the first bad set and its points.

    A repeated point is reported as the pair of indices, a collinear triple as the three
    indices (0-based within the set). ``record_offset`` is added to the batch index so
    callers streaming a file can report the record number in the file.
    """
    pts, _ = as_point_batch(points)
    n = pts.shape[1]
    ok = general_position_mask(pts)
    if ok.all():
        return
    b = int(np.flatnonzero(~ok)[0])
    s = pts[b]
    for i in range(n):
        for j in range(i + 1, n):
            if (s[i] == s[j]).all():
                raise GeneralPositionError(
                    f"record {b + record_offset}: points {i} and {j} are the same point {_fmt(s[i])}",
                    record=b + record_offset,
                    points=(i, j),
                )
    d = orientation_tensor(s[None])[0]
    a, bb, c = _triples(n)
    bad = np.flatnonzero(d[a, bb, c] == 0)
    t = int(bad[0])
    tri = (int(a[t]), int(bb[t]), int(c[t]))
    raise GeneralPositionError(
        f"record {b + record_offset}: points {tri[0]}, {tri[1]} and {tri[2]} are collinear "
        f"({_fmt(s[tri[0]])}, {_fmt(s[tri[1]])}, {_fmt(s[tri[2]])})",
        record=b + record_offset,
        points=tri,
    )


def _fmt(p: NDArray[np.float64]) -> str:
    x, y = (int(v) if float(v).is_integer() else float(v) for v in p)
    return f"({x}, {y})"
