"""Single-set orientation table: λ, margin and orderings agree with the batch core."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.core.canonical import canonical_orderings
from ottag_db.core.geometry import lambda_matrix, maximal_perturbation
from ottag_db.core.single_set import MAX_TABLE_POINTS, margin, orientation_table, pair_table, read_set

point_sets = st.integers(3, 8).flatmap(
    lambda k: st.lists(st.tuples(st.integers(0, 639), st.integers(0, 479)), min_size=k, max_size=k, unique=True)
)


@settings(max_examples=200, deadline=None)
@given(point_sets)
def test_single_set_matches_the_batch_core(points: list[tuple[int, int]]) -> None:
    pts = np.array(points, dtype=np.float64)
    table, orderings = read_set(pts)
    assert table.margin == pytest.approx(2 * maximal_perturbation(pts))
    assert margin(pts) == table.margin
    if table.margin > 0:
        assert np.array_equal(table.lambda_matrix(), lambda_matrix(pts))
        expected = canonical_orderings(pts)
        assert [lab for lab, _ in orderings] == [lab for lab, _ in expected]
        assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(orderings, expected, strict=True))
    else:
        assert orderings == []


def test_orientation_convention_and_distances() -> None:
    # screen coordinates: (0, -1) is above the x axis, i.e. left of (0, 0) → (1, 0)
    table = orientation_table([[0, 0], [1, 0], [0, -1]])
    assert table.cross[0, 2] < 0 and table.cross[0, 0] == table.cross[0, 1] == 0
    assert table.distance[0, 2] == 1.0 and np.isinf(table.distance[0, :2]).all()
    assert table.lambda_matrix().tolist() == [[0, 1, 0], [0, 0, 1], [1, 0, 0]]
    assert margin([[0, 0], [2, 0], [4, 0]]) == 0.0


def test_pair_tables_are_shared_and_read_only() -> None:
    t = pair_table(5)
    i, j = np.triu_indices(5, 1)
    assert np.array_equal(t.first, i) and np.array_equal(t.second, j)
    assert t is pair_table(5) and not t.own.flags.writeable
    big = pair_table(MAX_TABLE_POINTS + 1)
    assert len(big.first) == (MAX_TABLE_POINTS + 1) * MAX_TABLE_POINTS // 2
