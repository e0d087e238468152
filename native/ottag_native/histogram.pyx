# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""Otsu's threshold of a grey-level histogram (:func:`ottag_db.decode.image.otsu`), compiled.

Computes what the numpy version did, element for element, in float64: the running sums in
order (as ``np.cumsum``), every split's between-class variance and the first split of the
largest; built with ``-ffp-contract=off`` (no fused multiply-adds), as numpy computes.
"""

from libc.math cimport INFINITY


def otsu_split(const double[::1] hist, double[::1] out):
    """Otsu's split of a 256-bin histogram and the means of its two classes.

    Parameters
    ----------
    hist : memoryview of float64
        ``(256,)`` pixel counts per grey level.
    out : memoryview of float64
        ``(4,)`` out: the level (the split's last grey level of the dark class), the dark and the
        bright class's mean grey level, and the histogram's total count.

    Returns
    -------
    bool
        False (``out`` partly written) when the histogram holds fewer than 16 pixels or one
        class of the best split is empty.
    """
    cdef double w0[256]
    cdef double s0[256]
    cdef double total, s_all, num, den, between, best = -INFINITY
    cdef Py_ssize_t i, t = 0
    if hist.shape[0] != 256:
        raise ValueError(f"a histogram of 256 bins, not {hist.shape[0]}")
    w0[0] = hist[0]
    s0[0] = hist[0] * 0.0
    for i in range(1, 256):
        w0[i] = w0[i - 1] + hist[i]
        s0[i] = s0[i - 1] + hist[i] * <double>i
    total = w0[255]
    out[3] = total
    if total < 16:
        return False
    s_all = s0[255]
    for i in range(256):
        # between-class variance w0·w1·(m0 − m1)² = (total·s0 − s_all·w0)² / (w0·w1); an empty
        # class (den = 0) scores 0
        num = total * s0[i] - s_all * w0[i]
        den = w0[i] * (total - w0[i])
        between = num * num / (den if den > 0 else INFINITY)
        if between > best or (between != between and best == best):  # (argmax: a NaN wins first)
            best = between
            t = i
            if between != between:
                break
    if w0[t] <= 0 or total - w0[t] <= 0:
        return False
    out[0] = <double>t
    out[1] = s0[t] / w0[t]
    out[2] = (s_all - s0[t]) / (total - w0[t])
    return True
