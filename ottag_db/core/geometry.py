"""Batched plane geometry of point sets: orientations, λ-matrices, hulls and MP (no I/O).

Conventions: screen coordinates (x right, y down); ``p`` is *left* of the directed line
``p_i → p_j`` when ``(xj−xi)(yp−yi) − (yj−yi)(xp−xi) < 0``. Lengths are in the units of the
input coordinates (grid units for point-file coordinates).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.errors import GeneralPositionError

__all__ = [
    "PointSetAnalysis",
    "analyse_point_sets",
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
    "segment_distances",
    "triple_figures",
    "triple_indices",
    "triple_orientations",
]

TripleIndex = tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]


def as_point_batch(points: ArrayLike) -> tuple[NDArray[np.float64], bool]:
    """Return ``points`` as a float64 ``(B, n, 2)`` batch and whether the input was one set.

    Parameters
    ----------
    points : array_like
        One set ``(n, 2)`` or a batch ``(B, n, 2)`` of ``n ≥ 3`` points (any units).

    Returns
    -------
    batch : ndarray of float64, shape (B, n, 2)
        The coordinates, C-contiguous. Integer coordinates up to 16 bits are represented
        exactly, and every orientation computed from them in this module is exact too
        (products stay below 2**53).
    single : bool
        True when ``points`` was one ``(n, 2)`` set (then ``B = 1``).
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


# A pure constant table of n (no state): cached so the hot loops of the generator do not
# rebuild it per call; the arrays are read-only, so sharing them cannot leak changes.
@cache
def triple_indices(n: int) -> TripleIndex:
    """The index triples ``a < b < c`` of ``n`` points, in lexicographic order.

    Parameters
    ----------
    n : int
        Number of points.

    Returns
    -------
    a, b, c : ndarray of intp, shape (C(n, 3),) each
        Read-only; triple ``t`` is ``(a[t], b[t], c[t])``. The order is the one of
        ``itertools.combinations(range(n), 3)``.
    """
    idx = np.arange(n)
    ga, gb, gc = np.meshgrid(idx, idx, idx, indexing="ij")
    keep = (ga < gb) & (gb < gc)
    out = (ga[keep], gb[keep], gc[keep])
    for arr in out:
        arr.flags.writeable = False
    return out


def triple_orientations(points: ArrayLike) -> NDArray[np.float64]:
    """:func:`orientation_tensor` at the triples ``a < b < c`` only, without the ``n³`` tensor.

    The same products form and the same order of additions, so the values are bit-for-bit
    those of ``orientation_tensor(points)[:, a, b, c]`` (exact for integer coordinates below
    2**16, identical roundings for real-valued ones).

    Parameters
    ----------
    points : array_like, shape (n, 2) or (B, n, 2)
        Point sets (any units, screen coordinates).

    Returns
    -------
    ndarray of float64, shape (B, C(n, 3))
        ``D[b, t]`` in squared units, triples in the order of :func:`triple_indices`;
        ``c`` is left of ``a → b`` when ``D < 0``.
    """
    pts, _ = as_point_batch(points)
    x = pts[..., 0]
    y = pts[..., 1]
    a, b, c = triple_indices(pts.shape[1])
    m_ab = x[:, a] * y[:, b] - y[:, a] * x[:, b]
    m_bc = x[:, b] * y[:, c] - y[:, b] * x[:, c]
    m_ca = x[:, c] * y[:, a] - y[:, c] * x[:, a]
    d: NDArray[np.float64] = m_ab + m_bc + m_ca
    return d


def triple_figures(points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Signed orientation and longest side of every triple ``a < b < c`` of each set.

    The orientation is computed in the differences form
    ``D = (xb−xa)(yc−ya) − (yb−ya)(xc−xa)`` (twice the signed area; ``c`` is left of
    ``a → b`` when ``D < 0``, screen coordinates), from the same side vectors as the
    longest side. The smallest height of the triangle is ``|D| / longest``, so half the
    minimum of it over all triples is the MP. Exact for integer coordinates below 2**16,
    where it equals :func:`triple_orientations`; for real-valued points the two forms round
    differently. The generator's continuous optimisation uses this form and its results
    (the bundled data) depend on those roundings, so both forms are kept.

    Parameters
    ----------
    points : array_like, shape (..., n, 2)
        Point sets with any leading batch dimensions (any units, e.g. grid units).

    Returns
    -------
    orientation : ndarray of float64, shape (..., C(n, 3))
        ``D`` of each triple in the order of :func:`triple_indices` (squared units).
    longest : ndarray of float64, shape (..., C(n, 3))
        Length of the longest side of each triple (units of ``points``).
    """
    pts = np.asarray(points, dtype=np.float64)
    a, b, c = triple_indices(pts.shape[-2])
    pa, pb, pc = pts[..., a, :], pts[..., b, :], pts[..., c, :]
    ab = pb - pa
    ac = pc - pa
    bc = pc - pb
    d: NDArray[np.float64] = ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0]
    longest: NDArray[np.float64] = np.sqrt(
        np.maximum(np.maximum((ab * ab).sum(-1), (ac * ac).sum(-1)), (bc * bc).sum(-1))
    )
    return d, longest


def orientation_tensor(points: ArrayLike) -> NDArray[np.float64]:
    """Signed orientation ``D[b, i, j, p] = (xj−xi)(yp−yi) − (yj−yi)(xp−xi)`` of every triple.

    Screen convention (x right, y down): ``p`` is *left* of the directed line
    ``p_i → p_j`` when ``D < 0``. Computed as ``M[i,j] + M[j,p] + M[p,i]`` with
    ``M[a,b] = xa·yb − ya·xb``, which is exact for integer coordinates below 2**16.

    Parameters
    ----------
    points : array_like, shape (n, 2) or (B, n, 2)
        Point sets (any units).

    Returns
    -------
    ndarray of float64, shape (B, n, n, n)
        ``D`` in squared units of ``points`` (a single set gives ``B = 1``); 0 wherever
        two of ``i, j, p`` coincide.
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
    """One pass over a batch of ``B`` sets of ``n`` points (see :func:`analyse_point_sets`).

    - ``lambdas``: ``(B, n, n)`` int8 λ-matrices (meaningful where ``general_position``);
    - ``general_position``: ``(B,)`` bool, no repeated point and no collinear triple;
    - ``mp``: ``(B,)`` float64 MP in the units of the coordinates, 0 where not in general
      position.
    """

    lambdas: NDArray[np.int8]
    general_position: NDArray[np.bool_]
    mp: NDArray[np.float64]


def analyse_point_sets(points: ArrayLike) -> PointSetAnalysis:
    """λ-matrices, general-position mask and MP of a batch from one orientation pass.

    Cheaper than calling :func:`lambda_matrices`, :func:`general_position_mask` and
    :func:`maximal_perturbations` separately (the importer's hot path).

    Parameters
    ----------
    points : array_like, shape (B, n, 2)
        Point sets (file coordinates: grid units).

    Returns
    -------
    PointSetAnalysis
        λ-matrices, general-position flags and MP (units of ``points``) of every set.
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
    """λ-matrices: ``L[b, i, j]`` = number of points left of ``p_i → p_j`` (diagonal 0).

    Only pairs ``i < j`` are evaluated: in general position ``L[j, i] = n − 2 − L[i, j]``.

    Parameters
    ----------
    points : array_like, shape (B, n, 2)
        Point sets in general position (see :func:`check_general_position`), screen
        coordinates.

    Returns
    -------
    ndarray of int8, shape (B, n, n)
        The λ-matrices in input point order.
    """
    pts, _ = as_point_batch(points)
    d, first, second = _upper_orientations(pts)
    return _lambda_from_upper(d, first, second, pts.shape[1])


def lambda_matrix(points: ArrayLike) -> NDArray[np.int8]:
    """λ-matrix of one point set (see :func:`lambda_matrices`).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        One point set in general position, screen coordinates.

    Returns
    -------
    ndarray of int8, shape (n, n)
        Its λ-matrix.
    """
    pts = np.asarray(points)
    if pts.ndim != 2:
        raise ValueError("lambda_matrix takes one point set of shape (n, 2)")
    single: NDArray[np.int8] = lambda_matrices(pts[None])[0]
    return single


def hull_sizes(lam: NDArray[np.integer]) -> NDArray[np.int64]:
    """Number of convex-hull vertices of each set, from its λ-matrix.

    A point is a hull vertex exactly when the line to one of its neighbours has all other
    ``n − 2`` points on its left.

    Parameters
    ----------
    lam : ndarray of int, shape (B, n, n)
        λ-matrices of sets in general position.

    Returns
    -------
    ndarray of int64, shape (B,)
        Hull vertex counts.
    """
    n = lam.shape[-1]
    on_hull = (lam == n - 2).any(axis=2)
    counts: NDArray[np.int64] = on_hull.sum(axis=1).astype(np.int64)
    return counts


def hull_size(points: ArrayLike) -> int:
    """Number of convex-hull vertices of one point set.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        One point set in general position.

    Returns
    -------
    int
        Hull vertex count.
    """
    return int(hull_sizes(lambda_matrix(points)[None])[0])


def _pair_lengths(pts: NDArray[np.float64]) -> NDArray[np.float64]:
    diff = pts[:, :, None, :] - pts[:, None, :, :]
    lengths: NDArray[np.float64] = np.sqrt((diff * diff).sum(axis=3))
    return lengths


def maximal_perturbations(points: ArrayLike) -> NDArray[np.float64]:
    """MP of each set: half the smallest distance from a point to a line through two others.

    Moving every point by less than MP cannot change the order type (paper Sec. 5.3).

    Parameters
    ----------
    points : array_like, shape (B, n, 2)
        Point sets (file coordinates: grid units; placed points: data-area units).

    Returns
    -------
    ndarray of float64, shape (B,)
        MP in the units of ``points``.
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
    """MP of one point set (see :func:`maximal_perturbations`).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        One point set (any units).

    Returns
    -------
    float
        MP in the units of ``points``.
    """
    return float(maximal_perturbations(np.asarray(points)[None])[0])


def general_position_mask(points: ArrayLike, *, tolerance: float = 0.0) -> NDArray[np.bool_]:
    """Which sets have no repeated point and no collinear triple.

    Parameters
    ----------
    points : array_like, shape (B, n, 2)
        Point sets (any units).
    tolerance : float, optional
        Smallest accepted ``|D|`` (twice the triangle area, squared units); 0 means exact.

    Returns
    -------
    ndarray of bool, shape (B,)
        True where the set is in general position.
    """
    pts, _ = as_point_batch(points)
    ok: NDArray[np.bool_] = np.asarray((np.abs(triple_orientations(pts)) > tolerance).all(axis=1), dtype=bool)
    return ok


def check_general_position(points: ArrayLike, *, record_offset: int = 0) -> None:
    """Raise :class:`GeneralPositionError` naming the first bad set and its points.

    Parameters
    ----------
    points : array_like, shape (n, 2) or (B, n, 2)
        Point sets (any units).
    record_offset : int, optional
        Added to the batch index in the error, so callers streaming a file can report the
        record number in the file.

    Raises
    ------
    GeneralPositionError
        For the first set with a repeated point (reported as the pair of 0-based indices)
        or a collinear triple (the three indices).
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
    a, bb, c = triple_indices(n)
    bad = np.flatnonzero(triple_orientations(s[None])[0] == 0)
    t = int(bad[0])
    tri = (int(a[t]), int(bb[t]), int(c[t]))
    raise GeneralPositionError(
        f"record {b + record_offset}: points {tri[0]}, {tri[1]} and {tri[2]} are collinear "
        f"({_fmt(s[tri[0]])}, {_fmt(s[tri[1]])}, {_fmt(s[tri[2]])})",
        record=b + record_offset,
        points=tri,
    )


def segment_distances(points: ArrayLike, starts: ArrayLike, ends: ArrayLike) -> NDArray[np.float64]:
    """Euclidean distance of each point to each segment.

    Parameters
    ----------
    points : array_like
        ``(n, 2)`` points.
    starts, ends : array_like
        ``(m, 2)`` the segments' end points (a segment of zero length is its point).

    Returns
    -------
    numpy.ndarray
        ``(n, m)`` float64 distances.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    a = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
    d = np.asarray(ends, dtype=np.float64).reshape(-1, 2) - a
    rel = pts[:, None, :] - a  # (n, m, 2)
    length2 = np.einsum("md,md->m", d, d)
    t = np.clip(np.einsum("nmd,md->nm", rel, d) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    out: NDArray[np.float64] = np.linalg.norm(rel - t[..., None] * d, axis=2)
    return out


def _fmt(p: NDArray[np.float64]) -> str:
    x, y = (int(v) if float(v).is_integer() else float(v) for v in p)
    return f"({x}, {y})"
