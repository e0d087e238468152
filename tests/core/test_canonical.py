"""Tests of ottag_db.core.canonical: Algorithms 1 and 2, paper figures, invariance properties."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ottag_db.core.canonical import (
    canonical_batch,
    canonical_form,
    canonical_lambda,
    canonical_orderings,
    canonicalize_lambdas,
    lambda_text,
    mirror_lambdas,
    parse_lambda_text,
)
from ottag_db.core.geometry import lambda_matrices
from ottag_db.errors import LambdaFormatError
from tests.support.paper import FIG4, FIG8, TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)


def test_fig4_canonical_id_is_table9() -> None:
    form = canonical_form(FIG4)
    assert form.lambda_matrix.tolist() == TABLE9
    assert form.text == TABLE9_TEXT
    assert form.unique_min and form.hull_size == 6


def test_fig8_has_three_orderings_identity_largest() -> None:
    orderings = canonical_orderings(FIG8)
    assert len(orderings) == 3
    assert orderings[-1][0] == (0, 1, 2, 3, 4)
    mats = [m.ravel().tolist() for _, m in orderings]
    assert mats == sorted(mats) and len(set(map(tuple, mats))) == 3
    form = canonical_form(FIG8)
    assert form.minimal_orderings == 1
    # The paper: last row of the ID is [3, 0, 1, 2, -] (point 4).
    assert form.lambda_matrix[4].tolist() == [3, 0, 1, 2, 0]


def test_text_form_round_trip_and_errors() -> None:
    mat = parse_lambda_text(TABLE9_TEXT)
    assert lambda_text(mat) == TABLE9_TEXT
    for bad in ["7:123", "x:000", "3:0a0000000", "3:110000000", "12:0", "nocolon"]:
        with pytest.raises(LambdaFormatError):
            parse_lambda_text(bad)


def test_order_type_counts(point_sets: dict[int, np.ndarray]) -> None:
    # Tables 2 and 3, and the counts with mirrors.
    expected = {3: (1, 0, 1), 4: (2, 0, 2), 5: (3, 2, 3), 6: (16, 11, 20), 7: (135, 131, 242), 8: (3315, 3303, 6405)}
    for k, pts in point_sets.items():
        batch = canonical_batch(pts)
        mirror = canonicalize_lambdas(mirror_lambdas(lambda_matrices(pts)))
        ids = set(batch.texts())
        assert len(ids) == expected[k][0]
        assert int((batch.minimal_orderings == 1).sum()) == expected[k][1]
        assert len(ids | set(mirror.texts())) == expected[k][2]


def test_fig4_is_record_2_of_the_7_point_file(reference_sets: dict[int, np.ndarray]) -> None:
    assert reference_sets[7][2].tolist() == FIG4
    assert canonical_lambda(reference_sets[7][2]) == TABLE9_TEXT


def test_labeling_reproduces_the_canonical_matrix(point_sets: dict[int, np.ndarray]) -> None:
    pts = point_sets[8]
    batch = canonical_batch(pts)
    lam = lambda_matrices(pts)
    idx = np.arange(len(pts))[:, None, None]
    relabeled = lam[idx, batch.labelings[:, :, None], batch.labelings[:, None, :]]
    assert np.array_equal(relabeled, batch.lambdas)


def test_single_set_orderings_agree_with_the_batch(point_sets: dict[int, np.ndarray]) -> None:
    """canonical_orderings (single-set path): its smallest matrix and the number of orderings
    reaching it equal the batched canonicalization's, for every 7-point set."""
    pts = point_sets[7]
    batch = canonical_batch(pts)
    for b in range(len(pts)):
        orderings = canonical_orderings(pts[b])
        assert np.array_equal(orderings[0][1], batch.lambdas[b])
        assert sum(np.array_equal(m, orderings[0][1]) for _, m in orderings) == batch.minimal_orderings[b]
        assert len(orderings) == batch.hull_sizes[b]


# ----------------------------------------------------------------------------- invariance
def _base_sets() -> list[np.ndarray]:
    # Hand-made sets in general position with several hull sizes and symmetries.
    return [
        np.array(FIG4, dtype=float),
        np.array(FIG8, dtype=float),
        np.array([[52, 0], [0, 162], [127, 249], [255, 163], [202, 1]], dtype=float),
        np.array(
            [[10, 20], [200, 30], [120, 220], [90, 100], [130, 90], [110, 140], [60, 180], [180, 170]], dtype=float
        ),
        np.array([[0, 0], [255, 10], [240, 250], [5, 230], [100, 60], [160, 130], [70, 170]], dtype=float),
    ]


BASES = _base_sets()
settings.register_profile("ottag", deadline=None, max_examples=60, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ottag")


@given(idx=st.integers(0, len(BASES) - 1), seed=st.integers(0, 2**32 - 1))
def test_id_invariant_under_relabeling(idx: int, seed: int) -> None:
    pts = BASES[idx]
    perm = np.random.default_rng(seed).permutation(len(pts))
    assert canonical_lambda(pts[perm]) == canonical_lambda(pts)


@given(
    idx=st.integers(0, len(BASES) - 1),
    angle=st.floats(0, 2 * np.pi),
    tx=st.floats(-1e4, 1e4),
    ty=st.floats(-1e4, 1e4),
    sx=st.floats(0.05, 20),
    sy=st.floats(0.05, 20),
)
def test_id_invariant_under_similarity_and_scaling(
    idx: int, angle: float, tx: float, ty: float, sx: float, sy: float
) -> None:
    pts = BASES[idx]
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    want = canonical_lambda(pts)
    assert canonical_lambda(pts @ rot.T + [tx, ty]) == want  # rotation + translation
    assert canonical_lambda(pts * [sx, sx]) == want  # uniform scale
    assert canonical_lambda(pts * [sx, sy]) == want  # non-uniform scale


@given(idx=st.integers(0, len(BASES) - 1), seed=st.integers(0, 2**32 - 1))
def test_id_invariant_under_projective_maps(idx: int, seed: int) -> None:
    pts = BASES[idx]
    rng = np.random.default_rng(seed)
    h = np.eye(3) + rng.normal(scale=0.3, size=(3, 3))
    h[2, :2] = rng.normal(scale=2e-3, size=2)
    h[2, 2] = 1.0
    if np.linalg.det(h) < 0:  # a negative determinant reflects: keep orientation
        h[0, :] *= -1
    homog = np.c_[pts, np.ones(len(pts))] @ h.T
    if np.any(homog[:, 2] <= 0.05):  # keep every point on one side of the line at infinity
        return
    mapped = homog[:, :2] / homog[:, 2:]
    assert canonical_lambda(mapped) == canonical_lambda(pts)


@given(idx=st.integers(0, len(BASES) - 1), axis=st.sampled_from([0, 1]))
def test_reflection_changes_id_exactly_for_chiral_sets(idx: int, axis: int) -> None:
    pts = BASES[idx].copy()
    reflected = pts.copy()
    reflected[:, axis] *= -1
    original = canonical_batch(pts[None])
    mirror_text = canonicalize_lambdas(mirror_lambdas(lambda_matrices(pts[None]))).texts()[0]
    assert canonical_lambda(reflected) == mirror_text
    chiral = mirror_text != original.texts()[0]
    assert (canonical_lambda(reflected) != canonical_lambda(pts)) == chiral


def test_reflection_on_point_sets(point_sets: dict[int, np.ndarray]) -> None:
    pts = point_sets[7].astype(float)
    reflected = pts.copy()
    reflected[..., 0] = 255 - reflected[..., 0]
    a = canonical_batch(pts).texts()
    b = canonical_batch(reflected).texts()
    mirror = canonicalize_lambdas(mirror_lambdas(lambda_matrices(pts))).texts()
    assert b == mirror
    chiral = sum(x != y for x, y in zip(a, b, strict=True))
    assert chiral == 107  # 242 − 135 order types of 7 points are one of a chiral pair
