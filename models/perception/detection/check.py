"""Stage ``check``: precision (Eq. 5.4) and local recall (Eq. 5.5) of a grid rectangle, sides
along reveals, the image border, duplicate suppression and the least-squares plane refit of an
accepted rectangle."""

import math

import numba
import numpy as np

from mmlearn.models.perception.detection.grid import _Grid
from mmlearn.models.perception.detection.labels import IN_PLANE
from mmlearn.models.perception.detection.planes import _add_outer3, _mirror_upper3, _plane_from_scatter


def _gap_bounded(g, x0, x1, y0, y1, out_cells=3, in_cells=1, share=0.5, line=0.7):
    """(left, right, top, bottom): whether each side of the rectangle on grid ``g``
    (:class:`_Grid`) runs along a
    reveal: some grid line parallel to it, from ``in_cells`` inside to ``out_cells`` outside,
    is ``GAP`` on at least ``share`` of the side's length, or ``GAP`` on a fifth and ``GAP``
    or ``UNKNOWN`` on ``line`` of it (a reveal seen straight on has no return; the window of
    :func:`_gap_mask` does not label its last few cm before a step such as a countertop's
    edge)."""
    Hg, Wg = g.shape
    G, U = g.gap_sats()
    x0, x1, y0, y1 = int(x0), int(x1), int(y0), int(y1)
    res = []
    for lo, hi, vertical in ((x0 - out_cells, x0 + in_cells, True),
                             (x1 - in_cells, x1 + out_cells, True),
                             (y0 - out_cells, y0 + in_cells, False),
                             (y1 - in_cells, y1 + out_cells, False)):
        if vertical:
            lo, hi = max(0, lo), min(Wg, hi)
            a0, a1, length = y0, y1, y1 - y0
        else:
            lo, hi = max(0, lo), min(Hg, hi)
            a0, a1, length = x0, x1, x1 - x0
        if hi <= lo or length <= 0:
            res.append(False)
            continue
        # no GAP cell in the whole strip: not a reveal (one look-up for most sides)
        if vertical:
            tot = int(G[a1, hi] - G[a0, hi] - G[a1, lo] + G[a0, lo])
        else:
            tot = int(G[hi, a1] - G[lo, a1] - G[hi, a0] + G[lo, a0])
        if tot < 0.2 * length:
            res.append(False)
            continue
        hit = False
        for c in range(lo, hi):  # each grid line of the strip
            if vertical:
                g = int(G[a1, c + 1] - G[a0, c + 1] - G[a1, c] + G[a0, c])
                u = int(U[a1, c + 1] - U[a0, c + 1] - U[a1, c] + U[a0, c])
            else:
                g = int(G[c + 1, a1] - G[c, a1] - G[c + 1, a0] + G[c, a0])
                u = int(U[c + 1, a1] - U[c, a1] - U[c + 1, a0] + U[c, a0])
            if g >= share * length or (g >= 0.2 * length and g + u >= line * length):
                hit = True
                break
        res.append(hit)
    return res


def _precision_recall(g: _Grid, R, cfg):
    """Eq. 5.4 and the local recall of one grid rectangle: its in-plane area over that of the
    rectangle grown by ``recall_margin`` (no margin beyond a side along a reveal)."""
    x0, x1, y0, y1 = (int(v) for v in R)
    n = (x1 - x0) * (y1 - y0)
    if n <= 0:
        return 0.0, 0.0
    S = g.sat_cost
    cost = (S[y1, x1] - S[y0, x1] - S[y1, x0] + S[y0, x0]) / 255.0
    precision = (n - cost) / n
    I = g.sat_in
    inside = I[y1, x1] - I[y0, x1] - I[y1, x0] + I[y0, x0]
    mx = max(int(round(cfg.recall_margin * (x1 - x0))), int(round(cfg.min_recall_margin / g.c)))
    my = max(int(round(cfg.recall_margin * (y1 - y0))), int(round(cfg.min_recall_margin / g.c)))
    Hg, Wg = g.shape
    # a side along a reveal (GAP) is observed to end there: no margin beyond it (the plane
    # continues in the flush neighbouring front)
    ml, mr, mt, mb = (0 if b else m for b, m in zip(
        _gap_bounded(g, x0, x1, y0, y1), (mx, mx, my, my)))
    X0, X1 = max(0, x0 - ml), min(Wg, x1 + mr)
    Y0, Y1 = max(0, y0 - mt), min(Hg, y1 + mb)
    around = I[Y1, X1] - I[Y0, X1] - I[Y1, X0] + I[Y0, X0]
    recall = inside / around if around > 0 else 0.0
    return float(precision), float(recall)


def _corners_px(center, e1, e2, w, h, K):
    # the four corners center + sx w / 2 e1 + sy h / 2 e2 at once (the same products and
    # sums, in the same order, as corner by corner)
    a = np.array([sx * 0.5 * w for sx in (-1, 1, 1, -1)])[:, None]
    b = np.array([sy * 0.5 * h for sy in (-1, -1, 1, 1)])[:, None]
    corners = (center + a * e1) + b * e2
    z = corners[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = K.fx * corners[:, 0] / z + K.cx
        v = K.fy * corners[:, 1] / z + K.cy
    return u, v, z


def _inside_border(center, e1, e2, w, h, K, margin):
    """Whether the four corners (as :func:`_corners_px`) are in front of the camera and at
    least ``margin`` px inside the image: the same float operations on Python floats (a few
    us instead of ~20 us of small-array calls; ~50 calls per frame)."""
    c, a1, a2 = center.tolist(), e1.tolist(), e2.tolist()
    inside = True
    for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
        a, b = sx * 0.5 * w, sy * 0.5 * h
        x, y, z = ((c[i] + a * a1[i]) + b * a2[i] for i in range(3))
        if not z > 0:
            return False
        u = K.fx * x / z + K.cx
        v = K.fy * y / z + K.cy
        inside &= (margin <= u <= K.width - 1 - margin) and (margin <= v <= K.height - 1 - margin)
    return bool(inside)


def _refit_plane(Pc, lab_img, center, e1, e2, w, h, K, n_old, L):
    """Least-squares plane through the measured in-plane pixels inside the rectangle (shrunk
    by 10 %), searched in the rectangle's image bounding box. None when too few."""
    u, v, _ = _corners_px(center, e1, e2, w, h, K)
    c0, c1 = int(max(0, np.floor(u.min()))), int(min(K.width, np.ceil(u.max()) + 1))
    r0, r1 = int(max(0, np.floor(v.min()))), int(min(K.height, np.ceil(v.max()) + 1))
    if c1 <= c0 or r1 <= r0:
        return None
    # the in-plane pixels' offsets q to the centre inside the shrunk rectangle: their number,
    # sum and sum of q q^T in one compiled pass over the box (nothing gathered)
    sq, sqq = np.empty(3), np.empty((3, 3))
    k = _rect_sums(Pc, lab_img, r0, r1, c0, c1, np.asarray(center, np.float64),
                   np.asarray(e1, np.float64), np.asarray(e2, np.float64), 0.45 * w, 0.45 * h,
                   sq, sqq)
    if k < 10:
        return None
    # the scatter matrix from the offsets to the centre (small: no cancellation to speak of)
    # minus k times their mean's outer product
    mq = sq * (1.0 / k)
    n, d = _plane_from_scatter(center + mq, sqq - k * np.outer(mq, mq))
    if n @ n_old < math.cos(math.radians(10.0)):
        return None
    return n, d


@numba.njit(cache=True, nogil=True)
def _rect_sums(Pc, lab, r0, r1, c0, c1, center, e1, e2, hw, hh, sq, sqq):
    """Over the IN_PLANE pixels of rows r0:r1, columns c0:c1 whose point's offset q to
    ``center`` lies within ``hw`` along ``e1`` and ``hh`` along ``e2``: ``sq`` = sum of q,
    ``sqq`` = sum of q q^T (float64); returns their number."""
    k = 0
    sq[:] = 0.0
    sqq[:] = 0.0
    for r in range(r0, r1):
        for c in range(c0, c1):
            if lab[r, c] != IN_PLANE:
                continue
            q0 = np.float64(Pc[r, c, 0]) - center[0]
            q1 = np.float64(Pc[r, c, 1]) - center[1]
            q2 = np.float64(Pc[r, c, 2]) - center[2]
            if (abs(e1[0] * q0 + e1[1] * q1 + e1[2] * q2) <= hw
                    and abs(e2[0] * q0 + e2[1] * q1 + e2[2] * q2) <= hh):
                k += 1
                sq[0] += q0
                sq[1] += q1
                sq[2] += q2
                _add_outer3(sqq, q0, q1, q2)
    _mirror_upper3(sqq)
    return k


def _suppress(cands, normal_of, cfg):
    """Keep the best of candidates (score first, centre third element) whose centres are within
    ``duplicate_distance`` and normals within ``duplicate_angle_deg``."""
    cands = sorted(cands, key=lambda c: -c[0])
    cos_max = math.cos(math.radians(cfg.duplicate_angle_deg))
    kept = []
    for c in cands:
        dup = False
        for k in kept:
            if (np.linalg.norm(c[2] - k[2]) < cfg.duplicate_distance
                    and abs(normal_of(c) @ normal_of(k)) > cos_max):
                dup = True
                break
        if not dup:
            kept.append(c)
    return kept
