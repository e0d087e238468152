"""The generator's figures of merit: MP, relative MP and the signed margin."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.core.geometry import general_position_mask, maximal_perturbations
from ottag_db.generation.objective import grid_mp, relative_mp, signed_mp_terms, triple_signs


def _grid_sets(seed: int, k: int) -> np.ndarray:
    sets = np.random.default_rng(seed).integers(0, 256, size=(30, k, 2)).astype(float)
    return sets[general_position_mask(sets)]


@settings(deadline=None, max_examples=50)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(3, 8))
def test_figures_equal_the_core_mp_on_the_grid(seed: int, k: int) -> None:
    pts = _grid_sets(seed, k)
    mp = maximal_perturbations(pts)
    extent = (pts.max(axis=1) - pts.min(axis=1)).max(axis=1)
    assert np.array_equal(grid_mp(pts), mp)  # exact on integer coordinates
    assert np.array_equal(grid_mp(pts, triple_signs(pts)), mp)
    assert relative_mp(pts) == pytest.approx(mp / extent, rel=1e-12)


@settings(deadline=None, max_examples=50)
@given(
    seed=st.integers(0, 2**32 - 1),
    k=st.integers(3, 8),
    scale=st.floats(1e-3, 1e3),
    tx=st.floats(-1e3, 1e3),
    ty=st.floats(-1e3, 1e3),
)
def test_relative_mp_is_scale_free(seed: int, k: int, scale: float, tx: float, ty: float) -> None:
    pts = _grid_sets(seed, k)
    # The shift grows with the scale: relative_mp uses the products form of the orientation,
    # whose rounding error grows with |coordinates|² / |D| (see core.geometry.triple_figures).
    moved = (pts + np.array([tx, ty])) * scale
    assert relative_mp(moved) == pytest.approx(relative_mp(pts), rel=1e-6)
    assert grid_mp(moved) == pytest.approx(scale * grid_mp(pts), rel=1e-6)


@settings(deadline=None, max_examples=50)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(3, 8), flip=st.integers(0, 55))
def test_a_wrong_sign_makes_the_margin_non_positive(seed: int, k: int, flip: int) -> None:
    pts = _grid_sets(seed, k)
    signs = triple_signs(pts)
    terms = signed_mp_terms(pts, signs)
    assert (terms > 0).all()
    signs[:, flip % signs.shape[1]] *= -1
    assert (signed_mp_terms(pts, signs).min(axis=1) < 0).all()
