# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The fit of one triangle to a contour (:func:`ottag_db.decode.triangles.triangle_fit_parts`), compiled.

The numpy and plain-Python version spent about 0.1 ms per contour in small array operations
and list comprehensions over the hull; this computes the same values in the same order
(double precision, no fused multiply-adds: built with ``-ffp-contract=off``).
"""

from libc.math cimport INFINITY as INF, atan2, cos, fabs, hypot, sin
from libc.stdlib cimport free, malloc


cdef double _far(const double[:, ::1] flat, const int[::1] hull, int p0, int p1, int k) noexcept nogil:
    """Twice the area of the triangle of hull point ``k`` with hull points ``p0`` and ``p1``."""
    cdef double x0 = flat[hull[p0], 0], y0 = flat[hull[p0], 1]
    cdef double ex = flat[hull[p1], 0] - x0, ey = flat[hull[p1], 1] - y0
    return fabs(ex * (flat[hull[k], 1] - y0) - ey * (flat[hull[k], 0] - x0))


cdef int _farthest(const double[:, ::1] flat, const int[::1] hull, int p0, int p1) noexcept nogil:
    """The first hull point farthest from the line of hull points ``p0`` and ``p1``."""
    cdef int k, best = 0
    cdef double v, top = -1.0
    for k in range(hull.shape[0]):
        v = _far(flat, hull, p0, p1, k)
        if v > top:
            top = v
            best = k
    return best


cdef inline double _x(const double[:, ::1] flat, int n, int start, int j) noexcept nogil:
    return flat[(start + j) % n, 0]


cdef inline double _y(const double[:, ::1] flat, int n, int start, int j) noexcept nogil:
    return flat[(start + j) % n, 1]


def fit_triangle(const double[:, ::1] flat, const int[::1] hull, double contour_area, double perimeter):
    """The corners and side chains of a contour that is one triangle, or None.

    Parameters
    ----------
    flat : memoryview of float64
        ``(n, 2)`` the contour's points (integer pixel coordinates).
    hull : memoryview of int32
        Indices of its convex hull's points (``cv2.convexHull(returnPoints=False)``).
    contour_area, perimeter : float
        The contour's area and length (``cv2.contourArea``, ``cv2.arcLength``).

    Returns
    -------
    tuple of int or None
        ``(i0, i1, i2, trim0, trim1, trim2)``: the corners' contour indices in increasing
        order, and per side (side ``j`` from corner ``j`` to corner ``j + 1``, the contour
        points between them, ends included) how many points at each end its chain leaves out,
        or -1 where the chain is the chord (a side of under 6 points); None when the contour is
        not one triangle.
    """
    cdef int n = flat.shape[0]
    cdef int h = hull.shape[0]
    if flat.shape[1] != 2:
        raise ValueError("flat must be (n, 2)")
    for k in range(h):
        if hull[k] < 0 or hull[k] >= n:
            raise ValueError("hull indices must index the contour")
    if h < 3:
        return None
    cdef int i, j, ia = 0, ib = 0, ic, it, r, best, changed
    cdef double dx, dy, dd, top = -1.0
    cdef int sel[3]
    cdef int idx[3]
    cdef int trims[3]
    cdef int starts[3]
    cdef int lengths[3]
    cdef double t0x, t0y, t1x, t1y, t2x, t2y, t_area, ln, sx, sy, qx, qy
    cdef double gxx, gxy, gyy, sx_, sy_, x, y, cx, cy, theta, nx, ny, c, limit
    cdef int m, trim, t10, count, far = 0, s
    with nogil:
        # the two farthest hull points (the first pair, row by row, as np.argmax)
        for i in range(h):
            for j in range(h):
                dx = flat[hull[i], 0] - flat[hull[j], 0]
                dy = flat[hull[i], 1] - flat[hull[j], 1]
                dd = dx * dx + dy * dy
                if dd > top:
                    top = dd
                    ia = i
                    ib = j
        sel[0] = ia
        sel[1] = ib
        sel[2] = _farthest(flat, hull, ia, ib)
        # grown to the largest-area hull triangle (a blunt short side can fool the farthest pair)
        for it in range(3):
            changed = 0
            for r in range(3):
                if r == 2 and it == 0 and not changed:
                    break  # corner 2 is already the farthest from the unchanged side 0–1
                best = _farthest(flat, hull, sel[(r + 1) % 3], sel[(r + 2) % 3])
                if best != sel[r] and (
                    _far(flat, hull, sel[(r + 1) % 3], sel[(r + 2) % 3], best)
                    > _far(flat, hull, sel[(r + 1) % 3], sel[(r + 2) % 3], sel[r]) + 1e-9
                ):
                    sel[r] = best
                    changed = 1
            if not changed:
                break
        for i in range(3):
            idx[i] = hull[sel[i]]
        # sorted, distinct
        for i in range(3):
            for j in range(2 - i):
                if idx[j] > idx[j + 1]:
                    idx[j], idx[j + 1] = idx[j + 1], idx[j]
    if idx[0] == idx[1] or idx[1] == idx[2]:
        return None
    t0x, t0y = flat[idx[0], 0], flat[idx[0], 1]
    t1x, t1y = flat[idx[1], 0], flat[idx[1], 1]
    t2x, t2y = flat[idx[2], 0], flat[idx[2], 1]
    t_area = 0.5 * fabs((t1x - t0x) * (t2y - t0y) - (t1y - t0y) * (t2x - t0x))
    if t_area <= 0 or fabs(contour_area - t_area) > 0.2 * t_area + 0.25 * perimeter:
        return None
    starts[0], lengths[0] = idx[0], idx[1] - idx[0] + 1
    starts[1], lengths[1] = idx[1], idx[2] - idx[1] + 1
    starts[2], lengths[2] = idx[2], n - idx[2] + idx[0] + 1  # (around the contour's start)
    for s in range(3):
        m = lengths[s]
        sx, sy = flat[idx[s], 0], flat[idx[s], 1]
        qx, qy = flat[idx[(s + 1) % 3], 0], flat[idx[(s + 1) % 3], 1]
        ln = hypot(qx - sx, qy - sy)
        if ln < 1:
            return None
        if m < 6:
            trims[s] = -1  # a short side (the base of a needle): the chord; the grey-level fit refines it
            continue
        trim = <int>(0.15 * m)
        if trim < 1:
            trim = 1
        trims[s] = trim
        # the PCA line of the chain's core from raw moments (integer pixel coordinates: exact)
        gxx = gxy = gyy = sx_ = sy_ = 0.0
        for j in range(trim, m - trim):
            x = _x(flat, n, starts[s], j)
            y = _y(flat, n, starts[s], j)
            gxx += x * x
            gxy += x * y
            gyy += y * y
            sx_ += x
            sy_ += y
        count = m - 2 * trim
        cx = sx_ / count
        cy = sy_ / count
        theta = 0.5 * atan2(2 * (gxy - sx_ * cy), (gxx - sx_ * cx) - (gyy - sy_ * cy))
        nx = -sin(theta)
        ny = cos(theta)
        c = nx * cx + ny * cy
        # how many of the chain's points (without its ends) lie off the line fitted to its core
        t10 = <int>(0.1 * m)
        if t10 < 1:
            t10 = 1
        limit = 1.0 + 0.015 * ln
        for j in range(t10, m - t10):
            x = _x(flat, n, starts[s], j)
            y = _y(flat, n, starts[s], j)
            if fabs((x * nx + y * ny) - c) > limit:
                far += 1
    if far > max(2.0, 0.05 * n):
        return None
    return idx[0], idx[1], idx[2], trims[0], trims[1], trims[2]


def triangle_faults(const double[:, ::1] verts, const double[:, ::1] quad, double side):
    """Why fitted triangles cannot be a tag's (:func:`ottag_db.decode.triangles.bad_triangles`).

    Parameters
    ----------
    verts : memoryview of float64
        ``(3T, 2)`` triangle vertices, three per triangle (side j from vertex j to j + 1).
    quad : memoryview of float64
        ``(4, 2)`` data-area corners (convex, either orientation).
    side : float
        Data-area side (px): scales the tolerances.

    Returns
    -------
    int
        0: none; 1: a vertex is not finite; 2: a vertex lies outside the data area (beyond
        ``1 + 1 %`` of the side); 3: two triangles share part of a side (both ends of one side
        within ``max(0.8, 0.8 %`` of the side) of another's line, their projections overlapping
        over a third of the shorter).
    """
    cdef Py_ssize_t s = verts.shape[0], i, j, q, base
    cdef double slack = 1.0 + 0.01 * side, near = 0.008 * side
    cdef double dx, dy, cross, norm, ln_i, ln_j, shorter
    cdef double rax, ray, rbx, rby, off_a, off_b, pa, pb, hi, lo, overlap
    cdef bint inner_left = True, inner_right = True
    cdef double* ux
    cdef double* uy
    cdef double* ln
    cdef double* bx
    cdef double* by
    if s % 3:
        raise ValueError(f"triangles of 3 vertices, not {s} vertices")
    for i in range(s):
        if not (fabs(verts[i, 0]) < INF and fabs(verts[i, 1]) < INF):
            return 1
    for i in range(s):  # on the inner side of every quad side (either orientation)
        for q in range(4):
            dx = quad[(q + 1) % 4, 0] - quad[q, 0]
            dy = quad[(q + 1) % 4, 1] - quad[q, 1]
            cross = dx * (verts[i, 1] - quad[q, 1]) - dy * (verts[i, 0] - quad[q, 0])
            cross = cross / hypot(dx, dy)
            if not cross >= -slack:
                inner_left = False
            if not cross <= slack:
                inner_right = False
    if not (inner_left or inner_right):
        return 2
    if s < 6:
        return 0
    if near < 0.8:
        near = 0.8
    ux = <double*>malloc(5 * s * sizeof(double))
    if ux == NULL:
        raise MemoryError()
    uy, ln, bx, by = ux + s, ux + 2 * s, ux + 3 * s, ux + 4 * s
    try:
        for i in range(s):
            base = i - i % 3
            bx[i] = verts[base + (i % 3 + 1) % 3, 0]
            by[i] = verts[base + (i % 3 + 1) % 3, 1]
            dx = bx[i] - verts[i, 0]
            dy = by[i] - verts[i, 1]
            ln[i] = hypot(dx, dy)
            if not ln[i] >= 1e-9:
                ln[i] = 1e-9
            ux[i] = dx / ln[i]
            uy[i] = dy / ln[i]
        for i in range(s):
            for j in range(s):
                if i // 3 == j // 3:
                    continue
                rax = verts[j, 0] - verts[i, 0]
                ray = verts[j, 1] - verts[i, 1]
                rbx = bx[j] - verts[i, 0]
                rby = by[j] - verts[i, 1]
                off_a = fabs(rax * -uy[i] + ray * ux[i])
                off_b = fabs(rbx * -uy[i] + rby * ux[i])
                if not (off_a < near and off_b < near):
                    continue
                pa = rax * ux[i] + ray * uy[i]
                pb = rbx * ux[i] + rby * uy[i]
                hi = pa if pa >= pb else pb
                if hi > ln[i]:
                    hi = ln[i]
                lo = pa if pa <= pb else pb
                if lo < 0.0:
                    lo = 0.0
                overlap = hi - lo
                ln_j = ln[j]
                shorter = ln[i] if ln[i] <= ln_j else ln_j
                if overlap > shorter / 3:
                    return 3
        return 0
    finally:
        free(ux)
