"""One measured point set (float pixels): orientation table, margin, λ and canonical orderings.

The batch functions of :mod:`ottag_db.core.geometry` serve the database (many exact integer
sets at once); a decoder reads one set of sub-pixel points at a time, and needs its margin and
its λ from *one* orientation table, so that the ID and the distance that says how sure the ID
is cannot disagree. This module is that single-set path, shared by the decoder's reading and
by its check of a mapped realization.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.canonical import lambda_orderings

__all__ = ["MAX_TABLE_POINTS", "OrientationTable", "PairTable", "margin", "orientation_table", "pair_table", "read_set"]

_F64 = NDArray[np.float64]

#: Pair tables of up to this many points are built once at import (a tag has at most 8 points;
#: larger sets build theirs per call).
MAX_TABLE_POINTS = 16


@dataclass(frozen=True)
class PairTable:
    """Pairs ``i < j`` of ``k`` points (``np.triu_indices(k, 1)`` order) and the ``(P, k)`` mask
    ``own`` of (pair, point) entries where the point is one of the pair. Arrays are read-only."""

    first: NDArray[np.intp]
    second: NDArray[np.intp]
    own: NDArray[np.bool_]


def _build_pair_table(k: int) -> PairTable:
    first, second = np.triu_indices(k, 1)
    idx = np.arange(k)
    own = (idx[None, :] == first[:, None]) | (idx[None, :] == second[:, None])
    for arr in (first, second, own):
        arr.flags.writeable = False
    return PairTable(first, second, own)


_PAIR_TABLES: tuple[PairTable, ...] = tuple(_build_pair_table(k) for k in range(MAX_TABLE_POINTS + 1))


def pair_table(k: int) -> PairTable:
    """The :class:`PairTable` of ``k`` points (a shared read-only table for small ``k``).

    Parameters
    ----------
    k : int
        Number of points (>= 0).

    Returns
    -------
    PairTable
        The pairs ``i < j`` and the own-point mask.
    """
    return _PAIR_TABLES[k] if k <= MAX_TABLE_POINTS else _build_pair_table(k)


@dataclass(frozen=True)
class OrientationTable:
    """Orientations of one point set against every pair of its points.

    - ``pairs``: the :class:`PairTable` of the set;
    - ``cross``: ``(P, k)`` float64, ``(xj−xi)(yp−yi) − (yj−yi)(xp−xi)`` for pair ``(i, j)`` and
      point ``p`` (screen convention, x right, y down: negative = ``p`` left of ``i → j``;
      exactly 0 where ``p`` is ``i`` or ``j``);
    - ``distance``: ``(P, k)`` distance (coordinate units, e.g. px) from point ``p`` to the line
      through ``i`` and ``j``; ``inf`` where ``p`` is ``i`` or ``j``;
    - ``margin``: the smallest ``distance`` (twice the maximal perturbation, MP, of the set);
      0 when three points are collinear or two coincide.
    """

    pairs: PairTable
    cross: _F64
    distance: _F64
    margin: float

    def lambda_matrix(self) -> NDArray[np.int64]:
        """λ-matrix of the set (``(k, k)``: entry ``(i, j)`` = points left of ``i → j``).

        Returns
        -------
        numpy.ndarray
            ``(k, k)`` int64, diagonal 0; meaningful only when ``margin > 0``.
        """
        pr = self.pairs
        k = self.cross.shape[1]
        left = np.count_nonzero((self.cross < 0) & ~pr.own, axis=1)
        lam = np.zeros((k, k), dtype=np.int64)
        lam[pr.first, pr.second] = left
        lam[pr.second, pr.first] = k - 2 - left
        return lam


def orientation_table(points: ArrayLike) -> OrientationTable:
    """The :class:`OrientationTable` of one ``(k, 2)`` point set.

    Parameters
    ----------
    points : array_like
        ``(k, 2)`` coordinates (any unit; image pixels in the decoder), screen convention.

    Returns
    -------
    OrientationTable
        Orientation values, point-to-line distances and the margin (same unit as ``points``).
    """
    pts = np.asarray(points, dtype=np.float64)
    pr = pair_table(len(pts))
    a = pts[pr.first]
    d = pts[pr.second] - a
    cross = d[:, None, 0] * (pts[None, :, 1] - a[:, None, 1]) - d[:, None, 1] * (pts[None, :, 0] - a[:, None, 0])
    ln = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
    dist = np.abs(cross) / ln[:, None]
    dist[pr.own] = np.inf
    return OrientationTable(pr, cross, dist, float(dist.min()))


def margin(points: ArrayLike) -> float:
    """Smallest distance from a point of the set to the line through two others.

    Parameters
    ----------
    points : array_like
        ``(k, 2)`` coordinates.

    Returns
    -------
    float
        The margin in the unit of ``points`` (twice the set's MP).
    """
    return orientation_table(points).margin


def read_set(points: ArrayLike) -> tuple[OrientationTable, list[tuple[tuple[int, ...], NDArray[np.int8]]]]:
    """Orientation table and the canonical orderings of one set, smallest λ first.

    λ comes from the orientation table the margin is computed from (one table for both);
    the orderings are :func:`ottag_db.core.canonical.lambda_orderings` of that λ.

    Parameters
    ----------
    points : array_like
        ``(k, 2)`` coordinates.

    Returns
    -------
    tuple
        The :class:`OrientationTable` and a list of ``(labeling, λ-matrix)`` (``labeling[l]``
        is the input index of the point with label ``l``; int8 matrices), empty when the
        margin is not positive (the set is not in general position).
    """
    table = orientation_table(points)
    if not table.margin > 0:
        return table, []
    return table, lambda_orderings(table.lambda_matrix())
