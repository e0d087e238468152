"""Tests of ottag_db.core.placement: the placed set keeps its order type and the margins."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.core.canonical import canonical_batch, canonical_lambda
from ottag_db.core.geometry import maximal_perturbations
from ottag_db.core.placement import mirrored_placements, tag_placement, tag_placements
from ottag_db.errors import ExportError, UsageError
from tests.support.paper import FIG4, FIG8

SETS = [np.array(FIG4), np.array(FIG8), np.array([(20, 20), (230, 40), (200, 230), (60, 200), (120, 110)])]


def _apply(maps: np.ndarray, pts: np.ndarray) -> np.ndarray:
    placed: np.ndarray = np.einsum("bxy,bky->bkx", maps[:, :, :2], pts) + maps[:, None, :, 2]
    return placed


def test_bundled_sets_keep_their_ids_and_margins(bundled_sets: dict[int, np.ndarray]) -> None:
    pts = bundled_sets[7].astype(float)
    maps = tag_placements(pts)
    placed = _apply(maps, pts)
    assert canonical_batch(placed).texts() == canonical_batch(pts).texts()
    assert placed.min() >= 0.1 - 1e-9 and placed.max() <= 0.9 + 1e-9
    # The shear/stretch search starts from the identity's neighbourhood: it never loses to
    # plain uniform scaling into the same square.
    extent = (pts.max(axis=1) - pts.min(axis=1)).max(axis=1)
    assert (maximal_perturbations(placed) >= maximal_perturbations(pts) * 0.8 / extent - 1e-9).all()


@settings(deadline=None, max_examples=40)
@given(
    idx=st.integers(0, len(SETS) - 1),
    margin=st.floats(0.0, 0.45),
    scale=st.floats(0.01, 100.0),
    tx=st.floats(-1e3, 1e3),
    ty=st.floats(-1e3, 1e3),
)
def test_placement_keeps_the_order_type_and_the_margin(
    idx: int, margin: float, scale: float, tx: float, ty: float
) -> None:
    pts = SETS[idx] * scale + [tx, ty]
    m = tag_placement(pts, margin)
    placed = pts @ m[:, :2].T + m[:, 2]
    assert np.linalg.det(m[:, :2]) > 0  # not mirrored
    assert canonical_lambda(placed) == canonical_lambda(SETS[idx])
    assert placed.min() >= margin - 1e-9 and placed.max() <= 1 - margin + 1e-9
    # Scale-free: the placement of a scaled and shifted copy prints the same points.
    base = tag_placement(SETS[idx].astype(float), margin)
    assert placed == pytest.approx(SETS[idx] @ base[:, :2].T + base[:, 2], abs=1e-6)


@settings(deadline=None, max_examples=40)
@given(idx=st.integers(0, len(SETS) - 1), axis=st.integers(-300, 600), tx=st.integers(-50, 50))
def test_mirrored_placement_prints_the_reflected_tag(idx: int, axis: int, tx: int) -> None:
    pts = (SETS[idx] + [tx, 0]).astype(np.float64)
    mirror = np.stack([axis - pts[:, 0], pts[:, 1]], axis=1)
    m = tag_placements(pts[None])
    d = mirrored_placements(m, [axis])
    placed, mirror_placed = _apply(m, pts[None])[0], _apply(d, mirror[None])[0]
    np.testing.assert_allclose(mirror_placed, np.stack([1.0 - placed[:, 0], placed[:, 1]], axis=1), atol=1e-9)
    assert np.linalg.det(d[0, :, :2]) == pytest.approx(np.linalg.det(m[0, :, :2]))  # orientation kept
    assert maximal_perturbations(mirror_placed) == pytest.approx(maximal_perturbations(placed), rel=1e-9)
    assert canonical_lambda(mirror_placed) == canonical_lambda(mirror)


def test_bad_margin_and_degenerate_sets() -> None:
    with pytest.raises(UsageError):
        tag_placement(SETS[0], 0.5)
    with pytest.raises(ExportError):
        tag_placement(np.array([(0, 0), (1, 1), (2, 2), (5, 0)]))


def test_pruned_search_equals_the_search_over_every_edge(
    bundled_sets: dict[int, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    # The search evaluates only the edges that can bind (a bound on the rest decides, and
    # sets where it cannot are searched again over every edge): the maps must be exactly
    # those of the exhaustive search, for every k, nine points included.
    import ottag_db.core.placement as placement
    from tests.support.k9_sample import nine_point_sets

    sets = [bundled_sets[k].astype(float)[:300] for k in (5, 6, 7, 8)] + [nine_point_sets(20).astype(float)]
    pruned = [tag_placements(s) for s in sets]
    monkeypatch.setattr(placement, "_KEPT_EDGES", 10**6)
    for s, maps in zip(sets, pruned, strict=True):
        assert np.array_equal(tag_placements(s), maps)
