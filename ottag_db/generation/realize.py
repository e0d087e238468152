"""Realize order types on the 256 × 256 integer grid with the largest possible MP."""

from __future__ import annotations

import ctypes
import hashlib
import itertools
import os
import re
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize

from ottag_db.core.canonical import canonical_batch
from ottag_db.errors import UsageError

__all__ = [
    "GRID_MAX",
    "RealizeEffort",
    "RealizedSet",
    "default_effort",
    "grid_mp",
    "integer_local_search",
    "maximize_mp",
    "optimize_continuous",
    "realize_all",
    "set_rng",
    "tilt_failures",
]

#: Largest coordinate of the 8-bit grid; points live in [0, GRID_MAX]².
GRID_MAX = 255

#: Single-point moves of the integer search: every (dx, dy) in [−3, 3]² except (0, 0).
_MOVES = np.array([(dx, dy) for dx in range(-3, 4) for dy in range(-3, 4) if (dx, dy) != (0, 0)], dtype=np.float64)
#: The integer search compares the smallest few point-to-line distances lexicographically.
_KEY_SIZE = 3
#: Two keys are equal when they differ by less than this (grid units).
_KEY_EPS = 1e-9
#: Sets per work unit given to one process (fixed, so results do not depend on ``jobs``).
_CHUNK = 24
#: MP values (grid units) that the tilt-robust choice never crosses downwards: the
#: thresholds 0.5, 1.0, …, 9.0 of the summary table, then every integer.
_MP_STEPS = np.concatenate([np.arange(0.5, 9.01, 0.5), np.arange(10.0, 256.0)])
#: Camera of the projection experiments (paper's Table 4): focal length and distance (px, a.u.).
_FOCAL = 1000.0
_DISTANCE = 1000.0


@dataclass(frozen=True)
class RealizeEffort:
    """How hard to search for one set.

    - ``starts``: continuous optimizations from the seed and random projective images;
    - ``hops``: further optimizations from random perturbations of the best so far
      (standard deviations cycling through ``hop_sigmas``, grid units);
    - ``roundings``: rounding variants (sub-pixel shifts and slight shrinks) tried per set;
    - ``searched_roundings``: best rounding variants refined by the integer local search;
    - ``maxiter``: SLSQP iteration limit; ``search_iters``: integer-search iteration limit;
    - ``hard_below``: sets whose best continuous MP is below this count as *hard* and get
      ``hard_starts`` further SLSQP runs from uniformly random points (which land in other
      basins than the projective images of one realization) and ``exact_variants``
      sub-pixel shifts / slight shrinks of the optimum, each rounded in all ``4^k`` ways
      (floor or ceiling per coordinate), of which the ``exact_keep`` best go to the search;
    - ``tilt_tol``: of the searched integer sets, those with MP ≥ (1 − ``tilt_tol``) · best
      (never crossing a value of ``_MP_STEPS``) compete on :func:`tilt_failures`.
    """

    starts: int = 3
    hops: int = 1
    hop_sigmas: tuple[float, ...] = (15.0, 5.0, 30.0, 60.0)
    roundings: int = 24
    searched_roundings: int = 3
    maxiter: int = 200
    search_iters: int = 200
    hard_below: float = 0.0
    hard_starts: int = 0
    exact_variants: int = 0
    exact_keep: int = 2
    tilt_tol: float = 0.03


def default_effort(k: int) -> RealizeEffort:
    """Search effort used by :func:`realize_all` for sets of ``k`` points.

    Few sets exist for ``k ≤ 7``, so they get many starts; for ``k = 8`` (3315 sets) the
    budget is a few SLSQP runs each (multi-starts rarely change the optimum there).
    """
    if k <= 7:
        return RealizeEffort(starts=8, hops=16, roundings=64, searched_roundings=6, hard_below=np.inf, exact_variants=4)
    return RealizeEffort(starts=3, hops=0, hard_below=2.3, exact_variants=4)


@dataclass(frozen=True)
class RealizedSet:
    """Result for one order type: integer ``points`` ``(k, 2)`` in [0, 255]², their MP (grid
    units), the MP of the best continuous solution (an upper bound of what rounding can
    keep) and the canonical ID text (unchanged from the input)."""

    text: str
    points: NDArray[np.int64]
    mp: float
    continuous_mp: float


# --------------------------------------------------------------------------------------------
# BLAS threads: SLSQP calls BLAS on tiny matrices, where extra threads only burn CPU.
# --------------------------------------------------------------------------------------------

_BLAS_NAMES = (
    ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
    ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
    ("openblas_get_num_threads", "openblas_set_num_threads"),
)


def _blas_controls() -> list[tuple[Callable[[], int], Callable[[int], None]]]:
    out: list[tuple[Callable[[], int], Callable[[int], None]]] = []
    try:
        with open("/proc/self/maps", encoding="utf-8") as fh:
            paths = sorted(set(re.findall(r"(/\S*openblas\S*\.so\S*)", fh.read())))
    except OSError:
        return out
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for get_name, set_name in _BLAS_NAMES:
            getter = getattr(lib, get_name, None)
            setter = getattr(lib, set_name, None)
            if getter is not None and setter is not None:
                getter.restype = ctypes.c_int
                setter.argtypes = [ctypes.c_int]
                out.append((getter, setter))
                break
    return out


@contextmanager
def _single_blas_thread() -> Iterator[None]:
    """Run the block with OpenBLAS limited to one thread (restored afterwards; no-op elsewhere)."""
    controls = _blas_controls()
    old = [get() for get, _ in controls]
    for _, put in controls:
        put(1)
    try:
        yield
    finally:
        for (_, put), n in zip(controls, old, strict=True):
            put(n)


# --------------------------------------------------------------------------------------------
# Geometry of the constraints
# --------------------------------------------------------------------------------------------


@lru_cache(maxsize=16)
def _triples(k: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    rows = [(a, b, c) for a in range(k) for b in range(a + 1, k) for c in range(b + 1, k)]
    arr = np.array(rows, dtype=np.intp)
    return arr[:, 0], arr[:, 1], arr[:, 2]


@lru_cache(maxsize=16)
def _point_line(k: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Every (point p, line through i, j) with p, i, j distinct: 3 per triple, in triple order."""
    a, b, c = _triples(k)
    p = np.stack([a, b, c], axis=1).ravel()
    i = np.stack([b, a, a], axis=1).ravel()
    j = np.stack([c, c, b], axis=1).ravel()
    return p, i, j


def _triple_values(points: NDArray[np.float64], k: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Twice the signed area ``D`` and the longest side of every triple: ``(..., T)`` each."""
    a, b, c = _triples(k)
    pa, pb, pc = points[..., a, :], points[..., b, :], points[..., c, :]
    ab = pb - pa
    ac = pc - pa
    bc = pc - pb
    d = ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0]
    longest = np.sqrt(np.maximum(np.maximum((ab * ab).sum(-1), (ac * ac).sum(-1)), (bc * bc).sum(-1)))
    return d, longest


def _triple_signs(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Orientation sign (±1) of every triple of each ``(..., k, 2)`` set."""
    d, _ = _triple_values(points, points.shape[-2])
    return np.sign(d)


def _signed_mp_terms(points: NDArray[np.float64], signs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Half the smallest height of every triple, negative when its orientation is wrong."""
    d, longest = _triple_values(points, points.shape[-2])
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(longest > 0, 0.5 * signs * d / longest, -np.inf)
    out: NDArray[np.float64] = terms
    return out


def grid_mp(points: ArrayLike, signs: ArrayLike | None = None) -> NDArray[np.float64]:
    """MP of each ``(B, k, 2)`` set (coordinate units); with ``signs`` ``(B, T)`` a set whose
    triple orientations differ from ``signs`` gets a value ≤ 0."""
    pts = np.asarray(points, dtype=np.float64)
    if signs is None:
        d, longest = _triple_values(pts, pts.shape[-2])
        with np.errstate(divide="ignore", invalid="ignore"):
            terms = np.where(longest > 0, 0.5 * np.abs(d) / longest, 0.0)
        out: NDArray[np.float64] = terms.min(axis=-1)
        return out
    res: NDArray[np.float64] = _signed_mp_terms(pts, np.asarray(signs, dtype=np.float64)).min(axis=-1)
    return res


# --------------------------------------------------------------------------------------------
# Continuous optimization (SLSQP): maximize t with every signed point-to-line distance ≥ t
# --------------------------------------------------------------------------------------------


class _Problem:
    """Signed point-to-line distances of one labelled set and their Jacobian, cached per x."""

    def __init__(self, signs: NDArray[np.float64], k: int):
        self.k = k
        self.p, self.i, self.j = _point_line(k)
        # (p, line i→j) for a triple (a, b, c) with orientation s: (a, b→c) has s, (b, a→c)
        # has −s and (c, a→b) has s.
        self.signs = (signs[:, None] * np.array([1.0, -1.0, 1.0])).ravel()
        self.rows = np.arange(self.p.size)
        self._x: NDArray[np.float64] | None = None
        self._d = np.zeros(0)
        self._jac = np.zeros((0, 0))

    def _eval(self, x: NDArray[np.float64]) -> None:
        if self._x is not None and np.array_equal(x, self._x):
            return
        k = self.k
        pts = np.stack([x[:k], x[k : 2 * k]], axis=1)
        e = pts[self.j] - pts[self.i]
        w = pts[self.p] - pts[self.i]
        cross = e[:, 0] * w[:, 1] - e[:, 1] * w[:, 0]
        length = np.maximum(np.sqrt((e * e).sum(axis=1)), 1e-9)
        scale = self.signs / length
        ratio = (cross / length)[:, None]
        unit = e / length[:, None]
        g_p = np.stack([-e[:, 1], e[:, 0]], axis=1)
        g_j = np.stack([w[:, 1], -w[:, 0]], axis=1) - ratio * unit
        g_i = -g_p - g_j
        jac = np.zeros((self.p.size, 2 * k + 1))
        for grad, idx in ((g_p, self.p), (g_i, self.i), (g_j, self.j)):
            jac[self.rows, idx] = scale * grad[:, 0]
            jac[self.rows, k + idx] = scale * grad[:, 1]
        jac[:, -1] = -1.0
        self._x = x.copy()
        self._d = self.signs * cross / length
        self._jac = jac

    def constraint(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        self._eval(x)
        out: NDArray[np.float64] = self._d - x[-1]
        return out

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        self._eval(x)
        return self._jac


def _slsqp(start: NDArray[np.float64], signs: NDArray[np.float64], maxiter: int) -> tuple[NDArray[np.float64], float]:
    """One SLSQP run from ``start`` ``(k, 2)``; returns (points, MP) with MP ≤ 0 on failure.

    The margin ``t`` is unbounded below, so a start with some wrong orientations is fine:
    the optimizer pulls them to the right side if it can.
    """
    k = start.shape[0]
    prob = _Problem(signs, k)
    x0 = np.concatenate([start[:, 0], start[:, 1], [0.0]])
    x0[-1] = float(prob.constraint(x0).min())
    grad_obj = np.zeros(2 * k + 1)
    grad_obj[-1] = -1.0
    bounds = [(0.0, float(GRID_MAX))] * (2 * k) + [(None, None)]
    res = minimize(
        lambda x: -x[-1],
        x0,
        jac=lambda x: grad_obj,
        bounds=bounds,
        constraints=[{"type": "ineq", "fun": prob.constraint, "jac": prob.jacobian}],
        method="SLSQP",
        options={"maxiter": maxiter, "ftol": 1e-10},
    )
    x = np.asarray(res.x, dtype=np.float64)
    pts = np.clip(np.stack([x[:k], x[k : 2 * k]], axis=1), 0.0, float(GRID_MAX))
    if not np.all(np.isfinite(pts)):
        return start, -np.inf
    mp = float(grid_mp(pts[None], signs[None])[0])
    return pts, mp


def _to_box(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Scale uniformly to fill [0, 255]² in the longer direction and centre in the other."""
    lo = points.min(axis=0)
    span = float((points.max(axis=0) - lo).max())
    out = (points - lo) / span * GRID_MAX
    out += (GRID_MAX - out.max(axis=0)) / 2.0
    res: NDArray[np.float64] = out
    return res


def _random_projective(points: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
    """A random projective image keeping every point on one side of the line at infinity,
    then a random rotation and stretch, scaled into the box (same order type)."""
    q = points - points.mean(axis=0)
    q = q / np.abs(q).max()
    h = rng.uniform(-1.0, 1.0, 2)
    h *= rng.uniform(0.0, 0.8) / max(float(np.abs(h).sum()), 1e-12)
    q = q / (1.0 + q @ h)[:, None]
    angle = rng.uniform(0.0, 2.0 * np.pi)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    q = (q @ rot.T) * np.array([1.0, rng.uniform(0.6, 1.6)])
    return _to_box(q)


def set_rng(seed: int, text: str) -> np.random.Generator:
    """The random generator of one set: seeded from ``(seed, ID)`` only, so results do not
    depend on the order or the process in which sets are handled."""
    digest = hashlib.sha256(text.encode("ascii")).digest()
    words = [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4)]
    return np.random.default_rng([seed & 0xFFFFFFFF, *words])


def optimize_continuous(
    points: ArrayLike, rng: np.random.Generator, effort: RealizeEffort | None = None
) -> tuple[NDArray[np.float64], float]:
    """Best real-valued realization in [0, 255]² of the order type of ``points`` ``(k, 2)``.

    Runs SLSQP (maximize t s.t. every point-to-line distance, with the sign of the input,
    is ≥ t) from the input scaled into the box, from ``starts − 1`` random projective
    images and from ``hops`` random perturbations of the best so far (and, for a hard set,
    see :class:`RealizeEffort`, from ``hard_starts`` uniformly random points). Returns the best
    points (same labelling and orientations as the input) and their MP (grid units).
    """
    pts = np.asarray(points, dtype=np.float64)
    k = pts.shape[0]
    eff = effort if effort is not None else default_effort(k)
    signs = _triple_signs(pts)
    seed_pts = _to_box(pts)
    best_pts, best = seed_pts, float(grid_mp(seed_pts[None], signs[None])[0])
    with _single_blas_thread():
        for s in range(eff.starts):
            start = seed_pts if s == 0 else _random_projective(pts, rng)
            cand, value = _slsqp(start, signs, eff.maxiter)
            if value > best:
                best_pts, best = cand, value
        for h in range(eff.hops):
            sigma = eff.hop_sigmas[h % len(eff.hop_sigmas)]
            start = np.clip(best_pts + rng.normal(0.0, sigma, best_pts.shape), 0.0, float(GRID_MAX))
            cand, value = _slsqp(start, signs, eff.maxiter)
            if value > best:
                best_pts, best = cand, value
        if best < eff.hard_below:
            for _ in range(eff.hard_starts):
                cand, value = _slsqp(rng.uniform(0.0, float(GRID_MAX), pts.shape), signs, eff.maxiter)
                if value > best:
                    best_pts, best = cand, value
    return best_pts, best


# --------------------------------------------------------------------------------------------
# Integer stage: rounding variants and a batched local search on the grid
# --------------------------------------------------------------------------------------------


def _keys(terms: NDArray[np.float64]) -> NDArray[np.float64]:
    """The ``_KEY_SIZE`` smallest terms in increasing order (the search compares these)."""
    m = min(_KEY_SIZE, terms.shape[-1])
    part = np.partition(terms, m - 1, axis=-1)[..., :m]
    out: NDArray[np.float64] = np.sort(part, axis=-1)
    return out


def _lex_greater(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Elementwise lexicographic ``a > b`` over the last axis (with tolerance ``_KEY_EPS``)."""
    result = np.zeros(a.shape[:-1], dtype=bool)
    decided = np.zeros(a.shape[:-1], dtype=bool)
    for col in range(a.shape[-1]):
        gt = a[..., col] > b[..., col] + _KEY_EPS
        lt = a[..., col] < b[..., col] - _KEY_EPS
        result |= gt & ~decided
        decided |= gt | lt
    return result


def _lex_argmax(keys: NDArray[np.float64]) -> NDArray[np.intp]:
    """Index of the lexicographically largest key along axis 1 of ``(B, M, m)`` (first on ties)."""
    mask = np.ones(keys.shape[:2], dtype=bool)
    for col in range(keys.shape[2]):
        vals = np.where(mask, keys[..., col], -np.inf)
        mask &= vals >= vals.max(axis=1, keepdims=True) - _KEY_EPS
    out: NDArray[np.intp] = np.argmax(mask, axis=1)
    return out


def integer_local_search(
    points: ArrayLike, signs: ArrayLike, max_iters: int = 200
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Hill-climb integer sets ``(B, k, 2)`` in [0, 255]²: move one point by up to ±3 in x and y.

    Each round evaluates every single-point move of every set at once and applies the best
    one if it raises the smallest terms (half point-to-line distances) lexicographically;
    moves changing an orientation (``signs`` ``(B, T)``) are never taken, so the order
    type is kept. Returns the points and their MP (grid units).
    """
    pts = np.asarray(points, dtype=np.float64).copy()
    sg = np.asarray(signs, dtype=np.float64)
    b, k, _ = pts.shape
    n_moves = _MOVES.shape[0]
    keys = _keys(_signed_mp_terms(pts, sg))
    active = np.ones(b, dtype=bool)
    for _ in range(max_iters):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        cand = np.repeat(pts[idx][:, None, None], k * n_moves, axis=1).reshape(idx.size, k, n_moves, k, 2)
        for q in range(k):
            cand[:, q, :, q, :] += _MOVES
        cand = np.clip(cand.reshape(idx.size, k * n_moves, k, 2), 0.0, float(GRID_MAX))
        cand_keys = _keys(_signed_mp_terms(cand, sg[idx][:, None, :]))
        rows = np.arange(idx.size)
        best = _lex_argmax(cand_keys)
        best_keys = cand_keys[rows, best]
        improved = _lex_greater(best_keys, keys[idx])
        pts[idx[improved]] = cand[rows[improved], best[improved]]
        keys[idx[improved]] = best_keys[improved]
        active[idx[~improved]] = False
    return pts.astype(np.int64), keys[:, 0]


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


def _best_roundings(
    cont: NDArray[np.float64], signs: NDArray[np.float64], effort: RealizeEffort, rng: np.random.Generator
) -> NDArray[np.float64]:
    """The ``searched_roundings`` best rounding variants of one continuous solution."""
    variants = _rounding_variants(cont, effort.roundings, rng)
    keys = _keys(_signed_mp_terms(variants, np.broadcast_to(signs, (variants.shape[0], signs.size))))
    order = np.lexsort(tuple(-keys[:, c] for c in range(keys.shape[1] - 1, -1, -1)))
    out: NDArray[np.float64] = variants[order[: effort.searched_roundings]]
    return out


@lru_cache(maxsize=16)
def _corner_offsets(k: int) -> NDArray[np.float64]:
    """All ``4^k`` ways ``(4^k, k, 2)`` to add 0 or 1 to each coordinate of ``k`` points."""
    bits = (np.arange(1 << (2 * k))[:, None] >> np.arange(2 * k)) & 1
    out: NDArray[np.float64] = bits.reshape(-1, k, 2).astype(np.float64)
    return out


def _exact_roundings(
    cont: NDArray[np.float64], signs: NDArray[np.float64], effort: RealizeEffort, rng: np.random.Generator
) -> NDArray[np.float64]:
    """Best integer sets among all floor/ceiling roundings of ``exact_variants`` sub-pixel
    shifts and shrinks (by up to 1 %) of ``cont``: ``exact_keep`` per variant."""
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
        terms = _signed_mp_terms(cands, np.broadcast_to(signs, (cands.shape[0], signs.size)))
        low = terms.min(axis=1)
        m = min(effort.exact_keep, low.size)
        top = np.argpartition(-low, m - 1)[:m]
        top = top[np.lexsort((top, -low[top]))]
        out.append(cands[top])
    return np.concatenate(out) if out else np.zeros((0, k, 2))


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
    return out


def tilt_failures(points: ArrayLike) -> NDArray[np.int64]:
    """For each ``(B, k, 2)`` set (grid units), the number of strongly tilted camera views
    (distance 1000, f = 1000 px, θ2 = 84° … 89°, 36 values of θ1) whose rounded pixels
    change a triple orientation: a proxy of the projection experiment's failures."""
    pts = np.asarray(points, dtype=np.float64)
    views = _tilt_views()
    centred = pts - pts.mean(axis=1, keepdims=True)
    cam = np.einsum("vij,bkj->bvki", views, centred)
    depth = cam[..., 2] + _DISTANCE
    u = np.floor(_FOCAL * cam[..., 0] / depth + 0.5)
    v = np.floor(_FOCAL * cam[..., 1] / depth + 0.5)
    a, b, c = _triples(pts.shape[1])
    d = (u[..., b] - u[..., a]) * (v[..., c] - v[..., a]) - (v[..., b] - v[..., a]) * (u[..., c] - u[..., a])
    signs = _triple_signs(pts)[:, None, :]
    out: NDArray[np.int64] = (np.sign(d) != signs).any(axis=-1).sum(axis=-1).astype(np.int64)
    return out


def _tilt_choice(points: NDArray[np.int64], mps: NDArray[np.float64], tol: float) -> int:
    """Index of the chosen one of several integer realizations of one set: the fewest
    :func:`tilt_failures` among those with MP ≥ max((1 − tol) · best, the largest value
    of ``_MP_STEPS`` ≤ best), then the larger MP, then the first."""
    best = float(mps.max())
    steps = _MP_STEPS[best + _KEY_EPS >= _MP_STEPS]
    floor = max(best * (1.0 - tol), float(steps.max()) if steps.size else 0.0)
    ok = np.flatnonzero(mps >= floor - _KEY_EPS)
    fails = tilt_failures(points[ok])
    order = np.lexsort((ok, -mps[ok], fails))
    return int(ok[order[0]])


def maximize_mp(
    points: ArrayLike, seed: int = 0, *, text: str | None = None, effort: RealizeEffort | None = None
) -> NDArray[np.int64]:
    """Integer realization ``(k, 2)`` in [0, 255]² of the order type of ``points`` with large MP.

    ``points`` is any realization in general position (float or int, any scale).
    Deterministic for a given ``seed`` and order type. The result has the same canonical
    ID as ``points`` (checked; :class:`UsageError` if the search cannot keep it).
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
    conts: list[float] = []
    starts: list[NDArray[np.float64]] = []
    signs_list: list[NDArray[np.float64]] = []
    for pts, text in zip(points, texts, strict=True):
        rng = set_rng(seed, text)
        cont, cont_mp = optimize_continuous(pts, rng, eff)
        signs = _triple_signs(pts)
        cands = _best_roundings(cont, signs, eff, rng)
        if cont_mp < eff.hard_below and eff.exact_variants > 0:
            cands = np.concatenate([cands, _exact_roundings(cont, signs, eff, rng)])
        starts.append(cands)
        signs_list.append(np.broadcast_to(signs, (cands.shape[0], signs.size)))
        conts.append(cont_mp)
    found, mps = integer_local_search(np.concatenate(starts), np.concatenate(signs_list), eff.search_iters)
    bounds = np.cumsum([0] + [s.shape[0] for s in starts]).tolist()
    picks = [lo + _tilt_choice(found[lo:hi], mps[lo:hi], eff.tilt_tol) for lo, hi in itertools.pairwise(bounds)]
    chosen = found[picks]
    chosen_mp = mps[picks]
    got = canonical_batch(chosen).texts()
    out: list[RealizedSet] = []
    for i, text in enumerate(texts):
        if chosen_mp[i] <= 0 or got[i] != text:
            raise UsageError(f"could not realize {text} on the 256 × 256 grid (best MP {chosen_mp[i]:.3f})")
        out.append(RealizedSet(text=text, points=chosen[i], mp=float(chosen_mp[i]), continuous_mp=conts[i]))
    return out


def realize_all(
    points: Sequence[ArrayLike],
    texts: Sequence[str],
    *,
    seed: int = 0,
    jobs: int = 1,
    efforts: dict[int, RealizeEffort] | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    stage: str = "realize",
) -> list[RealizedSet]:
    """Realize many order types (``points[i]`` a realization of ID ``texts[i]``) on the grid.

    Work is cut into fixed chunks of ``_CHUNK`` sets and spread over ``jobs`` processes;
    each set is seeded from ``(seed, ID)``, so the result does not depend on ``jobs``.
    ``efforts`` overrides :func:`default_effort` per k. ``progress(stage, done, total)``
    is called as chunks finish. Returns the results in input order.
    """
    if jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {jobs}")
    pts_list = [np.asarray(p, dtype=np.float64) for p in points]
    if len(pts_list) != len(texts):
        raise ValueError("points and texts differ in length")
    total = len(pts_list)
    chunks: list[tuple[NDArray[np.float64], list[str], int, dict[int, RealizeEffort] | None]] = []
    for start in range(0, total, _CHUNK):
        block = pts_list[start : start + _CHUNK]
        ks = {p.shape[0] for p in block}
        if len(ks) == 1:
            chunks.append((np.stack(block), list(texts[start : start + _CHUNK]), seed, efforts))
        else:  # mixed k: one chunk per set
            for off, p in enumerate(block):
                chunks.append((p[None], [texts[start + off]], seed, efforts))
    results: list[RealizedSet] = []
    done = 0
    if progress is not None:
        progress(stage, 0, total)
    if jobs == 1 or len(chunks) == 1:
        for chunk in chunks:
            results.extend(_realize_chunk(chunk))
            done += len(chunk[1])
            if progress is not None:
                progress(stage, done, total)
        return results
    with ProcessPoolExecutor(max_workers=min(jobs, len(chunks), os.cpu_count() or jobs)) as pool:
        for part in pool.map(_realize_chunk, chunks):
            results.extend(part)
            done += len(part)
            if progress is not None:
                progress(stage, done, total)
    return results
