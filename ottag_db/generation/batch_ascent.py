"""Continuous stage for many sets at once: gradient ascent on a soft minimum of the heights.

The realizer's per-set SLSQP (:mod:`ottag_db.generation.continuous`) costs about 0.2 s per
set; for the 158,817 nine-point order types this module raises the MP of a whole batch
``(N, k, 2)`` in a compiled loop (Numba) instead. The objective is the log-sum-exp soft
minimum of the signed heights of every triangle (the three point-to-line distances of every
triple, signs from the target order type), maximized by Adam in the box [0, GRID_MAX]². The
smoothing ``τ`` is a fraction of each set's current smallest height, shrinking from
``tau_start`` to ``tau_end`` over the run, so the ascent is scale-free and ends close to the
true max-min (with enough steps, as close as an SLSQP polish: see ``default_effort``). A step
that would make any height ≤ 0 (flip a triple) is never taken: that set stays where it was and
halves its step size. The best iterate (largest smallest height) of each set is returned.

Each set is optimized on its own, in a fixed order of operations, so its result does not
depend on the other sets of the batch nor on how sets are split into batches. Terms of the
soft minimum more than ``_SOFT_MIN_CUTOFF`` smoothing scales above the minimum weigh less
than e⁻⁴⁰ and are skipped (most of them, once ``τ`` is small).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from ottag_db.generation.objective import GRID_MAX, triple_table

__all__ = ["AscentSchedule", "soft_min_ascent"]

_BETA1 = 0.9
_BETA2 = 0.999
#: Smallest height (grid units) the smoothing scale is taken relative to (keeps τ > 0 for a
#: start whose smallest height is tiny).
_TAU_FLOOR = 1e-3
#: Largest Adam step size as a fraction of the set's smallest height.
_STEP_PER_HEIGHT = 1.0 / 3.0
#: After a refused step the step size halves; each accepted step grows it back by this factor.
_RATE_RECOVERY = 1.1
#: Soft-minimum terms ``exp(−(h − h_min)/τ)`` below ``exp(−_SOFT_MIN_CUTOFF)`` count as 0.
_SOFT_MIN_CUTOFF = 40.0


@dataclass(frozen=True)
class AscentSchedule:
    """Iterations and geometric schedules of the batched ascent.

    - ``iters``: Adam steps;
    - ``lr_start`` → ``lr_end``: Adam step size (grid units per coordinate and step);
    - ``tau_start`` → ``tau_end``: soft-min smoothing as a fraction of each set's current
      smallest height (unitless).
    """

    iters: int = 300
    lr_start: float = 1.0
    lr_end: float = 0.01
    tau_start: float = 1.0
    tau_end: float = 0.003


# error_model="numpy": no zero-division checks inside the loops (each divisor is tested or
# positive there), the same results; cache=False: no files written beside the package.
@njit(cache=False, error_model="numpy")
def _heights(
    p: NDArray[np.float64],
    tri: NDArray[np.intp],
    signs: NDArray[np.float64],
    h: NDArray[np.float64],
    lengths: NDArray[np.float64],
) -> float:
    """Fill the signed heights ``h`` ``(T, 3)`` and opposite side lengths of set ``p``; return
    the smallest height (NaN or ≤ 0 when a triple is flat, flipped or degenerate)."""
    low = np.inf
    for t in range(tri.shape[0]):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        abx, aby = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1]
        acx, acy = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1]
        bcx, bcy = p[c, 0] - p[b, 0], p[c, 1] - p[b, 1]
        d = signs[t] * (abx * acy - aby * acx)
        lengths[t, 0] = np.sqrt(bcx * bcx + bcy * bcy)
        lengths[t, 1] = np.sqrt(acx * acx + acy * acy)
        lengths[t, 2] = np.sqrt(abx * abx + aby * aby)
        for r in range(3):
            v = d / lengths[t, r] if lengths[t, r] > 0 else -np.inf
            h[t, r] = v
            if not v >= low:  # NaN propagates: such a set is refused
                low = v
    return low


@njit(cache=False, error_model="numpy")
def _ascend_one(
    start: NDArray[np.float64],
    signs: NDArray[np.float64],
    tri: NDArray[np.intp],
    iters: int,
    lr_start: float,
    lr_end: float,
    tau_start: float,
    tau_end: float,
    out: NDArray[np.float64],
) -> float:
    """Ascend one set from ``start``; write the best iterate to ``out``, return its smallest height."""
    k = start.shape[0]
    n_tri = tri.shape[0]
    p = start.copy()
    q = np.empty_like(p)
    h, h_new = np.empty((n_tri, 3)), np.empty((n_tri, 3))
    lengths, lengths_new = np.empty((n_tri, 3)), np.empty((n_tri, 3))
    z = np.empty((n_tri, 3))
    grad = np.empty((k, 2))
    m1, m2 = np.zeros((k, 2)), np.zeros((k, 2))
    low = _heights(p, tri, signs, h, lengths)
    out[:] = p
    best = low
    rate = 1.0
    steps = max(iters - 1, 1)
    for it in range(iters):
        if not low > 0:  # a start that breaks the order type is left alone
            break
        frac = it / steps
        lr = lr_start * (lr_end / lr_start) ** frac
        tau = tau_start * (tau_end / tau_start) ** frac * max(low, _TAU_FLOOR)
        # Soft-min weights; ∇h_r = (s / L_r) ∇D − (h_r / L_r) ∇L_r per triple (D: twice the
        # signed area, s its target sign).
        total = 0.0
        cut = low + _SOFT_MIN_CUTOFF * tau
        for t in range(n_tri):
            for r in range(3):
                w = np.exp(-(h[t, r] - low) / tau) if h[t, r] < cut else 0.0
                z[t, r] = w
                total += w
        grad[:] = 0.0
        for t in range(n_tri):
            if z[t, 0] == 0.0 and z[t, 1] == 0.0 and z[t, 2] == 0.0:
                continue
            a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
            abx, aby = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1]
            acx, acy = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1]
            bcx, bcy = p[c, 0] - p[b, 0], p[c, 1] - p[b, 1]
            w0 = z[t, 0] / total / lengths[t, 0]
            w1 = z[t, 1] / total / lengths[t, 1]
            w2 = z[t, 2] / total / lengths[t, 2]
            cd = signs[t] * (w0 + w1 + w2)
            s0 = -(w0 * h[t, 0]) / lengths[t, 0]
            s1 = -(w1 * h[t, 1]) / lengths[t, 1]
            s2 = -(w2 * h[t, 2]) / lengths[t, 2]
            ubx, uby = s0 * bcx, s0 * bcy
            uax, uay = s1 * acx, s1 * acy
            ucx, ucy = s2 * abx, s2 * aby
            # ∇D: a → (−bc_y, bc_x), b → (ac_y, −ac_x), c → (−ab_y, ab_x).
            grad[a, 0] += -cd * bcy - ucx - uax
            grad[a, 1] += cd * bcx - ucy - uay
            grad[b, 0] += cd * acy + ucx - ubx
            grad[b, 1] += -cd * acx + ucy - uby
            grad[c, 0] += -cd * aby + uax + ubx
            grad[c, 1] += cd * abx + uay + uby
        # Adam moves a coordinate by about the step size, so a step below a third of the
        # smallest height rarely flips a triple: a near-degenerate start creeps out instead of
        # having every step refused.
        gain = min(lr * rate, _STEP_PER_HEIGHT * low) / (1.0 - _BETA1 ** (it + 1))
        second = 1.0 - _BETA2 ** (it + 1)
        for i in range(k):
            for j in range(2):
                m1[i, j] = _BETA1 * m1[i, j] + (1.0 - _BETA1) * grad[i, j]
                m2[i, j] = _BETA2 * m2[i, j] + (1.0 - _BETA2) * grad[i, j] * grad[i, j]
                moved = p[i, j] + gain * m1[i, j] / (np.sqrt(m2[i, j] / second) + 1e-12)
                q[i, j] = min(max(moved, 0.0), float(GRID_MAX))
        low_new = _heights(q, tri, signs, h_new, lengths_new)
        if low_new > 0:  # the order-type guard: a step that flips a triple is refused
            p, q = q, p
            h, h_new = h_new, h
            lengths, lengths_new = lengths_new, lengths
            low = low_new
            rate = min(rate * _RATE_RECOVERY, 1.0)
            if low > best:
                best = low
                out[:] = p
        else:
            rate *= 0.5
    return best


@njit(cache=False, error_model="numpy")
def _ascend_all(
    starts: NDArray[np.float64],
    signs: NDArray[np.float64],
    tri: NDArray[np.intp],
    iters: int,
    lr_start: float,
    lr_end: float,
    tau_start: float,
    tau_end: float,
    out: NDArray[np.float64],
    low: NDArray[np.float64],
) -> None:
    for n in range(starts.shape[0]):
        low[n] = _ascend_one(starts[n], signs[n], tri, iters, lr_start, lr_end, tau_start, tau_end, out[n])


def soft_min_ascent(
    starts: ArrayLike, signs: ArrayLike, schedule: AscentSchedule | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Raise the smallest point-to-line distance of many labelled sets at once.

    Parameters
    ----------
    starts : array_like, shape (N, k, 2)
        Start points in [0, GRID_MAX]² (grid units, screen coordinates), each with every
        triple oriented as ``signs`` says.
    signs : array_like, shape (N, C(k, 3))
        Target orientation of every triple ``a < b < c`` (±1, see
        :func:`~ottag_db.generation.objective.triple_signs`).
    schedule : AscentSchedule, optional
        Iterations and step / smoothing schedules; the defaults when None.

    Returns
    -------
    points : ndarray of float64, shape (N, k, 2)
        The best iterate of each set (grid units), orientations as ``signs``; the start
        itself when no step improved it.
    mp : ndarray of float64, shape (N,)
        Its MP: half the smallest point-to-line distance (grid units); ≤ 0 only for a start
        that already broke ``signs``.
    """
    sch = schedule if schedule is not None else AscentSchedule()
    pts = np.array(starts, dtype=np.float64, order="C")
    sg = np.ascontiguousarray(signs, dtype=np.float64)
    tri = triple_table(pts.shape[1])
    out = np.empty_like(pts)
    low = np.empty(pts.shape[0])
    _ascend_all(pts, sg, tri, sch.iters, sch.lr_start, sch.lr_end, sch.tau_start, sch.tau_end, out, low)
    return out, 0.5 * low
