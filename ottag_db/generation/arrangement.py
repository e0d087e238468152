"""One new point in every cell of the line arrangement of a point set (the enumeration's step)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["insertion_candidates", "vertex_layout"]

#: Distance (in units of the set's extent, which is 1 after normalization) at which points
#: are placed in unbounded cells.
_FAR = 1.5


def vertex_layout(m: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """The lines through pairs of ``m`` points and the crossings of disjoint lines.

    Parameters
    ----------
    m : int
        Number of points.

    Returns
    -------
    first, second : ndarray of intp, shape (P,) each
        The lines: point pairs ``i < j`` in ``np.triu_indices`` order.
    l1, l2 : ndarray of intp, shape (Q,) each
        Pairs of lines (indices into ``first``/``second``) through four distinct points,
        whose crossings are vertices of the arrangement.
    """
    first, second = np.triu_indices(m, 1)
    n_lines = first.size
    l1, l2 = np.triu_indices(n_lines, 1)
    disjoint = (
        (first[l1] != first[l2]) & (first[l1] != second[l2]) & (second[l1] != first[l2]) & (second[l1] != second[l2])
    )
    return first.astype(np.intp), second.astype(np.intp), l1[disjoint].astype(np.intp), l2[disjoint].astype(np.intp)


def insertion_candidates(base: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Points in the cells of the arrangement of lines through all pairs of each base set.

    ``base`` is ``(N, m, 2)`` (sets in general position, coordinates of order 1). Every
    cell of an arrangement of non-parallel lines has a vertex, and the cells around a
    vertex are the angular sectors between consecutive lines through it. For every vertex
    (the m input points, where m − 1 lines meet, and the crossings of two lines through
    four distinct points) and every sector, a candidate is put on the bisector halfway to
    the first line the bisecting ray meets (at distance ``_FAR`` when it meets none).

    Parameters
    ----------
    base : ndarray of float64, shape (N, m, 2)
        Base sets in general position, coordinates of order 1 (e.g. the unit square).

    Returns
    -------
    candidates : ndarray of float64, shape (N, C, 2)
        Candidate points, ``C`` per base set (units of ``base``).
    clearance : ndarray of float64, shape (N, C)
        Smallest distance from each candidate to any line (units of ``base``; 0 where not
        finite).
    """
    n_sets, m, _ = base.shape
    first, second, l1, l2 = vertex_layout(m)
    n_lines = first.size
    pi = base[:, first]
    pj = base[:, second]
    u = pj - pi
    u /= np.linalg.norm(u, axis=2, keepdims=True)
    normal = np.stack([-u[..., 1], u[..., 0]], axis=2)  # (N, P, 2)
    offset = -(normal * pi).sum(axis=2)  # (N, P)

    # (a) Vertices at the input points: 2(m − 1) rays, bisect consecutive ones.
    others = np.array([[j for j in range(m) if j != i] for i in range(m)], dtype=np.intp)  # (m, m−1)
    d = base[:, others] - base[:, :, None, :]  # (N, m, m−1, 2)
    ang = np.arctan2(d[..., 1], d[..., 0])
    ang = np.concatenate([ang, ang + np.pi], axis=2)
    ang = np.mod(ang, 2.0 * np.pi)
    ang.sort(axis=2)
    nxt = np.concatenate([ang[..., 1:], ang[..., :1] + 2.0 * np.pi], axis=2)
    mid = 0.5 * (ang + nxt)  # (N, m, S)
    dirs_a = np.stack([np.cos(mid), np.sin(mid)], axis=3)  # (N, m, S, 2)
    verts_a = base
    incident_a = (first[None, :] == np.arange(m)[:, None]) | (second[None, :] == np.arange(m)[:, None])  # (m, P)

    # (b) Crossings of two lines through four distinct points: 4 sectors each.
    n1, n2 = normal[:, l1], normal[:, l2]
    c1, c2 = offset[:, l1], offset[:, l2]
    det = n1[..., 0] * n2[..., 1] - n1[..., 1] * n2[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        vx = (-c1 * n2[..., 1] + c2 * n1[..., 1]) / det
        vy = (-n1[..., 0] * c2 + n2[..., 0] * c1) / det
    verts_b = np.stack([vx, vy], axis=2)  # (N, Q, 2)
    u1, u2 = u[:, l1], u[:, l2]
    s_dir = u1 + u2
    d_dir = u1 - u2
    s_dir /= np.linalg.norm(s_dir, axis=2, keepdims=True)
    d_dir /= np.linalg.norm(d_dir, axis=2, keepdims=True)
    dirs_b = np.stack([s_dir, -s_dir, d_dir, -d_dir], axis=2)  # (N, Q, 4, 2)
    line_ids = np.arange(n_lines)
    incident_b = (line_ids[None, :] == l1[:, None]) | (line_ids[None, :] == l2[:, None])  # (Q, P)

    out: list[NDArray[np.float64]] = []
    for verts, dirs, incident in ((verts_a, dirs_a, incident_a), (verts_b, dirs_b, incident_b)):
        side = (normal[:, None, :, :] * verts[:, :, None, :]).sum(axis=3) + offset[:, None, :]  # (N, V, P)
        rate = np.einsum("nvsd,npd->nvsp", dirs, normal)  # (N, V, S, P)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -side[:, :, None, :] / rate
        t = np.where((t > 0) & ~incident[None, :, None, :] & np.isfinite(t), t, np.inf)
        step = np.minimum(0.5 * t.min(axis=3), _FAR)  # (N, V, S)
        out.append((verts[:, :, None, :] + dirs * step[..., None]).reshape(n_sets, -1, 2))
    cand = np.concatenate(out, axis=1)
    dist = np.abs((normal[:, None, :, :] * cand[:, :, None, :]).sum(axis=3) + offset[:, None, :])
    clearance = dist.min(axis=2)
    clearance = np.where(np.isfinite(clearance), clearance, 0.0)
    return cand, clearance
