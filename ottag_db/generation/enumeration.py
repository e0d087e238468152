"""Enumerate all order types of 3 … 8 points from scratch and build the bundled point-set files."""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import canonical_batch, canonicalize_lambdas, mirror_lambdas
from ottag_db.core.types import MP_THRESHOLDS
from ottag_db.errors import UsageError
from ottag_db.files.pointfile import file_sha256, write_point_file

__all__ = [
    "MP_THRESHOLDS",
    "GenerationReport",
    "Progress",
    "Realization",
    "enumerate_order_types",
    "file_name",
    "generate_database",
    "insertion_candidates",
    "mirror_points",
    "normalize_unit",
    "relative_mp",
]

_T = TypeVar("_T")
_R = TypeVar("_R")

#: Progress callback ``(stage name, done, total)``.
Progress = Callable[[str, int, int], None]

#: MP thresholds (grid units) of the summary table, as in the paper's Table 7.

#: Candidates whose distance to a line of the arrangement is below this fraction of the
#: set's extent are dropped (they are numerically on the line).
_CLEARANCE_TOL = 1e-9
#: Candidate sets with a smaller relative MP are treated as numerically degenerate.
_MIN_QUALITY = 1e-9
#: Distance (in units of the set's extent, which is 1 after normalization) at which points
#: are placed in unbounded cells.
_FAR = 1.5
#: Base sets per work unit of the enumeration (fixed, so results do not depend on ``jobs``).
_ENUM_CHUNK = 1500
#: Candidate sets canonicalized per batch (bounds the memory to a few hundred MB).
_CHUNK_SETS = 200_000


@dataclass(frozen=True)
class Realization:
    """One order type with a float realization.

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
    """Translate and uniformly scale each ``(B, n, 2)`` set so its bounding box is in [0, 1]²."""
    lo = points.min(axis=1, keepdims=True)
    span = (points.max(axis=1, keepdims=True) - lo).max(axis=2, keepdims=True)
    out: NDArray[np.float64] = (points - lo) / span
    return out


def mirror_points(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Reflect ``(B, n, 2)`` sets in a vertical line (x → −x, then back into [0, 1]²)."""
    out = points.copy()
    out[..., 0] *= -1.0
    return normalize_unit(out)


def _triple_index(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    a, b, c = (np.asarray(v, dtype=np.intp) for v in zip(*_combinations3(n), strict=True))
    return a, b, c


def _combinations3(n: int) -> list[tuple[int, int, int]]:
    return [(a, b, c) for a in range(n) for b in range(a + 1, n) for c in range(b + 1, n)]


def relative_mp(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """MP of each ``(B, n, 2)`` set divided by the larger side of its bounding box (unitless).

    MP is half the smallest distance from a point to a line through two others; for a
    triangle the smallest of its three heights is twice its area over its longest side.
    """
    n = points.shape[1]
    a, b, c = _triple_index(n)
    pair_id = np.full((n, n), -1, dtype=np.intp)
    first, second = np.triu_indices(n, 1)
    pair_id[first, second] = np.arange(first.size)
    x = points[..., 0]
    y = points[..., 1]
    cross = x[:, first] * y[:, second] - y[:, first] * x[:, second]  # (B, P)
    dx = x[:, second] - x[:, first]
    dy = y[:, second] - y[:, first]
    sq = dx * dx + dy * dy
    ab, bc, ac = pair_id[a, b], pair_id[b, c], pair_id[a, c]
    area2 = np.abs(cross[:, ab] + cross[:, bc] - cross[:, ac])
    longest = np.sqrt(np.maximum(np.maximum(sq[:, ab], sq[:, bc]), sq[:, ac]))
    with np.errstate(divide="ignore", invalid="ignore"):
        heights = np.where(longest > 0, area2 / longest, 0.0)
    extent = (points.max(axis=1) - points.min(axis=1)).max(axis=1)
    out: NDArray[np.float64] = 0.5 * heights.min(axis=1) / extent
    return out


# --------------------------------------------------------------------------------------------
# Insertion of one point into every cell of the line arrangement
# --------------------------------------------------------------------------------------------


def _vertex_layout(m: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Pairs ``(i, j)`` (the lines) and pairs of disjoint lines ``(l1, l2)`` (crossing vertices)."""
    first, second = np.triu_indices(m, 1)
    n_lines = first.size
    l1, l2 = np.triu_indices(n_lines, 1)
    disjoint = (
        (first[l1] != first[l2]) & (first[l1] != second[l2]) & (second[l1] != first[l2]) & (second[l1] != second[l2])
    )
    return first.astype(np.intp), second.astype(np.intp), l1[disjoint].astype(np.intp), l2[disjoint].astype(np.intp)


def insertion_candidates(base: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Points in the cells of the arrangement of lines through all pairs of each base set.

    ``base`` is ``(N, m, 2)`` (sets in general position, coordinates of order 1). Every
    cell of an arrangement of non-parallel lines has a vertex, and the cells around a
    vertex are the angular sectors between consecutive lines through it. For every vertex
    (the m input points, where m − 1 lines meet, and the crossings of two lines through
    four distinct points) and every sector, a candidate is put on the bisector halfway to
    the first line the bisecting ray meets (at distance ``_FAR`` when it meets none).

    Returns ``(candidates (N, C, 2), clearance (N, C))`` where ``clearance`` is the
    smallest distance from the candidate to any line (same units as ``base``).
    """
    n_sets, m, _ = base.shape
    first, second, l1, l2 = _vertex_layout(m)
    n_lines = first.size
    pi = base[:, first]
    pj = base[:, second]
    u = pj - pi
    u /= np.linalg.norm(u, axis=2, keepdims=True)
    normal = np.stack([-u[..., 1], u[..., 0]], axis=2)  # (N, P, 2)
    offset = -(normal * pi).sum(axis=2)  # (N, P)

    # (a) Vertices at the input points: 2(m − 1) rays, bisect consecutive ones.
    others = np.array([[j for j in range(m) if j != i] for i in range(m)], dtype=np.intp)  # (m, m−1)
    d = base[:, others] - base[:, :, None, :]  # (N, m, m−1, 2)
    ang = np.arctan2(d[..., 1], d[..., 0])
    ang = np.concatenate([ang, ang + np.pi], axis=2)
    ang = np.mod(ang, 2.0 * np.pi)
    ang.sort(axis=2)
    nxt = np.concatenate([ang[..., 1:], ang[..., :1] + 2.0 * np.pi], axis=2)
    mid = 0.5 * (ang + nxt)  # (N, m, S)
    dirs_a = np.stack([np.cos(mid), np.sin(mid)], axis=3)  # (N, m, S, 2)
    verts_a = base
    incident_a = (first[None, :] == np.arange(m)[:, None]) | (second[None, :] == np.arange(m)[:, None])  # (m, P)

    # (b) Crossings of two lines through four distinct points: 4 sectors each.
    n1, n2 = normal[:, l1], normal[:, l2]
    c1, c2 = offset[:, l1], offset[:, l2]
    det = n1[..., 0] * n2[..., 1] - n1[..., 1] * n2[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        vx = (-c1 * n2[..., 1] + c2 * n1[..., 1]) / det
        vy = (-n1[..., 0] * c2 + n2[..., 0] * c1) / det
    verts_b = np.stack([vx, vy], axis=2)  # (N, Q, 2)
    u1, u2 = u[:, l1], u[:, l2]
    s_dir = u1 + u2
    d_dir = u1 - u2
    s_dir /= np.linalg.norm(s_dir, axis=2, keepdims=True)
    d_dir /= np.linalg.norm(d_dir, axis=2, keepdims=True)
    dirs_b = np.stack([s_dir, -s_dir, d_dir, -d_dir], axis=2)  # (N, Q, 4, 2)
    line_ids = np.arange(n_lines)
    incident_b = (line_ids[None, :] == l1[:, None]) | (line_ids[None, :] == l2[:, None])  # (Q, P)

    out: list[NDArray[np.float64]] = []
    for verts, dirs, incident in ((verts_a, dirs_a, incident_a), (verts_b, dirs_b, incident_b)):
        side = (normal[:, None, :, :] * verts[:, :, None, :]).sum(axis=3) + offset[:, None, :]  # (N, V, P)
        rate = np.einsum("nvsd,npd->nvsp", dirs, normal)  # (N, V, S, P)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -side[:, :, None, :] / rate
        t = np.where((t > 0) & ~incident[None, :, None, :] & np.isfinite(t), t, np.inf)
        step = np.minimum(0.5 * t.min(axis=3), _FAR)  # (N, V, S)
        out.append((verts[:, :, None, :] + dirs * step[..., None]).reshape(n_sets, -1, 2))
    cand = np.concatenate(out, axis=1)
    dist = np.abs((normal[:, None, :, :] * cand[:, :, None, :]).sum(axis=3) + offset[:, None, :])
    clearance = dist.min(axis=2)
    clearance = np.where(np.isfinite(clearance), clearance, 0.0)
    return cand, clearance


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
    per_set = max(1, _CHUNK_SETS // (m * 2 * (m - 1) + 4 * _vertex_layout(m)[2].size))
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
    base: NDArray[np.float64], jobs: int, stage: str, progress: Progress | None
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
    max_k: int = 8, progress: Progress | None = None, jobs: int = 1
) -> dict[int, list[Realization]]:
    """All order types of ``k = 3 … max_k`` points in general position, both chiralities.

    Starts from a triangle; the types of ``k`` points come from inserting a point into
    every cell of the line arrangement of a realization of each type of ``k − 1`` points,
    then (since the cells depend on the coordinates) into every ``(k − 1)``-subset of the
    new ``k``-point realizations, until a pass finds nothing new. Mirror images are added
    by reflection. Deterministic (also across ``jobs``, the number of processes). Returns
    ``{k: [Realization, …]}`` sorted by ID text; the points are in [0, 1]² and, of all
    candidates seen, the one with the largest relative MP is kept.
    ``progress(stage, done, total)`` is called per chunk of work.
    """
    if not 3 <= max_k <= 8:
        raise UsageError(f"max_k must be between 3 and 8, got {max_k}")
    if jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {jobs}")
    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]])
    tri_text = canonical_batch(tri).texts()[0]
    result: dict[int, list[Realization]] = {3: [Realization(tri_text, _mirror_texts(tri)[0], tri[0])]}
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
        result[k] = [Realization(t, mt, p) for t, mt, p in zip(texts, mirrors, pts_all, strict=True)]
    return result


# --------------------------------------------------------------------------------------------
# The bundled database files
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GenerationReport:
    """Summary of :func:`generate_database`.

    - ``records``: ``{k: sets in the file}`` (one per reflection pair);
    - ``with_mirrors``: ``{k: order types counting both chiralities}``;
    - ``files``: ``{k: path of ottag-kNN.b08}``; ``manifest``: path of manifest.json;
    - ``mp_thresholds``: the values v (grid units) of ``mp_table``;
    - ``mp_table``: ``{k: (number of sets with MP ≥ v for each v)}`` (paper's Table 7);
    - ``mp_min``: ``{k: smallest MP of the file}`` (grid units);
    - ``seed``; ``seconds``: wall time per stage ("enumerate", "realize", "total").
    """

    records: dict[int, int]
    with_mirrors: dict[int, int]
    files: dict[int, Path]
    manifest: Path
    mp_thresholds: tuple[float, ...]
    mp_table: dict[int, tuple[int, ...]]
    mp_min: dict[int, float]
    seed: int
    seconds: dict[str, float]


def _tool_version() -> str:
    """``ottag_db.__version__`` if the package defines it, else "0.1.0"."""
    version = getattr(sys.modules.get(__package__ or "ottag_db"), "__version__", None)
    return version if isinstance(version, str) else "0.1.0"


def file_name(k: int) -> str:
    """Name of the bundled point-set file of ``k`` points: ``ottag-kNN.b08``."""
    return f"ottag-k{k:02d}.b08"


def generate_database(
    max_k: int = 8,
    out_dir: Path = Path("data"),
    seed: int = 0,
    jobs: int = 1,
    progress: Progress | None = None,
) -> GenerationReport:
    """Enumerate all order types of 3 … ``max_k`` points, realize each reflection pair on the
    [0, 255]² grid with a large MP and write ``ottag-kNN.b08`` plus ``manifest.json``.

    Each file holds one set per reflection pair (the chirality whose ID text is smaller),
    sorted by that ID text: a drop-in replacement of the reference ``otypesNN.b08``. The
    output depends only on ``seed`` (not on ``jobs``, the number of processes); two runs
    with the same seed write identical files. ``progress(stage, done, total)`` reports
    the stages ("enumerate k=…", "realize k=…", "write").
    """
    if not 3 <= max_k <= 8:
        raise UsageError(f"max_k must be between 3 and 8, got {max_k}")
    if jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {jobs}")
    from ottag_db.generation.realize import realize_all

    t0 = time.perf_counter()
    types = enumerate_order_types(max_k, progress=progress, jobs=jobs)
    t1 = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    realized: dict[int, NDArray[np.int64]] = {}
    mps: dict[int, NDArray[np.float64]] = {}
    for k in range(3, max_k + 1):
        reps = sorted((r for r in types[k] if r.representative), key=lambda r: r.text)
        sets = realize_all(
            [r.points for r in reps],
            [r.text for r in reps],
            seed=seed,
            jobs=jobs,
            progress=progress,
            stage=f"realize k={k}",
        )
        realized[k] = np.stack([s.points for s in sets])
        mps[k] = np.array([s.mp for s in sets])
    t2 = time.perf_counter()
    ks = list(range(3, max_k + 1))
    if progress is not None:
        progress("write", 0, len(ks))
    files: dict[int, Path] = {}
    entries: dict[str, dict[str, object]] = {}
    for n, k in enumerate(ks, start=1):
        path = out / file_name(k)
        write_point_file(path, realized[k], bits=8)
        files[k] = path
        entries[str(k)] = {
            "file": path.name,
            "points": k,
            "records": int(realized[k].shape[0]),
            "order_types_with_mirrors": len(types[k]),
            "sha256": file_sha256(path),
            "mp_min": round(float(mps[k].min()), 6),
            "mp_median": round(float(np.median(mps[k])), 6),
        }
        if progress is not None:
            progress("write", n, len(ks))
    table = {k: tuple(int((mps[k] >= v).sum()) for v in MP_THRESHOLDS) for k in ks}
    manifest = {
        "format": "ottag-db order-type point sets",
        "tool": "ottag-db",
        "version": _tool_version(),
        "seed": seed,
        "grid": [0, 255],
        "description": (
            "One integer realization per order type and reflection pair (the chirality with "
            "the smaller canonical ID text), sorted by that ID; .b08 records of k (x, y) uint8 "
            "points. MP is half the smallest distance from a point to a line through two others."
        ),
        "files": entries,
        "mp_summary": {
            "thresholds": list(MP_THRESHOLDS),
            "counts_at_least": {str(k): list(table[k]) for k in ks},
        },
    }
    manifest_path = out / "manifest.json"
    manifest_path.write_text(json.dumps(manifest, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    t3 = time.perf_counter()
    return GenerationReport(
        records={k: int(realized[k].shape[0]) for k in ks},
        with_mirrors={k: len(types[k]) for k in ks},
        files=files,
        manifest=manifest_path,
        mp_thresholds=MP_THRESHOLDS,
        mp_table=table,
        mp_min={k: float(mps[k].min()) for k in ks},
        seed=seed,
        seconds={"enumerate": t1 - t0, "realize": t2 - t1, "total": t3 - t0},
    )
