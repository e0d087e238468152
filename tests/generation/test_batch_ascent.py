"""The batched realizer of nine-point sets (issue 14, item 3): the soft-min ascent keeps every
order type, raises MP, gives each set the same bytes whatever the batch, and the incremental
integer search is the old search, only cheaper.

Nine-point sets come from the bundled eight-point sets with a ninth point added at random in
general position (so many starts have a tiny MP: the hard case of the ascent).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.canonical import canonical_batch
from ottag_db.core.geometry import general_position_mask
from ottag_db.generation.batch_ascent import AscentSchedule, soft_min_ascent
from ottag_db.generation.continuous import _to_box
from ottag_db.generation.effort import default_effort
from ottag_db.generation.objective import GRID_MAX, grid_mp, signed_mp_terms, triple_signs
from ottag_db.generation.realize import _rescue, realize_all
from ottag_db.generation.rounding import _KEY_EPS, _MOVES, _keys, integer_local_search

SHORT = AscentSchedule(iters=120)


def _nine_point_sets(bundled: dict[int, np.ndarray], count: int, seed: int) -> np.ndarray:
    """``count`` nine-point sets in general position in the [0, 255]² box (float grid units)."""
    rng = np.random.default_rng(seed)
    eights = bundled[8][rng.choice(bundled[8].shape[0], 4 * count, replace=False)].astype(np.float64)
    extra = rng.uniform(0.0, 255.0, (eights.shape[0], 1, 2))
    sets = np.concatenate([eights, extra], axis=1)
    sets = sets[general_position_mask(sets)][:count]
    assert sets.shape[0] == count
    return np.stack([_to_box(s) for s in sets])


@pytest.fixture(scope="module")
def nines(bundled_sets: dict[int, np.ndarray]) -> np.ndarray:
    return _nine_point_sets(bundled_sets, 24, seed=3)


def test_ascent_keeps_every_order_type_and_raises_mp(nines: np.ndarray) -> None:
    signs = triple_signs(nines)
    before = grid_mp(nines, signs)
    out, mp = soft_min_ascent(nines, signs, SHORT)
    assert out.shape == nines.shape and out.min() >= 0 and out.max() <= GRID_MAX
    assert (triple_signs(out) == signs).all()
    assert canonical_batch(out).texts() == canonical_batch(nines).texts()
    assert np.allclose(mp, grid_mp(out, signs), rtol=1e-9)
    assert (mp >= before).all()
    # Random ninth points make thin triangles; the ascent opens them up many times over.
    assert np.median(mp / before) > 2.0


def test_ascent_result_does_not_depend_on_the_batch(nines: np.ndarray) -> None:
    signs = triple_signs(nines)
    whole, whole_mp = soft_min_ascent(nines, signs, SHORT)
    again, again_mp = soft_min_ascent(nines.copy(), signs.copy(), SHORT)
    assert whole.tobytes() == again.tobytes() and whole_mp.tobytes() == again_mp.tobytes()
    parts = [soft_min_ascent(nines[i : i + n], signs[i : i + n], SHORT) for i, n in ((0, 1), (1, 7), (8, 16))]
    split = np.concatenate([p[0] for p in parts])
    split_mp = np.concatenate([p[1] for p in parts])
    assert split.tobytes() == whole.tobytes() and split_mp.tobytes() == whole_mp.tobytes()
    # Order within the batch does not matter either.
    rev, rev_mp = soft_min_ascent(nines[::-1], signs[::-1], SHORT)
    assert rev[::-1].tobytes() == whole.tobytes() and rev_mp[::-1].tobytes() == whole_mp.tobytes()


def test_a_batch_mixing_easy_and_nearly_degenerate_sets(nines: np.ndarray) -> None:
    easy = nines[:4]
    # A point 1e-6 grid units from the line of two others: one triple is almost flat.
    thin = nines[4].copy()
    thin[8] = thin[0] + 0.37 * (thin[1] - thin[0])
    normal = np.array([-(thin[1] - thin[0])[1], (thin[1] - thin[0])[0]])
    thin[8] += 1e-6 * normal / np.linalg.norm(normal)
    # And one with two points 1e-3 grid units apart.
    close = nines[5].copy()
    close[3] = close[2] + 1e-3 * (close[3] - close[2]) / np.linalg.norm(close[3] - close[2])
    batch = np.concatenate([easy, thin[None], close[None]])
    assert general_position_mask(batch).all()
    signs = triple_signs(batch)
    start_mp = grid_mp(batch, signs)
    assert start_mp[4] < 1e-5 and start_mp[5] < 1e-3
    out, mp = soft_min_ascent(batch, signs, SHORT)
    assert (triple_signs(out) == signs).all()
    assert canonical_batch(out).texts() == canonical_batch(batch).texts()
    # Steps are capped at a third of the smallest height (see batch_ascent), so a set whose
    # smallest height comes from two close points grows geometrically, a few % per step.
    assert mp[4] > 1e5 * start_mp[4] and mp[5] > 10 * start_mp[5]
    alone, alone_mp = soft_min_ascent(easy, signs[:4], SHORT)
    assert alone.tobytes() == out[:4].tobytes() and alone_mp.tobytes() == mp[:4].tobytes()


def test_a_start_with_a_wrong_orientation_is_left_alone(nines: np.ndarray) -> None:
    signs = triple_signs(nines[:2])
    signs[1, 5] *= -1
    out, mp = soft_min_ascent(nines[:2], signs, SHORT)
    assert mp[0] > 0 and mp[1] <= 0
    assert np.array_equal(out[1], nines[1])


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


def full_local_search(
    points: ArrayLike, signs: ArrayLike, max_iters: int = 200
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The integer search recomputing every triple of every moved set (the oracle)."""
    pts = np.asarray(points, dtype=np.float64).copy()
    sg = np.asarray(signs, dtype=np.float64)
    b, k, _ = pts.shape
    n_moves = _MOVES.shape[0]
    keys = _keys(signed_mp_terms(pts, sg))
    active = np.ones(b, dtype=bool)
    for _ in range(max_iters):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        cand = np.repeat(pts[idx][:, None, None], k * n_moves, axis=1).reshape(idx.size, k, n_moves, k, 2)
        for q in range(k):
            cand[:, q, :, q, :] += _MOVES
        cand = np.clip(cand.reshape(idx.size, k * n_moves, k, 2), 0.0, float(GRID_MAX))
        cand_keys = _keys(signed_mp_terms(cand, sg[idx][:, None, :]))
        rows = np.arange(idx.size)
        best = _lex_argmax(cand_keys)
        best_keys = cand_keys[rows, best]
        improved = _lex_greater(best_keys, keys[idx])
        pts[idx[improved]] = cand[rows[improved], best[improved]]
        keys[idx[improved]] = best_keys[improved]
        active[idx[~improved]] = False
    return pts.astype(np.int64), keys[:, 0]


@settings(deadline=None, max_examples=25)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(3, 9))
def test_incremental_search_is_the_full_search(seed: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    pts = rng.integers(0, 256, size=(12, k, 2)).astype(np.float64)
    pts[:3] = np.clip(pts[:3], 0, 3)  # crowded at a corner: moves get clipped by the box
    pts = pts[general_position_mask(pts)]
    signs = triple_signs(pts)
    old, old_mp = full_local_search(pts, signs, 15)
    new, new_mp = integer_local_search(pts, signs, 15)
    assert new.tobytes() == old.tobytes()
    assert new_mp.tobytes() == old_mp.tobytes()


def test_default_effort_nine_uses_the_batched_path_and_eight_does_not() -> None:
    assert default_effort(9).ascent is not None and default_effort(9).chunk > 0
    for k in range(3, 9):
        eff = default_effort(k)
        assert eff.ascent is None and eff.chunk == 0 and eff.polish_below == 0.0


def test_realize_all_nine_points_keeps_ids_and_ignores_the_batching(nines: np.ndarray) -> None:
    sets = list(nines[:10])
    texts = canonical_batch(nines[:10]).texts()
    eff = default_effort(9)
    whole = realize_all(sets, texts, seed=5, efforts={9: eff})
    assert [s.text for s in whole] == texts
    got = canonical_batch(np.stack([s.points for s in whole])).texts()
    assert got == texts
    for s in whole:
        assert s.points.dtype == np.int64 and s.points.min() >= 0 and s.points.max() <= GRID_MAX
        assert 0 < s.mp <= s.continuous_mp + 1e-9
    # Three units of 4, 4 and 2 sets instead of one: the same bytes.
    small = realize_all(sets, texts, seed=5, efforts={9: dataclasses.replace(eff, chunk=4)})
    assert [s.points.tobytes() for s in small] == [s.points.tobytes() for s in whole]
    assert [s.mp for s in small] == [s.mp for s in whole]
    assert [s.continuous_mp for s in small] == [s.continuous_mp for s in whole]


def test_the_per_set_rescue_realizes_a_nearly_degenerate_set(nines: np.ndarray) -> None:
    # What the batched path falls back to for a set none of whose roundings keeps the order
    # type: one point 1e-3 grid units off the line of two others is opened up by SLSQP.
    thin = np.round(nines[6])
    thin[1] += (thin[1] - thin[0]) % 2  # an integer midpoint of points 0 and 1
    thin[8] = 0.5 * (thin[0] + thin[1])
    normal = np.array([-(thin[1] - thin[0])[1], (thin[1] - thin[0])[0]])
    thin[8] += 1e-3 * normal / np.linalg.norm(normal)
    text = canonical_batch(thin[None]).texts()[0]
    got = _rescue(thin, text, seed=2)
    assert got.text == text and canonical_batch(got.points[None]).texts() == [text]
    assert got.mp > 0 and got.continuous_mp > 100 * 1e-3
