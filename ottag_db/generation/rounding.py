"""Integer stage of the realization: roundings of a continuous optimum, a batched local
search on the grid and the tilt-robust choice among the results (grid units throughout)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import triple_indices
from ottag_db.core.types import MP_THRESHOLDS
from ottag_db.generation.effort import RealizeEffort
from ottag_db.generation.objective import GRID_MAX, signed_mp_terms, triple_signs, triple_table

__all__ = [
    "best_roundings",
    "exact_roundings",
    "integer_local_search",
    "tilt_choice",
    "tilt_failures",
]

#: Single-point moves of the integer search: every (dx, dy) in [−3, 3]² except (0, 0).
_MOVES = np.array([(dx, dy) for dx in range(-3, 4) for dy in range(-3, 4) if (dx, dy) != (0, 0)], dtype=np.float64)
#: The integer search compares the smallest few point-to-line distances lexicographically.
_KEY_SIZE = 3
#: Two keys are equal when they differ by less than this (grid units).
_KEY_EPS = 1e-9
#: MP values (grid units) that the tilt-robust choice never crosses downwards: the
#: thresholds 0.5, 1.0, …, 9.0 of the summary table, then every integer.
_MP_STEPS = np.concatenate([np.array(MP_THRESHOLDS), np.arange(10.0, 256.0)])
#: Camera of the projection experiments (paper's Table 4): focal length and distance (px, a.u.).
_FOCAL = 1000.0
_DISTANCE = 1000.0


def _keys(terms: NDArray[np.float64]) -> NDArray[np.float64]:
    """The ``_KEY_SIZE`` smallest terms in increasing order (the search compares these)."""
    m = min(_KEY_SIZE, terms.shape[-1])
    part = np.partition(terms, m - 1, axis=-1)[..., :m]
    out: NDArray[np.float64] = np.sort(part, axis=-1)
    return out


# Constant index tables of k, built once per k and read-only.
@lru_cache(maxsize=16)
def _moved_triples(k: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Per point ``q``: the triples containing it ``(k, C(k−1, 2))``, their other two points
    ``u, v`` in the cyclic order that keeps the triple's orientation (``D(q, u, v) = D(a, b, c)``)
    and the triples without ``q`` ``(k, C(k, 3) − C(k−1, 2))``."""
    a, b, c = triple_indices(k)
    every = np.arange(a.size)
    inc, us, vs, exc = [], [], [], []
    for q in range(k):
        t = np.flatnonzero((a == q) | (b == q) | (c == q))
        inc.append(t)
        us.append(np.where(a[t] == q, b[t], np.where(b[t] == q, c[t], a[t])))
        vs.append(np.where(a[t] == q, c[t], np.where(b[t] == q, a[t], b[t])))
        exc.append(np.setdiff1d(every, t))
    out = tuple(np.array(x, dtype=np.intp).reshape(k, -1) for x in (inc, us, vs, exc))
    for arr in out:
        arr.flags.writeable = False
    return out[0], out[1], out[2], out[3]


def integer_local_search(
    points: ArrayLike, signs: ArrayLike, max_iters: int = 200
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Hill-climb integer sets ``(B, k, 2)`` in [0, 255]²: move one point by up to ±3 in x and y.

    Each round evaluates every single-point move of a set and applies the best one if it
    raises the smallest terms (half point-to-line distances) lexicographically; moves
    changing an orientation (``signs`` ``(B, T)``) are never taken, so the order type is
    kept. A move of ``q`` only changes the ``C(k−1, 2)`` triples containing ``q``, so only those
    are recomputed per move and merged with the ``_KEY_SIZE`` smallest terms of the other
    triples; on integer coordinates below 2**16 every orientation and squared length is exact,
    so this gives bit for bit what recomputing every triple of every moved set gives
    (``tests/generation/test_batch_ascent.py`` keeps that evaluation as its oracle). The rounds
    run in a compiled loop (Numba), one set after the other, so a set's result does not depend
    on the others.

    Parameters
    ----------
    points : array_like, shape (B, k, 2)
        Integer-valued sets in [0, GRID_MAX]² (grid units).
    signs : array_like, shape (B, C(k, 3))
        Orientation sign of every triple to keep (see
        :func:`~ottag_db.generation.objective.triple_signs`).
    max_iters : int, optional
        Largest number of rounds.

    Returns
    -------
    points : ndarray of int64, shape (B, k, 2)
        The improved sets (grid units).
    mp : ndarray of float64, shape (B,)
        Their signed MP (grid units; ≤ 0 for an input that already broke ``signs``).
    """
    pts = np.array(points, dtype=np.float64, order="C")
    sg = np.ascontiguousarray(signs, dtype=np.float64)
    b, k, _ = pts.shape
    inc, us, vs, exc = _moved_triples(k)
    tri = triple_table(k)
    terms = np.ascontiguousarray(signed_mp_terms(pts, sg))
    mp = np.empty(b)
    if b:
        _search_all(pts, sg, terms, tri, inc, us, vs, exc, _MOVES, min(_KEY_SIZE, tri.shape[0]), max_iters, mp)
    return pts.astype(np.int64), mp


@njit(cache=False, error_model="numpy")
def _smallest(out: NDArray[np.float64], count: int, size: int, x: float) -> int:
    """Insert ``x`` into the ascending buffer ``out[:size]`` that keeps the ``count`` smallest
    values seen; return the new size."""
    if count == 0:
        return 0
    if size == count:
        if not x < out[size - 1]:
            return size
        size -= 1
    j = size
    while j > 0 and out[j - 1] > x:
        out[j] = out[j - 1]
        j -= 1
    out[j] = x
    return size + 1


@njit(cache=False, error_model="numpy")
def _set_terms(
    p: NDArray[np.float64], s: NDArray[np.float64], tri: NDArray[np.intp], terms: NDArray[np.float64]
) -> None:
    """``signed_mp_terms`` of one set (the differences form of :func:`~ottag_db.core.geometry.triple_figures`)."""
    for t in range(tri.shape[0]):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        abx, aby = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1]
        acx, acy = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1]
        bcx, bcy = p[c, 0] - p[b, 0], p[c, 1] - p[b, 1]
        d = abx * acy - aby * acx
        longest = np.sqrt(max(max(abx * abx + aby * aby, acx * acx + acy * acy), bcx * bcx + bcy * bcy))
        terms[t] = 0.5 * s[t] * d / longest if longest > 0 else -np.inf


@njit(cache=False, error_model="numpy")
def _search_all(
    pts: NDArray[np.float64],
    signs: NDArray[np.float64],
    terms: NDArray[np.float64],
    tri: NDArray[np.intp],
    inc: NDArray[np.intp],
    us: NDArray[np.intp],
    vs: NDArray[np.intp],
    exc: NDArray[np.intp],
    moves: NDArray[np.float64],
    m: int,
    max_iters: int,
    mp: NDArray[np.float64],
) -> None:
    """The rounds of :func:`integer_local_search` for every set (``pts``, ``terms`` updated in place)."""
    k = pts.shape[1]
    n_moves = moves.shape[0]
    n_inc = inc.shape[1]
    n_exc = exc.shape[1]
    m_rest = min(m, n_exc)
    keys = np.empty(m)
    rest = np.empty(m)
    cand = np.empty((k * n_moves, m))
    mask = np.empty(k * n_moves, dtype=np.bool_)
    buf = np.empty(m)
    for n in range(pts.shape[0]):
        p = pts[n]
        s = signs[n]
        size = 0
        for t in range(terms.shape[1]):
            size = _smallest(keys, m, size, terms[n, t])
        for _ in range(max_iters):
            for q in range(k):
                r = 0
                for e in range(n_exc):
                    r = _smallest(rest, m_rest, r, terms[n, exc[q, e]])
                for mv in range(n_moves):
                    qx = min(max(p[q, 0] + moves[mv, 0], 0.0), float(GRID_MAX))
                    qy = min(max(p[q, 1] + moves[mv, 1], 0.0), float(GRID_MAX))
                    size = r
                    for j in range(r):
                        buf[j] = rest[j]
                    for j in range(n_inc):
                        ux, uy = p[us[q, j], 0], p[us[q, j], 1]
                        vx, vy = p[vs[q, j], 0], p[vs[q, j], 1]
                        dux, duy = ux - qx, uy - qy
                        dvx, dvy = vx - qx, vy - qy
                        d = dux * dvy - duy * dvx
                        uvx, uvy = ux - vx, uy - vy
                        longest = np.sqrt(max(max(dux * dux + duy * duy, dvx * dvx + dvy * dvy), uvx * uvx + uvy * uvy))
                        x = 0.5 * s[inc[q, j]] * d / longest if longest > 0 else -np.inf
                        size = _smallest(buf, m, size, x)
                    cand[q * n_moves + mv, :] = buf
            # Lexicographic argmax with tolerance, column by column, first on ties.
            mask[:] = True
            for col in range(m):
                top = -np.inf
                for i in range(cand.shape[0]):
                    if mask[i] and cand[i, col] > top:
                        top = cand[i, col]
                for i in range(cand.shape[0]):
                    mask[i] = mask[i] and cand[i, col] >= top - _KEY_EPS
            best = 0
            while not mask[best]:
                best += 1
            improved = False
            for col in range(m):
                if cand[best, col] > keys[col] + _KEY_EPS:
                    improved = True
                    break
                if cand[best, col] < keys[col] - _KEY_EPS:
                    break
            if not improved:
                break
            q = best // n_moves
            mv = best % n_moves
            p[q, 0] = min(max(p[q, 0] + moves[mv, 0], 0.0), float(GRID_MAX))
            p[q, 1] = min(max(p[q, 1] + moves[mv, 1], 0.0), float(GRID_MAX))
            keys[:] = cand[best]
            _set_terms(p, s, tri, terms[n])
        mp[n] = keys[0]


def _rounding_variants(points: NDArray[np.float64], count: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """``count`` integer candidates near ``points``: plain rounding, then random sub-pixel
    shifts combined with shrinks by up to 2 % about the box centre."""
    out = np.empty((count, *points.shape))
    centre = GRID_MAX / 2.0
    for v in range(count):
        if v == 0:
            moved = points
        else:
            shrink = 1.0 - rng.uniform(0.0, 0.02)
            moved = centre + shrink * (points - centre) + rng.uniform(-0.5, 0.5, 2)
        out[v] = np.clip(np.rint(moved), 0, GRID_MAX)
    return out


def best_roundings(
    cont: NDArray[np.float64], signs: NDArray[np.float64], effort: RealizeEffort, rng: np.random.Generator
) -> NDArray[np.float64]:
    """The best rounding variants of one continuous solution.

    Variants are plain rounding, then random sub-pixel shifts combined with shrinks by up
    to 2 % about the box centre; they are ranked by their smallest signed terms.

    Parameters
    ----------
    cont : ndarray of float64, shape (k, 2)
        Continuous optimum in [0, GRID_MAX]² (grid units).
    signs : ndarray of float64, shape (C(k, 3),)
        Orientation signs to keep.
    effort : RealizeEffort
        ``roundings`` variants are tried, the ``searched_roundings`` best returned.
    rng : numpy.random.Generator
        Source of the shifts and shrinks.

    Returns
    -------
    ndarray of float64, shape (searched_roundings, k, 2)
        Integer-valued candidates (grid units), best first.
    """
    variants = _rounding_variants(cont, effort.roundings, rng)
    keys = _keys(signed_mp_terms(variants, np.broadcast_to(signs, (variants.shape[0], signs.size))))
    order = np.lexsort(tuple(-keys[:, c] for c in range(keys.shape[1] - 1, -1, -1)))
    out: NDArray[np.float64] = variants[order[: effort.searched_roundings]]
    return out


# A pure constant table of k (up to 8 MB for k = 8), built once per k instead of once per
# hard set; read-only, so sharing it cannot leak changes.
@lru_cache(maxsize=16)
def _corner_offsets(k: int) -> NDArray[np.float64]:
    """All ``4^k`` ways ``(4^k, k, 2)`` to add 0 or 1 to each coordinate of ``k`` points."""
    bits = (np.arange(1 << (2 * k))[:, None] >> np.arange(2 * k)) & 1
    out: NDArray[np.float64] = bits.reshape(-1, k, 2).astype(np.float64)
    out.flags.writeable = False
    return out


def exact_roundings(
    cont: NDArray[np.float64], signs: NDArray[np.float64], effort: RealizeEffort, rng: np.random.Generator
) -> NDArray[np.float64]:
    """Best integer sets among all floor/ceiling roundings of shifted and shrunk optima.

    Parameters
    ----------
    cont : ndarray of float64, shape (k, 2)
        Continuous optimum in [0, GRID_MAX]² (grid units).
    signs : ndarray of float64, shape (C(k, 3),)
        Orientation signs to keep.
    effort : RealizeEffort
        ``exact_variants`` variants (the optimum, then sub-pixel shifts and shrinks by up
        to 1 %), each rounded in all ``4^k`` ways; the ``exact_keep`` best of each kept.
    rng : numpy.random.Generator
        Source of the shifts and shrinks.

    Returns
    -------
    ndarray of float64, shape (exact_variants · exact_keep, k, 2)
        Integer-valued candidates (grid units), best first within each variant.
    """
    k = cont.shape[0]
    offsets = _corner_offsets(k)
    centre = GRID_MAX / 2.0
    out: list[NDArray[np.float64]] = []
    for v in range(effort.exact_variants):
        if v == 0:
            moved = cont
        else:
            moved = centre + (1.0 - rng.uniform(0.0, 0.01)) * (cont - centre) + rng.uniform(-0.5, 0.5, 2)
        cands = np.clip(np.floor(moved)[None] + offsets, 0.0, float(GRID_MAX))
        terms = signed_mp_terms(cands, np.broadcast_to(signs, (cands.shape[0], signs.size)))
        low = terms.min(axis=1)
        m = min(effort.exact_keep, low.size)
        top = np.argpartition(-low, m - 1)[:m]
        top = top[np.lexsort((top, -low[top]))]
        out.append(cands[top])
    return np.concatenate(out) if out else np.zeros((0, k, 2))


# A pure constant table (216 camera rotations), built once instead of per set.
@lru_cache(maxsize=4)
def _tilt_views() -> NDArray[np.float64]:
    """First two columns ``(V, 3, 2)`` of the camera rotations ``Ry(θ2) · Rz(θ1)`` of the
    strongest tilts of the rotation experiment: θ1 = 0°, 10°, …, 350°, θ2 = 84°, …, 89°."""
    t1, t2 = np.meshgrid(np.arange(0.0, 360.0, 10.0), np.arange(84.0, 90.0), indexing="ij")
    a, b = np.deg2rad(t1.ravel()), np.deg2rad(t2.ravel())
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    col0 = np.stack([cb * ca, sa, -sb * ca], axis=1)
    col1 = np.stack([-cb * sa, ca, sb * sa], axis=1)
    out: NDArray[np.float64] = np.stack([col0, col1], axis=2)
    out.flags.writeable = False
    return out


def tilt_failures(points: ArrayLike) -> NDArray[np.int64]:
    """Number of strongly tilted camera views under which a set changes its order type.

    A proxy of the projection experiment's failures: views at distance 1000 with
    f = 1000 px, θ2 = 84° … 89° and 36 values of θ1; a view fails when the rounded pixel
    positions change a triple orientation.

    Parameters
    ----------
    points : array_like, shape (B, k, 2)
        Point sets (grid units), centred on their mean before projection.

    Returns
    -------
    ndarray of int64, shape (B,)
        Failing views per set, 0 … 216.
    """
    pts = np.asarray(points, dtype=np.float64)
    views = _tilt_views()
    centred = pts - pts.mean(axis=1, keepdims=True)
    cam = np.einsum("vij,bkj->bvki", views, centred)
    depth = cam[..., 2] + _DISTANCE
    u = np.floor(_FOCAL * cam[..., 0] / depth + 0.5)
    v = np.floor(_FOCAL * cam[..., 1] / depth + 0.5)
    tri = triple_table(pts.shape[1])
    out = np.zeros(pts.shape[0], dtype=np.int64)
    _count_flipped_views(
        np.ascontiguousarray(u), np.ascontiguousarray(v), np.ascontiguousarray(triple_signs(pts)), tri, out
    )
    return out


@njit(cache=False, error_model="numpy")
def _count_flipped_views(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    signs: NDArray[np.float64],
    tri: NDArray[np.intp],
    out: NDArray[np.int64],
) -> None:
    """Per set, the views ``(B, V, k)`` of pixel positions in which some triple's orientation
    sign differs from ``signs`` (exact: pixel coordinates are small integers)."""
    for n in range(u.shape[0]):
        for view in range(u.shape[1]):
            x, y = u[n, view], v[n, view]
            for t in range(tri.shape[0]):
                a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
                d = (x[b] - x[a]) * (y[c] - y[a]) - (y[b] - y[a]) * (x[c] - x[a])
                if np.sign(d) != signs[n, t]:
                    out[n] += 1
                    break


def tilt_choice(points: NDArray[np.int64], mps: NDArray[np.float64], tol: float) -> int:
    """Which of several integer realizations of one set to keep.

    The fewest :func:`tilt_failures` among those with MP ≥ max((1 − tol) · best, the
    largest MP step ≤ best), then the larger MP, then the first.

    Parameters
    ----------
    points : ndarray of int64, shape (M, k, 2)
        Candidate realizations (grid units).
    mps : ndarray of float64, shape (M,)
        Their MP (grid units).
    tol : float
        Relative MP that may be given up for fewer tilt failures.

    Returns
    -------
    int
        Index into ``points``.
    """
    best = float(mps.max())
    steps = _MP_STEPS[best + _KEY_EPS >= _MP_STEPS]
    floor = max(best * (1.0 - tol), float(steps.max()) if steps.size else 0.0)
    ok = np.flatnonzero(mps >= floor - _KEY_EPS)
    if ok.size == 1:  # nothing to compare: skip the 216 projections
        return int(ok[0])
    fails = tilt_failures(points[ok])
    order = np.lexsort((ok, -mps[ok], fails))
    return int(ok[order[0]])
