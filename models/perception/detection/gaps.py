"""Stage ``masks``, reveals: the thin lines between flush fronts (``GAP``) from the depth alone.

A reveal is an image row or column that has no return or whose depth, averaged along the line,
lies a few mm behind the lines on both sides (which agree with each other and are not a crease);
runs shorter than ``gap_min_length`` are dropped. A second pass averages over a longer window with
a lowered threshold (:func:`_gap_mask`)."""

import math

import cv2
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
    w = valid.astype(np.float32)
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
            blocks[horizontal] = _line_blocks(z, w, var_scale, horizontal, Hc, Wc)
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
        # one pixel wider on either side across the line: a one-pixel line would fall
        # between the 5 mm cells of a plane's rectified grid (2.2 mm pixels at 1.3 m)
        wide = g.copy()
        wide[1:] |= g[:-1]
        wide[:-1] |= g[1:]
        if horizontal:  # back to every pixel along the line
            out[:, :Wc] |= np.repeat(wide, _SUB, axis=1)
            thin[:, :Wc] |= np.repeat(g, _SUB, axis=1)
        else:
            out[:Hc] |= np.repeat(np.ascontiguousarray(wide.T), _SUB, axis=0)
            thin[:Hc] |= np.repeat(np.ascontiguousarray(g.T), _SUB, axis=0)
    return out, thin


def _line_blocks(z, w, var_scale, horizontal, Hc, Wc):
    """Block means of 4 pixels along the lines (rows with ``horizontal``, else columns) of
    the depth ``z`` (0 where not measured), the measured share ``w`` and the noise variance
    factor (or None): (A, N, V), rows across the lines, columns along them."""
    H, W = z.shape
    if horizontal:
        size = (Wc // _SUB, H)
        A = cv2.resize(z[:, :Wc], size, interpolation=cv2.INTER_AREA)
        N = cv2.resize(w[:, :Wc], size, interpolation=cv2.INTER_AREA)
    else:
        size = (W, Hc // _SUB)
        A = np.ascontiguousarray(cv2.resize(z[:Hc], size, interpolation=cv2.INTER_AREA).T)
        N = np.ascontiguousarray(cv2.resize(w[:Hc], size, interpolation=cv2.INTER_AREA).T)
    V = None
    if var_scale is not None:
        V = cv2.resize(var_scale[:, :Wc] if horizontal else var_scale[:Hc],
                       size, interpolation=cv2.INTER_AREA)
        V = V if horizontal else np.ascontiguousarray(V.T)
    return A, N, V


def _bent_windows(A, N, nb, cfg):
    """Windows of ``nb`` blocks whose lines are not one surface (a step: an opened door in
    front of the cabinet's reveals): the middle block off the chord between the end blocks
    (a plane's depth is close to linear along a line over 32 px); bool, as ``A``."""
    with np.errstate(invalid="ignore", divide="ignore"):
        B = A / N
    h0, h1 = nb // 2, nb - 1 - nb // 2
    bent = np.zeros(B.shape, bool)
    if B.shape[1] > nb:  # (in place: the same float32 operations in the same order)
        with np.errstate(invalid="ignore"):
            chord = np.add(B[:, : B.shape[1] - nb + 1], B[:, nb - 1:])
            chord *= np.float32(0.5)
            zc = B[:, h0: B.shape[1] - h1]
            tol_b = np.multiply(np.float32(cfg.gap_side_tolerance_per_m2), zc)
            tol_b *= zc
            np.maximum(np.float32(0.01), tol_b, out=tol_b)
            np.subtract(zc, chord, out=chord)
            np.abs(chord, out=chord)
            np.greater(chord, tol_b, out=bent[:, h0: B.shape[1] - h1])
    return bent


def _window_means(A, N, V, nb, cfg):
    """The lines' means over windows of ``nb`` blocks: (mean depth, NaN where under a third
    measured; unmeasured; usable as a side line: >= 80 % measured and not bent; the line's
    noise std over one frame's, or None)."""
    Lw = nb * _SUB
    bent = _bent_windows(A, N, nb, cfg)
    A = cv2.boxFilter(A, -1, (nb, 1), normalize=False, borderType=cv2.BORDER_CONSTANT)
    N = cv2.boxFilter(N, -1, (nb, 1), normalize=False, borderType=cv2.BORDER_CONSTANT)
    A *= np.float32(_SUB)
    N *= np.float32(_SUB)
    if V is not None:  # the line's noise std over one frame's: sqrt(mean variance factor)
        V = cv2.boxFilter(V, -1, (nb, 1), normalize=False, borderType=cv2.BORDER_CONSTANT)
        V *= np.float32(_SUB)
        V = np.sqrt(np.minimum(V / np.maximum(N, np.float32(1.0)), np.float32(1.0)))
    meas = N >= max(3.0, Lw / 3.0)
    # side lines: well measured and not bent (one array for both side tests)
    side_ok = (N >= 0.8 * Lw) & ~bent
    m = A / np.maximum(N, np.float32(1.0))
    m[~meas] = np.nan
    return m, ~meas, side_ok, V


def _offset_candidates(m, unmeas, side_ok, gd, offsets):
    """Per offset o, the lines behind the mean of the lines o away on both sides by more than
    ``gd`` or unmeasured, with both side lines usable: (flat index, side mean, behind by,
    offset), concatenated over the offsets (None when there are none)."""
    n_rows, Wm = m.shape
    ref_buf, beh_buf = np.empty_like(m), np.empty_like(m)
    cand_buf = np.empty(m.shape, bool)
    c_ic, c_ref, c_beh, c_o = [], [], [], []
    for o in offsets:
        o = int(o)
        if n_rows <= 4 * o:
            continue
        # lines y - 2o, y - o | y | y + o, y + 2o for y in [2o, n_rows - 2o)
        r = slice(2 * o, n_rows - 2 * o)
        c = m[r]
        up, dn = m[o:n_rows - 3 * o], m[3 * o:n_rows - o]
        nr = n_rows - 4 * o  # (in buffers allocated once per pass: the same values)
        ref = np.add(up, dn, out=ref_buf[:nr])
        ref *= np.float32(0.5)
        behind = np.subtract(c, ref, out=beh_buf[:nr])
        # the selective test first on every line, the other tests only on its few candidates
        with np.errstate(invalid="ignore"):
            cand = np.greater(behind, gd, out=cand_buf[:nr])
        cand |= unmeas[r]
        # the side lines well measured and not bent (lines without return inside a region
        # of drop-outs have no measured sides)
        cand &= side_ok[o:n_rows - 3 * o]
        cand &= side_ok[3 * o:n_rows - o]
        idx = np.flatnonzero(cand)
        if not len(idx):
            continue
        c_ic.append(idx + (2 * o) * Wm)  # flat index of the line in m
        c_ref.append(ref.reshape(-1)[idx])
        c_beh.append(behind.reshape(-1)[idx])
        c_o.append(np.full(len(idx), o, np.int64))
    if not c_ic:
        return None
    return tuple(np.concatenate(x) for x in (c_ic, c_ref, c_beh, c_o))


def _line_hits(m, unmeas, side_ok, V, gd, gdz, fx, cfg, horizontal, to_image):
    """The reveal lines among the window means ``m`` (rows across the lines): (hit, depth of
    the side lines where hit), both as ``m``. The offsets' candidates are tested together
    (element-wise the same float32 arithmetic as one offset at a time)."""
    g = np.zeros(m.shape, bool)
    zg = np.zeros(m.shape, np.float32)  # depth of the side lines where hit
    cands = _offset_candidates(m, unmeas, side_ok, gd, cfg.gap_offsets_px)
    if cands is None:
        return g, zg
    Wm = m.shape[1]
    mf = m.reshape(-1)
    ic, refv, behv, ov = cands
    # behind by more than thr (the candidates are behind by gap_depth), or unmeasured
    z2v = refv * refv
    thrv = np.maximum(gd, gdz * z2v * (V.reshape(-1)[ic] if V is not None else 1.0))
    if to_image is not None:
        # a rectified view interpolates each image pixel over s >= 1 view pixels along the
        # line: a window's mean holds 1 / s of the independent samples it has on the image,
        # its noise sqrt(s) times larger
        thrv = thrv * np.sqrt(_view_stretch(to_image, ic, Wm, _SUB, horizontal, across=False))
    unm = unmeas.reshape(-1)[ic]
    with np.errstate(invalid="ignore"):
        keep = np.flatnonzero((behv > thrv) | unm)
    ic, ov = ic[keep], ov[keep]
    refv, z2v, thrv, unm = refv[keep], z2v[keep], thrv[keep], unm[keep]
    oW = ov * Wm
    ou = ic - oW         # side lines o and 2 o away
    od = ic + oW
    upv, dnv, cv = mf[ou], mf[od], mf[ic]
    tolv = np.maximum(np.float32(0.01), np.float32(cfg.gap_side_tolerance_per_m2) * z2v)
    with np.errstate(invalid="ignore"):
        hit = np.abs(upv - dnv) < tolv  # False where either side is NaN
        # behind the sides' extrapolations too (each side's two lines extended to the line):
        # a concave crease (an opened door meeting the cabinet's face at its hinge) lies
        # behind the mean of its sides, not behind their extensions
        ext = upv + dnv - np.float32(0.5) * (mf[ou - oW] + mf[od + oW])
        hit &= (cv - ext > np.float32(0.5) * thrv) | unm
        # only near for o > 5: a 5 mm reveal's band without return is ~2 + f 0.01 / z px (in
        # a rectified view, for a line without return: its image px count s >= 1 view px
        # each, o <= 5 s or 2 s + f 0.01 / z)
        near = (ov <= 5) | (refv * (ov - 2).astype(np.float32) < np.float32(0.01 * fx))
        if to_image is not None and unm.any():
            sv = _view_stretch(to_image, ic[unm], Wm, _SUB, horizontal)
            o_u, z_u = ov[unm], refv[unm]
            near[unm] = (o_u <= 5 * sv) | (z_u * (o_u - 2 * sv) < np.float32(0.01 * fx))
        hit &= near
    ih, zh = ic[hit], refv[hit]
    g.reshape(-1)[ih] = True
    # a line hit at several offsets keeps the depth of its last one (offset by offset, in
    # order: each offset's lines are distinct)
    cut = [0, *(np.flatnonzero(np.diff(ov[hit])) + 1).tolist(), len(ih)]
    zgf = zg.reshape(-1)
    for a, b in zip(cut[:-1], cut[1:]):
        zgf[ih[a:b]] = zh[a:b]
    return g, zg


def _long_runs(g, zg, fx, cfg, min_px_floor=None):
    """The runs of hit lines ``g`` at least ``gap_min_length`` long at their depth (and at
    least ``min_px_floor`` px: one long window's scatter is not a line), or None if none."""
    # (16-bit labels when they cannot overflow: OpenCV's stats pass is ~2.5x faster;
    # 8-connected, at most one component per 2 x 2 pixels)
    ltype = (cv2.CV_16U if ((g.shape[0] + 1) // 2) * ((g.shape[1] + 1) // 2) < 65535
             else cv2.CV_32S)
    n_lab, lab, stats, cent = cv2.connectedComponentsWithStats(g.view(np.uint8),
                                                               connectivity=8, ltype=ltype)
    if n_lab <= 1:
        return None
    length = _SUB * stats[1:, cv2.CC_STAT_WIDTH].astype(np.float64)
    # depth of each run: its side lines' depth at its centroid (a run is a thin line: the
    # centroid is on it), else the mean over the run
    cr = np.clip(np.round(cent[1:, 1]).astype(np.int64), 0, lab.shape[0] - 1)
    cc = np.clip(np.round(cent[1:, 0]).astype(np.int64), 0, lab.shape[1] - 1)
    zrun = zg[cr, cc].astype(np.float64)
    off = np.flatnonzero(lab[cr, cc] != np.arange(1, n_lab))
    if len(off):  # (on the run pixels only: the same sums in the same order)
        on = np.flatnonzero(g)
        zsum = np.bincount(lab.reshape(-1)[on], weights=zg.reshape(-1)[on],
                           minlength=n_lab)[1:]
        zrun[off] = zsum[off] / np.maximum(stats[1 + off, cv2.CC_STAT_AREA], 1)
    min_px = cfg.gap_min_length * fx / np.maximum(zrun, 1e-6)
    if min_px_floor is not None:
        min_px = np.maximum(min_px, np.float64(min_px_floor))
    keep = np.concatenate([[False], length >= min_px])
    if not keep.any():
        return None
    on = np.flatnonzero(g)  # (the kept runs' pixels: on the hits only)
    g = np.zeros(g.shape, bool)
    g.reshape(-1)[on] = keep[lab.reshape(-1)[on]]
    return g


def _view_stretch(to_image, ic, Wm, sub, horizontal, across=True):
    """View pixels per image pixel across the lines (``across``; else along them; >= 1: never
    less than on the image) at
    the line pixels ``ic`` (flat indices into :func:`_gap_mask`'s line-mean array: rows across
    the lines, one column per ``sub`` pixels along them) of a rectified view whose pixels map
    to the image by the homography ``to_image``."""
    a, b = np.divmod(ic, Wm)
    b = b * sub + 0.5 * (sub - 1)
    x, y = (b, a) if horizontal else (a, b)
    Hi = to_image
    p = Hi[:, 0:1] * x + Hi[:, 1:2] * y + Hi[:, 2:3]  # (3, n)
    # across the lines: view y for rows, view x for columns; along them the other one
    k = (1 if horizontal else 0) if across else (0 if horizontal else 1)
    du = (Hi[0, k] * p[2] - p[0] * Hi[2, k]) / (p[2] * p[2])
    dv = (Hi[1, k] * p[2] - p[1] * Hi[2, k]) / (p[2] * p[2])
    return np.maximum(1.0, 1.0 / np.maximum(np.hypot(du, dv), 1e-9)).astype(np.float32)
