# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The refinement stage's kernels (:mod:`ottag_db.decode.refine`), compiled: the moments of
point chains (:func:`~ottag_db.decode.refine.fit_chains`), and the sample grid, the grey-level
crossings and their moments of :func:`~ottag_db.decode.refine.refine_lines`.

:func:`chain_moments` sums what the least-squares lines of the chains need.
:func:`sample_grid` lays out the samples along every side and across it (and how far each
sample lies from the other triangle sides); OpenCV's ``remap`` reads the grey levels there;
:func:`level_crossings` finds, on each row of samples across a side, the crossing of the level
nearest the side; :func:`crossing_moments` sums what the least-squares lines of the crossings
need. Each computes what the numpy version did, element for element, in float64 (float32 where
it rounded the grid for ``remap``), its sums in numpy's order (pairwise: eight accumulators,
halves beyond 128 numbers; a segment of ``np.add.reduceat`` is its first number plus the
pairwise sum of the rest); built with ``-ffp-contract=off`` (no fused multiply-adds), as numpy
computes.
"""

from libc.math cimport INFINITY, sqrt
from libc.stdlib cimport free, malloc

cdef enum:
    MAX_ROW = 128  # the longest row of crossings (a buffer on the stack)


cdef double _pairwise(const double* x, Py_ssize_t n) noexcept nogil:
    """``x[:n]`` summed as numpy's pairwise summation adds a contiguous run: one by one under
    8 numbers, eight accumulators up to 128, halves (at a multiple of 8) beyond."""
    cdef double r[8]
    cdef double res
    cdef Py_ssize_t i, j, half
    if n < 8:
        res = -0.0
        for i in range(n):
            res += x[i]
        return res
    if n <= 128:
        for j in range(8):
            r[j] = x[j]
        i = 8
        while i < n - n % 8:
            for j in range(8):
                r[j] += x[i + j]
            i += 8
        res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
        while i < n:
            res += x[i]
            i += 1
        return res
    half = n // 2
    half -= half % 8
    return _pairwise(x, half) + _pairwise(x + half, n - half)


cdef double _reduceat(const double* x, Py_ssize_t n) noexcept nogil:
    """A segment of ``np.add.reduceat``: its first number plus the pairwise sum of the rest."""
    return x[0] + _pairwise(x + 1, n - 1)


def sample_grid(
    const double[:, ::1] a,
    const double[:, ::1] sd,
    const double[:, ::1] normal,
    int st,
    const double[::1] fractions,
    const double[::1] offsets,
    double[:, ::1] base_x,
    double[:, ::1] base_y,
    double[:, ::1] width,
    unsigned char[:, ::1] wide,
    float[:, :, :, ::1] grid,
):
    """Sample positions along the sides, their widths, and the grid across the sides.

    Parameters
    ----------
    a, sd : memoryview of float64
        ``(S, 2)``: each side's first end and its vector to the other end; the first ``st``
        sides are the triangles' (finite: a side without ends has zeros here).
    normal : memoryview of float64
        ``(S, 2)`` unit normals of the sides.
    st : int
        How many of the sides are triangle sides (the others are the data area's).
    fractions : memoryview of float64
        ``(M,)`` sample positions along a side, as fractions of it.
    offsets : memoryview of float64
        ``(O,)`` sample offsets across a side, along its normal (px).
    base_x, base_y : memoryview of float64
        ``(S, M)`` out: the samples on the sides, ``a + fraction · sd``.
    width : memoryview of float64
        ``(S, M)`` out: each sample's distance to the nearest triangle side segment other
        than its own (infinite when there is none).
    wide : memoryview of uint8
        ``(S, M)`` out: 1 where a triangle side's sample lies at least
        ``min(3, 0.6 × the side's widest sample)`` from the other sides; 1 on the data area's.
    grid : memoryview of float32
        ``(S, M, O, 2)`` out: the samples moved across their side by each offset, (x, y).
    """
    cdef Py_ssize_t s = a.shape[0], m = fractions.shape[0], n_o = offsets.shape[0]
    cdef Py_ssize_t i, k, t, o
    cdef double bx, by, dx, dy, rx, ry, u, gap, least, widest, limit, nx, ny
    # each triangle side's squared length, at least 1e-12 (np.maximum: a NaN stays NaN), once
    cdef double* ln2 = <double*>malloc((st if st > 0 else 1) * sizeof(double))
    if ln2 == NULL:
        raise MemoryError()
    for t in range(st):
        ln2[t] = sd[t, 0] * sd[t, 0] + sd[t, 1] * sd[t, 1]
        if ln2[t] < 1e-12:
            ln2[t] = 1e-12
    for i in range(s):
        for k in range(m):
            base_x[i, k] = a[i, 0] + fractions[k] * sd[i, 0]
            base_y[i, k] = a[i, 1] + fractions[k] * sd[i, 1]
    for i in range(s):
        for k in range(m):
            bx = base_x[i, k]
            by = base_y[i, k]
            least = INFINITY
            for t in range(st):
                if t == i:
                    continue
                dx = sd[t, 0]
                dy = sd[t, 1]
                rx = bx - a[t, 0]
                ry = by - a[t, 1]
                u = (rx * dx + ry * dy) / ln2[t]
                if u < 0.0:  # (np.clip(u, 0, 1))
                    u = 0.0
                elif u > 1.0:
                    u = 1.0
                rx = rx - u * dx
                ry = ry - u * dy
                gap = rx * rx + ry * ry
                if gap < least:
                    least = gap
            width[i, k] = sqrt(least)
            wide[i, k] = 1
    for i in range(st):
        widest = 0.0
        for k in range(m):
            if width[i, k] > widest:
                widest = width[i, k]
        limit = 0.6 * widest
        if 3.0 < limit:
            limit = 3.0
        for k in range(m):
            wide[i, k] = width[i, k] >= limit
    for i in range(s):
        nx = normal[i, 0]
        ny = normal[i, 1]
        for k in range(m):
            for o in range(n_o):
                grid[i, k, o, 0] = <float>(base_x[i, k] + offsets[o] * nx)
                grid[i, k, o, 1] = <float>(base_y[i, k] + offsets[o] * ny)
    free(ln2)


def level_crossings(
    const float[:, ::1] values,
    double level,
    int st,
    const unsigned char[::1] inward,
    const double[::1] offsets,
    const double[::1] middles,
    const double[:, ::1] base_x,
    const double[:, ::1] base_y,
    const double[:, ::1] normal,
    const unsigned char[:, ::1] wide,
    double[:, ::1] px,
    double[:, ::1] py,
    unsigned char[:, ::1] valid,
):
    """On each row of samples across a side, the ``level`` crossing nearest the side.

    Parameters
    ----------
    values : memoryview of float32
        ``(S · M, O)`` grey levels at :func:`sample_grid`'s grid.
    level : float
        The grey level of the edges.
    st : int
        How many of the sides are triangle sides.
    inward : memoryview of uint8
        ``(S − st,)``: whether each data-area side's normal points into the data area. A
        data-area side takes only crossings the border's way: falling along its normal when
        it points inward, rising when it points out (empty without data-area sides).
    offsets : memoryview of float64
        ``(O,)`` the grid's offsets across a side.
    middles : memoryview of float64
        ``(O − 1,)``: how far from the side each crossing between two offsets lies, ``|the
        offsets' mean|``; the nearest wins (the first of equals).
    base_x, base_y, normal, wide : memoryview
        As :func:`sample_grid` gave them.
    px, py : memoryview of float64
        ``(S, M)`` out: the crossing (linearly interpolated between its two offsets; halfway
        where they hold the same level); where there is none, a point between the first two
        offsets, which ``valid`` marks as not found.
    valid : memoryview of uint8
        ``(S, M)`` out: 1 where a crossing was found on a wide sample.
    """
    cdef Py_ssize_t s = base_x.shape[0], m = base_x.shape[1], n_o = offsets.shape[0]
    cdef Py_ssize_t i, k, o, row, best
    cdef double nearest, v0, v1, den, frac, at, step = offsets[1] - offsets[0]
    cdef bint above0, above1, change, found, falling
    for i in range(s):
        for k in range(m):
            row = i * m + k
            found = False
            best = 0
            nearest = INFINITY
            above1 = (<double>values[row, 0] - level) > 0
            for o in range(n_o - 1):
                above0 = above1
                above1 = (<double>values[row, o + 1] - level) > 0
                change = above0 != above1
                if change and i >= st:
                    falling = above0 and not above1
                    change = falling == (inward[i - st] != 0)
                if change:
                    found = True
                    if middles[o] < nearest:
                        nearest = middles[o]
                        best = o
            v0 = <double>values[row, best] - level
            v1 = <double>values[row, best + 1] - level
            den = v0 - v1
            frac = v0 / den if den != 0 else 0.5
            at = offsets[best] + frac * step
            valid[i, k] = found and wide[i, k] != 0
            px[i, k] = base_x[i, k] + at * normal[i, 0]
            py[i, k] = base_y[i, k] + at * normal[i, 1]


def inward_sides(const double[:, ::1] normal, const double[::1] offset, const double[:, ::1] quad, unsigned char[::1] out):
    """Whether each line's normal points into the quad: ``normal · centre − offset > 0``.

    Parameters
    ----------
    normal, offset : memoryview of float64
        ``(L, 2)`` unit normals and ``(L,)`` offsets of lines ``n·x = c``.
    quad : memoryview of float64
        ``(4, 2)`` corners; the centre is their mean, summed in order as numpy does.
    out : memoryview of uint8
        ``(L,)`` out. (Only the sign counts: the centre of a data area lies far from its sides.)
    """
    cdef double cx = (((quad[0, 0] + quad[1, 0]) + quad[2, 0]) + quad[3, 0]) / 4.0
    cdef double cy = (((quad[0, 1] + quad[1, 1]) + quad[2, 1]) + quad[3, 1]) / 4.0
    cdef Py_ssize_t i
    for i in range(normal.shape[0]):
        out[i] = (normal[i, 0] * cx + normal[i, 1] * cy) - offset[i] > 0


def crossing_moments(
    const double[:, ::1] px,
    const double[:, ::1] py,
    const unsigned char[:, ::1] valid,
    double[::1] mx,
    double[::1] my,
    double[::1] sxx,
    double[::1] sxy,
    double[::1] syy,
    double[::1] count,
):
    """Per row, the mean and central second moments of the valid crossings.

    Parameters
    ----------
    px, py : memoryview of float64
        ``(S, M)`` crossings, ``M ≤ 128``.
    valid : memoryview of uint8
        ``(S, M)``: which count (weight 1; the others weight 0).
    mx, my, sxx, sxy, syy, count : memoryview of float64
        ``(S,)`` out: ``Σw·px / max(Σw, 1)`` and its ``y`` twin, ``Σw·qx·qx``, ``Σw·qx·qy``,
        ``Σw·qy·qy`` about the means, and ``Σw``.
    """
    cdef Py_ssize_t s = px.shape[0], m = px.shape[1], i, k
    cdef double buf[MAX_ROW]
    cdef double qx[MAX_ROW]
    cdef double qy[MAX_ROW]
    cdef double w, cnt, cnt_safe, ax, ay
    if m > MAX_ROW:
        raise ValueError(f"rows of at most {MAX_ROW} crossings, not {m}")
    for i in range(s):
        for k in range(m):
            buf[k] = valid[i, k] != 0
        cnt = _pairwise(buf, m)
        cnt_safe = cnt if cnt > 1.0 else 1.0
        for k in range(m):
            buf[k] = (valid[i, k] != 0) * px[i, k]
        ax = _pairwise(buf, m) / cnt_safe
        for k in range(m):
            buf[k] = (valid[i, k] != 0) * py[i, k]
        ay = _pairwise(buf, m) / cnt_safe
        for k in range(m):
            qx[k] = px[i, k] - ax
            qy[k] = py[i, k] - ay
        for k in range(m):
            buf[k] = ((valid[i, k] != 0) * qx[k]) * qx[k]
        sxx[i] = _pairwise(buf, m)
        for k in range(m):
            buf[k] = ((valid[i, k] != 0) * qx[k]) * qy[k]
        sxy[i] = _pairwise(buf, m)
        for k in range(m):
            buf[k] = ((valid[i, k] != 0) * qy[k]) * qy[k]
        syy[i] = _pairwise(buf, m)
        mx[i] = ax
        my[i] = ay
        count[i] = cnt


def chain_moments(list chains, double[::1] mx, double[::1] my, double[::1] sxx, double[::1] sxy, double[::1] syy):
    """Per point chain, the mean and the central second moments of its points.

    Parameters
    ----------
    chains : list of numpy.ndarray
        ``(m, 2)`` float64 point chains, ``m ≥ 1``.
    mx, my, sxx, sxy, syy : memoryview of float64
        ``(len(chains),)`` out: ``Σx / m`` and ``Σy / m``; ``Σdx·dx``, ``Σdx·dy``, ``Σdy·dy``
        with ``d`` the points less the mean, each sum as ``np.add.reduceat`` adds.
    """
    cdef Py_ssize_t c, i, n, most = 0
    cdef const double[:, :] pts
    cdef double ax, ay
    cdef double* buf
    cdef double* dx
    cdef double* dy
    for c in range(len(chains)):
        n = len(chains[c])
        if n > most:
            most = n
    buf = <double*>malloc(3 * (most + 1) * sizeof(double))
    if buf == NULL:
        raise MemoryError()
    dx = buf + most + 1
    dy = dx + most + 1
    try:
        for c in range(len(chains)):
            pts = chains[c]
            n = pts.shape[0]
            if n < 1 or pts.shape[1] != 2:
                raise ValueError(f"chain {c}: ({n}, {pts.shape[1]}) points, not (m ≥ 1, 2)")
            for i in range(n):
                buf[i] = pts[i, 0]
            ax = _reduceat(buf, n) / <double>n
            for i in range(n):
                buf[i] = pts[i, 1]
            ay = _reduceat(buf, n) / <double>n
            for i in range(n):
                dx[i] = pts[i, 0] - ax
                dy[i] = pts[i, 1] - ay
            for i in range(n):
                buf[i] = dx[i] * dx[i]
            sxx[c] = _reduceat(buf, n)
            for i in range(n):
                buf[i] = dx[i] * dy[i]
            sxy[c] = _reduceat(buf, n)
            for i in range(n):
                buf[i] = dy[i] * dy[i]
            syy[c] = _reduceat(buf, n)
            mx[c] = ax
            my[c] = ay
    finally:
        free(buf)
