"""Continuous stage for many sets at once: gradient ascent on a soft minimum of the heights.

The realizer's per-set SLSQP (:mod:`ottag_db.generation.continuous`) costs about 0.2 s per
set; for the 158,817 nine-point order types this module optimizes a whole batch
``(N, k, 2)`` with numpy instead. The objective is the log-sum-exp soft minimum of the
signed heights of every triangle (the three point-to-line distances of every triple, signs
from the target order type), maximized by Adam in the box [0, GRID_MAX]². The smoothing
``τ`` is a fraction of each set's current smallest height, shrinking from ``tau_start`` to
``tau_end`` over the run, so the ascent is scale-free and ends close to the true
max-min. A step that would make any height ≤ 0 (flip a triple) is never taken: that set
stays where it was and halves its step size. The best iterate (largest smallest height) of
each set is returned.

Every operation acts row by row (elementwise arithmetic, gathers, reductions along the
axes of one set; no BLAS), so a set's result does not depend on the other sets of the batch
nor on how sets are split into batches.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import triple_indices
from ottag_db.generation.objective import GRID_MAX

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


# Constant index table of k, built once per k and read-only.
@cache
def _owner_slots(k: int) -> NDArray[np.intp]:
    """``(k, C(k−1, 2))`` positions of point ``q`` in the stacked per-triple gradients
    ``[grad a | grad b | grad c]`` (each ``C(k, 3)`` long)."""
    a, b, c = triple_indices(k)
    owner = np.concatenate([a, b, c])
    out = np.stack([np.flatnonzero(owner == q) for q in range(k)])
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class _State:
    """Points ``(N, k, 2)`` and the figures of their triples: side vectors ``ab, ac, bc``
    ``(N, T, 2)``, twice the signed area ``d`` ``(N, T)``, side lengths opposite a, b, c
    ``lengths`` ``(N, T, 3)``, signed heights ``heights`` ``(N, T, 3)`` and the smallest
    height ``low`` ``(N,)`` (grid units)."""

    points: NDArray[np.float64]
    ab: NDArray[np.float64]
    ac: NDArray[np.float64]
    bc: NDArray[np.float64]
    d: NDArray[np.float64]
    lengths: NDArray[np.float64]
    heights: NDArray[np.float64]
    low: NDArray[np.float64]


def _state(points: NDArray[np.float64], signs: NDArray[np.float64]) -> _State:
    a, b, c = triple_indices(points.shape[1])
    pa, pb, pc = points[:, a], points[:, b], points[:, c]
    ab, ac, bc = pb - pa, pc - pa, pc - pb
    d = ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0]
    lengths = np.sqrt(np.stack([(bc * bc).sum(-1), (ac * ac).sum(-1), (ab * ab).sum(-1)], axis=-1))
    with np.errstate(divide="ignore", invalid="ignore"):
        heights = np.where(lengths > 0, (signs * d)[..., None] / lengths, -np.inf)
    low = heights.reshape(heights.shape[0], -1).min(axis=1)
    return _State(points, ab, ac, bc, d, lengths, heights, low)


def _gradient(st: _State, signs: NDArray[np.float64], tau: NDArray[np.float64]) -> NDArray[np.float64]:
    """Gradient ``(N, k, 2)`` of the soft minimum ``−τ log Σ exp(−h/τ)`` of the heights."""
    k = st.points.shape[1]
    z = np.exp(-(st.heights - st.low[:, None, None]) / tau[:, None, None])
    weights = z / z.sum(axis=(1, 2), keepdims=True)
    per_length = weights / st.lengths
    # h_r = s·D / L_r, so ∇h_r = (s / L_r) ∇D − (h_r / L_r) ∇L_r: one coefficient on ∇D per
    # triple and one per side on the gradient of its length.
    coef_d = (signs * per_length.sum(axis=-1))[..., None]
    side = -(per_length * st.heights) / st.lengths
    u_bc = side[..., 0, None] * st.bc
    u_ac = side[..., 1, None] * st.ac
    u_ab = side[..., 2, None] * st.ab
    # ∇D: a → (−bc_y, bc_x), b → (ac_y, −ac_x), c → (−ab_y, ab_x).
    ga = coef_d * np.stack([-st.bc[..., 1], st.bc[..., 0]], axis=-1) - u_ab - u_ac
    gb = coef_d * np.stack([st.ac[..., 1], -st.ac[..., 0]], axis=-1) + u_ab - u_bc
    gc = coef_d * np.stack([-st.ab[..., 1], st.ab[..., 0]], axis=-1) + u_ac + u_bc
    stacked = np.concatenate([ga, gb, gc], axis=1)
    out: NDArray[np.float64] = stacked[:, _owner_slots(k)].sum(axis=2)
    return out


def _keep_rows(new: _State, old: _State, rows: NDArray[np.bool_]) -> _State:
    """``new`` with ``rows`` taken from ``old`` (the sets whose step was refused)."""
    fields = []
    for name in ("points", "ab", "ac", "bc", "d", "lengths", "heights", "low"):
        arr = getattr(new, name).copy()
        arr[rows] = getattr(old, name)[rows]
        fields.append(arr)
    return _State(*fields)


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
    # C order for both: the layout of the intermediate arrays follows the inputs', and the
    # order in which a sum over a set's triples adds its terms follows that layout.
    sg = np.ascontiguousarray(signs, dtype=np.float64)
    st = _state(np.array(starts, dtype=np.float64, order="C"), sg)
    best = st.points.copy()
    best_low = st.low.copy()
    n = best.shape[0]
    m1 = np.zeros_like(best)
    m2 = np.zeros_like(best)
    rate = np.ones(n)
    steps = max(sch.iters - 1, 1)
    for t in range(sch.iters):
        frac = t / steps
        lr = sch.lr_start * (sch.lr_end / sch.lr_start) ** frac
        tau = sch.tau_start * (sch.tau_end / sch.tau_start) ** frac * np.maximum(st.low, _TAU_FLOOR)
        grad = _gradient(st, sg, tau)
        m1 = _BETA1 * m1 + (1.0 - _BETA1) * grad
        m2 = _BETA2 * m2 + (1.0 - _BETA2) * grad * grad
        # Adam moves a coordinate by about the step size, so a step below a third of the
        # smallest height rarely flips a triple: a near-degenerate start creeps out instead of
        # having every step refused.
        gain = np.minimum(lr * rate, _STEP_PER_HEIGHT * np.maximum(st.low, 0.0)) / (1.0 - _BETA1 ** (t + 1))
        step = gain[:, None, None] * m1 / (np.sqrt(m2 / (1.0 - _BETA2 ** (t + 1))) + 1e-12)
        new = _state(np.clip(st.points + step, 0.0, float(GRID_MAX)), sg)
        # The order-type guard: a set whose step would flip (or flatten) a triple stays put.
        refused = ~(new.low > 0)
        if refused.any():
            new = _keep_rows(new, st, refused)
        rate = np.where(refused, rate * 0.5, np.minimum(rate * _RATE_RECOVERY, 1.0))
        st = new
        better = st.low > best_low
        best[better] = st.points[better]
        best_low[better] = st.low[better]
    return best, 0.5 * best_low
