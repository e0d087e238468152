"""The generator's figures of merit: MP of point sets and the signed margin to a target order type.

All use the smallest height of a triangle, ``|D| / longest side``, from
:mod:`ottag_db.core.geometry`. Grid units are the coordinates of the 256 × 256 grid,
[0, GRID_MAX].
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import triple_figures, triple_indices, triple_orientations

__all__ = ["GRID_MAX", "grid_mp", "relative_mp", "signed_mp_terms", "triple_signs", "triple_table"]

#: Largest coordinate of the 8-bit grid; points live in [0, GRID_MAX]².
GRID_MAX = 255


# A constant index table of k, built once per k and read-only.
@lru_cache(maxsize=16)
def triple_table(k: int) -> NDArray[np.intp]:
    """The triples ``a < b < c`` of :func:`~ottag_db.core.geometry.triple_indices` as one
    contiguous ``(C(k, 3), 3)`` table, the form the compiled loops of the generator read.

    Parameters
    ----------
    k : int
        Number of points.

    Returns
    -------
    ndarray of intp, shape (C(k, 3), 3)
        One row ``(a, b, c)`` per triple (read-only).
    """
    out = np.ascontiguousarray(np.stack(triple_indices(k), axis=1).astype(np.intp))
    out.flags.writeable = False
    return out


def triple_signs(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Orientation sign of every triple ``a < b < c`` of each set.

    Parameters
    ----------
    points : ndarray of float64, shape (..., k, 2)
        Point sets (any units; screen coordinates).

    Returns
    -------
    ndarray of float64, shape (..., C(k, 3))
        −1 where ``c`` is left of ``a → b``, +1 where right, 0 when collinear.
    """
    d, _ = triple_figures(points)
    out: NDArray[np.float64] = np.sign(d)
    return out


def signed_mp_terms(points: NDArray[np.float64], signs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Half the smallest height of every triple, negative when its orientation is wrong.

    Parameters
    ----------
    points : ndarray of float64, shape (..., k, 2)
        Point sets (grid units).
    signs : ndarray of float64, shape (..., C(k, 3))
        Target orientation signs (see :func:`triple_signs`), broadcast against ``points``.

    Returns
    -------
    ndarray of float64, shape (..., C(k, 3))
        ``0.5 · sign · D / longest side`` (grid units); −inf for a triple with repeated
        points. The minimum over the last axis is the set's MP when every orientation
        agrees with ``signs`` and ≤ 0 otherwise.
    """
    d, longest = triple_figures(points)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms: NDArray[np.float64] = np.where(longest > 0, 0.5 * signs * d / longest, -np.inf)
    return terms


def grid_mp(points: ArrayLike, signs: ArrayLike | None = None) -> NDArray[np.float64]:
    """MP of each set, or its signed margin to target orientations.

    Parameters
    ----------
    points : array_like, shape (B, k, 2)
        Point sets (grid units, or any units).
    signs : array_like, shape (B, C(k, 3)), optional
        Target orientation signs (see :func:`triple_signs`).

    Returns
    -------
    ndarray of float64, shape (B,)
        Without ``signs``: the MP (half the smallest point-to-line distance, units of
        ``points``). With ``signs``: the same for a set whose orientations all agree with
        ``signs``, a value ≤ 0 for any other.
    """
    pts = np.asarray(points, dtype=np.float64)
    if signs is None:
        d, longest = triple_figures(pts)
        with np.errstate(divide="ignore", invalid="ignore"):
            terms = np.where(longest > 0, 0.5 * np.abs(d) / longest, 0.0)
        out: NDArray[np.float64] = terms.min(axis=-1)
        return out
    res: NDArray[np.float64] = signed_mp_terms(pts, np.asarray(signs, dtype=np.float64)).min(axis=-1)
    return res


def relative_mp(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """MP of each set divided by the larger side of its bounding box (scale-free).

    Parameters
    ----------
    points : ndarray of float64, shape (B, n, 2)
        Point sets (any units).

    Returns
    -------
    ndarray of float64, shape (B,)
        MP over the bounding box's larger side (unitless).
    """
    # The enumeration keeps, per order type, the candidate with the largest value: its
    # choices (and so the bundled data) depend on the roundings of the products form of D
    # (triple_orientations), not the differences form of grid_mp.
    d = triple_orientations(points)
    _, longest = triple_figures(points)
    with np.errstate(divide="ignore", invalid="ignore"):
        heights = np.where(longest > 0, np.abs(d) / longest, 0.0)
    extent = (points.max(axis=1) - points.min(axis=1)).max(axis=1)
    out: NDArray[np.float64] = 0.5 * heights.min(axis=1) / extent
    return out
