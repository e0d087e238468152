"""Triangle layouts of order-type tags: fewest empty, disjoint triangles covering every point.

The search lives here; what it measures (index tables, per-set figures, the score) in
:mod:`ottag_db.core.layout_figures`; the independent checker :func:`validate_layout` in
:mod:`ottag_db.core.layout_check` (re-exported here, where callers look for it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import as_point_batch, check_general_position, maximal_perturbations
from ottag_db.core.layout_check import validate_layout
from ottag_db.core.layout_figures import (
    SCORE_REFERENCES,
    SetGeometry,
    cover_figures,
    cover_table,
    index_tables,
    layout_score,
)
from ottag_db.core.placement import apply_placements, tag_placements
from ottag_db.core.types import ProgressCallback
from ottag_db.errors import ExportError

__all__ = [
    "LAYOUT_MAX_K",
    "LAYOUT_MIN_K",
    "SCORE_REFERENCES",
    "Layout",
    "compute_layout",
    "compute_layouts",
    "lay_out_and_place",
    "layout_quality",
    "layout_supported",
    "validate_layout",
]

#: Smallest and largest number of points a layout is computed for (k = 4 is refused, see below).
LAYOUT_MIN_K = 3
LAYOUT_MAX_K = 9

Triangle = tuple[int, int, int]

_K4_MESSAGE = (
    "order types with 4 points cannot be drawn as tags: any two triangles on 4 points share an "
    "edge (convex position), or the only triangle holding all points is not empty (one point "
    "inside), so no layout satisfies the tag rules (use k = 3 or 5 … 9)"
)


@dataclass(frozen=True)
class Layout:
    """Triangles drawn for one point set and their quality figures.

    ``triangles`` are index triples into the point set, each sorted ascending, the tuple
    sorted lexicographically. Figures are measured on the points the layout was computed
    for (file / grid units for lengths):

    - ``min_angle_deg``: smallest interior angle of any triangle, degrees;
    - ``min_side``: shortest triangle side, coordinate units;
    - ``min_gap``: smallest distance between two triangles sharing no vertex, coordinate
      units (None when every pair of triangles shares a vertex, e.g. one triangle);
    - ``min_shared_gap_deg``: smallest angle, at a shared vertex, between two triangles
      meeting there (None when no vertex is shared);
    - ``diameter``: largest distance between two points (coordinate units);
    - ``score``: ``min(q) + 0.1 · mean(q)`` over the four terms, each capped at 1,
      ``q_angle = min_angle_deg / 30``, ``q_side = min_side / (0.25 · diameter)``,
      ``q_gap = min_gap / (0.10 · diameter)``, ``q_shared = min_shared_gap_deg / 30``
      (a term that does not apply counts 1); so the score is scale-free and in [0, 1.1].
      The references are :data:`SCORE_REFERENCES`.

    Validity (emptiness, disjointness, no shared edge) is affine-invariant, so a layout
    stays valid under the placement map of the renderer; the figures are not.
    """

    triangles: tuple[Triangle, ...]
    min_angle_deg: float
    min_side: float
    min_gap: float | None
    min_shared_gap_deg: float | None
    diameter: float
    score: float

    @property
    def size(self) -> int:
        """Number of triangles."""
        return len(self.triangles)


def layout_supported(k: int) -> bool:
    """Whether point sets of ``k`` points get a layout.

    Parameters
    ----------
    k : int
        Number of points.

    Returns
    -------
    bool
        True for k = 3 and 5 … 9 (k = 4 cannot be drawn as a tag).
    """
    return LAYOUT_MIN_K <= k <= LAYOUT_MAX_K and k != 4


def _check_k(k: int) -> None:
    if k == 4:
        raise ExportError(_K4_MESSAGE)
    if not LAYOUT_MIN_K <= k <= LAYOUT_MAX_K:
        raise ExportError(f"tag layouts are computed for 3 ≤ k ≤ {LAYOUT_MAX_K} points (k ≠ 4); got k = {k}")


def _make_layout(
    tris: NDArray[np.intp], angle: float, side: float, gap: float, shared: float, diameter: float
) -> Layout:
    score = float(layout_score(np.array(angle), np.array(side / diameter), np.array(gap / diameter), np.array(shared)))
    triangles = tuple(sorted(tuple(sorted(int(i) for i in t)) for t in tris))
    return Layout(
        triangles=triangles,  # type: ignore[arg-type]
        min_angle_deg=float(angle),
        min_side=float(side),
        min_gap=None if math.isinf(gap) else float(gap),
        min_shared_gap_deg=None if math.isinf(shared) else float(shared),
        diameter=float(diameter),
        score=score,
    )


def _solve_more(pts: NDArray[np.float64], m_start: int) -> list[Layout]:
    """Layouts of sets that have none with fewer than ``m_start`` triangles."""
    b, k, _ = pts.shape
    tb = index_tables(k)
    result: list[Layout | None] = [None] * b
    todo = np.arange(b)
    m = m_start
    while todo.size:
        if m > k:
            raise ExportError("no triangle layout exists for a point set of this batch")
        cov = cover_table(k, m)
        if len(cov.cands) == 0:
            m += 1
            continue
        sub = SetGeometry(pts[todo])
        valid, angle, side, gap, shared = cover_figures(sub, cov)
        diam = sub.diameter[:, None]
        score = np.where(valid, layout_score(angle, side / diam, gap / diam, shared), -np.inf)
        best = score.argmax(axis=1)
        found = valid[np.arange(len(todo)), best]
        rows = np.flatnonzero(found)
        cols = best[rows]
        # one conversion per figure for the whole batch (the score is the same float the
        # scalar path of layout_quality computes: elementwise, same reductions)
        figures = zip(
            cols.tolist(),
            angle[rows, cols].tolist(),
            side[rows, cols].tolist(),
            gap[rows, cols].tolist(),
            shared[rows, cols].tolist(),
            sub.diameter[rows].tolist(),
            score[rows, cols].tolist(),
            strict=True,
        )
        tris_of: dict[int, tuple[Triangle, ...]] = {}
        for row, (c, ang, sd, gp, sh, dm, sc) in zip(rows.tolist(), figures, strict=True):
            if c not in tris_of:
                # covers list ascending triangle ids of sorted triples: already in layout order
                tris_of[c] = tuple((int(t[0]), int(t[1]), int(t[2])) for t in tb.tris[cov.cands[c]].tolist())
            result[int(todo[row])] = Layout(
                triangles=tris_of[c],
                min_angle_deg=ang,
                min_side=sd,
                min_gap=None if math.isinf(gp) else gp,
                min_shared_gap_deg=None if math.isinf(sh) else sh,
                diameter=dm,
                score=sc,
            )
        todo = todo[~found]
        m += 1
    return [r for r in result if r is not None]


def compute_layouts(
    points_batch: ArrayLike, progress: ProgressCallback | None = None, *, chunk: int = 256
) -> list[Layout]:
    """Best layout of each of ``B`` point sets given as ``(B, k, 2)`` (3 ≤ k ≤ 9, k ≠ 4).

    Exhaustive over covers of ``m = ⌈k/3⌉, ⌈k/3⌉ + 1, …`` empty triangles (vertex-level
    candidate covers are tabulated once per (k, m); per set only emptiness, crossings and
    the figures are evaluated, batched over ``chunk`` sets). Among valid covers with the
    fewest triangles the highest :attr:`Layout.score` wins; ties go to the lexicographically
    first cover, so results are deterministic. ``progress(done, total)`` is called after each
    chunk. Nine points always get three vertex-disjoint triangles (sorted by x, consecutive
    triples are empty and disjoint), so k = 9 evaluates the 280 partitions into triples only.

    Parameters
    ----------
    points_batch : array_like, shape (B, k, 2)
        Point sets in general position (any units, e.g. grid units; screen coordinates).
    progress : ProgressCallback, optional
        ``progress(done, total)`` in sets, after each chunk.
    chunk : int, optional
        Sets evaluated per batch (bounds the memory).

    Returns
    -------
    list of Layout
        One layout per set, in input order; figures in the units of ``points_batch``.

    Raises
    ------
    ExportError
        For k = 4 or k outside 3 … 9.
    GeneralPositionError
        For a set with a repeated point or a collinear triple.
    """
    pts, _ = as_point_batch(points_batch)
    b, k, _ = pts.shape
    _check_k(k)
    layouts: list[Layout] = []
    for start in range(0, b, chunk):
        part = pts[start : start + chunk]
        check_general_position(part, record_offset=start)
        layouts.extend(_solve_more(part, -(-k // 3)))
        if progress is not None:
            progress(min(start + chunk, b), b)
    if b == 0 and progress is not None:
        progress(0, 0)
    return layouts


def compute_layout(points: ArrayLike) -> Layout:
    """Best layout of one point set; see :func:`compute_layouts`.

    Parameters
    ----------
    points : array_like, shape (k, 2)
        One point set in general position (any units; screen coordinates).

    Returns
    -------
    Layout
        Its layout, figures in the units of ``points``.
    """
    arr = np.asarray(points)
    if arr.ndim != 2:
        raise ValueError(f"compute_layout takes one point set of shape (k, 2), got {arr.shape}")
    return compute_layouts(arr[None])[0]


def layout_quality(points: ArrayLike, triangles: Sequence[Sequence[int]]) -> Layout:
    """Figures and score of a given (assumed valid) layout on ``points`` — e.g. placed points.

    Parameters
    ----------
    points : array_like, shape (k, 2)
        The point set (any units, e.g. data-area units of placed points).
    triangles : sequence of sequence of int
        Index triples into ``points`` (validity is not checked, see
        :func:`validate_layout`).

    Returns
    -------
    Layout
        The triangles (sorted) with their figures measured on ``points``.
    """
    pts, _ = as_point_batch(np.asarray(points)[None])
    k = pts.shape[1]
    tris = [tuple(sorted(int(i) for i in t)) for t in triangles]
    tb = index_tables(k)
    index = {tuple(int(v) for v in t): n for n, t in enumerate(tb.tris)}
    ids = np.array([index[t] for t in tris], dtype=np.intp)
    geo = SetGeometry(pts)
    angle = float(geo.tri_angle[ids, 0].min())
    side = float(geo.tri_side[ids, 0].min())
    pairs = np.array(list(combinations(ids.tolist(), 2)), dtype=np.intp).reshape(-1, 2)
    shared = np.array(
        [next(iter(set(tb.tris[a].tolist()) & set(tb.tris[b].tolist())), -1) for a, b in pairs],
        dtype=np.intp,
    )
    gap = shared_gap = math.inf
    if len(pairs):
        _, g, a = geo.pair_figures(pairs, shared)
        gap, shared_gap = float(g.min()), float(a.min())
    return _make_layout(tb.tris[ids], angle, side, gap, shared_gap, float(geo.diameter[0]))


def lay_out_and_place(
    points_batch: NDArray[np.float64],
) -> tuple[list[Layout], NDArray[np.float64], NDArray[np.float64]]:
    """Layouts, tag placements and printed MPs of a batch: what ``import`` stores for each set.

    One top-level function of plain arrays, so a process pool can run batches in parallel
    (each result depends on its set only, not on the batch).

    Parameters
    ----------
    points_batch : ndarray of float64, shape (B, k, 2)
        Point sets in general position, file coordinates (grid units; screen convention).

    Returns
    -------
    layouts : list of Layout
        :func:`compute_layouts` of the batch.
    maps : ndarray of float64, shape (B, 2, 3)
        :func:`~ottag_db.core.placement.tag_placements` of the batch.
    printed : ndarray of float64, shape (B,)
        MP of the placed points, in data-area sides.
    """
    maps = tag_placements(points_batch)
    printed = maximal_perturbations(apply_placements(maps, points_batch))
    return compute_layouts(points_batch), maps, printed
