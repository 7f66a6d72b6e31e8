"""Stage ``masks``, reveals: the thin lines between flush fronts (``GAP``) from the depth alone.

A reveal is an image row or column that has no return or whose depth, averaged along the line,
lies a few mm behind the lines on both sides (which agree with each other and are not a crease);
runs shorter than ``gap_min_length`` are dropped. A second pass averages over a longer window with
a lowered threshold (:func:`_gap_mask`)."""

import math

import cv2
import numba
import numpy as np

_SUB = 4  # the line means are smooth along a line: one per 4 pixels along it suffices


def _gap_mask(d, valid, fx, cfg, dzero=None, long_pass=True, scale_floor=False, var_scale=None,
              to_image=None):
    """Pixels on the reveals between flush fronts (``GAP``) from the depth image alone (one
    pass per frame for all planes): (wide, thin), (H, W) bool each; ``wide`` is ``thin`` one
    pixel wider on either side across the line (for the rectified grids).

    A reveal is a thin line (image rows or columns: the fronts' sides are horizontal and
    vertical seen from the front) that either has no return (a structured-light camera drops
    the pixels of a 5 mm gap seen straight on, its depth edges) or lies a few mm *behind* the
    surface on both sides (the 5 mm horizontal reveal seen from 25 deg above shows the lower
    front's top face, 6-7 mm behind: inside the inlier distance L, so in-plane for Eq. 5.2,
    and the two fronts are one plane region). Each line's depth is averaged over
    ``gap_window_px`` pixels along it (the camera's noise, ~9 mm per pixel at 2.3 m, would
    hide a one-pixel dip; the mean of 32 pixels scatters by ~1.7 mm there) and compared with
    the mean of the lines ``gap_offsets_px`` away on either side, which must agree (one
    surface on both sides: a depth step is not a reveal), and with half the threshold with
    each side's two lines (``o`` and ``2 o`` away) extended to the line (a concave crease is
    behind the mean of its sides but not behind their extensions). Lines with fewer than a third of
    their pixels measured are reveals too. Detections
    shorter than ``gap_min_length`` at their depth are dropped (noise gives short runs, a
    reveal runs along a whole front; ``dzero``: ``d`` with 0 where not ``valid``, if at
    hand). The side lines must be well measured (>= 80 % of their
    pixels: a countertop seen at grazing incidence drops a third of its pixels, and its line
    means scatter beyond the noise model). ``long_pass``: also the lines averaged over
    ``gap_long_window_px`` (threshold's z^2 part scaled by the square root of the windows'
    ratio; with ``scale_floor`` the ``gap_depth`` floor too). ``var_scale``: (H, W) float32,
    each pixel's noise variance over one frame's (a temporally filtered image,
    :mod:`mmlearn.models.perception.depth_filter`; 0 where not valid), or None (1): the threshold's z^2
    part is scaled by the square root of its mean over the line (the line mean's noise).
    ``to_image``: the 3 x 3
    homography from ``d``'s pixels to the camera image's when ``d`` is a rectified view: the
    offsets allowed across a band without return (5 px, or 2 px plus 0.01 f / z) count image
    pixels, and a plane seen at grazing incidence stretches each image pixel over s >= 1 view
    pixels (a door opened 90 deg seen 67 deg off its normal: its hinge seam, 4-6 image px
    without return, is 9-12 view px wide at s ~ 1.6)."""
    H, W = d.shape
    z = np.where(valid, d, np.float32(0.0)) if dzero is None else dzero
    Hc, Wc = H - H % _SUB, W - W % _SUB
    out = np.zeros((H, W), bool)
    thin = np.zeros((H, W), bool)
    # (window, threshold scale): the short window, and the long one whose mean scatters by
    # sqrt(short / long) of the short one's, so its threshold is scaled by that (a reveal
    # runs across a cabinet's fronts: its few-mm dip, sampled at an unlucky pixel phase, is
    # within the short window's noise but not within the long one's)
    nb0 = max(1, int(round(cfg.gap_window_px / _SUB)))
    scales = [(nb0, 1.0)]
    if cfg.gap_long_window_px and long_pass:
        nbl = max(nb0 + 1, int(round(cfg.gap_long_window_px / _SUB)))
        scales.append((nbl, math.sqrt(nb0 / nbl)))
    blocks = {}
    for horizontal, (nb, tscale) in ((h, s) for h in (True, False) for s in scales):
        if horizontal not in blocks:  # (the same blocks for both windows)
            blocks[horizontal] = _line_blocks(z, valid, var_scale, horizontal, Hc, Wc)
        m, unmeas, side_ok, V = _window_means(*blocks[horizontal], nb, cfg)
        gd = np.float32(cfg.gap_depth * (tscale if scale_floor else 1.0))
        gdz = np.float32(cfg.gap_depth_per_m2 * tscale)
        g, zg = _line_hits(m, unmeas, side_ok, V, gd, gdz, fx, cfg, horizontal, to_image)
        if not g.any():
            continue
        min_windows = cfg.gap_long_min_windows * (nb * _SUB) if nb != nb0 else None
        g = _long_runs(g, zg, fx, cfg, min_windows)
        if g is None:
            continue
        # one pixel wider on either side across the line (a one-pixel line would fall
        # between the 5 mm cells of a plane's rectified grid, 2.2 mm pixels at 1.3 m), and
        # back to every pixel along the line
        _or_lines(g, horizontal, out, thin)
    return out, thin


@numba.njit(cache=True, nogil=True)
def _or_lines(g, horizontal, out, thin):
    """In place: each hit of ``g`` (rows across the lines, one column per ``_SUB`` pixels
    along them) or-ed into ``thin`` on its ``_SUB`` pixels, and into ``out`` on those and on
    the lines on either side of it (image rows with ``horizontal``, else columns)."""
    n_rows, nb = g.shape
    for r in range(n_rows):
        for b in range(nb):
            if not g[r, b]:
                continue
            for k in range(_SUB):
                p = _SUB * b + k
                for q in range(max(0, r - 1), min(n_rows, r + 2)):
                    if horizontal:
                        out[q, p] = True
                    else:
                        out[p, q] = True
                if horizontal:
                    thin[r, p] = True
                else:
                    thin[p, r] = True


_TILE = 16  # block rows per tile in _block_means_kernel's columns


@numba.njit(cache=True, nogil=True)
def _block_means_kernel(z, valid, horizontal, A, N):
    """Means of 4 pixels along the lines of ``z`` (float32) and of ``valid`` (as 0 / 1) into
    ``A`` and ``N`` (rows across the lines): the sums in the order of OpenCV's INTER_AREA
    resize by 4 (((a + b) + c) + d) times 1/4 in float32, so the same values, in one pass
    for both and with the columns' transpose written directly."""
    q = np.float32(0.25)
    if horizontal:
        for r in range(A.shape[0]):
            for c in range(A.shape[1]):
                j = _SUB * c
                s = z[r, j] + z[r, j + 1]
                s += z[r, j + 2]
                s += z[r, j + 3]
                A[r, c] = s * q
                n = np.float32(valid[r, j]) + np.float32(valid[r, j + 1])
                n += np.float32(valid[r, j + 2])
                n += np.float32(valid[r, j + 3])
                N[r, c] = n * q
    else:
        # _TILE blocks down the columns at a time, along the image rows into a small tile,
        # then each column's _TILE values written together (writing the transpose one
        # element at a time touched a new cache line per element)
        W, nbk = A.shape
        TA = np.empty((_TILE, W), np.float32)
        TN = np.empty((_TILE, W), np.float32)
        for b0 in range(0, nbk, _TILE):
            nt = min(_TILE, nbk - b0)
            for t in range(nt):
                i = _SUB * (b0 + t)
                z0, z1, z2, z3 = z[i], z[i + 1], z[i + 2], z[i + 3]
                v0, v1, v2, v3 = valid[i], valid[i + 1], valid[i + 2], valid[i + 3]
                ta, tn = TA[t], TN[t]
                for c in range(W):
                    s = z0[c] + z1[c]
                    s += z2[c]
                    s += z3[c]
                    ta[c] = s * q
                    n = np.float32(v0[c]) + np.float32(v1[c])
                    n += np.float32(v2[c])
                    n += np.float32(v3[c])
                    tn[c] = n * q
            for c in range(W):
                for t in range(nt):
                    A[c, b0 + t] = TA[t, c]
                    N[c, b0 + t] = TN[t, c]


def _line_blocks(z, valid, var_scale, horizontal, Hc, Wc):
    """Block means of 4 pixels along the lines (rows with ``horizontal``, else columns) of
    the depth ``z`` (float32, 0 where not measured), the measured share (``valid``, bool) and
    the noise variance factor (or None): (A, N, V), rows across the lines, columns along
    them (float32; the values of OpenCV's INTER_AREA resize by 4 along the lines)."""
    H, W = z.shape
    shape = (H, Wc // _SUB) if horizontal else (W, Hc // _SUB)
    A = np.empty(shape, np.float32)
    N = np.empty(shape, np.float32)
    _block_means_kernel(np.ascontiguousarray(z, np.float32), np.ascontiguousarray(valid),
                        bool(horizontal), A, N)
    V = None
    if var_scale is not None:
        size = (Wc // _SUB, H) if horizontal else (W, Hc // _SUB)
        V = cv2.resize(var_scale[:, :Wc] if horizontal else var_scale[:Hc],
                       size, interpolation=cv2.INTER_AREA)
        V = V if horizontal else np.ascontiguousarray(V.T)
    return A, N, V


def _bent_windows(A, N, nb, cfg):
    """Windows of ``nb`` blocks whose lines are not one surface (a step: an opened door in
    front of the cabinet's reveals): the middle block off the chord between the end blocks
    (a plane's depth is close to linear along a line over 32 px); bool, as ``A`` (one
    compiled pass, :func:`_bent_kernel`)."""
    bent = np.zeros(A.shape, bool)
    _bent_kernel(A, N, int(nb), np.float32(cfg.gap_side_tolerance_per_m2), bent)
    return bent


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _bent_kernel(A, N, nb, tol_m2, bent):
    """In place: ``bent[:, h0 + i]`` = |B[:, h0 + i] - (B[:, i] + B[:, i + nb - 1]) 0.5| >
    max(0.01, tol_m2 z z) with B = A / N and z = B[:, h0 + i], h0 = nb // 2 (float32, the
    array expression's operations in its order; NaN compares false)."""
    n_rows, n = A.shape
    h0 = nb // 2
    if n <= nb:
        return
    half = np.float32(0.5)
    tmin = np.float32(0.01)
    B = np.empty(n, np.float32)
    m = n - nb + 1
    for r in range(n_rows):
        Ar, Nr = A[r], N[r]
        for i in range(n):
            B[i] = Ar[i] / Nr[i]
        # (the shifted rows as slices indexed from 0: the compiler makes vector operations)
        Bc, Be, bo = B[h0:h0 + m], B[nb - 1:nb - 1 + m], bent[r, h0:h0 + m]
        for i in range(m):
            zc = Bc[i]
            chord = (B[i] + Be[i]) * half
            t = (tol_m2 * zc) * zc
            tol = t if t > tmin else tmin
            bo[i] = (abs(zc - chord) > tol) & (t == t)


def _window_means(A, N, V, nb, cfg):
    """The lines' means over windows of ``nb`` blocks: (mean depth, NaN where under a third
    measured; unmeasured; usable as a side line: >= 80 % measured and not bent; the line's
    noise std over one frame's, or None). One compiled pass (:func:`_window_kernel`) after
    :func:`_bent_windows`."""
    Lw = nb * _SUB
    bent = _bent_windows(A, N, nb, cfg)
    m = np.empty(A.shape, np.float32)
    unmeas = np.empty(A.shape, bool)
    side_ok = np.empty(A.shape, bool)
    Vo = None if V is None else np.empty(A.shape, np.float32)
    # (the thresholds as numpy compares a float32 array with a Python float: in float32)
    _window_kernel(A, N, np.zeros((1, 1), np.float32) if V is None else V, V is not None,
                   int(nb), np.float32(max(3.0, Lw / 3.0)), np.float32(0.8 * Lw), bent, m,
                   unmeas, side_ok, np.zeros((1, 1), np.float32) if V is None else Vo)
    return m, unmeas, side_ok, Vo


@numba.njit(cache=True, nogil=True)
def _box_row(x, nb, out):
    """OpenCV's unnormalised (nb, 1) box filter (``cv2.boxFilter``, ``BORDER_CONSTANT``,
    anchor nb // 2) of one float32 row: the running sum in float64 of the zero-padded row
    (the first window summed, then plus the value entering minus the one leaving), rounded
    to float32 (the same values)."""
    n = x.shape[0]
    a = nb // 2
    s = 0.0
    for i in range(nb):
        c = i - a
        if 0 <= c < n:
            s += np.float64(x[c])
    out[0] = np.float32(s)
    # output i + 1: x[i + nb - a] enters (0 past the end), x[i - a] leaves (0 before the
    # start); the three ranges of i without a test per element
    i0 = min(a, n - 1)                  # i < a: nothing leaves
    i1 = max(i0, min(n - 1, n - nb + a))  # i + nb - a < n: something enters
    for i in range(i0):
        cin = i + nb - a
        s += (np.float64(x[cin]) if cin < n else 0.0) - 0.0
        out[i + 1] = np.float32(s)
    for i in range(i0, i1):
        s += np.float64(x[i + nb - a]) - np.float64(x[i - a])
        out[i + 1] = np.float32(s)
    for i in range(i1, n - 1):
        s += 0.0 - np.float64(x[i - a])
        out[i + 1] = np.float32(s)


@numba.njit(cache=True, nogil=True)
def _box_rows(X, nb, out):
    """:func:`_box_row` of every row of ``X`` into ``out``, four rows at a time in lockstep
    (four independent running sums: the same values, twice as fast)."""
    n_rows, n = X.shape
    a = nb // 2
    i0 = min(a, n - 1)
    i1 = max(i0, min(n - 1, n - nb + a))
    r = 0
    while r + 4 <= n_rows:
        x0, x1, x2, x3 = X[r], X[r + 1], X[r + 2], X[r + 3]
        o0, o1, o2, o3 = out[r], out[r + 1], out[r + 2], out[r + 3]
        s0 = s1 = s2 = s3 = 0.0
        for i in range(nb):
            c = i - a
            if 0 <= c < n:
                s0 += np.float64(x0[c])
                s1 += np.float64(x1[c])
                s2 += np.float64(x2[c])
                s3 += np.float64(x3[c])
        o0[0] = np.float32(s0)
        o1[0] = np.float32(s1)
        o2[0] = np.float32(s2)
        o3[0] = np.float32(s3)
        for i in range(i0):
            cin = i + nb - a
            if cin < n:
                s0 += np.float64(x0[cin]) - 0.0
                s1 += np.float64(x1[cin]) - 0.0
                s2 += np.float64(x2[cin]) - 0.0
                s3 += np.float64(x3[cin]) - 0.0
            else:  # (as the padded row's 0 - 0)
                s0 += 0.0
                s1 += 0.0
                s2 += 0.0
                s3 += 0.0
            o0[i + 1] = np.float32(s0)
            o1[i + 1] = np.float32(s1)
            o2[i + 1] = np.float32(s2)
            o3[i + 1] = np.float32(s3)
        for i in range(i0, i1):
            ci, co = i + nb - a, i - a
            s0 += np.float64(x0[ci]) - np.float64(x0[co])
            s1 += np.float64(x1[ci]) - np.float64(x1[co])
            s2 += np.float64(x2[ci]) - np.float64(x2[co])
            s3 += np.float64(x3[ci]) - np.float64(x3[co])
            o0[i + 1] = np.float32(s0)
            o1[i + 1] = np.float32(s1)
            o2[i + 1] = np.float32(s2)
            o3[i + 1] = np.float32(s3)
        for i in range(i1, n - 1):
            co = i - a
            s0 += 0.0 - np.float64(x0[co])
            s1 += 0.0 - np.float64(x1[co])
            s2 += 0.0 - np.float64(x2[co])
            s3 += 0.0 - np.float64(x3[co])
            o0[i + 1] = np.float32(s0)
            o1[i + 1] = np.float32(s1)
            o2[i + 1] = np.float32(s2)
            o3[i + 1] = np.float32(s3)
        r += 4
    while r < n_rows:
        _box_row(X[r], nb, out[r])
        r += 1



@numba.njit(cache=True, nogil=True)
def _window_kernel(A, N, V, has_v, nb, meas_min, side_min, bent, m, unmeas, side_ok, Vo):
    """:func:`_window_means`: the window sums (:func:`_box_rows`) times ``_SUB``,
    ``unmeas`` = sum N < ``meas_min``, ``side_ok`` = sum N >= ``side_min`` and not ``bent``,
    ``m`` = sum A / max(sum N, 1) (NaN where unmeasured), ``Vo`` = sqrt(min(sum V / max(sum
    N, 1), 1)) (float32, the array expressions' operations in their order). Four rows at a
    time through small buffers (whole-array sums were fresh memory on every call)."""
    n_rows, n = A.shape
    q = np.float32(_SUB)
    one = np.float32(1.0)
    nan = np.float32(np.nan)
    sa = np.empty((4, n), np.float32)
    sn = np.empty((4, n), np.float32)
    sv = np.empty((4, n), np.float32)
    for r0 in range(0, n_rows, 4):
        r1 = min(n_rows, r0 + 4)
        _box_rows(A[r0:r1], nb, sa[:r1 - r0])
        _box_rows(N[r0:r1], nb, sn[:r1 - r0])
        if has_v:
            _box_rows(V[r0:r1], nb, sv[:r1 - r0])
        for r in range(r0, r1):
            i = r - r0
            for c in range(n):
                w = sn[i, c] * q
                w1 = max(w, one)
                meas = w >= meas_min
                unmeas[r, c] = not meas
                side_ok[r, c] = (w >= side_min) & (not bent[r, c])
                mv = (sa[i, c] * q) / w1
                m[r, c] = mv if meas else nan
                if has_v:
                    Vo[r, c] = np.sqrt(min((sv[i, c] * q) / w1, one))


#: whether an unmeasured band counts its offsets in image pixels in a rectified view
#: (:func:`_line_hits`; off only to show what it does)
_STRETCH_ACROSS = True


@numba.njit(cache=True, nogil=True)
def _stretch_at(Hi, r, c, sub, horizontal, across):
    """View pixels per image pixel across the lines (``across``; else along them; >= 1: never
    less than on the image) at the line-mean element (row ``r``, column ``c``) of
    :func:`_gap_mask`'s line-mean array (rows across the lines, one column per ``sub`` pixels
    along them) of a rectified view whose pixels map to the image by the homography ``Hi``
    (float32)."""
    b = c * sub + 0.5 * (sub - 1)
    x, y = (b, float(r)) if horizontal else (float(r), b)
    p0 = Hi[0, 0] * x + Hi[0, 1] * y + Hi[0, 2]
    p1 = Hi[1, 0] * x + Hi[1, 1] * y + Hi[1, 2]
    p2 = Hi[2, 0] * x + Hi[2, 1] * y + Hi[2, 2]
    k = (1 if horizontal else 0) if across else (0 if horizontal else 1)
    du = (Hi[0, k] * p2 - p0 * Hi[2, k]) / (p2 * p2)
    dv = (Hi[1, k] * p2 - p1 * Hi[2, k]) / (p2 * p2)
    return np.float32(max(1.0, 1.0 / max(math.hypot(du, dv), 1e-9)))


@numba.njit(cache=True, nogil=True)
def _line_hits_kernel(m, unmeas, side_ok, V, Hi, gd, gdz, tol_m2, near_z, offsets, horizontal,
                      has_v, has_h, stretch_across, g, zg):
    """The tests of :func:`_line_hits`, element by element in float32 (the same operations in
    the same order as on arrays), offset after offset; writes ``g`` and ``zg``. ``unmeas`` and
    ``side_ok`` are 0 / 1 bytes."""
    n_rows, Wm = m.shape
    half = np.float32(0.5)
    tmin = np.float32(0.01)
    Wp = (Wm + 7) // 8 * 8
    cand = np.zeros(Wp, np.uint8)
    cand64 = cand.view(np.uint64)  # eight columns at a time: most are no candidate
    idx = np.empty(Wp, np.int64)
    zero = np.float32(0.0)
    # the candidates' threshold: gd with the noise factor (V <= 1 only lowers the z^2 part:
    # tested below), else max(gd, gdz z^2)
    gdz_c = zero if has_v else gdz
    for o in offsets:
        if n_rows <= 4 * o:
            continue
        of = np.float32(o - 2)
        for r in range(2 * o, n_rows - 2 * o):
            # the tests that need no stretch, on the whole row without branches (vectorised by
            # the compiler): both sides usable, behind by the threshold without its noise
            # factor V <= 1 (then by the floor gd) and stretch s >= 1 (the full threshold is
            # never smaller), or unmeasured, and the sides agreeing; the same float32
            # operations as below, so a column failing here fails there
            # (selects rather than max() and abs(), the noise factor's case outside the loop:
            # vector operations of the same values; a NaN makes both compares false either way)
            mu, md, mc = m[r - o], m[r + o], m[r]
            su, sd, un = side_ok[r - o], side_ok[r + o], unmeas[r]
            for c in range(Wm):
                up, dn = mu[c], md[c]
                ref = (up + dn) * half
                z2 = ref * ref
                t1 = gdz_c * z2
                thr = t1 if t1 > gd else gd
                t2 = tol_m2 * z2
                tol = t2 if t2 > tmin else tmin
                dd = up - dn
                ad = dd if dd >= zero else -dd
                cand[c] = (su[c] & sd[c] & (np.uint8(mc[c] - ref > thr) | un[c])
                           & np.uint8(ad < tol))
            # the few candidates' columns, without a conditional jump per column (a mispredicted
            # jump per candidate cost more than the remaining tests)
            nc = 0
            for w in range(Wp // 8):
                if cand64[w] != 0:
                    for c in range(8 * w, 8 * w + 8):
                        idx[nc] = c
                        nc += cand[c]
            for j in range(nc):
                c = idx[j]
                up, dn, cv = mu[c], md[c], mc[c]
                ref = (up + dn) * half
                behind = cv - ref
                unm = un[c] != 0
                z2 = ref * ref
                t = gdz * z2
                if has_v:
                    t = t * V[r, c]
                thr = max(gd, t)
                if has_h:
                    thr = thr * np.sqrt(_stretch_at(Hi, r, c, _SUB, horizontal, False))
                if not (behind > thr or unm):
                    continue
                tol = max(tmin, tol_m2 * z2)
                if not abs(up - dn) < tol:
                    continue
                ext = (up + dn) - half * (m[r - 2 * o, c] + m[r + 2 * o, c])
                if not (cv - ext > half * thr or unm):
                    continue
                if has_h and unm:
                    sv = _stretch_at(Hi, r, c, _SUB, horizontal, True) if stretch_across \
                        else np.float32(1.0)
                    # (as numpy: 5 s in float32, compared with the integer o in float64)
                    near = (o <= float(np.float32(5.0) * sv)) or (
                        float(ref) * (o - 2.0 * float(sv)) < float(near_z))
                else:
                    near = o <= 5 or ref * of < near_z
                if near:
                    g[r, c] = True
                    zg[r, c] = ref


def _line_hits(m, unmeas, side_ok, V, gd, gdz, fx, cfg, horizontal, to_image):
    """The reveal lines among the window means ``m`` (rows across the lines): (hit, depth of
    the side lines where hit), both as ``m``.

    Per offset o (``gap_offsets_px``) and line: both side lines o away usable (``side_ok``),
    the line behind their mean by more than thr = max(gd, gdz z^2 (V)) or unmeasured (in a
    rectified view the threshold times sqrt of the view's stretch along the line: a window's
    mean holds 1 / s of the independent samples it has on the image), the sides agreeing
    within max(0.01, gap_side_tolerance_per_m2 z^2), behind the sides' extrapolations (each
    side's two lines extended to the line) by thr / 2 or unmeasured (a concave crease, an
    opened door meeting the cabinet's face at its hinge, lies behind the mean of its sides,
    not behind their extensions), and for o > 5 only near (a 5 mm reveal's band without
    return is ~2 + f 0.01 / z px; in a rectified view, for a line without return, its image
    px count s >= 1 view px each: o <= 5 s or z (o - 2 s) < 0.01 f). A line hit at several
    offsets keeps the depth of its last one. A compiled loop (:func:`_line_hits_kernel`):
    most lines fail the first tests, which numpy evaluated on whole arrays."""
    g = np.zeros(m.shape, bool)
    zg = np.zeros(m.shape, np.float32)  # depth of the side lines where hit
    dummy = np.zeros((1, 1), np.float32)
    _line_hits_kernel(
        m, unmeas.view(np.uint8), side_ok.view(np.uint8), dummy if V is None else V,
        np.eye(3) if to_image is None else np.asarray(to_image, np.float64),
        np.float32(gd), np.float32(gdz), np.float32(cfg.gap_side_tolerance_per_m2),
        np.float32(0.01 * fx), np.asarray(cfg.gap_offsets_px, np.int64), bool(horizontal),
        V is not None, to_image is not None, _STRETCH_ACROSS, g, zg)
    return g, zg


def _long_runs(g, zg, fx, cfg, min_px_floor=None):
    """The runs of hit lines ``g`` at least ``gap_min_length`` long at their depth (and at
    least ``min_px_floor`` px: one long window's scatter is not a line), or None if none.

    A run is an 8-connected region of ``g``; its length is its extent along the lines, its
    depth its side lines' depth ``zg`` at its centroid (a run is a thin line: the centroid is
    on it), else the mean over the run (one compiled pass, :func:`_runs_kernel`)."""
    out = np.zeros(g.shape, bool)
    floor = -1.0 if min_px_floor is None else float(min_px_floor)
    if not _runs_kernel(np.ascontiguousarray(g), np.ascontiguousarray(zg, np.float32),
                        float(cfg.gap_min_length) * float(fx), floor, out):
        return None
    return out


@numba.njit(cache=True, nogil=True)
def _runs_kernel(g, zg, min_len_fx, floor, out):
    """:func:`_long_runs`: each 8-connected region of ``g`` (a flood fill from its first
    pixel in raster order) with its column extent, centroid (float64 sums of the pixel
    coordinates over the area, rounded half to even) and depth: ``zg`` at the centroid when
    the centroid's pixel is the region's, else the mean of ``zg`` over the region (summed in
    raster order); kept (set in ``out``, all False on entry: only the regions' pixels are
    written, in the order visited) when ``_SUB`` x extent >= max(min_len_fx /
    max(depth, 1e-6), floor). Returns whether any was kept."""
    H, W = g.shape
    npx = 0  # (the set pixels bound the regions and the stack: arrays of that size)
    for r in range(H):
        for c in range(W):
            npx += 1 if g[r, c] else 0
    if npx == 0:
        return False
    lab = np.zeros((H, W), np.int32)
    stack = np.empty(npx, np.int64)
    # per region: first pixel, area, column extent, coordinate sums
    first = np.empty(npx, np.int64)
    nl = 0
    cmin = np.empty(npx, np.int64)
    cmax = np.empty(npx, np.int64)
    area = np.empty(npx, np.int64)
    sx = np.empty(npx)
    sy = np.empty(npx)
    order = np.empty(npx, np.int64)  # the regions' pixels as visited
    nvis = 0
    for r in range(H):
        for c in range(W):
            if not g[r, c] or lab[r, c] != 0:
                continue
            nl += 1
            k = nl - 1
            first[k] = r * W + c
            lab[r, c] = nl
            stack[0] = r * W + c
            top = 1
            a = 0
            x0 = x1 = c
            tx = ty = 0.0
            while top > 0:
                top -= 1
                p = stack[top]
                order[nvis] = p
                nvis += 1
                pr, pc = p // W, p % W
                a += 1
                tx += pc
                ty += pr
                x0 = min(x0, pc)
                x1 = max(x1, pc)
                for r2 in range(max(0, pr - 1), min(H, pr + 2)):
                    for c2 in range(max(0, pc - 1), min(W, pc + 2)):
                        if g[r2, c2] and lab[r2, c2] == 0:
                            lab[r2, c2] = nl
                            stack[top] = r2 * W + c2
                            top += 1
            area[k], cmin[k], cmax[k], sx[k], sy[k] = a, x0, x1, tx, ty
    if nl == 0:
        return False
    zrun = np.empty(nl)
    need = np.zeros(nl, np.bool_)
    for k in range(nl):
        cr = min(max(int(np.round(sy[k] / area[k])), 0), H - 1)
        cc = min(max(int(np.round(sx[k] / area[k])), 0), W - 1)
        if lab[cr, cc] == k + 1:
            zrun[k] = np.float64(zg[cr, cc])
        else:
            need[k] = True
            zrun[k] = 0.0
    for r in range(H):  # the regions whose centroid is off them: their mean depth
        for c in range(W):
            k = lab[r, c] - 1
            if k >= 0 and need[k]:
                zrun[k] += np.float64(zg[r, c])
    keep = np.zeros(nl + 1, np.bool_)
    anyk = False
    for k in range(nl):
        if need[k]:
            zrun[k] = zrun[k] / max(area[k], 1)
        min_px = min_len_fx / max(zrun[k], 1e-6)
        if floor >= 0.0:
            min_px = max(min_px, floor)
        if _SUB * np.float64(cmax[k] - cmin[k] + 1) >= min_px:
            keep[k + 1] = True
            anyk = True
    if anyk:  # (``out`` is all False: only the regions' pixels to set)
        for i in range(nvis):
            p = order[i]
            r, c = p // W, p % W
            out[r, c] = keep[lab[r, c]]
    return anyk
