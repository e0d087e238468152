"""Realize order types on the 256 × 256 integer grid with the largest possible MP.

Per set: the continuous stage (:mod:`ottag_db.generation.continuous`) finds a real-valued
optimum, the integer stage (:mod:`ottag_db.generation.rounding`) rounds it, hill-climbs on
the grid and picks the tilt-robust result. This module orders the stages, seeds them per
set, spreads the work over Dask workers (:mod:`~ottag_db.generation.parallel`) and keeps
finished batches for a resumed run (:mod:`~ottag_db.generation.checkpoint`).
"""

from __future__ import annotations

import hashlib
import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.canonical import canonical_batch
from ottag_db.core.types import StageProgress
from ottag_db.errors import UsageError
from ottag_db.generation.batch_ascent import soft_min_ascent
from ottag_db.generation.checkpoint import BatchStore, StoredBatch, batch_digest
from ottag_db.generation.continuous import optimize_continuous, polish_slsqp, start_points
from ottag_db.generation.effort import RealizeEffort, default_effort, rescue_efforts
from ottag_db.generation.objective import triple_signs
from ottag_db.generation.parallel import BatchRunner, Workers, open_workers
from ottag_db.generation.rounding import (
    best_roundings,
    exact_roundings,
    integer_local_search,
    tilt_choice,
)

__all__ = ["BatchDone", "RealizedSet", "chunk_size", "maximize_mp", "realize_all", "set_rng"]

#: Largest number of sets per work unit given to one worker.
_CHUNK = 24
#: The work is cut into at least this many units when there are enough sets (so small runs,
#: e.g. the 16 six-point sets, also spread over workers).
_MIN_CHUNKS = 8


@dataclass(frozen=True)
class RealizedSet:
    """Result for one order type: integer ``points`` ``(k, 2)`` in [0, 255]², their MP (grid
    units), the MP of the best continuous solution (an upper bound of what rounding can
    keep) and the canonical ID text (unchanged from the input)."""

    text: str
    points: NDArray[np.int64]
    mp: float
    continuous_mp: float


def set_rng(seed: int, text: str) -> np.random.Generator:
    """The random generator of one set.

    Seeded from ``(seed, ID)`` only, so results do not depend on the order or the process
    in which sets are handled.

    Parameters
    ----------
    seed : int
        Run seed (its low 32 bits are used).
    text : str
        Canonical ID ``k:digits`` of the set.

    Returns
    -------
    numpy.random.Generator
        A fresh generator.
    """
    digest = hashlib.sha256(text.encode("ascii")).digest()
    words = [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4)]
    return np.random.default_rng([seed & 0xFFFFFFFF, *words])


def maximize_mp(
    points: ArrayLike, seed: int = 0, *, text: str | None = None, effort: RealizeEffort | None = None
) -> NDArray[np.int64]:
    """Integer realization ``(k, 2)`` in [0, 255]² of the order type of ``points`` with large MP.

    ``points`` is any realization in general position (float or int, any scale).
    Deterministic for a given ``seed`` and order type. The result has the same canonical
    ID as ``points``.

    Parameters
    ----------
    points : array_like, shape (k, 2)
        Any realization in general position (float or int, any scale; screen coordinates).
    seed : int, optional
        Run seed (see :func:`set_rng`).
    text : str, optional
        Canonical ID of ``points`` when known (computed otherwise).
    effort : RealizeEffort, optional
        Search effort; :func:`~ottag_db.generation.effort.default_effort` of ``k`` when None.

    Returns
    -------
    ndarray of int64, shape (k, 2)
        The realization in [0, 255]² (grid units), same labelling as ``points``.

    Raises
    ------
    UsageError
        When the search cannot keep the ID (or ``text`` is not the ID of ``points``).
    """
    pts = np.asarray(points, dtype=np.float64)
    target = text if text is not None else canonical_batch(pts[None]).texts()[0]
    efforts = {pts.shape[0]: effort} if effort is not None else None
    return _realize_chunk((pts[None], [target], seed, efforts))[0].points


def _realize_chunk(
    args: tuple[NDArray[np.float64], list[str], int, dict[int, RealizeEffort] | None],
) -> list[RealizedSet]:
    """Realize sets of one k: continuous optimization per set, then one batched integer search."""
    points, texts, seed, efforts = args
    k = points.shape[1]
    eff = efforts.get(k, default_effort(k)) if efforts else default_effort(k)
    if eff.ascent is not None:
        return _realize_chunk_batched(points, texts, seed, eff)
    conts: list[float] = []
    starts: list[NDArray[np.float64]] = []
    signs_list: list[NDArray[np.float64]] = []
    for pts, text in zip(points, texts, strict=True):
        rng = set_rng(seed, text)
        cont, cont_mp = optimize_continuous(pts, rng, eff)
        signs = triple_signs(pts)
        cands = best_roundings(cont, signs, eff, rng)
        if cont_mp < eff.hard_below and eff.exact_variants > 0:
            cands = np.concatenate([cands, exact_roundings(cont, signs, eff, rng)])
        starts.append(cands)
        signs_list.append(np.broadcast_to(signs, (cands.shape[0], signs.size)))
        conts.append(cont_mp)
    found, mps = integer_local_search(np.concatenate(starts), np.concatenate(signs_list), eff.search_iters)
    return _choose(found, mps, [s.shape[0] for s in starts], texts, conts, eff)


def _realize_chunk_batched(
    points: NDArray[np.float64], texts: list[str], seed: int, eff: RealizeEffort
) -> list[RealizedSet]:
    """Realize sets of one k with the batched ascent (``eff.ascent``), SLSQP only for the sets
    it leaves below ``eff.polish_below``, and the integer search.

    Per set, the generator of :func:`set_rng` draws the projective starts, then the rounding
    variants; every batched step works row by row, so each set's result is the one it gets
    alone.
    """
    b, k, _ = points.shape
    n_starts = max(eff.starts, 1)
    rngs = [set_rng(seed, text) for text in texts]
    signs = triple_signs(points)
    starts = np.stack([start_points(p, rng, n_starts) for p, rng in zip(points, rngs, strict=True)])
    found, found_mp = soft_min_ascent(starts.reshape(-1, k, 2), np.repeat(signs, n_starts, axis=0), eff.ascent)
    found_mp = found_mp.reshape(b, n_starts)
    pick = np.argmax(found_mp, axis=1)
    rows = np.arange(b)
    conts = found.reshape(b, n_starts, k, 2)[rows, pick]
    cont_mps = found_mp[rows, pick]
    lagging = np.flatnonzero(cont_mps < eff.polish_below)
    conts[lagging], cont_mps[lagging] = polish_slsqp(conts[lagging], signs[lagging], eff.maxiter)
    cands = [best_roundings(conts[i], signs[i], eff, rngs[i]) for i in range(b)]
    sizes = [c.shape[0] for c in cands]
    found_int, mps = integer_local_search(np.concatenate(cands), np.repeat(signs, sizes, axis=0), eff.search_iters)
    bounds = np.cumsum([0, *sizes])
    good = [i for i in range(b) if mps[bounds[i] : bounds[i + 1]].max() > 0]
    rows_of = np.concatenate([np.arange(bounds[i], bounds[i + 1]) for i in good]) if good else np.arange(0)
    chosen = _choose(
        found_int[rows_of],
        mps[rows_of],
        [sizes[i] for i in good],
        [texts[i] for i in good],
        [float(cont_mps[i]) for i in good],
        eff,
    )
    out: dict[int, RealizedSet] = dict(zip(good, chosen, strict=True))
    # A set none of whose roundings keeps the order type (a tiny MP the ascent alone did not
    # open far enough) takes the per-set path: SLSQP from several starts, then exact roundings.
    for i in range(b):
        if i not in out:
            out[i] = _rescue(points[i], texts[i], seed)
    return [out[i] for i in range(b)]


def _rescue(points: NDArray[np.float64], text: str, seed: int) -> RealizedSet:
    """The per-set path with :func:`~ottag_db.generation.effort.rescue_efforts`, cheapest first."""
    k = points.shape[0]
    *cheaper, last = rescue_efforts(k)
    for eff in cheaper:
        try:
            return _realize_chunk((points[None], [text], seed, {k: eff}))[0]
        except UsageError:
            continue
    return _realize_chunk((points[None], [text], seed, {k: last}))[0]


def _choose(
    found: NDArray[np.int64],
    mps: NDArray[np.float64],
    sizes: list[int],
    texts: list[str],
    conts: list[float],
    eff: RealizeEffort,
) -> list[RealizedSet]:
    """The tilt-robust pick among each set's searched candidates (``sizes[i]`` rows each), the
    ID kept or an error."""
    bounds = np.cumsum([0, *sizes]).tolist()
    picks = [lo + tilt_choice(found[lo:hi], mps[lo:hi], eff.tilt_tol) for lo, hi in itertools.pairwise(bounds)]
    chosen = found[picks]
    chosen_mp = mps[picks]
    got = canonical_batch(chosen).texts()
    out: list[RealizedSet] = []
    for i, text in enumerate(texts):
        if chosen_mp[i] <= 0 or got[i] != text:
            raise UsageError(f"could not realize {text} on the 256 × 256 grid (best MP {chosen_mp[i]:.3f})")
        out.append(RealizedSet(text=text, points=chosen[i], mp=float(chosen_mp[i]), continuous_mp=conts[i]))
    return out


def chunk_size(total: int) -> int:
    """Sets per work unit of :func:`realize_all` for ``total`` sets.

    At most ``_CHUNK`` (the integer search is batched per unit) and small enough for
    ``_MIN_CHUNKS`` units; it depends on ``total`` only, never on the number of processes.

    Parameters
    ----------
    total : int
        Number of sets to realize.

    Returns
    -------
    int
        Sets per unit, ≥ 1.
    """
    return max(1, min(_CHUNK, -(-total // _MIN_CHUNKS)))


@dataclass(frozen=True)
class BatchDone:
    """A batch of :func:`realize_all` that is finished: its ``index`` (in the call), the number
    of ``sets`` in it, and ``reused`` — True when it was read from the work folder of an
    earlier, interrupted run instead of computed."""

    index: int
    sets: int
    reused: bool


_Chunk = tuple[NDArray[np.float64], list[str], int, dict[int, RealizeEffort] | None]


def _chunks(
    pts_list: list[NDArray[np.float64]], texts: Sequence[str], seed: int, efforts: dict[int, RealizeEffort] | None
) -> list[_Chunk]:
    """Work units of :func:`chunk_size` sets (one per set where a unit would mix k)."""
    total = len(pts_list)
    size = chunk_size(total)
    ks = {p.shape[0] for p in pts_list}
    if len(ks) == 1:  # one k: its effort may ask for larger units (a function of k only)
        (k,) = ks
        eff = efforts.get(k, default_effort(k)) if efforts else default_effort(k)
        size = eff.chunk or size
    chunks: list[_Chunk] = []
    for start in range(0, total, size):
        block = pts_list[start : start + size]
        ks = {p.shape[0] for p in block}
        if len(ks) == 1:
            chunks.append((np.stack(block), list(texts[start : start + size]), seed, efforts))
        else:  # mixed k: one chunk per set
            for off, p in enumerate(block):
                chunks.append((p[None], [texts[start + off]], seed, efforts))
    return chunks


def _chunk_path(store: BatchStore, index: int, chunk: _Chunk) -> Path:
    points, texts, seed, efforts = chunk
    k = points.shape[1]
    eff = efforts.get(k, default_effort(k)) if efforts else default_effort(k)
    return store.path(k, seed, index, batch_digest(points, texts, seed, eff))


def realize_all(
    points: Sequence[ArrayLike],
    texts: Sequence[str],
    *,
    seed: int = 0,
    jobs: int = 1,
    scheduler: str | None = None,
    runner: BatchRunner | None = None,
    work_dir: Path | None = None,
    efforts: dict[int, RealizeEffort] | None = None,
    progress: StageProgress | None = None,
    stage: str = "realize",
    on_batch: Callable[[BatchDone], None] | None = None,
) -> list[RealizedSet]:
    """Realize many order types (``points[i]`` a realization of ID ``texts[i]``) on the grid.

    Work is cut into batches of :func:`chunk_size` sets (a function of the number of sets
    only) and run in this process (``jobs`` = 1), on a local Dask cluster of ``jobs`` worker
    processes, or on an existing Dask cluster (``scheduler`` or ``runner``). Each set is seeded
    from ``(seed, ID)`` and computed on its own (a batch only batches the integer search, row
    by row) and results are put back in input order, so the result depends neither on the
    workers nor on the batching, nor on the other sets of the call. With ``work_dir`` every
    finished batch is kept there (see :mod:`~ottag_db.generation.checkpoint`) and batches
    found there are not computed again: a run interrupted at any point resumes where it
    stopped. ``efforts`` overrides :func:`~ottag_db.generation.effort.default_effort` per k.

    Parameters
    ----------
    points : sequence of array_like, shape (k, 2) each
        A realization in general position of each order type (any scale).
    texts : sequence of str
        Canonical ID ``k:digits`` of each.
    seed : int, optional
        Run seed (see :func:`set_rng`).
    jobs : int, optional
        Worker processes of a local Dask cluster (≥ 1; 1 runs in this process). Ignored
        with ``scheduler`` or ``runner``.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``).
    runner : BatchRunner, optional
        Workers already opened with :func:`~ottag_db.generation.parallel.open_workers`
        (one cluster for several calls).
    work_dir : Path, optional
        Folder for finished batches (created when needed; never emptied here).
    efforts : dict of int to RealizeEffort, optional
        Effort per k, overriding :func:`default_effort`.
    progress : StageProgress, optional
        ``progress(stage, done, total)`` in sets, as batches finish (reused ones first).
    stage : str, optional
        Stage name passed to ``progress``.
    on_batch : callable, optional
        ``on_batch(BatchDone)`` after each batch is finished and kept; an exception raised
        there stops the run (the batches kept so far stay in ``work_dir``).

    Returns
    -------
    list of RealizedSet
        The results in input order (points in [0, 255]², grid units).

    Raises
    ------
    UsageError
        For ``jobs < 1`` or a set whose ID cannot be kept.
    ClusterError
        When ``scheduler`` cannot be reached.
    """
    if jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {jobs}")
    pts_list = [np.asarray(p, dtype=np.float64) for p in points]
    if len(pts_list) != len(texts):
        raise ValueError("points and texts differ in length")
    total = len(pts_list)
    chunks = _chunks(pts_list, texts, seed, efforts)
    store = BatchStore(work_dir) if work_dir is not None else None
    paths = [_chunk_path(store, i, c) for i, c in enumerate(chunks)] if store is not None else []
    results: list[list[RealizedSet] | None] = [None] * len(chunks)
    done = 0
    if progress is not None:
        progress(stage, 0, total)

    def finished(i: int, part: list[RealizedSet], reused: bool) -> None:
        nonlocal done
        results[i] = part
        done += len(part)
        if progress is not None:
            progress(stage, done, total)
        if on_batch is not None:
            on_batch(BatchDone(index=i, sets=len(part), reused=reused))

    todo: list[int] = []
    for i, chunk in enumerate(chunks):
        kept = store.load(paths[i], chunk[1]) if store is not None else None
        if kept is None:
            todo.append(i)
        else:
            finished(i, _from_stored(kept), True)

    def computed(j: int, part: list[RealizedSet]) -> None:
        i = todo[j]
        if store is not None:
            store.save(paths[i], _to_stored(part))
        finished(i, part, False)

    work = [chunks[i] for i in todo]
    if runner is not None:
        runner.run(_realize_chunk, work, computed)
    else:
        workers = Workers(jobs=jobs if len(work) > 1 else 1, scheduler=scheduler)
        with open_workers(workers) as own:
            own.run(_realize_chunk, work, computed)
    return [s for part in results if part is not None for s in part]


def _to_stored(part: list[RealizedSet]) -> StoredBatch:
    return StoredBatch(
        texts=tuple(s.text for s in part),
        points=np.stack([s.points for s in part]).astype(np.int64),
        mp=np.array([s.mp for s in part], dtype=np.float64),
        continuous_mp=np.array([s.continuous_mp for s in part], dtype=np.float64),
    )


def _from_stored(batch: StoredBatch) -> list[RealizedSet]:
    return [
        RealizedSet(text=t, points=batch.points[i], mp=float(batch.mp[i]), continuous_mp=float(batch.continuous_mp[i]))
        for i, t in enumerate(batch.texts)
    ]
