"""Tests of ottag_db.core.geometry: λ-matrices, hulls, MP and general position."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.core.canonical import mirror_lambdas, relabel_lambda
from ottag_db.core.geometry import (
    analyse_point_sets,
    check_general_position,
    general_position_mask,
    hull_size,
    hull_sizes,
    lambda_matrices,
    lambda_matrix,
    maximal_perturbation,
    maximal_perturbations,
    orientation_tensor,
    segment_distances,
    triple_figures,
    triple_indices,
    triple_orientations,
)
from ottag_db.errors import GeneralPositionError
from tests.support.paper import FIG4, FIG8, TABLE9


def test_orientation_convention_screen_coordinates() -> None:
    # y grows downwards: (0,0)->(10,0) and the point (5,-5) is "above" on screen = left.
    d = orientation_tensor([[0, 0], [10, 0], [5, -5]])[0]
    assert d[0, 1, 2] < 0
    assert lambda_matrix([[0, 0], [10, 0], [5, -5]])[0, 1] == 1


def test_fig4_lambda_in_canonical_order_is_table9() -> None:
    lam = lambda_matrix(FIG4)
    # Canonical labeling of Fig. 4 found by Algorithm 2 (file index of labels 0..6).
    assert relabel_lambda(lam, [4, 6, 5, 0, 1, 2, 3]).tolist() == TABLE9


def test_lambda_rows_sum_and_antisymmetry() -> None:
    rng = np.random.default_rng(1)
    pts = rng.integers(0, 65536, size=(200, 9, 2))
    lam = lambda_matrices(pts).astype(int)
    n = 9
    off = ~np.eye(n, dtype=bool)
    assert np.all((lam + lam.transpose(0, 2, 1))[:, off] == n - 2)


def test_16_bit_coordinates_do_not_overflow() -> None:
    # A nearly degenerate triple at the 16-bit extremes: exact arithmetic must see it.
    pts = np.array([[0, 0], [65535, 65534], [65534, 65533]])
    d = orientation_tensor(pts)[0]
    exact = (65535 - 0) * (65533 - 0) - (65534 - 0) * (65534 - 0)
    assert d[0, 1, 2] == exact
    assert lambda_matrix(pts)[0, 1] == (1 if exact < 0 else 0)


def test_hull_sizes() -> None:
    assert hull_size(FIG4) == 6
    assert hull_size(FIG8) == 3
    square_plus_center = [[0, 0], [10, 0], [10, 10], [0, 10], [4, 6]]
    assert hull_size(square_plus_center) == 4
    assert hull_sizes(lambda_matrices(np.array([square_plus_center, FIG8]))).tolist() == [4, 3]


def test_maximal_perturbation_by_hand() -> None:
    # Triangle with base 10 and height 4: smallest point-line distance is the height of
    # the shortest altitude = 2*area / longest side.
    pts = np.array([[0, 0], [10, 0], [5, 4]])
    area2 = 40.0
    longest = 10.0
    assert maximal_perturbation(pts) == pytest.approx(0.5 * area2 / longest)
    batch = maximal_perturbations(np.stack([pts, pts * 2]))
    assert batch[1] == pytest.approx(2 * batch[0])


def test_general_position_errors_name_the_points() -> None:
    with pytest.raises(GeneralPositionError, match=r"points 0, 1 and 3 are collinear") as err:
        check_general_position([[0, 0], [1, 1], [5, 0], [2, 2]])
    assert err.value.points == (0, 1, 3)
    with pytest.raises(GeneralPositionError, match=r"points 1 and 2 are the same point"):
        check_general_position([[0, 0], [3, 1], [3, 1], [7, 9]])
    with pytest.raises(GeneralPositionError, match=r"record 12"):
        check_general_position(np.array([[[0, 0], [1, 1], [2, 2]]]), record_offset=12)
    assert general_position_mask(np.array([FIG8, [[0, 0], [1, 1], [2, 2], [3, 7], [9, 1]]])).tolist() == [True, False]


# ----------------------------------------------------------------------------- properties
def _grid_sets(seed: int, k: int, count: int = 20) -> np.ndarray:
    """Random integer sets on the 256 × 256 grid in general position."""
    sets = np.random.default_rng(seed).integers(0, 256, size=(count, k, 2))
    return sets[general_position_mask(sets)]


def test_triple_indices_are_the_combinations() -> None:
    for n in range(3, 11):
        a, b, c = triple_indices(n)
        assert list(zip(a.tolist(), b.tolist(), c.tolist(), strict=True)) == list(combinations(range(n), 3))
        assert not a.flags.writeable


@settings(deadline=None, max_examples=60)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(3, 10), scale=st.sampled_from([1.0, 1e-3, 255.0, 1e4]))
def test_triple_orientations_are_the_tensor_at_the_triples(seed: int, k: int, scale: float) -> None:
    pts = np.random.default_rng(seed).random((5, k, 2)) * scale
    a, b, c = triple_indices(k)
    assert np.array_equal(triple_orientations(pts), orientation_tensor(pts)[:, a, b, c])  # bit for bit


@settings(deadline=None, max_examples=60)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(3, 10))
def test_both_orientation_forms_agree_exactly_on_the_grid(seed: int, k: int) -> None:
    pts = np.random.default_rng(seed).integers(0, 65536, size=(10, k, 2))
    d, longest = triple_figures(pts)
    assert np.array_equal(d, triple_orientations(pts))
    a, b, c = triple_indices(k)
    sides = np.linalg.norm(pts[:, [a, b, a]] - pts[:, [b, c, c]], axis=-1)  # (B, 3, T)
    assert np.allclose(longest, sides.max(axis=1), rtol=1e-12)
    ok = general_position_mask(pts)
    with np.errstate(divide="ignore", invalid="ignore"):
        mp = 0.5 * (np.abs(d) / longest).min(axis=1)
    assert np.allclose(mp[ok], maximal_perturbations(pts[ok]), rtol=1e-12)


@settings(deadline=None, max_examples=60)
@given(
    seed=st.integers(0, 2**32 - 1),
    k=st.integers(3, 9),
    dx=st.integers(-1000, 1000),
    dy=st.integers(-1000, 1000),
    turns=st.integers(0, 3),
    factor=st.integers(1, 50),
)
def test_lambda_and_mp_under_translation_rotation_and_scaling(
    seed: int, k: int, dx: int, dy: int, turns: int, factor: int
) -> None:
    pts = _grid_sets(seed, k)
    moved = pts + np.array([dx, dy])
    for _ in range(turns):  # quarter turns keep orientation and integer coordinates
        moved = np.stack([-moved[..., 1], moved[..., 0]], axis=-1)
    assert np.array_equal(lambda_matrices(moved), lambda_matrices(pts))
    assert np.allclose(maximal_perturbations(moved), maximal_perturbations(pts), rtol=1e-12)
    assert np.allclose(maximal_perturbations(pts * factor), factor * maximal_perturbations(pts), rtol=1e-12)
    analysis = analyse_point_sets(pts)
    assert analysis.general_position.all()
    assert np.array_equal(analysis.lambdas, lambda_matrices(pts))
    assert np.allclose(analysis.mp, maximal_perturbations(pts), rtol=1e-12)


@settings(deadline=None, max_examples=60)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(3, 9), axis=st.sampled_from([0, 1]))
def test_reflection_complements_lambda(seed: int, k: int, axis: int) -> None:
    pts = _grid_sets(seed, k)
    reflected = pts.copy()
    reflected[..., axis] = 255 - reflected[..., axis]
    assert np.array_equal(lambda_matrices(reflected), mirror_lambdas(lambda_matrices(pts)))
    assert np.array_equal(hull_sizes(lambda_matrices(reflected)), hull_sizes(lambda_matrices(pts)))


_coord = st.floats(-100.0, 100.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(_coord, _coord), min_size=3, max_size=3))
def test_segment_distance_is_the_closest_point_of_the_segment(xy) -> None:
    """The distance to a segment is that of its closest point: never more than to either end, and
    within a hair of the nearest of 2,001 points along it; zero at the segment's own points."""
    p, a, b = (np.array(v) for v in xy)
    d = float(segment_distances(p[None], a[None], b[None])[0, 0])
    along = a + np.linspace(0.0, 1.0, 2001)[:, None] * (b - a)
    sampled = float(np.linalg.norm(along - p, axis=1).min())
    assert d <= min(np.linalg.norm(p - a), np.linalg.norm(p - b)) + 1e-9
    assert sampled - np.linalg.norm(b - a) / 2000 - 1e-9 <= d <= sampled + 1e-9
    assert segment_distances(along[::500], a[None], b[None]).max() < 1e-9
