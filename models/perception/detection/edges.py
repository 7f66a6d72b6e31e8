"""Stage ``check``, sub-cell sides: each side of an accepted rectangle moved to where the share
of in-plane samples across it falls below 1/2, or their depth falls behind the front's, on 1 mm
lines resampled from the image (:func:`_refine_edges`)."""

import math

import cv2
import numpy as np

from mmlearn.models.perception.detection.grid import _warp_float, _warp_labels
from mmlearn.models.perception.detection.labels import FREE, GAP, IN_PLANE, OFF_SURFACE, OUTSIDE


def _first_run(mask, k, start=1):
    """First index j >= ``start`` where ``mask[j:j + k]`` is all True (positions beyond the
    end count as True), else ``len(mask)``. ``mask``: a list of bools (short profiles: a
    Python scan is cheaper than the numpy calls it replaces)."""
    n = len(mask)
    run = 0  # consecutive Trues from j on (the end counts as an endless run)
    best = n
    for j in range(n - 1, start - 1, -1):
        if mask[j]:
            run += 1
            if run >= k or j + run >= n:
                best = j
        else:
            run = 0
    return best


def _edge_crossing(prof_in, prof_out, level, pos, step, persist=1):
    """Where a side ends along a profile of lines (positions ``pos``, inside first): the first
    line whose share of in-plane samples p = in / (in + out) falls below 1/2, or whose mean
    signed distance ``level`` (of its in-plane samples, m) lies more than ``step`` behind the
    level of the innermost quarter of lines, whichever comes first (linear interpolation
    between that line and the one before). Lines without enough measured samples take p from
    their neighbours. None when the profile does not start inside or never leaves."""
    n = prof_in + prof_out
    n_l = len(n)
    if n_l < 4:
        return None
    ok = n >= max(3.0, 0.2 * float(n.max()))
    okl = np.flatnonzero(ok)
    if len(okl) < 2:
        return None
    p = np.interp(np.arange(n_l), okl, prof_in[okl] / n[okl])
    if p[0] < 0.5:
        return None
    inner = sorted(x for x in level[: max(1, n_l // 4)].tolist() if math.isfinite(x))
    if len(inner) >= 2:
        h = len(inner) // 2  # median and (population) std of a few numbers, in Python
        ref = inner[h] if len(inner) % 2 else 0.5 * (inner[h - 1] + inner[h])
        mean = sum(inner) / len(inner)
        std = math.sqrt(sum((x - mean) ** 2 for x in inner) / len(inner))
        # behind by more than `step` (or 3 x the scatter of the inner lines' levels: a short
        # side of a far front has few pixels per line), on lines that are still mostly
        # in-plane, and on `persist` lines in a row (lines closer than a pixel see the same
        # pixels)
        thr = max(step, 3.0 * std)
        with np.errstate(invalid="ignore"):
            dev = np.where((p >= 0.5) & np.isfinite(level), ref - level, 0.0) - thr
        i_dev = _first_run((dev > 0).tolist(), persist)
    else:
        dev = None
        i_dev = n_l
    last = int(okl[-1])
    # out on 2 x `persist` lines in a row (about two pixels: a one-pixel strip where a plane
    # crossing the front takes its pixels is not its side)
    i_low = _first_run((p < 0.5).tolist(), 2 * persist)
    i = min(i_low, i_dev, last + 1)
    if i >= n_l:
        return None
    if i == i_low:
        return float(pos[i - 1] + (p[i - 1] - 0.5) / (p[i - 1] - p[i]) * (pos[i] - pos[i - 1]))
    if i == i_dev:
        # the values the run test gives its lines: > 0 on a run of `persist`, < 0 otherwise
        d1 = max(float(dev[i]), 1e-12) if persist > 1 else float(dev[i])
        d0 = float(dev[i - 1])
        if persist > 1:
            d0 = max(d0, 1e-12) if _first_run((dev[i - 1:i - 1 + persist] > 0).tolist(),
                                               persist, 0) == 0 else min(d0, -1e-12)
        f = (-d0) / (d1 - d0) if d0 < 0 else 0.0
        return float(pos[i - 1] + f * (pos[i] - pos[i - 1]))
    # the measured lines end inside the front (drop-outs to the end of the strip): its side
    # is at least there
    return float(pos[last] + 0.5 * (pos[i] - pos[i - 1]))


# the edge refinement's sample classes: in (in-plane, off the surface) 1, out (free, outside
# the image, reveal) 1 << 16, unknown / occluded 0 (they say nothing)
_EDGE_CODE = np.zeros(256, np.int32)
_EDGE_CODE[[IN_PLANE, OFF_SURFACE]] = 1
_EDGE_CODE[[FREE, OUTSIDE, GAP]] = 1 << 16


class _CropIntrinsics:
    """Intrinsics of an image crop (only what :func:`_warp_labels` uses)."""

    def __init__(self, K, r0, c0):
        self.fx, self.fy, self.cx, self.cy = K.fx, K.fy, K.cx - c0, K.cy - r0


def _refine_edges(lab_img, dzero, xs, ys, n, dpl, K, o, e1, e2, a0, a1, b0, b1, cfg,
                  gap_thin=None):
    """Sub-cell position of each side of a rectangle [a0, a1] x [b0, b1] (m, plane
    coordinates along e1, e2 from ``o``; plane n . p + dpl = 0, camera frame). The label
    image and the signed distances of the measured points to the plane are resampled on a
    strip of lines parallel to the side (``edge_refine_cell`` apart, ``edge_refine_band`` on
    either side of it, over the middle ``edge_refine_span`` of its length); going outwards,
    the side ends where the share of in-plane samples among the measured ones (in-plane,
    free, outside the image, off the surface; unknown and occluded samples say nothing)
    falls below 1/2, or where the in-plane samples' mean distance falls behind the inner
    lines' by more than max(edge_refine_depth_step, edge_refine_depth_step_per_m2 z^2) (the
    19 mm top face of a panel seen from above lies within L of its front face). A side
    without such a crossing in its strip stays. ``GAP`` samples are out, except those of
    the one-pixel widening of the reveals (``gap_thin``: the reveals themselves). Returns
    (a0, a1, b0, b1)."""
    band, cf, span = cfg.edge_refine_band, cfg.edge_refine_cell, cfg.edge_refine_span
    # image crop around the rectangle grown by the band
    P = np.array([o + a * e1 + b * e2 for a in (a0 - band, a1 + band)
                  for b in (b0 - band, b1 + band)])
    if np.any(P[:, 2] <= 0.05):
        return a0, a1, b0, b1
    u = K.fx * P[:, 0] / P[:, 2] + K.cx
    v = K.fy * P[:, 1] / P[:, 2] + K.cy
    H, W = lab_img.shape
    c0, c1 = max(0, int(np.floor(u.min())) - 1), min(W, int(np.ceil(u.max())) + 2)
    r0, r1 = max(0, int(np.floor(v.min())) - 1), min(H, int(np.ceil(v.max())) + 2)
    if c1 - c0 < 2 or r1 - r0 < 2:
        return a0, a1, b0, b1
    lab_c = lab_img[r0:r1, c0:c1]
    if gap_thin is not None:
        # the reveal itself is out; the pixel beside it that the GAP label's widening took
        # (for the rectified grids) is the front's
        ring = (lab_c == GAP) & ~gap_thin[r0:r1, c0:c1]
        if ring.any():
            lab_c = np.where(ring, np.uint8(IN_PLANE), lab_c)
    nr = (np.float32(n[0]) * xs[:, c0:c1] + np.float32(n[2])) + np.float32(n[1]) * ys[r0:r1, :]
    S = np.multiply(dzero[r0:r1, c0:c1], nr, out=nr)  # (in place: the same float32 values)
    S += np.float32(dpl)
    # the plane's surface samples only: the others 0 (they count in neither the sums nor
    # the numbers of samples, ``n_in`` below, which count exactly the surface samples)
    S[cv2.LUT(lab_c, _EDGE_CODE) != 1] = 0.0
    Kc = _CropIntrinsics(K, r0, c0)
    zc = float((o + 0.5 * (a0 + a1) * e1 + 0.5 * (b0 + b1) * e2)[2])
    step = max(cfg.edge_refine_depth_step, cfg.edge_refine_depth_step_per_m2 * zc * zc)
    persist = max(1, int(round(zc / K.fx / cf)))  # lines per pixel at the rectangle's depth
    out = [a0, a1, b0, b1]
    for side in range(4):
        along_a = side >= 2  # a horizontal side (b = const) runs along e1
        # the strip reaches at most a third of the way across the rectangle
        band = min(cfg.edge_refine_band, ((b1 - b0) if along_a else (a1 - a0)) / 3.0)
        nl = max(4, int(round(2 * band / cf)))
        lo, hi = (a0, a1) if along_a else (b0, b1)
        m = 0.5 * (1.0 - span) * (hi - lo)
        length = (hi - lo) - 2 * m
        ns = max(8, min(200, int(round(length / cf))))
        cs = length / ns
        e = (a0, a1, b0, b1)[side]
        outwards = side in (1, 3)  # a1, b1: outwards is +e1 / +e2
        start = e - band if outwards else e + band - nl * cf  # lowest line coordinate
        if along_a:  # lines are rows (along e1), the profile runs down the rows
            args = (Kc, o, e1, e2, lo + m, start, cs, (nl, ns), cf)
            axis = 1
        else:        # lines are columns (along e2), the profile runs along the columns
            args = (Kc, o, e1, e2, start, lo + m, cf, (ns, nl), cs)
            axis = 0
        lab = _warp_labels(lab_c, *args)
        # the same pixels as ``lab`` (the same homography). Cells within 5 cm of the camera
        # plane, which _warp_labels marks OUTSIDE, do not occur: the strip lies inside the
        # rectangle grown by the band (to half a 1 mm line), whose corners are > 5 cm in front
        dist = _warp_float(S, *args, outside=0.0)
        # in (1) and out (1 << 16) samples counted together (a line has < 2^16 samples)
        code = cv2.LUT(lab, _EDGE_CODE).sum(axis=axis)
        n_in = (code & 0xFFFF).astype(np.float64)
        n_out = code >> 16
        with np.errstate(all="ignore"):
            # mean of the in-plane samples' distances (the surface samples are the in-plane
            # ones, n_in of them; the others are 0 in ``dist``), NaN where none
            level = dist.sum(axis=axis, dtype=np.float64) / n_in
        pos = start + (np.arange(nl) + 0.5) * cf  # line coordinates, increasing
        if not outwards:  # inside first
            n_in, n_out, level, pos = n_in[::-1], n_out[::-1], level[::-1], pos[::-1]
        x = _edge_crossing(n_in, n_out.astype(np.float64), level, pos, step, persist)
        if x is not None:
            out[side] = x
    return tuple(out)
