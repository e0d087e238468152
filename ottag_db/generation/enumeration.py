"""Enumerate every order type of 3 … 8 points from scratch and of 9 points from realizations of
the 8-point types, each with a float realization in [0, 1]²."""

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

__all__ = [
    "ENUMERATION_MAX_K",
    "FROM_SCRATCH_MAX_K",
    "EnumeratedSet",
    "EnumerationPass",
    "enumerate_order_types",
    "extend_order_types",
    "mirror_points",
    "normalize_unit",
]

_T = TypeVar("_T")
_R = TypeVar("_R")

#: Candidates whose distance to a line of the arrangement is below this fraction of the
#: set's extent are dropped (they are numerically on the line).
_CLEARANCE_TOL = 1e-9
#: Candidate sets with a smaller relative MP are treated as numerically degenerate.
_MIN_QUALITY = 1e-9
#: Largest number of base sets per work unit of the enumeration.
_ENUM_CHUNK = 1500
#: Candidate sets canonicalized per batch (bounds the memory to a few hundred MB).
_CHUNK_SETS = 200_000
#: Sets whose ID texts are computed at once (k = 9: 50,000 orientation tensors, 300 MB; the
#: enumeration handles ten times more sets at a time).
_TEXT_CHUNK = 50_000
#: Largest number of points the enumeration handles (:func:`extend_order_types`).
ENUMERATION_MAX_K = 9
#: Largest number of points :func:`enumerate_order_types` reaches with its own float
#: realizations: at k = 9 they miss one chiral pair of the 158,817 (see :func:`extend_order_types`).
FROM_SCRATCH_MAX_K = 8
#: From this k on (by default), the passes after the first insert into a sample of the new sets' subsets:
#: all of them would be 9 subsets of each of ~316,000 nine-point sets (1.4 million bases, hours),
#: while a few per (k − 1)-point type already reach every order type (k = 9: passes of 25,619,
#: 5,132, 1,030, 205 and 63 bases after the first 3,315, about 7 minutes on one core).
_SAMPLED_FROM_K = 9
#: Subsets kept per (k − 1)-point order type and pass when sampling.
_SUBSETS_PER_TYPE = 4


@dataclass(frozen=True)
class EnumerationPass:
    """One pass of the enumeration of ``k``-point order types.

    - ``k``; ``number``: 1 for the insertion into one realization per (k − 1)-point type,
      then 2, 3, … for the insertions into subsets of the sets found by the pass before (or,
      after a pass that found nothing when sampling, into a sample of subsets of all sets);
    - ``bases``: the (k − 1)-point realizations whose arrangements were used in this pass;
    - ``new``: order types first found in this pass (both chiralities, mirrors added after);
    - ``total``: order types known after it (both chiralities).
    """

    k: int
    number: int
    bases: int
    new: int
    total: int


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
    texts = _texts(sets)
    return {t: (p, float(q)) for t, p, q in zip(texts, sets, quality, strict=True)}


def _texts(points: NDArray[np.float64]) -> list[str]:
    """Canonical ID texts of ``(N, k, 2)`` sets, in chunks of ``_TEXT_CHUNK``."""
    out: list[str] = []
    for start in range(0, points.shape[0], _TEXT_CHUNK):
        out += canonical_batch(points[start : start + _TEXT_CHUNK]).texts()
    return out


def _mirror_texts(points: NDArray[np.float64]) -> list[str]:
    """Canonical ID texts of the mirror images of ``(N, k, 2)`` sets, in chunks of ``_TEXT_CHUNK``."""
    out: list[str] = []
    for start in range(0, points.shape[0], _TEXT_CHUNK):
        lam = canonical_batch(points[start : start + _TEXT_CHUNK]).lambdas
        out += canonicalize_lambdas(mirror_lambdas(lam)).texts()
    return out


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
    """:func:`_insert_points` over chunks of ``base``, merged keeping each ID's first best
    candidate in base order (so the chunks do not matter); equal chunks of at most
    ``_ENUM_CHUNK``, a multiple of ``jobs`` in number, so no process idles at the end."""
    n = base.shape[0]
    count = -(-n // _ENUM_CHUNK)
    count = jobs * -(-count // jobs)
    size = max(1, -(-n // count))
    chunks = [base[i : i + size] for i in range(0, n, size)]
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


def _sample_subsets(subs: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
    """Up to ``_SUBSETS_PER_TYPE`` of the ``(N, k − 1, 2)`` sets per order type (seeded choice), jittered."""
    groups: dict[str, list[int]] = {}
    # In chunks (_texts): canonicalizing all subsets at once (k = 9: 2.4 million sets of
    # 8 points) would hold their orientation tensors, about 10 GB.
    for i, text in enumerate(_texts(subs)):
        groups.setdefault(text, []).append(i)
    pick: list[int] = []
    for text in sorted(groups):
        members = groups[text]
        take = min(_SUBSETS_PER_TYPE, len(members))
        pick.extend(rng.choice(members, size=take, replace=False).tolist())
    return _jitter(subs[np.array(sorted(pick), dtype=np.intp)], rng)


def _next_bases(
    fresh_pts: NDArray[np.float64], frontier: list[NDArray[np.float64]], sampled: bool, rng: np.random.Generator
) -> NDArray[np.float64]:
    """Bases of the next pass, jittered: the (k − 1)-subsets of the new sets of the frontier
    (one chirality per pair), or when ``sampled`` a sample of the subsets of all new sets."""
    if not sampled:
        return _jitter(_subsets(np.stack(frontier)), rng)
    return _sample_subsets(_subsets(fresh_pts), rng)


def _sweep_bases(found: dict[str, tuple[NDArray[np.float64], float]], rng: np.random.Generator) -> NDArray[np.float64]:
    """Bases of a sweep: one random (k − 1)-subset of every known set, sampled per order type.

    When the sampled passes stop, a type can still be missing because its cell occurs only
    in realizations no sample drew (k = 9: one chiral pair of 158,817 in a run without
    sweeps); a sweep draws new subsets from all known sets, not only the latest ones.
    """
    pts = np.stack([found[t][0] for t in sorted(found)])
    b, k, _ = pts.shape
    drop = np.asarray(rng.integers(0, k, size=b), dtype=np.intp)
    keep = np.arange(k)[None, :] != drop[:, None]
    return _sample_subsets(pts[keep].reshape(b, k - 1, 2), rng)


def extend_order_types(
    k: int,
    bases: NDArray[np.float64],
    progress: StageProgress | None = None,
    jobs: int = 1,
    on_pass: Callable[[EnumerationPass], None] | None = None,
    *,
    sampled: bool | None = None,
) -> list[EnumeratedSet]:
    """Every order type of ``k`` points (both chiralities), from realizations of all (k − 1)-point types.

    The first pass inserts a point into every cell of the line arrangement of each base set
    (jittered, see :func:`_jitter`); since the cells depend on the coordinates, later passes
    insert into ``(k − 1)``-subsets of the new ``k``-point realizations — all of them, or when
    ``sampled`` a few per ``(k − 1)``-point order type, closed by sweeps over subsets of all
    known sets — until a pass (a sweep, when sampling) finds nothing new. Mirror images are
    added by reflection. Deterministic for given ``bases`` (also across ``jobs``): the random
    generator is seeded by ``k``.

    Which realizations start it matters at k = 9: from the enumeration's own float
    realizations of the 8-point types the sampled passes reach 158,816 of the 158,817 types
    (up to reflection); from their MP-maximized grid realizations (the bundled
    ``ottag-k08.b08``, as ``generate`` does) all 158,817.

    Parameters
    ----------
    k : int
        Number of points of the result, 4 … 9.
    bases : ndarray, shape (B, k − 1, 2)
        One realization of every (k − 1)-point order type up to reflection, any scale
        (screen convention).
    progress : StageProgress, optional
        ``progress(stage, done, total)`` in chunks of base sets.
    jobs : int, optional
        Number of processes (≥ 1).
    on_pass : callable, optional
        Called with an :class:`EnumerationPass` after every pass (the realizations it took).
    sampled : bool, optional
        Sample the subsets in the later passes; default: from k = 9 on.

    Returns
    -------
    list of EnumeratedSet
        Sorted by ID; the points are in [0, 1]² and, of all candidates seen, the one with the
        largest relative MP is kept.

    Raises
    ------
    UsageError
        For ``k`` outside 4 … 9, ``bases`` not of shape (B, k − 1, 2) or ``jobs < 1``.
    """
    if not 4 <= k <= ENUMERATION_MAX_K:
        raise UsageError(f"k must be between 4 and {ENUMERATION_MAX_K}, got {k}")
    if bases.ndim != 3 or bases.shape[1:] != (k - 1, 2) or bases.shape[0] == 0:
        raise UsageError(f"bases must have shape (B, {k - 1}, 2), got {bases.shape}")
    if jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {jobs}")
    sample = k >= _SAMPLED_FROM_K if sampled is None else sampled
    rng = np.random.default_rng(k)
    base = _jitter(np.asarray(bases, dtype=np.float64), rng)
    found: dict[str, tuple[NDArray[np.float64], float]] = {}
    passes = 0
    # Sampled passes end with a sweep over all known sets; another one follows any pass that
    # found something new, so the run stops after a sweep that found nothing.
    swept = False
    while base.shape[0]:
        passes += 1
        new = _insert_all(base, jobs, f"enumerate k={k} pass {passes}", progress)
        fresh = sorted(t for t in new if t not in found)
        for text, (pts, q) in new.items():
            old = found.get(text)
            if old is None or q > old[1]:
                found[text] = (pts, q)
        if not fresh:
            if on_pass is not None:
                on_pass(EnumerationPass(k, passes, int(base.shape[0]), 0, len(found)))
            if not sample or swept:
                break
            swept = True
            base = _sweep_bases(found, rng)
            continue
        swept = False
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
        if on_pass is not None:
            on_pass(EnumerationPass(k, passes, int(base.shape[0]), len(fresh), len(found)))
        base = _next_bases(fresh_pts, frontier, sample, rng)
    texts = sorted(found)
    pts_all = np.stack([found[t][0] for t in texts])
    mirrors = _mirror_texts(pts_all)
    return [EnumeratedSet(t, mt, p) for t, mt, p in zip(texts, mirrors, pts_all, strict=True)]


def enumerate_order_types(
    max_k: int = 8,
    progress: StageProgress | None = None,
    jobs: int = 1,
    on_pass: Callable[[EnumerationPass], None] | None = None,
    *,
    sampled_from_k: int = _SAMPLED_FROM_K,
) -> dict[int, list[EnumeratedSet]]:
    """All order types of ``k = 3 … max_k`` points in general position, both chiralities.

    Starts from a triangle; the types of ``k`` points come from :func:`extend_order_types`
    on the enumeration's own float realization of each (k − 1)-point type up to reflection.
    Deterministic (also across ``jobs``, the number of processes). For nine points, call
    :func:`extend_order_types` with grid realizations of the 8-point types (as ``generate``
    does): from these float ones it misses one chiral pair.

    Parameters
    ----------
    max_k : int, optional
        Largest number of points, 3 … 8.
    progress : StageProgress, optional
        ``progress(stage, done, total)`` in chunks of base sets.
    jobs : int, optional
        Number of processes (≥ 1).
    on_pass : callable, optional
        Called with an :class:`EnumerationPass` after every pass (the realizations it took).
    sampled_from_k : int, optional
        First k whose later passes sample the subsets (9: the bundled files of k ≤ 8 were
        made without sampling; exhaustive subsets at k = 9 would take hours).

    Returns
    -------
    dict of int to list of EnumeratedSet
        Every order type of ``k = 3 … max_k`` points (both chiralities), sorted by ID; the
        points are in [0, 1]².

    Raises
    ------
    UsageError
        For ``max_k`` outside 3 … 8 or ``jobs < 1``.
    """
    if not 3 <= max_k <= FROM_SCRATCH_MAX_K:
        raise UsageError(
            f"max_k must be between 3 and {FROM_SCRATCH_MAX_K}, got {max_k}"
            " (nine points: extend_order_types from realizations of the 8-point types)"
        )
    if jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {jobs}")
    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]])
    tri_text = canonical_batch(tri).texts()[0]
    result: dict[int, list[EnumeratedSet]] = {3: [EnumeratedSet(tri_text, _mirror_texts(tri)[0], tri[0])]}
    for k in range(4, max_k + 1):
        reps = [r for r in result[k - 1] if r.representative]
        result[k] = extend_order_types(
            k, np.stack([r.points for r in reps]), progress, jobs, on_pass, sampled=k >= sampled_from_k
        )
    return result
