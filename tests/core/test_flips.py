"""Tests of ottag_db.core.flips: hand-made examples, symmetry, mirrors, confirmation by orientations."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.core.canonical import canonical_batch, canonical_lambda
from ottag_db.core.flips import flip_edges, flip_neighbours
from ottag_db.core.geometry import orientation_tensor


def _complete(sets: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Both chiralities of the given sets, deduplicated, rows in canonical order."""
    mirrored = sets.astype(float).copy()
    mirrored[..., 0] = 255 - mirrored[..., 0]
    allp = np.concatenate([sets.astype(float), mirrored])
    cb = canonical_batch(allp)
    texts = cb.texts()
    first: dict[str, int] = {}
    for i, t in enumerate(texts):
        first.setdefault(t, i)
    idx = list(first.values())
    pts = allp[idx][np.arange(len(idx))[:, None], cb.labelings[idx]]
    return pts, [texts[i] for i in idx]


def _graph(pts: np.ndarray, texts: list[str]) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {t: set() for t in texts}
    for e in flip_neighbours(pts, texts):
        out[texts[e.source]].add(texts[e.target])
    return out


PENTAGON = [[100, 0], [200, 70], [160, 190], [40, 190], [0, 70]]
FOUR_PLUS_ONE = [[0, 0], [200, 0], [200, 200], [0, 200], [90, 60]]
THREE_PLUS_TWO = [[0, 0], [255, 10], [120, 250], [100, 80], [150, 125]]


def test_convex_pentagon_neighbours() -> None:
    sets = np.array([PENTAGON, FOUR_PLUS_ONE, THREE_PLUS_TWO])
    pts, texts = _complete(sets)
    assert len(texts) == 3
    g = _graph(pts, texts)
    pent, four, three = (canonical_lambda(np.array(s)) for s in (PENTAGON, FOUR_PLUS_ONE, THREE_PLUS_TWO))
    # Moving one hull vertex inside is the only flip of a convex pentagon.
    assert g[pent] == {four}
    assert pent in g[four] and three in g[four]
    assert g[three] - {three} == {four}


def test_symmetry_and_mirrors(point_sets: dict[int, np.ndarray]) -> None:
    pts, texts = _complete(point_sets[7])
    assert len(texts) == 242
    g = _graph(pts, texts)
    for a, nbrs in g.items():
        for b in nbrs:
            assert a in g[b]
    mirror_of = {}
    mirrored = pts.copy()
    mirrored[..., 0] = 255 - mirrored[..., 0]
    for t, m in zip(texts, canonical_batch(mirrored).texts(), strict=True):
        mirror_of[t] = m
    for a, nbrs in g.items():
        assert {mirror_of[b] for b in nbrs} == g[mirror_of[a]]


def test_every_edge_differs_by_exactly_one_triple(point_sets: dict[int, np.ndarray]) -> None:
    pts, texts = _complete(point_sets[6])
    left = orientation_tensor(pts) < 0
    edges = flip_neighbours(pts, texts)
    assert edges
    for e in edges:
        a, b, c = e.triple
        flipped = left[e.source].copy()
        for x, y, z in ((a, b, c), (b, c, a), (c, a, b), (b, a, c), (a, c, b), (c, b, a)):
            flipped[x, y, z] = ~flipped[x, y, z]
        # Some relabeling of the target has exactly these orientations: find it by canonicalizing.
        target = pts[e.target]
        assert canonical_lambda(target) == texts[e.target]
        diff = (left[e.source] != flipped).sum()
        assert diff == 6


@settings(deadline=None, max_examples=20)
@given(seed=st.integers(0, 2**32 - 1))
def test_edges_do_not_depend_on_the_order_of_the_list(bundled_sets: dict[int, np.ndarray], seed: int) -> None:
    pts, texts = _complete(bundled_sets[6])
    perm = np.random.default_rng(seed).permutation(len(texts))
    shuffled = [texts[i] for i in perm]
    want = {(texts[e.source], texts[e.target]) for e in flip_neighbours(pts, texts)}
    got = {(shuffled[e.source], shuffled[e.target]) for e in flip_neighbours(pts[perm], shuffled)}
    assert got == want


def test_flip_edges_from_chosen_sources_are_the_full_graphs_rows(bundled_sets: dict[int, np.ndarray]) -> None:
    pts, texts = _complete(bundled_sets[7])
    full = flip_edges(pts, texts)
    assert len(full) == len(flip_neighbours(pts, texts))
    chosen = np.array([5, 0, 131, 240])
    part = flip_edges(pts, texts, sources=chosen, chunk=100)
    want = {
        (s, t, tuple(x)) for s, t, x in zip(full.source, full.target, full.triple.tolist(), strict=True) if s in chosen
    }
    got = {(s, t, tuple(x)) for s, t, x in zip(part.source, part.target, part.triple.tolist(), strict=True)}
    assert got == want and len(part) == len(want)
    assert part.source.tolist() == sorted(part.source.tolist(), key=chosen.tolist().index)  # in the order given
    assert len(flip_edges(pts, texts, sources=np.array([], dtype=int))) == 0
