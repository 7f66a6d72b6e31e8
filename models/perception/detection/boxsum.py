"""Stage ``masks``, window sums: the 5 x 5 unnormalised box sums of the surface check and of
the crossings' nearer-plane rule in compiled passes fused with what they feed, with the values
of ``cv2.boxFilter(x, -1, (5, 5), normalize=False)`` on a float32 image (its default border,
BORDER_REFLECT_101).

OpenCV sums a 5-wide window of a row in float64 in one expression (((x0 + x1) + x2) + x3) + x4,
then runs down each column a float64 sum that adds the row entering the window and, after
writing the output (rounded to float32), subtracts the row leaving it; the first four rows
(two reflected above the image and its first two) start that sum from 0. The kernels here do
the same operations in the same order, so their sums are the same floats; the counts of
in-plane pixels are integers (exact in any order)."""

import numba
import numpy as np

#: the window side the kernels replicate (other sides fall back to OpenCV)
BOX = 5


@numba.njit(cache=True, nogil=True, inline="always")
def _reflect101(i, n):
    """OpenCV's BORDER_REFLECT_101 index of ``i`` into ``n`` >= 3 elements (|i| <= 2 past
    an end)."""
    if i < 0:
        return -i
    if i >= n:
        return 2 * (n - 1) - i
    return i


@numba.njit(cache=True, nogil=True, inline="always")
def _row_sums(e, out):
    """``out[c]`` = (((e[c] + e[c+1]) + e[c+2]) + e[c+3]) + e[c+4] (float64; ``e`` the row
    extended by two reflected elements on either side)."""
    for c in range(out.shape[0]):
        out[c] = (((e[c] + e[c + 1]) + e[c + 2]) + e[c + 3]) + e[c + 4]


@numba.njit(cache=True, nogil=True, inline="always")
def _extend(row, e):
    """``e`` (float64, len(row) + 4) = ``row`` with two BORDER_REFLECT_101 elements on either
    side."""
    w = row.shape[0]
    for c in range(w):
        e[c + 2] = np.float64(row[c])
    e[0], e[1] = e[4], e[3]
    e[w + 2], e[w + 3] = e[w], e[w - 1]


@numba.njit(cache=True, nogil=True)
def _row_extents(m, y0, y1, x0, x1, lo, hi):
    """Each row's first and last column (counted from x0) where ``m`` is not 0 on the box rows
    y0:y1, columns x0:x1, into ``lo`` / ``hi`` (``lo`` = the box's width: none)."""
    w = x1 - x0
    for r in range(y1 - y0):
        mr = m[y0 + r, x0:x1]
        i = 0
        while i < w and mr[i] == 0:
            i += 1
        j = w - 1
        while j > i and mr[j] == 0:
            j -= 1
        lo[r], hi[r] = i, j


@numba.njit(cache=True, nogil=True, inline="always")
def _sparse_row_sums(e, w, l, u, R):
    """The window sums ``R`` along an extended row ``e`` (w + 4: the row's values at
    e[2:w + 2], 0 outside the columns l..u, two BORDER_REFLECT_101 elements set on either
    side here) on the columns where they are not 0: returned as (first, last). Every loop
    runs over slices indexed from 0 (no negative-index wraparound: vector operations)."""
    e[0], e[1] = e[4], e[3]
    e[w + 2], e[w + 3] = e[w], e[w - 1]
    p, q = max(0, l - 2), min(w - 1, u + 2)
    ep, Rs = e[p:q + 5], R[p:q + 1]
    for t in range(q + 1 - p):
        Rs[t] = (((ep[t] + ep[t + 1]) + ep[t + 2]) + ep[t + 3]) + ep[t + 4]
    e[0] = e[1] = e[w + 2] = e[w + 3] = 0.0
    return p, q


@numba.njit(cache=True, nogil=True, inline="always")
def _add_rows(acc, R, p, q, sign):
    """``acc[p:q + 1]`` += ``R[p:q + 1]`` (``sign`` > 0), else -=."""
    a, b = acc[p:q + 1], R[p:q + 1]
    if sign > 0:
        for t in range(q + 1 - p):
            a[t] = a[t] + b[t]
    else:
        for t in range(q + 1 - p):
            a[t] = a[t] - b[t]


@numba.njit(cache=True, nogil=True, inline="always")
def _push_rows(e1, e2, R1, R2, acc1, acc2, ext, k, w, l, u):
    """Two extended rows entering the window (``e1``, ``e2``: their values on the columns
    l..u, 0 elsewhere): their window sums into the ring's rows ``R1[k]``, ``R2[k]`` (on the
    columns ``ext[k]`` where they are not 0) and added to the column sums ``acc1``,
    ``acc2``; the rows' values set back to 0."""
    p, q = _sparse_row_sums(e1, w, l, u, R1[k])
    _sparse_row_sums(e2, w, l, u, R2[k])
    z1, z2 = e1[l + 2:u + 3], e2[l + 2:u + 3]
    for t in range(u + 1 - l):
        z1[t] = 0
        z2[t] = 0
    ext[k, 0], ext[k, 1] = p, q
    _add_rows(acc1, R1[k], p, q, 1)
    _add_rows(acc2, R2[k], p, q, 1)


@numba.njit(cache=True, nogil=True, inline="always")
def _pop_rows(R1, R2, acc1, acc2, ext, old):
    """The ring's rows ``old`` leaving the window: subtracted from the column sums."""
    _add_rows(acc1, R1[old], ext[old, 0], ext[old, 1], -1)
    _add_rows(acc2, R2[old], ext[old, 0], ext[old, 1], -1)


@numba.njit(cache=True, nogil=True)
def surface_marks(S, m8, Lm, y0, y1, x0, x1, a, b, c, with_ramp, lab):
    """The surface check's marks on the box rows y0:y1, columns x0:x1 (at least 3 x 3) of the
    images: with dev = (S - ((a x + b y) + c)) m (float32, x and y counted from the box's
    corner; without ``with_ramp`` S m; m = 1 where ``m8`` is set, else 0), num and den the 5 x
    5 box sums over the box of dev and of m (``cv2.boxFilter`` of the box, see the module),
    OFF_SURFACE (5) is or-ed into ``lab`` where ``m8`` is set and |num| > den ``Lm``.

    Only the columns between a row's first and last in-plane pixel are summed: elsewhere dev
    and m are 0 (of either sign), their window sums are 0, and adding or subtracting 0 leaves
    a column's running sum as it is (the same values)."""
    h, w = y1 - y0, x1 - x0
    one, zero = np.float32(1.0), np.float32(0.0)
    flag = np.uint8(5)
    lo, hi = np.empty(h, np.int64), np.empty(h, np.int64)
    _row_extents(m8, y0, y1, x0, x1, lo, hi)
    xf = np.arange(w).astype(np.float32)
    # (the extended rows, 0 outside the extents; the counts in float32: integers up to 25,
    # exact, as OpenCV's integer sums)
    e, ei = np.zeros(w + 4), np.zeros(w + 4, np.float32)
    R, Rn = np.empty((BOX, w)), np.empty((BOX, w), np.float32)  # the last five rows' sums
    ext = np.empty((BOX, 2), np.int64)  # ... and the columns they are not 0 on
    acc, accn = np.zeros(w), np.zeros(w, np.float32)
    for re in range(h + BOX - 1):
        r = _reflect101(re - 2, h)
        k = re % BOX
        l, u = lo[r], hi[r]
        ext[k, 0], ext[k, 1] = 0, -1
        if l < w:
            n = u + 1 - l
            Ss, ms, xs = S[y0 + r, x0 + l:x0 + u + 1], m8[y0 + r, x0 + l:x0 + u + 1], xf[l:u + 1]
            es, eis = e[l + 2:u + 3], ei[l + 2:u + 3]
            if with_ramp:
                by = b * np.float32(r)
                for t in range(n):
                    f = one if ms[t] != 0 else zero
                    es[t] = np.float64((Ss[t] - ((a * xs[t] + by) + c)) * f)
                    eis[t] = f
            else:
                for t in range(n):
                    f = one if ms[t] != 0 else zero
                    es[t] = np.float64(Ss[t] * f)
                    eis[t] = f
            _push_rows(e, ei, R, Rn, acc, accn, ext, k, w, l, u)
        if re < BOX - 1:
            continue
        y = re - (BOX - 1)  # (its sums are acc, accn now)
        if lo[y] < w:  # (marks on the row's in-plane columns only)
            ly, uy = lo[y], hi[y] + 1
            Lr, m8r = Lm[y0 + y, x0 + ly:x0 + uy], m8[y0 + y, x0 + ly:x0 + uy]
            lr, ac, an = lab[y0 + y, x0 + ly:x0 + uy], acc[ly:uy], accn[ly:uy]
            for t in range(uy - ly):
                hit = (m8r[t] != 0) & (abs(np.float32(ac[t])) > an[t] * Lr[t])
                lr[t] = lr[t] | (flag if hit else np.uint8(0))
        _pop_rows(R, Rn, acc, accn, ext, (re + 1) % BOX)  # (the row re - 4)


@numba.njit(cache=True, nogil=True)
def pair_window_sums(Sk, Sj, y0, y1, x0, x1, rows, cols, ak, aj):
    """The crossings' window sums of one pair of planes: with w = 1 at the pixels (``rows``,
    ``cols``: image rows and columns, in raster order) and 0 elsewhere on the box rows y0:y1,
    columns x0:x1 (at least 3 x 3), ``ak`` / ``aj`` = |5 x 5 box sum of ``Sk`` w / ``Sj`` w|
    at those pixels (float32; ``cv2.boxFilter`` of the box, see the module; only the columns
    between a row's first and last pixel are summed, as in :func:`surface_marks`)."""
    h, w = y1 - y0, x1 - x0
    n = rows.shape[0]
    one, zero = np.float32(1.0), np.float32(0.0)
    wb = np.zeros((h, w), np.uint8)
    for i in range(n):
        wb[rows[i] - y0, cols[i] - x0] = 1
    lo, hi = np.empty(h, np.int64), np.empty(h, np.int64)
    _row_extents(wb, 0, h, 0, w, lo, hi)
    start = np.full(h, n, np.int64)  # each box row's first pixel in the list
    for i in range(n - 1, -1, -1):
        start[rows[i] - y0] = i
    ek, ej = np.zeros(w + 4), np.zeros(w + 4)
    Rk, Rj = np.empty((BOX, w)), np.empty((BOX, w))
    ext = np.empty((BOX, 2), np.int64)
    acck, accj = np.zeros(w), np.zeros(w)
    for re in range(h + BOX - 1):
        r = _reflect101(re - 2, h)
        k = re % BOX
        l, u = lo[r], hi[r]
        ext[k, 0], ext[k, 1] = 0, -1
        if l < w:
            m = u + 1 - l
            Sks, Sjs, ws = Sk[y0 + r, x0 + l:x0 + u + 1], Sj[y0 + r, x0 + l:x0 + u + 1], wb[r, l:u + 1]
            eks, ejs = ek[l + 2:u + 3], ej[l + 2:u + 3]
            for t in range(m):
                f = one if ws[t] != 0 else zero
                eks[t] = np.float64(Sks[t] * f)
                ejs[t] = np.float64(Sjs[t] * f)
            _push_rows(ek, ej, Rk, Rj, acck, accj, ext, k, w, l, u)
        if re < BOX - 1:
            continue
        y = re - (BOX - 1)
        i = start[y]
        while i < n and rows[i] - y0 == y:
            x = cols[i] - x0
            ak[i] = abs(np.float32(acck[x]))
            aj[i] = abs(np.float32(accj[x]))
            i += 1
        _pop_rows(Rk, Rj, acck, accj, ext, (re + 1) % BOX)


@numba.njit(cache=True, nogil=True)
def box_sums(X, out):
    """``out`` = the 5 x 5 box sums of the float32 image ``X`` (at least 3 x 3), as
    ``cv2.boxFilter(X, -1, (5, 5), normalize=False)`` (the same operations: see the module).
    For the tests: the kernels above fuse this with their inputs and outputs."""
    h, w = X.shape
    e = np.empty(w + 4)
    R = np.empty((BOX, w))
    acc = np.zeros(w)
    for re in range(h + BOX - 1):
        _extend(X[_reflect101(re - 2, h)], e)
        k = re % BOX
        _row_sums(e, R[k])
        if re < BOX - 1:
            for x in range(w):
                acc[x] += R[k, x]
            continue
        y = re - (BOX - 1)
        Ro = R[(re + 1) % BOX]
        for x in range(w):
            s0 = acc[x] + R[k, x]
            out[y, x] = np.float32(s0)
            acc[x] = s0 - Ro[x]
