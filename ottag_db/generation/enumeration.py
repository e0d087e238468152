"""Enumerate all order types of 3 … 8 points from scratch, each with a float realization in [0, 1]²."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import canonical_batch, canonicalize_lambdas, mirror_lambdas
from ottag_db.core.types import StageProgress
from ottag_db.errors import UsageError
from ottag_db.generation.arrangement import insertion_candidates, vertex_layout
from ottag_db.generation.objective import relative_mp

__all__ = ["EnumeratedSet", "enumerate_order_types", "mirror_points", "normalize_unit"]

_T = TypeVar("_T")
_R = TypeVar("_R")

#: Candidates whose distance to a line of the arrangement is below this fraction of the
#: set's extent are dropped (they are numerically on the line).
_CLEARANCE_TOL = 1e-9
#: Candidate sets with a smaller relative MP are treated as numerically degenerate.
_MIN_QUALITY = 1e-9
#: Base sets per work unit of the enumeration (fixed, so results do not depend on ``jobs``).
_ENUM_CHUNK = 1500
#: Candidate sets canonicalized per batch (bounds the memory to a few hundred MB).
_CHUNK_SETS = 200_000


@dataclass(frozen=True)
class EnumeratedSet:
    """One order type found by the enumeration, with a float realization.

    - ``text``: canonical ID ``k:digits`` of ``points``;
    - ``mirror_text``: canonical ID of the reflected set (equal to ``text`` if achiral);
    - ``points``: ``(k, 2)`` float64 coordinates, scaled into the unit square [0, 1]²
      (screen convention, unitless).
    """

    text: str
    mirror_text: str
    points: NDArray[np.float64]

    @property
    def k(self) -> int:
        """Number of points."""
        return int(self.points.shape[0])

    @property
    def representative(self) -> bool:
        """True for the chirality whose ID text is the smaller one of its reflection pair."""
        return self.text <= self.mirror_text


# --------------------------------------------------------------------------------------------
# Small batched helpers
# --------------------------------------------------------------------------------------------


def normalize_unit(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Translate and uniformly scale each set so its bounding box is in [0, 1]².

    Parameters
    ----------
    points : ndarray of float64, shape (B, n, 2)
        Point sets (any units).

    Returns
    -------
    ndarray of float64, shape (B, n, 2)
        The sets with the bounding box's lower corner at 0 and larger side 1 (unitless).
    """
    lo = points.min(axis=1, keepdims=True)
    span = (points.max(axis=1, keepdims=True) - lo).max(axis=2, keepdims=True)
    out: NDArray[np.float64] = (points - lo) / span
    return out


def mirror_points(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Reflect sets in a vertical line (x → −x, then back into [0, 1]²).

    Parameters
    ----------
    points : ndarray of float64, shape (B, n, 2)
        Point sets (any units).

    Returns
    -------
    ndarray of float64, shape (B, n, 2)
        The mirror images, normalized as by :func:`normalize_unit`.
    """
    out = points.copy()
    out[..., 0] *= -1.0
    return normalize_unit(out)


def _best_per_key(keys: NDArray[np.void], quality: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.void]]:
    """Index of the highest-quality entry of every distinct key (ties: the first), keys sorted."""
    uniq, inverse = np.unique(keys, return_inverse=True)
    order = np.lexsort((np.arange(keys.size), -quality, inverse.ravel()))
    starts = np.searchsorted(inverse.ravel()[order], np.arange(uniq.size))
    picked: NDArray[np.intp] = order[starts]
    return picked, uniq


def _lambda_keys(lam: NDArray[np.int8]) -> NDArray[np.void]:
    b, k, _ = lam.shape
    flat = np.ascontiguousarray(lam.reshape(b, k * k))
    keys: NDArray[np.void] = flat.view(np.dtype((np.void, k * k))).ravel()
    return keys


def _insert_points(base: NDArray[np.float64]) -> dict[str, tuple[NDArray[np.float64], float]]:
    """All order types obtained by adding one point to a base set: ID → (best set, quality).

    Candidates in the same cell of the same base set are merged first (by their sign
    vector with respect to all lines); candidate sets whose :func:`relative_mp` is below
    ``_MIN_QUALITY`` are dropped as numerically degenerate; of the sets with the same
    canonical ID the one with the largest :func:`relative_mp` is kept (normalized into
    [0, 1]²).
    """
    n_sets, m, _ = base.shape
    first, second = np.triu_indices(m, 1)
    per_set = max(1, _CHUNK_SETS // (m * 2 * (m - 1) + 4 * vertex_layout(m)[2].size))
    all_sets: list[NDArray[np.float64]] = []
    all_quality: list[NDArray[np.float64]] = []
    all_keys: list[NDArray[np.void]] = []
    for start in range(0, n_sets, per_set):
        chunk = base[start : start + per_set]
        with np.errstate(divide="ignore", invalid="ignore"):
            cand, clearance = insertion_candidates(chunk)
        nb, nc, _ = cand.shape
        pi = chunk[:, first][:, None]
        pj = chunk[:, second][:, None]
        cross = (pj[..., 0] - pi[..., 0]) * (cand[:, :, None, 1] - pi[..., 1]) - (pj[..., 1] - pi[..., 1]) * (
            cand[:, :, None, 0] - pi[..., 0]
        )  # (nb, nc, P)
        bits = (cross < 0).astype(np.int64) << np.arange(first.size, dtype=np.int64)
        code = bits.sum(axis=2).ravel()
        ok = (clearance > _CLEARANCE_TOL).ravel()
        set_idx = np.repeat(np.arange(nb), nc)
        # One candidate per (base set, cell): the one farthest from all lines.
        order = np.lexsort((-clearance.ravel(), code, set_idx))
        order = order[ok[order]]
        keys = set_idx[order] * (1 << 40) + code[order]
        _, first_pos = np.unique(keys, return_index=True)
        pick = order[first_pos]
        sets = np.concatenate([chunk[set_idx[pick]], cand.reshape(-1, 2)[pick][:, None, :]], axis=1)
        quality = relative_mp(sets)
        good = quality > _MIN_QUALITY
        sets, quality = sets[good], quality[good]
        lam_keys = _lambda_keys(canonical_batch(sets).lambdas)
        idx, _ = _best_per_key(lam_keys, quality)
        all_sets.append(sets[idx])
        all_quality.append(quality[idx])
        all_keys.append(lam_keys[idx])
    if not all_sets:
        return {}
    sets = np.concatenate(all_sets)
    quality = np.concatenate(all_quality)
    idx, _ = _best_per_key(np.concatenate(all_keys), quality)
    sets = normalize_unit(sets[idx])
    quality = quality[idx]
    texts = canonical_batch(sets).texts()
    return {t: (p, float(q)) for t, p, q in zip(texts, sets, quality, strict=True)}


def _mirror_texts(points: NDArray[np.float64]) -> list[str]:
    lam = canonical_batch(points).lambdas
    return canonicalize_lambdas(mirror_lambdas(lam)).texts()


def _jitter(points: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
    """Move every point by less than a tenth of its set's MP: same order type, no symmetries.

    Realizations with large MP tend to be symmetric (parallel lines, three lines through one
    crossing), which would hide cells of the arrangement; a small random displacement
    removes such coincidences without changing the order type.
    """
    scale = relative_mp(points) * (points.max(axis=1) - points.min(axis=1)).max(axis=1)
    step = np.clip(rng.normal(0.0, 0.03, size=points.shape), -0.07, 0.07) * scale[:, None, None]
    return normalize_unit(points + step)


def _subsets(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """All ``(B·k, k − 1, 2)`` subsets obtained by dropping one point of each ``(B, k, 2)`` set."""
    k = points.shape[1]
    keep = np.array([[j for j in range(k) if j != i] for i in range(k)], dtype=np.intp)
    out: NDArray[np.float64] = points[:, keep].reshape(-1, k - 1, 2)
    return out


def _parallel_map(
    fn: Callable[[_T], _R], items: list[_T], jobs: int, on_done: Callable[[int], None] | None = None
) -> list[_R]:
    """``[fn(x) for x in items]`` over ``jobs`` processes (in order); ``on_done(i)`` after each."""
    out: list[_R] = []
    if jobs <= 1 or len(items) <= 1:
        for item in items:
            out.append(fn(item))
            if on_done is not None:
                on_done(len(out))
        return out
    with ProcessPoolExecutor(max_workers=min(jobs, len(items))) as pool:
        for res in pool.map(fn, items):
            out.append(res)
            if on_done is not None:
                on_done(len(out))
    return out


def _insert_all(
    base: NDArray[np.float64], jobs: int, stage: str, progress: StageProgress | None
) -> dict[str, tuple[NDArray[np.float64], float]]:
    """:func:`_insert_points` over fixed chunks of ``base`` (so the result is independent of
    ``jobs``), merged keeping the best quality per ID (earlier chunk on ties)."""
    chunks = [base[i : i + _ENUM_CHUNK] for i in range(0, base.shape[0], _ENUM_CHUNK)]
    if progress is not None:
        progress(stage, 0, len(chunks))

    def done(i: int) -> None:
        if progress is not None:
            progress(stage, i, len(chunks))

    merged: dict[str, tuple[NDArray[np.float64], float]] = {}
    for part in _parallel_map(_insert_points, chunks, jobs, done):
        for text, (pts, q) in part.items():
            old = merged.get(text)
            if old is None or q > old[1]:
                merged[text] = (pts, q)
    return merged


def enumerate_order_types(
    max_k: int = 8, progress: StageProgress | None = None, jobs: int = 1
) -> dict[int, list[EnumeratedSet]]:
    """All order types of ``k = 3 … max_k`` points in general position, both chiralities.

    Starts from a triangle; the types of ``k`` points come from inserting a point into
    every cell of the line arrangement of a realization of each type of ``k − 1`` points,
    then (since the cells depend on the coordinates) into every ``(k − 1)``-subset of the
    new ``k``-point realizations, until a pass finds nothing new. Mirror images are added
    by reflection. Deterministic (also across ``jobs``, the number of processes). Returns
    ``{k: [EnumeratedSet, …]}`` sorted by ID text; the points are in [0, 1]² and, of all
    candidates seen, the one with the largest relative MP is kept.
    ``progress(stage, done, total)`` is called per chunk of work.

    Parameters
    ----------
    max_k : int, optional
        Largest number of points, 3 … 8.
    progress : StageProgress, optional
        ``progress(stage, done, total)`` in chunks of base sets.
    jobs : int, optional
        Number of processes (≥ 1).

    Returns
    -------
    dict of int to list of EnumeratedSet
        Every order type of ``k = 3 … max_k`` points (both chiralities), sorted by ID.

    Raises
    ------
    UsageError
        For ``max_k`` outside 3 … 8 or ``jobs < 1``.
    """
    if not 3 <= max_k <= 8:
        raise UsageError(f"max_k must be between 3 and 8, got {max_k}")
    if jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {jobs}")
    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]])
    tri_text = canonical_batch(tri).texts()[0]
    result: dict[int, list[EnumeratedSet]] = {3: [EnumeratedSet(tri_text, _mirror_texts(tri)[0], tri[0])]}
    for k in range(4, max_k + 1):
        rng = np.random.default_rng(k)
        reps = [r for r in result[k - 1] if r.representative]
        base = _jitter(np.stack([r.points for r in reps]), rng)
        found: dict[str, tuple[NDArray[np.float64], float]] = {}
        passes = 0
        while base.shape[0]:
            passes += 1
            new = _insert_all(base, jobs, f"enumerate k={k} pass {passes}", progress)
            fresh = sorted(t for t in new if t not in found)
            for text, (pts, q) in new.items():
                old = found.get(text)
                if old is None or q > old[1]:
                    found[text] = (pts, q)
            if not fresh:
                break
            # Close under reflection. Extending a reflected set gives only the reflections of
            # the extensions of the original, so one chirality per pair is extended further.
            fresh_pts = np.stack([found[t][0] for t in fresh])
            fresh_set = set(fresh)
            frontier: list[NDArray[np.float64]] = []
            mirrored = mirror_points(fresh_pts)
            for text, mtext, pts, mpts, mq in zip(
                fresh, _mirror_texts(fresh_pts), fresh_pts, mirrored, relative_mp(mirrored), strict=True
            ):
                if text <= mtext or mtext not in fresh_set:
                    frontier.append(pts)
                if mtext not in found:
                    found[mtext] = (mpts, float(mq))
            base = _jitter(_subsets(np.stack(frontier)), rng)
        texts = sorted(found)
        pts_all = np.stack([found[t][0] for t in texts])
        mirrors = _mirror_texts(pts_all)
        result[k] = [EnumeratedSet(t, mt, p) for t, mt, p in zip(texts, mirrors, pts_all, strict=True)]
    return result
