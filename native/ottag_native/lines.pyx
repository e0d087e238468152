# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The quad of an outline's four straightest runs (:func:`ottag_db.decode.outlines.lines_outline`), compiled.

Given the outline's polygon, this computes what the plain-Python version did, in the same
order: the runs of collinear edges (longest first), the combinations of four of the longest
runs, their quads (OpenCV's ``isContourConvex`` and ``contourArea`` on float32 corners, as
OpenCV computes them), each quad's support and the share of its outline inside the frame.
Built with ``-ffp-contract=off`` (no fused multiply-adds), as Python computes.
"""

from libc.math cimport fabs, hypot, sqrtf

cdef enum:
    MAX_POLY = 32  # lines_outline hands over at most 24 vertices
    MAX_CONSIDERED = 16


# An edge is the tuple (length, index, ax, ay, ux, uy) and a run the tuple (support, px, py,
# dx, dy, first edge), as the plain-Python version kept them: rows of 6 doubles (the indices are
# small integers, exact as doubles), ordered as Python orders tuples.
ctypedef double Row[6]

cdef enum:
    LENGTH = 0  # an edge's fields: its length, index in the polygon, start and unit direction
    INDEX = 1
    AX = 2
    AY = 3
    UX = 4
    UY = 5
    SUPPORT = 0  # a run's fields: its support, a point, its unit direction and its first edge
    PX = 1
    PY = 2
    DX = 3
    DY = 4
    FIRST = 5


cdef bint _before(const double* a, const double* b) noexcept nogil:
    """Python's order of two tuples of 6 numbers, descending (``sorted(..., reverse=True)``)."""
    cdef int i
    for i in range(6):
        if a[i] != b[i]:
            return a[i] > b[i]
    return False


cdef void _sort_descending(Row* rows, int* order, int n) noexcept nogil:
    """``order`` (indices of ``rows``) sorted so that the rows go in descending tuple order."""
    cdef int i, j, x
    for i in range(n):
        order[i] = i
    for i in range(1, n):
        x = order[i]
        j = i - 1
        while j >= 0 and _before(rows[x], rows[order[j]]):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = x


cdef bint _convex(float* x, float* y, int n) noexcept nogil:
    """OpenCV's isContourConvex of float points."""
    cdef float px = x[(n - 2 + n) % n], py = y[(n - 2 + n) % n]
    cdef float cx = x[n - 1], cy = y[n - 1]
    cdef float dx0 = cx - px, dy0 = cy - py, dx, dy, dxdy0, dydx0
    cdef int orientation = 0, i
    for i in range(n):
        px = cx
        py = cy
        cx = x[i]
        cy = y[i]
        dx = cx - px
        dy = cy - py
        dxdy0 = dx * dy0
        dydx0 = dy * dx0
        if dydx0 > dxdy0:
            orientation |= 1
        elif dydx0 < dxdy0:
            orientation |= 2
        else:
            orientation |= 3
        if orientation == 3:
            return False
        dx0 = dx
        dy0 = dy
    return True


cdef double _area(float* x, float* y, int n) noexcept nogil:
    """OpenCV's contourArea of float points (unoriented)."""
    cdef double a00 = 0
    cdef float px = x[n - 1], py = y[n - 1]
    cdef int i
    for i in range(n):
        a00 += <double>px * y[i] - <double>py * x[i]
        px = x[i]
        py = y[i]
    a00 *= 0.5
    return fabs(a00)


cdef double _arc_length(float* x, float* y, int n) noexcept nogil:
    """OpenCV's arcLength of a closed float polygon."""
    cdef double perimeter = 0
    cdef float px = x[n - 1], py = y[n - 1], dx, dy
    cdef int i
    for i in range(n):
        dx = x[i] - px
        dy = y[i] - py
        perimeter += sqrtf(dx * dx + dy * dy)  # (std::sqrt of a float, as OpenCV)
        px = x[i]
        py = y[i]
    return perimeter


def lines_quad(
    const double[:, ::1] poly,
    double tol,
    double cos_tol,
    int width,
    int height,
    double least_area,
    double most_area,
    int considered,
    double min_support,
    float[:, ::1] out,
):
    """The quad of the four lines with the most support among an outline's runs.

    Parameters
    ----------
    poly : memoryview of float64
        ``(k, 2)`` the outline's polygon (5 ≤ k ≤ 24).
    tol : float
        Distance (px) within which edges lie on one line; edges shorter than twice it count not.
    cos_tol : float
        Cosine of the angle within which edges are parallel.
    width, height : int
        The frame's size (edges along its border are left out).
    least_area, most_area : float
        The quad's area must lie within these (px²).
    considered : int
        How many of the longest runs are combined.
    min_support : float
        The share of the quad's outline inside the frame that the runs must support.
    out : memoryview of float32
        ``(4, 2)`` written: the quad's corners (side ``i`` from corner ``i − 1`` to ``i``).

    Returns
    -------
    bool
        Whether a quad was found.
    """
    cdef int k = poly.shape[0]
    if poly.shape[1] != 2 or k > MAX_POLY or out.shape[0] != 4 or out.shape[1] != 2:
        raise ValueError(f"poly must be (k, 2) with k <= {MAX_POLY} and out (4, 2)")
    if considered > MAX_CONSIDERED or considered < 0:
        raise ValueError(f"considered must be 0 … {MAX_CONSIDERED}")
    cdef Row edges[MAX_POLY]
    cdef Row runs[MAX_POLY]
    cdef int edge_order[MAX_POLY]
    cdef int run_order[MAX_POLY]
    cdef double span_lo[MAX_POLY]
    cdef double span_hi[MAX_POLY]
    cdef int span_run[MAX_POLY]  # (spans in the order they were added, each with its run's first edge)
    cdef int n_edges = 0, n_runs = 0, n_spans = 0
    cdef int i, j, a, b, c, d, r, q, e
    cdef double ax, ay, bx, by, length, ux, uy, s0, s1, lo, hi, t0, t1, total, t, det
    cdef double best_support = 0.0, sum4, area, support, seen, p_, q_
    cdef bint found = False, along_frame, ok
    cdef float qx[4]
    cdef float qy[4]
    cdef float best_x[4]
    cdef float best_y[4]
    cdef double* four[4]
    cdef double* run
    cdef double* tmp
    cdef int idx[4]
    with nogil:
        for i in range(k):
            ax = poly[i, 0]
            ay = poly[i, 1]
            bx = poly[(i + 1) % k, 0]
            by = poly[(i + 1) % k, 1]
            along_frame = (ax <= 1 and bx <= 1) or (ay <= 1 and by <= 1) or (ax >= width - 2 and bx >= width - 2)
            if along_frame or (ay >= height - 2 and by >= height - 2):
                continue  # the frame's edge, not a side
            length = hypot(bx - ax, by - ay)
            if length >= 2 * tol:
                edges[n_edges][LENGTH] = length
                edges[n_edges][INDEX] = i
                edges[n_edges][AX] = ax
                edges[n_edges][AY] = ay
                edges[n_edges][UX] = (bx - ax) / length
                edges[n_edges][UY] = (by - ay) / length
                n_edges += 1
        _sort_descending(edges, edge_order, n_edges)  # longest first
        for e in range(n_edges):
            i = edge_order[e]
            length = edges[i][LENGTH]
            ax = edges[i][AX]
            ay = edges[i][AY]
            ux = edges[i][UX]
            uy = edges[i][UY]
            bx = ax + length * ux
            by = ay + length * uy
            for r in range(n_runs):
                run = runs[r]
                if (
                    fabs(ux * run[DX] + uy * run[DY]) >= cos_tol
                    and max(
                        fabs((ax - run[PX]) * run[DY] - (ay - run[PY]) * run[DX]),
                        fabs((bx - run[PX]) * run[DY] - (by - run[PY]) * run[DX]),
                    ) <= tol
                ):
                    run[SUPPORT] = run[SUPPORT] + length
                    s0 = (ax - run[PX]) * run[DX] + (ay - run[PY]) * run[DY]
                    s1 = (bx - run[PX]) * run[DX] + (by - run[PY]) * run[DY]
                    span_lo[n_spans] = min(s0, s1)
                    span_hi[n_spans] = max(s0, s1)
                    span_run[n_spans] = <int>run[FIRST]
                    n_spans += 1
                    break
            else:
                runs[n_runs][SUPPORT] = length
                runs[n_runs][PX] = ax
                runs[n_runs][PY] = ay
                runs[n_runs][DX] = ux
                runs[n_runs][DY] = uy
                runs[n_runs][FIRST] = edges[i][INDEX]
                n_runs += 1
                span_lo[n_spans] = 0.0
                span_hi[n_spans] = length
                span_run[n_spans] = <int>edges[i][INDEX]
                n_spans += 1
    if n_runs < 4:
        return False
    with nogil:
        _sort_descending(runs, run_order, n_runs)  # the most support first
        c = n_runs if n_runs < considered else considered
        # itertools.combinations of the longest runs, four at a time, in its order
        for a in range(c):
            for b in range(a + 1, c):
                for q in range(b + 1, c):
                    for d in range(q + 1, c):
                        idx[0] = a
                        idx[1] = b
                        idx[2] = q
                        idx[3] = d
                        sum4 = 0.0
                        for i in range(4):
                            sum4 = sum4 + runs[run_order[idx[i]]][SUPPORT]
                        if sum4 <= best_support:
                            continue
                        # in the outline's order (by first edge; sorted() is stable)
                        for i in range(4):
                            four[i] = runs[run_order[idx[i]]]
                        for i in range(1, 4):
                            tmp = four[i]
                            j = i - 1
                            while j >= 0 and tmp[FIRST] < four[j][FIRST]:
                                four[j + 1] = four[j]
                                j -= 1
                            four[j + 1] = tmp
                        # each line meets the next at a corner (nearly parallel: none)
                        ok = True
                        for i in range(4):
                            det = four[i][DX] * four[(i + 1) % 4][DY] - four[i][DY] * four[(i + 1) % 4][DX]
                            if fabs(det) < 0.2:
                                ok = False
                                break
                            t = (
                                (four[(i + 1) % 4][PX] - four[i][PX]) * four[(i + 1) % 4][DY]
                                - (four[(i + 1) % 4][PY] - four[i][PY]) * four[(i + 1) % 4][DX]
                            ) / det
                            qx[i] = <float>(four[i][PX] + t * four[i][DX])
                            qy[i] = <float>(four[i][PY] + t * four[i][DY])
                        if not ok or not _convex(qx, qy, 4):
                            continue
                        area = _area(qx, qy, 4)
                        if not (least_area <= area <= most_area):
                            continue
                        # a run supports its side only between the side's corners
                        support = 0.0
                        for i in range(4):
                            t0 = (qx[(i + 3) % 4] - four[i][PX]) * four[i][DX] + (qy[(i + 3) % 4] - four[i][PY]) * four[i][DY]
                            t1 = (qx[i] - four[i][PX]) * four[i][DX] + (qy[i] - four[i][PY]) * four[i][DY]
                            lo = min(t0, t1)
                            hi = max(t0, t1)
                            total = 0.0
                            for j in range(n_spans):
                                if span_run[j] == <int>four[i][FIRST]:
                                    total = total + max(0.0, min(hi, span_hi[j]) - max(lo, span_lo[j]))
                            support = support + total
                        if support > best_support:
                            best_support = support
                            found = True
                            for i in range(4):
                                best_x[i] = qx[i]
                                best_y[i] = qy[i]
    if not found:
        return False
    # the share of its outline inside the frame (one corner beyond the edge at most)
    cdef int outside = 0
    for i in range(4):
        if not (0 <= best_x[i] <= width - 1 and 0 <= best_y[i] <= height - 1):
            outside += 1
    if outside > 1:
        seen = _arc_length(best_x, best_y, 4)
    else:
        seen = 0.0
        for i in range(4):
            ax = best_x[i]
            ay = best_y[i]
            bx = best_x[(i + 1) % 4]
            by = best_y[(i + 1) % 4]
            lo = 0.0
            hi = 1.0
            for j in range(4):
                if j == 0:
                    p_, q_ = ax - bx, ax
                elif j == 1:
                    p_, q_ = bx - ax, width - 1 - ax
                elif j == 2:
                    p_, q_ = ay - by, ay
                else:
                    p_, q_ = by - ay, height - 1 - ay
                if p_ == 0:
                    if q_ < 0:
                        hi = lo - 1.0
                    continue
                t = q_ / p_
                if p_ < 0:
                    lo = max(lo, t)
                else:
                    hi = min(hi, t)
            if hi > lo:
                seen = seen + (hi - lo) * hypot(bx - ax, by - ay)
    if best_support < min_support * seen:
        return False
    for i in range(4):
        out[i, 0] = best_x[i]
        out[i, 1] = best_y[i]
    return True
