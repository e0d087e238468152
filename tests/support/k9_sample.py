"""Deterministic nine-point sets for CI (the k = 9 bundle is not needed and never copied).

:func:`nine_point_sets` draws seeded random points on the 8-bit grid and improves each set's
MP by a batched random local search (move one point, keep the move when the MP grows), then
keeps distinct order types. The sets are ordinary random sets with a decent MP — no bytes of
Aichholzer's files or of any bundle.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import canonical_batch
from ottag_db.core.geometry import maximal_perturbations

__all__ = ["nine_point_sets"]


def nine_point_sets(count: int = 20, *, seed: int = 9, steps: int = 400) -> NDArray[np.int64]:
    """``(count, 9, 2)`` integer point sets in [0, 255]², distinct order types, MP ≥ 4 grid units.

    Parameters
    ----------
    count : int, optional
        Number of sets.
    seed : int, optional
        Seed of the generator (same seed, same sets).
    steps : int, optional
        Local-search steps per set.

    Returns
    -------
    ndarray of int64, shape (count, 9, 2)
        The sets, grid units, sorted by decreasing MP; their canonical IDs are distinct and
        none is the mirror image of another.
    """
    rng = np.random.default_rng(seed)
    pool = 3 * count
    pts = rng.integers(0, 256, (pool, 9, 2)).astype(np.float64)
    mp = np.nan_to_num(maximal_perturbations(pts), nan=0.0)
    rows = np.arange(pool)
    for step in range(steps):
        # big jumps first, then small moves: a coarse spread, then a polish
        radius = 64.0 if step < steps // 2 else 12.0
        which = rng.integers(0, 9, pool)
        cand = pts.copy()
        moved = cand[rows, which] + rng.integers(-int(radius), int(radius) + 1, (pool, 2))
        cand[rows, which] = np.clip(moved, 0, 255)
        new = np.nan_to_num(maximal_perturbations(cand), nan=0.0)
        better = new > mp
        pts[better] = cand[better]
        mp[better] = new[better]
    order = np.argsort(-mp, kind="stable")
    pts, mp = pts[order], mp[order]
    batch = canonical_batch(pts)
    texts = batch.texts()
    mirrors = canonical_batch(pts * np.array([-1.0, 1.0])).texts()
    seen: set[str] = set()
    keep: list[int] = []
    for i, (text, mirror) in enumerate(zip(texts, mirrors, strict=True)):
        if text in seen or mirror in seen or mp[i] < 4.0:
            continue
        seen.update((text, mirror))
        keep.append(i)
        if len(keep) == count:
            break
    if len(keep) < count:
        raise ValueError(f"only {len(keep)} nine-point sets with MP ≥ 4 (seed {seed}); raise steps")
    result: NDArray[np.int64] = pts[keep].astype(np.int64)
    return result
