"""Clustering stage: triangle vertex estimates → point hypotheses (shared vertices merged)."""

from __future__ import annotations

import numpy as np
from ottag_native.cluster import vertex_groupings

from ottag_db.decode.types import PointHypothesis, TriangleLines

__all__ = ["cluster_hypotheses"]


def cluster_hypotheses(
    tris: TriangleLines, cap: float, sure: float, tol: float, max_doubtful: int = 4
) -> list[PointHypothesis]:
    """Point hypotheses from the triangle vertex estimates, most merges first.

    Estimates of different triangles may be one shared point when the least-squares
    intersection of all their side lines stays within ``tol`` px of every line (estimates at
    most ``cap`` px apart). Merges of estimates closer than ``sure`` px are always made; up to
    ``max_doubtful`` farther ones (sharp tips give long error ellipses along the bisector) are
    tried in and out, and the decoder keeps the first hypothesis that reads and verifies.

    Parameters
    ----------
    tris : TriangleLines
        Refined side lines and vertices.
    cap, sure, tol : float
        Distances in the unit of the lines (pixels), see above.
    max_doubtful : int
        Doubtful merges tried in and out (2 ** max_doubtful hypotheses at most).

    Returns
    -------
    list of PointHypothesis
        Each point the least-squares intersection of its side lines, with the indices of
        these lines; no two hypotheses with the same grouping.
    """
    # compiled (ottag_native.cluster), as numpy and plain Python computed it: the candidate
    # merges of estimates of different triangles under ``cap`` apart, nearest first (a stable
    # sort), kept when the least-squares point of their side lines lies within ``tol`` of each;
    # per subset of the doubtful ones (most merges first), the greedy union of estimates along
    # the merges (never two corners of one triangle; a union of more than two only within
    # ``tol``), and each group's least-squares point. Vertex j of triangle t is estimate 3t + j;
    # its side lines are sides j − 1 and j of the triangle.
    groupings = vertex_groupings(
        np.ascontiguousarray(tris.vertices, dtype=np.float64).reshape(-1, 2),
        np.ascontiguousarray(tris.normal, dtype=np.float64),
        np.ascontiguousarray(tris.offset, dtype=np.float64),
        cap, sure, tol, max_doubtful,
    )  # fmt: skip
    return [
        PointHypothesis(np.array(points, dtype=np.float64), tuple(np.array(ids, dtype=np.int64) for ids in lines))
        for points, lines in groupings
    ]
