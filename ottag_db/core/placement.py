"""Placement: the affine map that puts a point set into the data area with the largest printed MP."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import as_point_batch
from ottag_db.errors import ExportError, UsageError

__all__ = ["DEFAULT_INNER_MARGIN", "apply_placements", "mirrored_placements", "tag_placement", "tag_placements"]

#: Default smallest distance between a point and the data-area border, in data-area units.
DEFAULT_INNER_MARGIN = 0.10

# Placement search: x' = x + u·y, y' = w·x + r·y (then uniform scale and translation).
_U_RANGE = 0.5
_R_RANGE = 2.0
_MIN_DET = 0.25


def _candidate_maps(u: NDArray[np.float64], w: NDArray[np.float64], r: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(..., 2, 2)`` linear maps [[1, u], [w, r]]."""
    a = np.empty((*u.shape, 2, 2))
    a[..., 0, 0] = 1.0
    a[..., 0, 1] = u
    a[..., 1, 0] = w
    a[..., 1, 1] = r
    return a


@dataclass(frozen=True)
class _Edges:
    """Per-set inputs of the printed-MP formula, restricted to the edges that can bind.

    ``e`` ``(B, K, 2)`` edge vectors and ``h`` ``(B, K)`` their smallest |orientation| with a
    third point, for the ``K`` edges of smallest ``h / |e|`` (the edges of the whole set when
    ``K = E``); ``bound`` ``(B,)`` is the ``(K+1)``-th smallest ``h / |e|`` (inf when every
    edge is kept). Under a linear map ``A`` an edge's ratio ``h / |A e|`` is at least
    ``(h / |e|) / σmax(A)``, so a left-out edge cannot be the minimum when the kept minimum is
    at most ``bound / σmax(A)``: then the value is exact (the minimum over the same floats).
    """

    e: NDArray[np.float64]
    h: NDArray[np.float64]
    bound: NDArray[np.float64]

    def rows(self, sel: slice | NDArray[np.intp]) -> _Edges:
        """The same for the sets ``sel``."""
        return _Edges(self.e[sel], self.h[sel], self.bound[sel])


#: A batch of candidate maps as three axes, ``(B, Nu)`` values of ``u``, ``(B, Nw)`` of ``w``
#: and ``(B, Nr)`` of ``log r``: candidate ``iu·Nw·Nr + iw·Nr + ir`` is their combination.
_Axes = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


def _placement_mp(
    pts: NDArray[np.float64], edges: _Edges, axes: _Axes, usable: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Printed MP (data-area units) of each set under each candidate map, and its exactness.

    ``pts`` ``(B, k, 2)``; ``edges`` the sets' kept edges (see :class:`_Edges`); ``axes`` the
    candidate maps ``[[1, u], [w, r]]`` (see :data:`_Axes`). The mapped set is scaled so its
    bounding box's larger side is ``usable``; maps with ``det ≤ 0.25`` score −inf. Returns
    ``(B, G)`` values, each at least the MP over every edge, and ``(B, G)`` flags of the
    values that equal it exactly (``G = Nu·Nw·Nr``).
    """
    b = pts.shape[0]
    # Edges and points lead the axes: the reductions over them are then elementwise
    # min/max of contiguous slices, much faster than reducing a short last axis. What
    # depends on u alone or on (w, r) alone is computed once per value, not per candidate.
    u = axes[0][:, :, None, None]  # (B, Nu, 1, 1)
    w = axes[1][:, None, :, None]  # (B, 1, Nw, 1)
    r = np.exp(axes[2])[:, None, None, :]  # (B, 1, 1, Nr)
    e = edges.e.transpose(1, 0, 2)[:, :, None, None, None, :]  # (K, B, 1, 1, 1, 2)
    ex, ey = e[..., 0], e[..., 1]
    length = np.hypot(ex + u * ey, w * ex + r * ey)  # (K, B, Nu, Nw, Nr)
    det = r - u * w  # (B, Nu, Nw, Nr)
    ratio = (edges.h.T[:, :, None, None, None] / length).min(axis=0)
    mp = 0.5 * det * ratio
    q = pts.transpose(1, 0, 2)[:, :, None, None, None, :]  # (k, B, 1, 1, 1, 2)
    x, y = q[..., 0], q[..., 1]
    qx = x + u * y  # (k, B, Nu, 1, 1)
    qy = w * x + r * y  # (k, B, 1, Nw, Nr)
    extent = np.maximum(qx.max(axis=0) - qx.min(axis=0), qy.max(axis=0) - qy.min(axis=0))
    ok = det > _MIN_DET
    value: NDArray[np.float64] = np.where(ok, mp * usable / extent, -np.inf)
    # largest singular value of [[1, u], [w, r]]: σ² = (F + √(F² − 4 det²)) / 2, F = Frobenius²
    fro = 1.0 + u * u + w * w + r * r
    smax = np.sqrt(0.5 * (fro + np.sqrt(np.maximum(fro * fro - 4.0 * det * det, 0.0))))
    exact = ~ok | (ratio <= edges.bound[:, None, None, None] / smax * (1.0 - 1e-9))
    return value.reshape(b, -1), exact.reshape(b, -1)


def _best(pts: NDArray[np.float64], kept: _Edges, full: _Edges, axes: _Axes, usable: float) -> NDArray[np.float64]:
    """The best candidate ``(u, w, log r)`` of each set, ``(B, 3)``, as a search over every edge.

    The kept-edge value is an upper bound of the true one; where the argmax is exact it is
    the true argmax (every other candidate's true value is at most its bound, and ties go to
    the first index either way); the few sets whose argmax is not exact are searched again
    over every edge.
    """
    value, exact = _placement_mp(pts, kept, axes, usable)
    best = value.argmax(axis=1)
    redo = np.flatnonzero(~exact[np.arange(len(best)), best])
    if redo.size:
        sub: _Axes = (axes[0][redo], axes[1][redo], axes[2][redo])
        best[redo] = _placement_mp(pts[redo], full.rows(redo), sub, usable)[0].argmax(axis=1)
    iu, iw, ir = np.unravel_index(best, (axes[0].shape[1], axes[1].shape[1], axes[2].shape[1]))
    rows = np.arange(len(best))
    return np.stack([axes[0][rows, iu], axes[1][rows, iw], axes[2][rows, ir]], axis=1)


#: Edges kept per set in the search (the rest are checked by a bound, see :class:`_Edges`).
_KEPT_EDGES = 8


def tag_placements(points_batch: ArrayLike, inner_margin: float = DEFAULT_INNER_MARGIN) -> NDArray[np.float64]:
    """Affine maps ``(B, 2, 3)`` taking file coordinates to data-area unit coordinates.

    Unit coordinates: x right, y down, origin at the top-left corner of the data area, the
    data area is [0, 1]². A point ``p`` goes to ``M[:, :2] @ p + M[:, 2]``. The map is
    ``s · A`` followed by a translation, with ``A = [[1, u], [w, r]]`` (shear and
    non-uniform scale, ``|u|, |w| ≤ 0.5``, ``0.5 ≤ r ≤ 2``, ``det A > 0.25`` — orientation is
    kept, so the order type is unchanged and not mirrored). ``A`` maximises the printed MP
    (7 × 7 × 7 grid search, then four local 5 × 5 × 5 refinements, batched over sets); ``s``
    makes the larger side of the bounding box ``1 − 2 · inner_margin`` and the box is
    centred, so every point keeps at least ``inner_margin`` from the border.

    Each candidate map is scored on the 8 edges of smallest ``h / |e|`` only; a bound on the
    other edges proves the best candidate's score exact, and the rare sets where it cannot
    are scored again on every edge — so the maps are exactly those of the search over every
    edge (bit for bit), several times faster (k = 9: 36 edges).

    Parameters
    ----------
    points_batch : array_like, shape (B, k, 2)
        Point sets in general position, file coordinates (grid units; screen convention).
    inner_margin : float, optional
        Smallest distance between a point and the data-area border, in data-area units
        (fraction of its side), in [0, 0.5).

    Returns
    -------
    ndarray of float64, shape (B, 2, 3)
        One affine map per set, file coordinates → data-area unit coordinates.

    Raises
    ------
    UsageError
        For ``inner_margin`` outside [0, 0.5).
    ExportError
        For a set that is not in general position.
    """
    if not 0.0 <= inner_margin < 0.5:
        raise UsageError(f"inner margin must be in [0, 0.5) of the data-area side, got {inner_margin}")
    pts, _ = as_point_batch(points_batch)
    b, k, _ = pts.shape
    usable = 1.0 - 2.0 * inner_margin
    i, j = np.triu_indices(k, 1)
    # h[b, e] = min over third points p of |orient(i, j, p)|
    x, y = pts[..., 0], pts[..., 1]
    m = x[:, :, None] * y[:, None, :] - y[:, :, None] * x[:, None, :]
    d = np.abs(m[:, i, j][:, :, None] + (m[:, j, :] - m[:, i, :]))  # (B, E, k)
    d[:, np.arange(len(i)), i] = np.inf
    d[:, np.arange(len(i)), j] = np.inf
    h = d.min(axis=2)
    if np.any(h == 0):
        raise ExportError("cannot place a point set that is not in general position")
    e = pts[:, j] - pts[:, i]  # (B, E, 2)
    full = _Edges(e, h, np.full(b, np.inf))
    kept = full
    if len(i) > _KEPT_EDGES:
        ratio = h / np.hypot(e[..., 0], e[..., 1])
        order = np.argsort(ratio, axis=1, kind="stable")
        top = order[:, :_KEPT_EDGES]
        rows = np.arange(b)[:, None]
        kept = _Edges(e[rows, top], h[rows, top], ratio[np.arange(b), order[:, _KEPT_EDGES]])
    lo = np.array([-_U_RANGE, -_U_RANGE, -np.log(_R_RANGE)])
    hi = -lo
    n_grid = 7
    grid = [np.linspace(lo[c], hi[c], n_grid) for c in range(3)]
    # small chunks keep the (K, chunk, G) temporaries in cache; results do not depend on it
    chunk = 64
    best = np.empty((b, 3))
    for s in range(0, b, chunk):
        part = slice(s, s + chunk)
        n = len(pts[part])
        axes: _Axes = (
            np.broadcast_to(grid[0], (n, n_grid)),
            np.broadcast_to(grid[1], (n, n_grid)),
            np.broadcast_to(grid[2], (n, n_grid)),
        )
        best[part] = _best(pts[part], kept.rows(part), full.rows(part), axes, usable)
    step = (hi - lo) / (n_grid - 1)
    offs = np.linspace(-1.0, 1.0, 5)
    for _ in range(4):
        step = step / 2.0
        # 5 × 5 × 5 candidates around the best so far, each parameter kept in its range
        cand = [np.clip(best[:, c, None] + offs[None] * step[c], lo[c], hi[c]) for c in range(3)]  # 3 × (B, 5)
        for s in range(0, b, chunk):
            part = slice(s, s + chunk)
            best[part] = _best(
                pts[part], kept.rows(part), full.rows(part), (cand[0][part], cand[1][part], cand[2][part]), usable
            )
    a = _candidate_maps(best[:, 0], best[:, 1], np.exp(best[:, 2]))  # (B, 2, 2)
    q = np.einsum("bxy,bky->bkx", a, pts)
    lo_q, hi_q = q.min(axis=1), q.max(axis=1)
    scale = usable / (hi_q - lo_q).max(axis=1)
    centre = 0.5 * (lo_q + hi_q)
    out = np.empty((b, 2, 3))
    out[:, :, :2] = scale[:, None, None] * a
    out[:, :, 2] = 0.5 - scale[:, None] * centre
    return out


def tag_placement(points: ArrayLike, inner_margin: float = DEFAULT_INNER_MARGIN) -> NDArray[np.float64]:
    """Affine map of one point set into the data area; see :func:`tag_placements`.

    Parameters
    ----------
    points : array_like, shape (k, 2)
        One point set in general position, file coordinates (grid units).
    inner_margin : float, optional
        Smallest distance between a point and the border, data-area units.

    Returns
    -------
    ndarray of float64, shape (2, 3)
        The map ``p ↦ M[:, :2] @ p + M[:, 2]`` to data-area unit coordinates (x right, y
        down, the data area is [0, 1]²).
    """
    arr = np.asarray(points)
    if arr.ndim != 2:
        raise ValueError(f"tag_placement takes one point set of shape (k, 2), got {arr.shape}")
    return np.asarray(tag_placements(arr[None], inner_margin)[0], dtype=np.float64)


def apply_placements(maps: ArrayLike, points_batch: ArrayLike) -> NDArray[np.float64]:
    """Points of each set in data-area units: ``M[:, :2] @ p + M[:, 2]`` per set.

    Parameters
    ----------
    maps : array_like, shape (B, 2, 3)
        Affine maps as :func:`tag_placements` returns them (file coordinates → data-area units).
    points_batch : array_like, shape (B, k, 2)
        The sets in file coordinates (grid units), file order.

    Returns
    -------
    ndarray of float64, shape (B, k, 2)
        The placed points: x right, y down, the data area is [0, 1]².
    """
    m = np.asarray(maps, dtype=np.float64)
    pts = np.asarray(points_batch, dtype=np.float64)
    placed: NDArray[np.float64] = np.einsum("bxy,bky->bkx", m[:, :, :2], pts) + m[:, None, :, 2]
    return placed


def mirrored_placements(maps: ArrayLike, axis_sums: ArrayLike) -> NDArray[np.float64]:
    """Placements of mirror images: each the original's placed tag reflected in the data area.

    A set ``p`` and its mirror image ``q`` (``q_x = c − p_x``, ``q_y = p_y``) have the same
    placement problem reflected, so the original's map ``M``, followed by ``x ↦ 1 − x`` in the
    data area, places ``q``: the mirror's printed tag is the mirror image of the original's,
    with the same printed MP. The map stays of the form ``s · [[1, u], [w, r]]`` plus a
    translation (``u`` and ``w`` change sign, the determinant is kept).

    Parameters
    ----------
    maps : array_like, shape (B, 2, 3)
        Placements of the original sets, as :func:`tag_placements` returns them.
    axis_sums : array_like, shape (B,)
        ``c = p_x + q_x`` of each pair (file coordinates; the largest coordinate of the file
        for a mirror made as ``x → max − x``).

    Returns
    -------
    ndarray of float64, shape (B, 2, 3)
        Maps of the mirror images, file coordinates → data-area units.
    """
    m = np.asarray(maps, dtype=np.float64)
    c = np.asarray(axis_sums, dtype=np.float64)
    out = m.copy()
    out[:, 0, 1] = -m[:, 0, 1]
    out[:, 1, 0] = -m[:, 1, 0]
    out[:, 0, 2] = 1.0 - m[:, 0, 2] - m[:, 0, 0] * c
    out[:, 1, 2] = m[:, 1, 2] + m[:, 1, 0] * c
    return out
