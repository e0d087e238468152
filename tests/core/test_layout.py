"""Triangle layouts: every rule on every order type (and mirror), checker, edge cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.core.geometry import general_position_mask
from ottag_db.core.layout import (
    Layout,
    compute_layout,
    compute_layouts,
    layout_quality,
    layout_supported,
    validate_layout,
)
from ottag_db.errors import ExportError, GeneralPositionError
from tests.support.k9_sample import nine_point_sets
from tests.support.paper import FIG4

# Hand-made sets (not from the reference files).
SET5 = np.array([(20, 20), (230, 40), (200, 230), (60, 200), (120, 110)])
SET7 = np.array([(2, 135), (209, 203), (42, 71), (138, 55), (31, 192), (252, 177), (228, 94)])
SET8 = np.array([(142, 249), (16, 73), (229, 172), (235, 89), (40, 24), (191, 108), (191, 5), (99, 242)])


def _with_mirrors(points: np.ndarray) -> np.ndarray:
    mirrored = points.copy()
    mirrored[..., 0] = 255 - mirrored[..., 0]
    return np.concatenate([points, mirrored])


def _angles_deg(p: np.ndarray) -> list[float]:
    out = []
    for i in range(3):
        a, b, c = p[i], p[(i + 1) % 3], p[(i + 2) % 3]
        u, v = b - a, c - a
        out.append(math.degrees(math.acos(float(u @ v) / (np.linalg.norm(u) * np.linalg.norm(v)))))
    return out


@pytest.mark.parametrize("k", [5, 6, 7, 8])
def test_every_order_type_gets_a_valid_minimal_layout(point_sets: dict[int, np.ndarray], k: int) -> None:
    sets = _with_mirrors(point_sets[k])
    layouts = compute_layouts(sets)
    assert len(layouts) == len(sets)
    for n, (pts, lay) in enumerate(zip(sets, layouts, strict=True)):
        problems = validate_layout(pts, lay.triangles)
        assert problems == [], f"set {n}: {problems}"
        # ⌈k/3⌉ is a lower bound, so reaching it proves minimality
        assert lay.size == math.ceil(k / 3), f"set {n}: {lay.size} triangles"
        assert all(list(t) == sorted(t) for t in lay.triangles)
        assert list(lay.triangles) == sorted(lay.triangles)
        assert lay.min_angle_deg > 0 and lay.min_side > 0 and 0 < lay.score <= 1.1
        if lay.min_gap is not None:
            assert lay.min_gap > 0
        if lay.min_shared_gap_deg is not None:
            assert lay.min_shared_gap_deg > 0
    # figures agree with an independent computation on a sample
    for n in range(0, len(sets), max(1, len(sets) // 50)):
        pts = sets[n].astype(float)
        lay = layouts[n]
        angles = [a for t in lay.triangles for a in _angles_deg(pts[list(t)])]
        sides = [
            float(np.linalg.norm(pts[t[i]] - pts[t[j]])) for t in lay.triangles for i, j in ((0, 1), (1, 2), (0, 2))
        ]
        assert min(angles) == pytest.approx(lay.min_angle_deg, abs=1e-6)
        assert min(sides) == pytest.approx(lay.min_side, rel=1e-9)
        again = layout_quality(pts, lay.triangles)
        assert again == lay


def test_paper_figure_4_set() -> None:
    pts = np.array(FIG4)  # record 2 of the reference otypes07.b08 (see test_canonical)
    assert pts.tolist()[0] == [206, 159]
    lay = compute_layout(pts)
    assert lay.size == 3
    assert validate_layout(pts, lay.triangles) == []


def test_random_sets_always_get_layouts() -> None:
    # Validity depends on the order type only and every order type has a layout (tested
    # above), so random sets in general position must all get one too.
    rng = np.random.default_rng(1234)
    for k in (5, 6, 7, 8, 9):
        sets = rng.integers(0, 256, size=(400, k, 2))
        sets = sets[general_position_mask(sets)][:200]
        for pts, lay in zip(sets, compute_layouts(sets, chunk=64), strict=True):
            assert validate_layout(pts, lay.triangles) == []
            assert lay.size == math.ceil(k / 3)


def test_float_coordinates_and_affine_invariance() -> None:
    lay = compute_layout(SET8)
    a = np.array([[0.7, 0.3], [-0.2, 1.1]])  # det > 0
    moved = SET8 @ a.T / 300.0 + 0.1
    assert validate_layout(moved, lay.triangles) == []


def test_batch_and_single_agree_and_are_deterministic() -> None:
    batch = np.stack([SET8, SET8[::-1], SET8 + 3])
    progress: list[tuple[int, int]] = []
    many = compute_layouts(batch, progress=lambda d, t: progress.append((d, t)), chunk=2)
    assert progress == [(2, 3), (3, 3)]
    assert many[0] == compute_layout(SET8) == compute_layouts(batch)[0]
    assert many[2].triangles == many[0].triangles  # translation changes nothing
    # reversed labels: same triangles up to relabelling
    relabel = {len(SET8) - 1 - i: i for i in range(len(SET8))}
    same = sorted(tuple(sorted(relabel[v] for v in t)) for t in many[1].triangles)
    assert same == list(many[0].triangles)


def test_k3_trivial_and_k4_refused() -> None:
    lay = compute_layout(np.array([(0, 0), (100, 10), (30, 90)]))
    assert lay.triangles == ((0, 1, 2),)
    assert lay.min_gap is None and lay.min_shared_gap_deg is None
    assert isinstance(lay, Layout)
    assert layout_supported(3) and not layout_supported(4) and layout_supported(8)
    assert layout_supported(9) and not layout_supported(10)
    with pytest.raises(ExportError, match="4 points"):
        compute_layout(np.array([(0, 0), (100, 0), (100, 100), (0, 100)]))
    with pytest.raises(ExportError, match="4 points"):
        compute_layout(np.array([(0, 0), (100, 0), (50, 100), (50, 30)]))
    with pytest.raises(ExportError, match="3 ≤ k"):
        compute_layout(np.array([(i, i * i) for i in range(10)]))


def test_degenerate_set_is_rejected() -> None:
    with pytest.raises(GeneralPositionError):
        compute_layout(np.array([(0, 0), (10, 10), (20, 20), (0, 30), (50, 3)]))


def test_validate_layout_catches_bad_layouts() -> None:
    pts = np.array([(0, 0), (100, 0), (100, 100), (0, 100), (50, 40), (200, 50), (60, 160)])
    good = [(0, 1, 4), (2, 3, 6), (1, 2, 5)]
    assert validate_layout(pts, good) == [], validate_layout(pts, good)

    def problems(tris: list[tuple[int, ...]], text: str) -> None:
        found = validate_layout(pts, tris)
        assert any(text in p for p in found), found

    problems([(0, 1, 4), (2, 3, 6)], "not a vertex")  # point 5 unused
    problems([(0, 1, 4), (1, 4, 2), (2, 3, 6), (2, 5, 1)], "share the edge")
    problems([(0, 1, 2), (2, 3, 6), (1, 2, 5)], "inside or on")  # 4 inside (0, 1, 2)
    problems([(0, 1, 4), (2, 3, 6), (1, 2, 5), (3, 4, 5)], "crosses")
    problems([(0, 1, 4), (2, 3, 6), (1, 2, 5), (3, 4, 5)], "overlap")
    problems([(0, 1, 9), (2, 3, 6), (1, 2, 5)], "outside")
    problems([(0, 0, 4), (2, 3, 6), (1, 2, 5)], "repeats")
    problems([(0, 1, 4), (4, 1, 0), (2, 3, 6), (1, 2, 5)], "twice")
    problems([], "no triangles")
    # a triangle inside another one, sharing no edge
    nested = np.array([(0, 0), (300, 0), (0, 300), (40, 40), (120, 40), (40, 120)])
    found = validate_layout(nested, [(0, 1, 2), (3, 4, 5)])
    assert any("overlap" in p for p in found) and any("inside or on" in p for p in found)
    # collinear vertices
    line = np.array([(0, 0), (10, 10), (20, 20), (0, 30), (50, 3), (80, 90)])
    assert any("degenerate" in p for p in validate_layout(line, [(0, 1, 2), (3, 4, 5)]))


# ----------------------------------------------------------------------------- properties
LAYOUT_SETS = [SET5, SET7, SET8, np.array(FIG4)]


@settings(deadline=None, max_examples=40)
@given(
    idx=st.integers(0, len(LAYOUT_SETS) - 1),
    a=st.floats(0.2, 3.0),
    b=st.floats(-1.0, 1.0),
    c=st.floats(-1.0, 1.0),
    d=st.floats(0.2, 3.0),
    tx=st.floats(-1e3, 1e3),
    ty=st.floats(-1e3, 1e3),
)
def test_layout_stays_valid_under_orientation_preserving_affine_maps(
    idx: int, a: float, b: float, c: float, d: float, tx: float, ty: float
) -> None:
    m = np.array([[a, b], [c, d]])
    if np.linalg.det(m) < 0.05:  # keep orientation (and away from degenerate maps)
        return
    pts = LAYOUT_SETS[idx].astype(float)
    lay = compute_layout(pts)
    assert validate_layout(pts @ m.T + [tx, ty], lay.triangles) == []


@settings(deadline=None, max_examples=40)
@given(idx=st.integers(0, len(LAYOUT_SETS) - 1), seed=st.integers(0, 2**32 - 1))
def test_layout_size_and_score_do_not_depend_on_labels(idx: int, seed: int) -> None:
    pts = LAYOUT_SETS[idx]
    perm = np.random.default_rng(seed).permutation(len(pts))
    lay, relabeled = compute_layout(pts), compute_layout(pts[perm])
    assert relabeled.size == lay.size
    assert relabeled.score == pytest.approx(lay.score, rel=1e-9)
    assert validate_layout(pts[perm], relabeled.triangles) == []


def test_nine_points_get_three_vertex_disjoint_triangles() -> None:
    # Sorting by x and taking consecutive triples always gives three empty, disjoint
    # triangles, so every nine-point set has a layout of ⌈9/3⌉ = 3 vertex-disjoint ones.
    sets = _with_mirrors(nine_point_sets(20))
    layouts = compute_layouts(sets, chunk=7)
    for n, (pts, lay) in enumerate(zip(sets, layouts, strict=True)):
        assert validate_layout(pts, lay.triangles) == [], f"set {n}"
        assert lay.size == 3
        assert sorted(v for t in lay.triangles for v in t) == list(range(9))
        assert lay.min_gap is not None and lay.min_gap > 0 and lay.min_shared_gap_deg is None
        assert layout_quality(pts.astype(float), lay.triangles) == lay
    # a mirror image gets the mirrored layout: the same triangles, the same figures
    half = len(sets) // 2
    for lay, mirror in zip(layouts[:half], layouts[half:], strict=True):
        assert mirror.triangles == lay.triangles
        assert mirror.score == pytest.approx(lay.score, abs=1e-12)
