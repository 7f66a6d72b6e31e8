"""Stage ``masks``, offset layers: a front standing a few mm to a few cm proud of a larger
parallel plane (a drawer pulled out by its first centimetres) gets a plane of its own
(:func:`_offset_layers`); the layer and its parent share pixels by the nearer-plane rule."""

import math

import cv2
import numba
import numpy as np

from mmlearn.models.perception.detection.grid import _median
from mmlearn.models.perception.detection.labels import GAP, IN_PLANE, OCCLUDED, OFF_SURFACE, UNKNOWN
from mmlearn.models.perception.detection.planes import _fit_plane_many, Plane


_SQUARE5 = np.ones((5, 5), np.uint8)


_LAYER_MAX_RING = 0.35


def _offset_layers(planes, labels, S, Pc, Lmap, Lband, K, cfg, st, off):
    """Planes for the *offset layers* of the ``cfg.layer_planes`` largest planes: connected
    regions of a plane's region that lie a few mm to a few cm in front of it, parallel to it.
    Returns the new planes (``parent`` = the plane they were split from; none when nothing
    qualifies).

    Why: a drawer pulled out by its first 5-40 mm stands that far proud of its cabinet's
    face, within L (2 cm; the removal band: 3.3 cm at 1.8 m, 4.1 cm at 2.3 m) of the face's
    plane. RANSAC counted its points to the face and took them out of the pool, so it got no
    plane of its own; on the face's plane the surface check (window means beyond the
    surface distance) or Eq. 5.2 (beyond L) labelled it OFF_SURFACE / OCCLUDED, and the
    drawer was missed in its first 2-4 opening frames at every distance (seeds 6000-6009:
    0.005 / 0.016 / 0.027 m missed in all runs at 1.8 m). Here those pixels (in
    front of the plane within the removal band ``Lband``, OFF_SURFACE or OCCLUDED) form
    candidate regions on the plane's region; a region spanning at least ``layer_min_size`` in
    both directions (a panel's edge face seen obliquely is a strip), of at least
    ``layer_min_pixels`` pixels, whose plane (started parallel to the parent, refitted three
    times on the pixels within L / 2 of it, at least 40 % of them) stays within 10 deg of
    the parent's normal, whose centroid lies in front of the parent by more than the surface
    distance, that is no other plane's front already and is a step rather than a ramp,
    becomes a plane. The pair then shares its pixels by the nearer-plane rule
    (:func:`_crossings`), so the face does not reach into the drawer's rectangle nor the
    drawer into the face's."""
    new: list[Plane] = []
    if cfg.layer_planes <= 0 or cfg.layer_max_layers <= 0 or not planes:
        return new
    H, W = labels[0].shape
    order = sorted(range(len(planes)), key=lambda i: -planes[i].support)
    for k in order[:int(cfg.layer_planes)]:
        if planes[k].parent >= 0:
            continue
        found = _candidate_regions(planes[k], labels[k], S[k], Pc, Lband, K, cfg, st, off)
        if found is None:
            continue
        cand, R0, C0 = found
        ncomp, cl, stats, _ = cv2.connectedComponentsWithStats(cand, connectivity=8)
        big = [i for i in range(1, ncomp) if stats[i, cv2.CC_STAT_AREA] >= cfg.layer_min_pixels]
        big.sort(key=lambda i: -stats[i, cv2.CC_STAT_AREA])
        for i in big:
            x, y, w, h = (int(v) for v in stats[i, :4])
            sub = cl[y:y + h, x:x + w] == i
            box = (R0 + y, R0 + y + h, C0 + x, C0 + x + w)
            layer = _layer_plane(k, planes, labels, new, box, sub, Pc, Lmap, K, cfg, st, off)
            if layer is not None:
                new.append(layer)
                if len(new) >= cfg.layer_max_layers:
                    return new
    return new


def _candidate_regions(pl, lab_full, S_full, Pc, Lband, K, cfg, st, off):
    """The candidate pixels of a plane's offset layers on its region's crop: in front of it
    within the removal band, ``OFF_SURFACE`` or ``OCCLUDED``, closed over noise holes (not
    across reveals or unmeasured pixels) and opened by 2/3 ``layer_min_size``; (uint8 mask on
    its bounding box, row and column of the box) or None when too few."""
    H, W = lab_full.shape
    r0, r1, c0, c1 = pl.bbox
    R0, R1 = max(0, off + st * r0 - st), min(H, off + st * r1 + st)
    C0, C1 = max(0, off + st * c0 - st), min(W, off + st * c1 + st)
    if R1 - R0 < 3 or C1 - C0 < 3:
        return None
    # only in front of the plane (s > 0, towards the camera): a front pulled out of its
    # carcass stands proud of the face. (Behind it were a cabinet's bottom rail 1-2 cm behind
    # its door and the far part of a plane fitted across both: the layer split the door, and
    # the robot took its handle 7 cm off.)
    cand = np.empty((R1 - R0, C1 - C0), np.uint8)
    if _band_candidates(S_full, Lband, lab_full, R0, C0, cand) < cfg.layer_min_pixels:
        return None
    # opened by a square of 2/3 layer_min_size at the region's median depth (of the crop's
    # sampled pixels: a plane's own depth on a ray can be anything for a plane seen
    # edge-on): thin strips joined the drawer to its neighbours (the countertop's edge, 3 cm
    # tall and 2 cm proud of the fronts like the drawer, above it; the drawer's top face seen
    # from above), and their least-squares plane was tilted 4-6 deg
    zs = Pc[R0 + off:R1:st, C0 + off:C1:st, 2].reshape(-1)
    zs = zs[np.isfinite(zs)]
    if len(zs) == 0:
        return None
    zc = max(float(_median(zs)), 0.1)
    # (an odd side: OpenCV dilates with the kernel unreflected, so an even square's opening
    # is shifted by a pixel and not a subset)
    ko = min(max(1, int(round(1.0 / 3.0 * cfg.layer_min_size * K.fx / zc))), 50) * 2 + 1
    # closed first (5 x 5): the pixels whose noise carries them out of the band are single
    # holes, and one hole in the opening's square takes its centre away
    cand = cv2.morphologyEx(cand, cv2.MORPH_CLOSE, _SQUARE5)
    # (but not across a reveal or a pixel without a measurement)
    _drop_unknown_gap(lab_full, R0, C0, cand)
    cand = cv2.morphologyEx(cand, cv2.MORPH_OPEN, np.ones((ko, ko), np.uint8))
    if cv2.countNonZero(cand) < cfg.layer_min_pixels:
        return None
    # (the components on the candidates' bounding box only)
    bx, by, bw, bh = cv2.boundingRect(cand)
    return cand[by:by + bh, bx:bx + bw], R0 + by, C0 + bx


@numba.njit(cache=True, nogil=True)
def _band_candidates(S, Lband, lab, R0, C0, cand):
    """``cand`` (uint8, 255 / 0, the crop of its shape at (``R0``, ``C0``) of the images) =
    0 < ``S`` <= ``Lband`` (float32 compares: NaN fails) and ``lab`` OCCLUDED or
    OFF_SURFACE, as OpenCV's compares and their bitwise and; returns the candidates'
    number."""
    h, w = cand.shape
    zero = np.float32(0.0)
    occ, off = np.uint8(OCCLUDED), np.uint8(OFF_SURFACE)
    n = 0
    for r in range(h):
        Sr, Lr = S[R0 + r, C0:C0 + w], Lband[R0 + r, C0:C0 + w]
        lr, cr = lab[R0 + r, C0:C0 + w], cand[r]
        # (0 - 1 = 255 in bytes, no selects: vector operations)
        for c in range(w):
            s, v = Sr[c], lr[c]
            ok = (s <= Lr[c]) & (s > zero) & ((v == occ) | (v == off))
            cr[c] = np.uint8(0) - np.uint8(ok)
        for c in range(w):
            n += cr[c] & np.uint8(1)
    return n


@numba.njit(cache=True, nogil=True)
def _drop_unknown_gap(lab, R0, C0, cand):
    """In place: ``cand`` (uint8) set to 0 where the image ``lab``'s crop of its shape at
    (``R0``, ``C0``) is UNKNOWN or GAP (as OpenCV's ``cand &= compare(lab, UNKNOWN,
    CMP_NE)`` and the same for GAP)."""
    h, w = cand.shape
    unk, gap = np.uint8(UNKNOWN), np.uint8(GAP)
    for r in range(h):
        lr, cr = lab[R0 + r, C0:C0 + w], cand[r]
        for c in range(w):
            v = lr[c]
            keep = np.uint8((v != unk) & (v != gap))
            cr[c] = cr[c] & (np.uint8(0) - keep)  # (and with 255 or 0: vector operations)


def _fit_parallel_start(pl, P, Lp):
    """The layer's plane: started parallel to the parent ``pl`` at the region's median offset
    (robust to the other surfaces in the region: the top faces of the drawer and the
    countertop seen from above tilted a plain least-squares fit by 4-7 deg), then three
    least-squares rounds on the pixels within L / 2 (a door turned by a few degrees tilts
    it: 5.2 deg at 2.3 m came out 3.2 deg after two rounds). (n, d, the last round's points)
    or None when fewer than 40 % of the points are within L / 2 or it turns beyond 10 deg."""
    cos10 = math.cos(math.radians(10.0))
    n, d = pl.n, pl.d - float(_median(P @ pl.n + pl.d))
    for _ in range(3):
        sel = np.abs(P @ n + d) <= 0.5 * Lp
        if np.count_nonzero(sel) < 0.4 * len(P):
            return None
        n, d = _fit_plane_many(np.compress(sel, P, axis=0))
        if n @ pl.n < cos10:
            return None
    return n, d, np.compress(sel, P, axis=0)


def _layer_plane(k, planes, labels, new, box, sub, Pc, Lmap, K, cfg, st, off):
    """The offset layer of plane ``k`` on one candidate region (image rows and columns
    ``box``, its pixels ``sub`` in the box), or None when the region is too small, not in
    front of the plane, another plane's front already, a copy of a layer in ``new`` or a
    ramp rather than a step."""
    pl = planes[k]
    H, W = labels[0].shape
    y0, y1, x0, x1 = box
    h, w = y1 - y0, x1 - x0
    P = Pc[y0:y1, x0:x1][sub].astype(np.float64)
    Lp = Lmap[y0:y1, x0:x1][sub].astype(np.float64)
    if len(P) < 3:
        return None
    z = float(_median(P[:, 2]))
    if min(w * z / K.fx, h * z / K.fy) < cfg.layer_min_size:
        return None
    fit = _fit_parallel_start(pl, P, Lp)
    if fit is None:
        return None
    n, d, Psel = fit
    cen = np.ones(len(Psel)) @ Psel / len(Psel)
    thr = max(cfg.surface_distance, cfg.surface_distance_per_m2 * z * z)
    if cen @ pl.n + pl.d < thr:
        return None
    # a front that has a plane already (most of the region's pixels in-plane for another
    # plane after the surface check, e.g. a door RANSAC found): nothing new. (A plane RANSAC
    # drew from the remnant of a front that the removal band thinned out is tilted by a few
    # degrees and leaves the front OFF_SURFACE: the layer is kept beside it; the drawer
    # pulled out 4 cm at 2.2 m.)
    win = (slice(y0, y1), slice(x0, x1))
    if any(q != k and 2 * np.count_nonzero(labels[q][win][sub] == IN_PLANE) >= len(P)
           for q in range(len(planes))):
        return None
    cos1 = math.cos(math.radians(1.0))
    if any(abs(q.n @ n) > cos1 and abs(q.n @ cen + q.d) < thr for q in new):
        return None
    # the layer's region (its only in-plane pixels): its box grown by half its size on every
    # side (room for the sides the opening trimmed, a door's hinge side nearer the face than
    # the threshold, and the recall's margin)
    gy, gx = (h + 1) // 2, (w + 1) // 2
    region = (max(0, y0 - gy), min(H, y1 + gy), max(0, x0 - gx), min(W, x1 + gx))
    if _is_ramp(labels[k], region, box, sub, Pc, n, d, thr):
        return None
    rows = (np.array([y0, y1 - 1]) - off) / st
    cols = (np.array([x0, x1 - 1]) - off) / st
    return Plane(n=n, d=d, support=max(1, len(Psel) // (st * st)),
                 bbox=(max(0, int(math.floor(rows[0]))), int(math.ceil(rows[1])) + 1,
                       max(0, int(math.floor(cols[0]))), int(math.ceil(cols[1])) + 1),
                 parent=k, region=region)


def _is_ramp(lab_parent, region, box, sub, Pc, n, d, thr):
    """Whether the parent's own pixels around the candidate (in ``region``, outside its
    pixels ``sub`` in ``box``) lie on the layer's plane: more than ``_LAYER_MAX_RING`` of them
    within ``thr``. Measured on development frames: 0-0.25 for drawers pulled out 1.6-4 cm and
    doors turned 5 deg, whose hinge side meets the face; 0.45-0.95 for ramps and for a door
    turned 85 deg against its compartment's wall. Where the parent is a plane fitted across a
    door and the rail 1-2 cm behind it, the door's lower part lies 5-13 mm in front of it and
    fits a "layer" that is the door's own plane, which the door's upper part, in-plane for the
    parent, continues: the pair then split the door in two."""
    r0_, r1_, c0_, c1_ = region
    y0, y1, x0, x1 = box
    ring = lab_parent[r0_:r1_, c0_:c1_] == IN_PLANE
    ring[y0 - r0_:y1 - r0_, x0 - c0_:x1 - c0_] &= ~sub
    Q = Pc[r0_:r1_, c0_:c1_][ring]
    return bool(len(Q) and np.count_nonzero(np.abs(Q @ n + d) <= thr) > _LAYER_MAX_RING * len(Q))
