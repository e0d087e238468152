# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The clustering stage's groupings (:func:`ottag_db.decode.cluster.cluster_hypotheses`), compiled.

Computes what the numpy and plain-Python version did, in the same order and in double
precision (a Python float): the distances of the vertex estimates, the candidate merges in
order of distance (a stable sort), each least-squares point summed line by line, the greedy
union of estimates per subset of the doubtful merges, and the points of each new grouping;
built with ``-ffp-contract=off`` (no fused multiply-adds), as Python computes.
"""

from libc.math cimport INFINITY, fabs, isfinite, sqrt
from libc.stdlib cimport free, malloc


cdef double _ls_point(
    const double[:, ::1] normal, const double[::1] offset, const int* ids, int m, double* x, double* y
) noexcept nogil:
    """The least-squares intersection ``(x, y)`` of the lines ``ids[:m]`` and its largest
    distance to them (as ``max`` of Python: the first, replaced by any larger); infinite, with
    ``x`` and ``y`` NaN, when the lines are (nearly) parallel."""
    cdef double a00 = 0.0, a01 = 0.0, a11 = 0.0, b0 = 0.0, b1 = 0.0, nx, ny, c, det, worst, d
    cdef int t, i
    for t in range(m):
        i = ids[t]
        nx = normal[i, 0]
        ny = normal[i, 1]
        c = offset[i]
        a00 += nx * nx
        a01 += nx * ny
        a11 += ny * ny
        b0 += nx * c
        b1 += ny * c
    det = a00 * a11 - a01 * a01
    if fabs(det) < 1e-9:
        x[0] = y[0] = 0.0 * INFINITY
        return INFINITY
    x[0] = (b0 * a11 - a01 * b1) / det
    y[0] = (a00 * b1 - a01 * b0) / det
    worst = 0.0
    for t in range(m):
        i = ids[t]
        d = fabs(normal[i, 0] * x[0] + normal[i, 1] * y[0] - offset[i])
        if t == 0 or d > worst:
            worst = d
    return worst


cdef inline int _line(int m, int which) noexcept nogil:
    """The side lines through vertex ``m`` (vertex j of triangle t at 3t + j; side j from vertex j
    to j + 1): side j − 1 (``which`` 0), then side j."""
    return 3 * (m // 3) + ((m % 3 + 2) % 3 if which == 0 else m % 3)


cdef int _lines_of(const int* members, int count, int* out) noexcept nogil:
    """The two side lines of each member, in order; how many."""
    cdef int t
    for t in range(count):
        out[2 * t] = _line(members[t], 0)
        out[2 * t + 1] = _line(members[t], 1)
    return 2 * count


def vertex_groupings(
    const double[:, ::1] vertices,
    const double[:, ::1] normal,
    const double[::1] offset,
    double cap,
    double sure,
    double tol,
    int max_doubtful,
):
    """Point hypotheses from triangle vertex estimates, most merges first.

    Parameters
    ----------
    vertices : memoryview of float64
        ``(n, 2)`` vertex estimates, three per triangle.
    normal, offset : memoryview of float64
        ``(n, 2)`` and ``(n,)``: the triangles' side lines ``n·x = c`` (side j of triangle t at
        3t + j).
    cap, sure, tol : float
        As :func:`ottag_db.decode.cluster.cluster_hypotheses` takes them.
    max_doubtful : int
        Doubtful merges tried in and out.

    Returns
    -------
    list of tuple
        Per hypothesis, its points ``[(x, y), ...]`` and, per point, the side lines through it
        ``[[line, ...], ...]``.
    """
    cdef int n = vertices.shape[0], i, j, p, q, t, k, a, b, count, pairs_n = 0, sure_n = 0, doubt_n = 0
    cdef int subsets, r, used, m, g
    cdef double dx, dy, x, y, res
    cdef double* dist = NULL
    cdef int* pair_i = NULL
    cdef int* pair_j = NULL
    cdef int* order = NULL
    cdef int* chosen = NULL
    cdef int* root = NULL
    cdef int* size = NULL
    cdef int* members = NULL
    cdef int* ids = NULL
    cdef int* subset_order = NULL
    cdef int* bits = NULL
    out = []
    seen = set()
    if n == 0:
        return out
    try:
        dist = <double*>malloc(n * n * sizeof(double))
        pair_i = <int*>malloc(n * n * sizeof(int))
        pair_j = <int*>malloc(n * n * sizeof(int))
        order = <int*>malloc(n * n * sizeof(int))
        chosen = <int*>malloc(n * n * sizeof(int))
        root = <int*>malloc(n * sizeof(int))
        size = <int*>malloc(n * sizeof(int))
        members = <int*>malloc(n * n * sizeof(int))  # members[a * n + t]: of the group keyed a
        ids = <int*>malloc(2 * n * sizeof(int))
        subset_order = <int*>malloc((1 << max(max_doubtful, 0)) * sizeof(int))
        bits = <int*>malloc((1 << max(max_doubtful, 0)) * sizeof(int))
        if not (dist and pair_i and pair_j and order and chosen and root and size and members and ids and subset_order and bits):
            raise MemoryError()
        # candidate merges: estimates of different triangles under ``cap`` apart, in the order of
        # numpy's nonzero (row by row, i < j), sorted stably by distance
        for i in range(n):
            for j in range(i + 1, n):
                dx = vertices[i, 0] - vertices[j, 0]
                dy = vertices[i, 1] - vertices[j, 1]
                dist[i * n + j] = sqrt(dx * dx + dy * dy)
                if i // 3 != j // 3 and dist[i * n + j] < cap:
                    pair_i[pairs_n] = i
                    pair_j[pairs_n] = j
                    pairs_n += 1
        for p in range(pairs_n):  # (insertion sort: stable)
            order[p] = p
            q = p
            while q > 0 and dist[pair_i[order[q - 1]] * n + pair_j[order[q - 1]]] > dist[pair_i[p] * n + pair_j[p]]:
                order[q] = order[q - 1]
                q -= 1
            order[q] = p
        # the merges whose lines meet within ``tol``: sure ones first in ``chosen``, the
        # doubtful ones (at most ``max_doubtful``) in ``merged``'s place after them
        for t in range(pairs_n):
            p = order[t]
            i, j = pair_i[p], pair_j[p]
            count = _lines_of(&i, 1, ids)
            count += _lines_of(&j, 1, ids + count)
            res = _ls_point(normal, offset, ids, count, &x, &y)
            if res > tol:
                continue
            if dist[i * n + j] <= sure:
                chosen[sure_n] = p
                sure_n += 1
            else:
                order[doubt_n] = p  # (order's first entries are read already)
                doubt_n += 1
        if doubt_n > max_doubtful:
            doubt_n = max_doubtful
        # the subsets of the doubtful merges, in itertools.product((True, False), ...) order,
        # sorted stably by how many they use, most first
        subsets = 1 << doubt_n
        for r in range(subsets):
            used = 0
            for q in range(doubt_n):
                used += not ((r >> (doubt_n - 1 - q)) & 1)
            bits[r] = used
            q = r
            while q > 0 and bits[subset_order[q - 1]] < used:
                subset_order[q] = subset_order[q - 1]
                q -= 1
            subset_order[q] = r
        for t in range(subsets):
            r = subset_order[t]
            # greedy union along the pairs: the sure ones, then the doubtful ones in the subset
            for i in range(n):
                root[i] = i
                size[i] = 1
                members[i * n] = i
            for k in range(sure_n + doubt_n):
                if k < sure_n:
                    p = chosen[k]
                elif (r >> (doubt_n - 1 - (k - sure_n))) & 1:
                    continue
                else:
                    p = order[k - sure_n]
                a, b = root[pair_i[p]], root[pair_j[p]]
                if a == b:
                    continue
                if _share_triangle(members + a * n, size[a], members + b * n, size[b]):
                    continue
                if size[a] + size[b] > 2:
                    count = _lines_of(members + a * n, size[a], ids)
                    count += _lines_of(members + b * n, size[b], ids + count)
                    res = _ls_point(normal, offset, ids, count, &x, &y)
                    if res > tol:
                        continue
                for q in range(size[b]):
                    m = members[b * n + q]
                    members[a * n + size[a] + q] = m
                    root[m] = a
                size[a] += size[b]
                size[b] = 0
            least = []
            for g in range(n):
                if size[g] > 0:
                    least.append(_least(members + g * n, size[g]))
            key = tuple(sorted(least))
            if key in seen:
                continue
            seen.add(key)
            points = []
            lines = []
            for g in range(n):
                if size[g] == 0:
                    continue
                count = _lines_of(members + g * n, size[g], ids)
                res = _ls_point(normal, offset, ids, count, &x, &y)
                if not (isfinite(x) and isfinite(y)):
                    break
                points.append((x, y))
                lines.append([ids[q] for q in range(count)])
            else:
                out.append((points, lines))
    finally:
        free(dist)
        free(pair_i)
        free(pair_j)
        free(order)
        free(chosen)
        free(root)
        free(size)
        free(members)
        free(ids)
        free(subset_order)
        free(bits)
    return out


cdef bint _share_triangle(const int* ga, int na, const int* gb, int nb) noexcept nogil:
    """Whether two groups hold corners of one triangle (vertex m is a corner of triangle m // 3)."""
    cdef int s, t
    for s in range(na):
        for t in range(nb):
            if ga[s] // 3 == gb[t] // 3:
                return True
    return False


cdef int _least(const int* group, int count) noexcept nogil:
    cdef int t, least = group[0]
    for t in range(1, count):
        if group[t] < least:
            least = group[t]
    return least
