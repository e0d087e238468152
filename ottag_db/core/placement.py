"""Placement: the affine map that puts a point set into the data area with the largest printed MP."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import as_point_batch
from ottag_db.errors import ExportError, UsageError

__all__ = ["DEFAULT_INNER_MARGIN", "apply_placements", "tag_placement", "tag_placements"]

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


def _placement_mp(
    pts: NDArray[np.float64], h: NDArray[np.float64], params: NDArray[np.float64], usable: float
) -> NDArray[np.float64]:
    """Printed MP (data-area units) of each set under each candidate map: ``(B, G)``.

    ``pts`` ``(B, k, 2)``; ``h`` ``(B, E)`` = min over third points of |orientation| for the
    edge ``e``; ``params`` ``(B, G, 3)`` or ``(G, 3)`` rows ``(u, w, log r)`` of the map
    ``[[1, u], [w, r]]``. The mapped set is scaled so its bounding box's larger side is
    ``usable``; maps with ``det ≤ 0.25`` score −inf.
    """
    k = pts.shape[1]
    i, j = np.triu_indices(k, 1)
    e = pts[:, j] - pts[:, i]  # (B, E, 2)
    if params.ndim == 2:
        params = np.broadcast_to(params, (pts.shape[0], *params.shape))
    u = params[..., 0, None]  # (B, G, 1)
    w = params[..., 1, None]
    r = np.exp(params[..., 2, None])
    ex, ey = e[:, None, :, 0], e[:, None, :, 1]  # (B, 1, E)
    length = np.hypot(ex + u * ey, w * ex + r * ey)  # (B, G, E)
    det = (r - u * w)[..., 0]  # (B, G)
    mp = 0.5 * det * (h[:, None, :] / length).min(axis=2)
    x, y = pts[:, None, :, 0], pts[:, None, :, 1]  # (B, 1, k)
    qx = x + u * y
    qy = w * x + r * y
    extent = np.maximum(qx.max(axis=2) - qx.min(axis=2), qy.max(axis=2) - qy.min(axis=2))
    result: NDArray[np.float64] = np.where(det > _MIN_DET, mp * usable / extent, -np.inf)
    return result


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
    lo = np.array([-_U_RANGE, -_U_RANGE, -np.log(_R_RANGE)])
    hi = -lo
    n_grid = 7
    axes = [np.linspace(lo[c], hi[c], n_grid) for c in range(3)]
    params = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)  # (G, 3)
    chunk = 512
    best = np.empty((b, 3))
    for s in range(0, b, chunk):
        mp = _placement_mp(pts[s : s + chunk], h[s : s + chunk], params, usable)
        best[s : s + chunk] = params[mp.argmax(axis=1)]
    step = (hi - lo) / (n_grid - 1)
    offs = np.stack(np.meshgrid(*([np.linspace(-1.0, 1.0, 5)] * 3), indexing="ij"), axis=-1).reshape(-1, 3)
    for _ in range(4):
        step = step / 2.0
        cand = np.clip(best[:, None, :] + offs[None] * step, lo, hi)  # (B, 125, 3)
        for s in range(0, b, chunk):
            c = cand[s : s + chunk]
            mp = _placement_mp(pts[s : s + chunk], h[s : s + chunk], c, usable)
            best[s : s + chunk] = c[np.arange(len(c)), mp.argmax(axis=1)]
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
