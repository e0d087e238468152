"""Clustering stage: vertex estimates of several triangles → point hypotheses."""

from __future__ import annotations

import numpy as np

from ottag_db.decode.cluster import cluster_hypotheses
from ottag_db.decode.refine import fit_chains, triangle_vertices
from ottag_db.decode.types import TriangleLines


def _lines(*tris: np.ndarray) -> TriangleLines:
    chains = [np.linspace(t[j], t[(j + 1) % 3], 10)[1:-1] for t in tris for j in range(3)]
    normal, offset = fit_chains(chains)
    return TriangleLines(normal, offset, triangle_vertices(normal, offset))


def test_shared_vertex_is_one_point() -> None:
    a = np.array([[10.0, 10.0], [50.0, 50.0], [10.0, 90.0]])
    b = np.array([[50.0, 50.0], [90.0, 10.0], [90.0, 90.0]])
    hyps = cluster_hypotheses(_lines(a, b), cap=15.0, sure=2.0, tol=1.0)
    assert len(hyps) == 1
    pts = hyps[0].points
    assert len(pts) == 5 and np.abs(pts - [50, 50]).sum(axis=1).min() < 1e-6
    shared = next(i for i, p in enumerate(pts) if np.allclose(p, [50, 50]))
    assert len(hyps[0].line_ids[shared]) == 4  # two sides of each triangle


def test_separate_triangles_and_doubtful_merges() -> None:
    a = np.array([[10.0, 10.0], [40.0, 10.0], [10.0, 40.0]])
    b = np.array([[60.0, 60.0], [90.0, 60.0], [60.0, 90.0]])
    assert [len(h.points) for h in cluster_hypotheses(_lines(a, b), 15.0, 2.0, 1.0)] == [6]
    # vertices 5 px apart whose lines meet: merged only as a doubtful merge, tried in and out
    c = np.array([[45.0, 13.0], [80.0, 13.0], [80.0, 40.0]])
    near = _lines(np.array([[10.0, 10.0], [40.0, 10.0], [10.0, 40.0]]), c)
    assert [len(h.points) for h in cluster_hypotheses(near, 15.0, 2.0, 50.0)] == [5, 6]
