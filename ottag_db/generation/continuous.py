"""Continuous stage of the realization: SLSQP maximizes the smallest signed point-to-line
distance of a labelled set in the box [0, GRID_MAX]² (grid units)."""

from __future__ import annotations

import ctypes
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize

from ottag_db.core.geometry import triple_indices
from ottag_db.generation.effort import RealizeEffort, default_effort
from ottag_db.generation.objective import GRID_MAX, grid_mp, triple_signs

__all__ = ["optimize_continuous", "polish_slsqp", "start_points"]

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
# Continuous optimization (SLSQP): maximize t with every signed point-to-line distance ≥ t
# --------------------------------------------------------------------------------------------


def _point_line(k: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Every (point p, line through i, j) with p, i, j distinct: 3 per triple, in triple order."""
    a, b, c = triple_indices(k)
    p = np.stack([a, b, c], axis=1).ravel()
    i = np.stack([b, a, a], axis=1).ravel()
    j = np.stack([c, c, b], axis=1).ravel()
    return p, i, j


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


def optimize_continuous(
    points: ArrayLike, rng: np.random.Generator, effort: RealizeEffort | None = None
) -> tuple[NDArray[np.float64], float]:
    """Best real-valued realization in [0, 255]² of the order type of ``points`` ``(k, 2)``.

    Runs SLSQP (maximize t s.t. every point-to-line distance, with the sign of the input,
    is ≥ t) from the input scaled into the box, from ``starts − 1`` random projective
    images and from ``hops`` random perturbations of the best so far (and, for a hard set,
    see :class:`RealizeEffort`, from ``hard_starts`` uniformly random points). Returns the best
    points (same labelling and orientations as the input) and their MP (grid units).

    Parameters
    ----------
    points : array_like, shape (k, 2)
        A realization in general position (any units, screen coordinates).
    rng : numpy.random.Generator
        Source of the random starts (see :func:`~ottag_db.generation.realize.set_rng`).
    effort : RealizeEffort, optional
        Search effort; :func:`default_effort` of ``k`` when None.

    Returns
    -------
    points : ndarray of float64, shape (k, 2)
        The best realization found, in [0, GRID_MAX]² (grid units).
    mp : float
        Its MP (grid units); ≤ 0 only when no run kept every orientation.
    """
    pts = np.asarray(points, dtype=np.float64)
    k = pts.shape[0]
    eff = effort if effort is not None else default_effort(k)
    signs = triple_signs(pts)
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


def start_points(points: ArrayLike, rng: np.random.Generator, count: int) -> NDArray[np.float64]:
    """The starts :func:`optimize_continuous` begins with: ``points`` scaled into the box, then
    ``count − 1`` random projective images of it (same order type).

    Parameters
    ----------
    points : array_like, shape (k, 2)
        A realization in general position (any units, screen coordinates).
    rng : numpy.random.Generator
        Source of the projective maps.
    count : int
        Number of starts (≥ 1).

    Returns
    -------
    ndarray of float64, shape (count, k, 2)
        Start points in [0, GRID_MAX]² (grid units).
    """
    pts = np.asarray(points, dtype=np.float64)
    return np.stack([_to_box(pts)] + [_random_projective(pts, rng) for _ in range(count - 1)])


def polish_slsqp(
    points: NDArray[np.float64], signs: NDArray[np.float64], maxiter: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One SLSQP run from each of several sets, OpenBLAS on one thread (as in
    :func:`optimize_continuous`); a set keeps its input when SLSQP does not beat it.

    Parameters
    ----------
    points : ndarray of float64, shape (M, k, 2)
        Start points in [0, GRID_MAX]² (grid units), orientations as ``signs``.
    signs : ndarray of float64, shape (M, C(k, 3))
        Target orientation of every triple.
    maxiter : int
        SLSQP iteration limit.

    Returns
    -------
    points : ndarray of float64, shape (M, k, 2)
        The better of input and SLSQP result per set (grid units).
    mp : ndarray of float64, shape (M,)
        Its MP (grid units).
    """
    out = np.array(points, dtype=np.float64)
    mps = grid_mp(out, signs) if out.shape[0] else np.zeros(0)
    with _single_blas_thread():
        for i in range(out.shape[0]):
            cand, value = _slsqp(out[i], signs[i], maxiter)
            if value > mps[i]:
                out[i], mps[i] = cand, value
    return out, mps
