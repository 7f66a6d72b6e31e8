"""Stage ``masks``, labels: one Eq. 5.2 label image per plane.

In-plane ``|s| <= L``, occluded ``s > L``, free ``s < -L``, unknown without a measurement (``s``
the signed distance, normal towards the camera). Where two crossing planes (or an offset layer
and its parent) are both within L of a pixel, only the nearer one keeps it
(:func:`_crossings`); the surface check marks in-plane pixels whose neighbourhood lies off the
plane's surface ``OFF_SURFACE`` (:func:`_surface_check`); the reveals are ``GAP``. Planes tilted
by a neighbour crossing them at a shallow angle are refitted on their own pixels
(:func:`_refit_on_own_pixels`)."""

import math

import cv2
import numba
import numpy as np

from mmlearn.models.perception.detection.boxsum import BOX, pair_window_sums, surface_marks
from mmlearn.models.perception.detection.planes import _fit_plane_many, Plane
from mmlearn.models.perception.detection.scratch import scratch


# mask labels (Eq. 5.2), plus cells of the rectified grid that the camera does not see
IN_PLANE, FREE, OCCLUDED, UNKNOWN, OUTSIDE = 0, 1, 2, 3, 4


# a measured pixel within L of the plane that the surface check found off its surface (a
# panel's edge face seen obliquely): costs like UNKNOWN, but is not the plane's surface for the
# edge refinement
OFF_SURFACE = 5


# a pixel on a thin line that lies behind the measured surface on both sides of it, or has no
# return between measured lines on both sides (the reveal between two flush fronts): costs
# like FREE, and a rectangle's side along such a line is observed to end there (recall)
GAP = 6


@numba.njit(cache=True, nogil=True)
def _plane_label_kernel(ax, by, d, valid, L, dpl, S, lab):
    """One plane's signed distances ``S`` = (ax + by) d + dpl (float32, the operations of
    the array expression in its order; ``ax`` = n0 x + n2, (1 or H, W), ``by`` = n1 y,
    (H, 1 or W)) and Eq. 5.2 labels ``lab``: FREE where s < -L, OCCLUDED where s > L,
    UNKNOWN where not ``valid`` (else IN_PLANE)."""
    H, W = S.shape
    for r in range(H):
        axr = ax[r if ax.shape[0] > 1 else 0]
        dr, vr, Lr, Sr, lr = d[r], valid[r], L[r], S[r], lab[r]
        if by.shape[1] > 1:
            byr = by[r]
            for c in range(W):
                _label_pixel(axr[c] + byr[c], dr[c], dpl, Lr[c], vr[c], Sr, lr, c)
        else:  # (one value per row: rows of selects that the compiler makes vector operations)
            b0 = by[r, 0]
            for c in range(W):
                _label_pixel(axr[c] + b0, dr[c], dpl, Lr[c], vr[c], Sr, lr, c)


@numba.njit(cache=True, nogil=True)
def _label_pixel(nray, dv, dpl, Lv, ok, Sr, lr, c):
    """:func:`_plane_label_kernel` at one pixel: ``Sr[c]`` = n . ray d + dpl and its label
    (selects, no jumps)."""
    s = nray * dv
    s = s + dpl
    Sr[c] = s
    v = np.uint8(FREE) if s < -Lv else (np.uint8(OCCLUDED) if s > Lv else np.uint8(0))
    lr[c] = v if ok else np.uint8(UNKNOWN)


def _broadcast_rows(a, shape):
    """``a`` (float32, contiguous) broadcast to (1 or shape[0], shape[1])."""
    a = np.atleast_2d(np.asarray(a, np.float32))
    return np.ascontiguousarray(np.broadcast_to(a, (a.shape[0] if a.shape[0] == 1 else shape[0],
                                                    shape[1])))


def _label_images(d, valid, ray_x, ray_y, planes, L, crossing_angle_deg,
                  smooth_px=5, surface=None, gap=None, keep_distances=False, previous=None,
                  slot=None):
    """Eq. 5.2 labels of every pixel for every plane n . p + dpl = 0. The signed distance of
    the pixel's point p = depth * (ray_x, ray_y, 1) is depth * (n . ray) + dpl (separable in
    rows and columns). A pixel within L of two planes that cross at more than
    ``crossing_angle_deg`` and nearer to the one with the larger support is free for the
    other: in that strip the surface seen is the larger plane's (e.g. the cabinet's face next
    to the hinge of an open door, which would otherwise widen the door by L / sin(angle)).
    An offset layer and the plane it was split from (``Plane.parent``, :func:`_offset_layers`)
    share their pixels the same way, whatever their angle; a pixel the other plane keeps is
    OCCLUDED for a plane it lies in front of and FREE for one it lies behind.
    Otherwise pixels belong to every plane they are within L of (5.1.1).
    Returns the label images (a list, one uint8 image per plane), and with
    ``keep_distances`` also the (planes, H, W) float32 signed distances.

    ``previous``: (planes, label images) of an earlier call on the same image with the same
    other arguments, whose planes this call's list holds unchanged (the same objects) where
    it was not refitted, followed by new ones (offset layers): the images of the planes
    that neither changed nor cross a changed or new plane (before or now) are the same, and
    are taken from it (:func:`_unchanged_planes`); the crossings are then decided only for
    the pairs with another plane, and the surface check and the reveals applied only to the
    others' images.

    ``slot``: None (fresh arrays), or a name under which the distances and label images are
    this thread's scratch arrays (:func:`scratch`: kept from frame to frame; they are
    overwritten by the next call with the same ``slot`` in the thread)."""
    P = len(planes)
    if slot is None:
        S = np.empty((P,) + d.shape, np.float32)
        stack = np.empty((P,) + d.shape, np.uint8)  # (the images side by side: _crossings)
    else:
        S = scratch(f"distances{slot}", (P,) + d.shape, np.float32)
        stack = scratch(f"labels{slot}", (P,) + d.shape, np.uint8)
    L = np.broadcast_to(np.asarray(L, np.float32), d.shape).copy() if np.ndim(L) == 0 else L
    L32 = np.ascontiguousarray(L, np.float32)
    d32 = np.ascontiguousarray(d, np.float32)
    valid = np.ascontiguousarray(valid, bool)
    ray_x, ray_y = np.asarray(ray_x, np.float32), np.asarray(ray_y, np.float32)
    labs = []
    for k, pl in enumerate(planes):
        n = pl.n
        lab = stack[k]
        # n . ray, times the depth, plus the offset (S[k]), and its label, in one pass
        ax = _broadcast_rows(np.float32(n[0]) * ray_x + np.float32(n[2]), d.shape)
        by = _broadcast_rows((np.float32(n[1]) * ray_y).T, d.shape[::-1]).T
        _plane_label_kernel(ax, by, d32, valid, L32, np.float32(pl.d), S[k], lab)
        if pl.parent >= 0 and pl.region is not None:
            # an offset layer is its region's surface only: elsewhere its infinite plane,
            # a degree off its parent's, runs through the parent's fronts
            r0, r1, c0, c1 = pl.region
            keep = lab[r0:r1, c0:c1].copy()
            lab[lab == IN_PLANE] = FREE
            lab[r0:r1, c0:c1] = keep
        labs.append(lab)
    same = (np.zeros(P, bool) if previous is None
            else _unchanged_planes(previous[0], planes, crossing_angle_deg))
    _crossings(labs, S, planes, valid, crossing_angle_deg, smooth_px, need=~same, stack=stack)
    for k in np.flatnonzero(same):
        labs[k] = previous[1][k]
    if surface is not None:  # after the crossings: their strips would bias the means
        for k in np.flatnonzero(~same):
            _surface_check(labs[k], S[k], *surface)
    if gap is not None:  # reveals (_gap_mask): GAP unless something is in front
        gi = np.flatnonzero(gap.reshape(-1))
        if len(gi):
            for k in np.flatnonzero(~same):
                flat = labs[k].reshape(-1)
                sub = flat[gi]
                flat[gi] = np.where(sub == OCCLUDED, sub, np.uint8(GAP))
    return (labs, S) if keep_distances else labs


_CROSSING_MIN_SHARE = 0.1


def _crossing_pairs(planes, crossing_angle_deg):
    """:func:`_crossings`' pairs: (crossing, layer), bool (planes, planes); ``crossing[k,
    j]``: plane j may take pixels from plane k (layer pairs included), ``layer``: an offset
    layer and its parent."""
    P = len(planes)
    N = np.array([pl.n for pl in planes])
    sup = np.array([pl.support for pl in planes])
    # [k, j]: j may take pixels from k. Planes crossing at less than 30 deg share a wide strip
    # (L / sin(angle)): there each keeps the pixels nearer to it (letting only the plane of
    # larger support take them widened a door opened 11-16 deg and seen from 0.8 m, larger in
    # the image than the neighbouring front, by the 2-4 cm strip of that front within L of
    # the door's plane next to the hinge, measured). At steeper crossings only the plane of
    # larger support takes them: the strip is narrow, and a plane whose surface is elsewhere
    # cut a one-pixel line through a far drawer, which was then lost (measured).
    cosang = np.abs(N @ N.T)
    crossing = ((cosang < math.cos(math.radians(crossing_angle_deg)))
                & ((cosang > math.cos(math.radians(30.0))) | (sup[None, :] >= sup[:, None])))
    # a plane with under _CROSSING_MIN_SHARE of the other's support takes no pixels from it
    # (a spurious small plane of a few dozen samples tilted ~12 deg through a cabinet's face
    # cut a FREE line through a closed drawer at 2.2 m, which the greedy moves then did not
    # cross)
    crossing &= sup[None, :] >= _CROSSING_MIN_SHARE * sup[:, None]
    # an offset layer and its parent plane: each keeps the pixels nearer to it, whatever
    # their angle and supports (a drawer pulled out 16 mm is parallel to the cabinet's face,
    # within L of it, and has a twentieth of its support)
    layer = np.zeros((P, P), bool)
    for j, pl in enumerate(planes):
        if 0 <= pl.parent < P:
            layer[pl.parent, j] = layer[j, pl.parent] = True
    crossing |= layer
    return crossing, layer


def _unchanged_planes(old, planes, crossing_angle_deg):
    """Per plane of ``planes``, whether its label image equals the one it had among ``old``
    (:func:`_label_images`' ``previous``): the same plane object at the same index, crossing
    (:func:`_crossing_pairs`, either way) no plane that changed or is new, neither among
    ``old`` nor among ``planes``."""
    P, P0 = len(planes), len(old)
    changed = np.array([k >= P0 or planes[k] is not old[k] for k in range(P)])
    same = ~changed
    if not changed.any() or not same.any():
        return same
    for pls, ch in ((old, changed[:P0]), (planes, changed)):
        c, _ = _crossing_pairs(pls, crossing_angle_deg)
        pair = c | c.T
        n = len(pls)
        same[:n] &= ~pair[:, ch].any(axis=1)
    return same


def _crossings(labs, S, planes, valid, crossing_angle_deg, smooth_px, need=None, stack=None):
    """In place: where two crossing planes are both within L of a pixel, the pixel stays
    in-plane only for the nearer one (see :func:`_label_images` and below). ``need``: per
    plane, whether its image is wanted (bool; None: all): the pairs of two planes that are
    not are skipped (their images are left as they are). ``stack``: the images as one
    (planes, H, W) array whose planes ``labs`` are, if at hand: the pixels in-plane for
    several planes are then found in one compiled pass (:func:`_shared_in_plane`)."""
    P = len(planes)
    if P < 2:
        return
    if stack is not None and P <= 64:  # (one compiled pass)
        bits = np.empty(valid.size, np.uint16 if P <= 16 else np.uint64)
        pows = (np.uint64(1) << np.arange(P, dtype=np.uint64)).astype(bits.dtype)
        shared, near_sh = _shared_in_plane(stack.reshape(P, -1), pows, bits)
    else:
        count = np.zeros(valid.shape, np.uint8)
        for lab in labs:
            count += (lab == IN_PLANE).view(np.uint8)  # (bytes + bytes: no per-element cast)
        shared = np.flatnonzero(count > 1)
        near_sh = np.array([lab.reshape(-1)[shared] == IN_PLANE for lab in labs])
    if len(shared) == 0:
        return
    crossing, layer = _crossing_pairs(planes, crossing_angle_deg)
    if not crossing.any():
        return
    # Which plane is nearer is decided on the two planes' signed distances, each summed over
    # the smooth_px x smooth_px pixels around that are within L of both (the noise of one
    # pixel would otherwise fray the edge along the crossing): the plane whose mean is nearer
    # zero keeps the pixel. Near the crossing line the surface seen beside it lies on one
    # plane on either side and off the other by x sin(angle), so the window means keep the
    # order of the centre pixel's true distances. (Averaging each plane's distance over every
    # measured pixel around, as before, mixed in the pixels of a 5 mm reveal and of the other
    # surface: at 2.3 m the door's hinge side lost ~1 cm to the cabinet's face, measured.)
    H, W = valid.shape
    ys, xs = np.divmod(shared, W)
    r = smooth_px // 2
    take = np.zeros(near_sh.shape, bool)  # [k, i]: shared pixel i is nearer another plane
    take_layer = np.zeros(near_sh.shape, bool) if layer.any() else None
    pairs = [(k, j) for k in range(P) for j in range(k + 1, P)
             if (crossing[k, j] or crossing[j, k]) and (need is None or need[k] or need[j])]
    if smooth_px == BOX and H >= 3 and W >= 3 and pairs:
        # every pair in one compiled pass (:func:`_pair_takes`; its boxes are >= 3 x 3)
        _pair_takes(S, near_sh, ys, xs, np.array(pairs, np.int64), crossing, layer, r, take,
                    np.zeros((1, 1), bool) if take_layer is None else take_layer)
        pairs = []
    for k, j in pairs:
        both = np.flatnonzero(near_sh[k] & near_sh[j])
        if len(both) == 0:
            continue
        by, bx = ys[both], xs[both]
        # the pair's pixels' bounding box with the window's margin (``shared`` is
        # increasing, so its rows are: the first and last are the least and largest)
        y0, y1 = max(0, int(by[0]) - r), min(H, int(by[-1]) + r + 1)
        x0, x1 = max(0, int(bx.min()) - r), min(W, int(bx.max()) + r + 1)
        ak, aj = _pair_window_sums_cv(S[k], S[j], y0, y1, x0, x1, by, bx, smooth_px)
        if layer[k, j]:  # (a layer pair: both directions, sign-dependent labels)
            # (only in the layer's region: outside it the layer has no in-plane pixels)
            take_layer[k, both] |= aj < ak
            take_layer[j, both] |= ak < aj
            continue
        if crossing[k, j]:
            tk = take[k]
            tk[both] |= aj < ak
        if crossing[j, k]:
            tj = take[j]
            tj[both] |= ak < aj
    for k in range(P):
        if take[k].any():
            flat = labs[k].reshape(-1)
            flat[shared[take[k]]] = FREE                # in-plane -> FREE
        if take_layer is not None and take_layer[k].any():
            # the other layer keeps them: in front of plane k (s > 0) they hide it
            # (OCCLUDED), behind it the camera sees through it (FREE)
            px = shared[take_layer[k] & ~take[k]]
            flat = labs[k].reshape(-1)
            flat[px] = np.where(S[k].reshape(-1)[px] > 0, np.uint8(OCCLUDED), np.uint8(FREE))


@numba.njit(cache=True, nogil=True)
def _pair_takes(S, near_sh, ys, xs, pairs, crossing, layer, r, take, take_layer):
    """:func:`_crossings`' pairs (``pairs``: (k, j) rows) in one compiled pass, the window
    sums by :func:`boxsum.pair_window_sums` (5 x 5): for each pair, its shared pixels (in-plane
    for both, ``near_sh``; image rows ``ys`` and columns ``xs``) on their bounding box with
    the margin ``r``; ``take_layer`` both ways for a layer pair, else ``take`` for the plane
    that the crossing lets the other take pixels from (as the loop it replaces)."""
    H, W = S.shape[1], S.shape[2]
    ns = near_sh.shape[1]
    idx = np.empty(ns, np.int64)
    for t in range(pairs.shape[0]):
        k, j = pairs[t, 0], pairs[t, 1]
        nk, nj = near_sh[k], near_sh[j]
        m = 0
        for i in range(ns):  # (without a conditional jump per pixel)
            idx[m] = i
            m += nk[i] & nj[i]
        if m == 0:
            continue
        both = idx[:m]
        by, bx = ys[both], xs[both]
        y0, y1 = max(0, by[0] - r), min(H, by[m - 1] + r + 1)
        x0, x1 = max(0, bx.min() - r), min(W, bx.max() + r + 1)
        ak = np.empty(m, np.float32)
        aj = np.empty(m, np.float32)
        pair_window_sums(S[k], S[j], y0, y1, x0, x1, by, bx, ak, aj)
        if layer[k, j]:
            for q in range(m):
                take_layer[k, both[q]] |= aj[q] < ak[q]
                take_layer[j, both[q]] |= ak[q] < aj[q]
            continue
        if crossing[k, j]:
            for q in range(m):
                take[k, both[q]] |= aj[q] < ak[q]
        if crossing[j, k]:
            for q in range(m):
                take[j, both[q]] |= ak[q] < aj[q]


def _pair_window_sums_cv(Sk, Sj, y0, y1, x0, x1, by, bx, smooth_px):
    """:func:`boxsum.pair_window_sums` with OpenCV's box filter (any window side, any box):
    (ak, aj) at the pixels (``by``, ``bx``)."""
    bw = x1 - x0
    fi = (by - y0) * bw + (bx - x0)  # (flat indices in the box: one gather each)
    w = np.zeros((y1 - y0) * bw, np.float32)
    w[fi] = 1.0
    w = w.reshape(y1 - y0, bw)
    box = (smooth_px, smooth_px)
    ak = np.abs(cv2.boxFilter(Sk[y0:y1, x0:x1] * w, -1, box, normalize=False).reshape(-1)[fi])
    aj = np.abs(cv2.boxFilter(Sj[y0:y1, x0:x1] * w, -1, box, normalize=False).reshape(-1)[fi])
    return ak, aj


@numba.njit(cache=True, nogil=True)
def _shared_in_plane(stack, pows, bits):
    """The pixels in-plane for more than one plane of the label images ``stack`` (planes,
    pixels): (their flat indices in increasing order, (planes, those) bool: in-plane for each
    plane), as ``np.flatnonzero`` of the in-plane counts above 1 and the images at them.
    ``pows``: 2^k for each plane k, of ``bits``' integer type (pixels, scratch): each pixel's
    in-plane planes as the bits of one integer, set plane by plane in vector operations."""
    P, n = stack.shape
    zero = pows[0] - pows[0]
    for i in range(n):
        bits[i] = zero
    for k in range(P):
        row, pw = stack[k], pows[k]
        for i in range(n):
            bits[i] = bits[i] | (pw if row[i] == IN_PLANE else zero)
    idx = np.empty(n, np.int64)
    ns = 0
    for i in range(n):  # (without a conditional jump per pixel)
        b = bits[i]
        idx[ns] = i
        ns += (b & (b - pows[0])) != zero
    shared = idx[:ns].copy()
    near = np.empty((P, ns), np.bool_)
    for j in range(ns):
        b = bits[shared[j]]
        for k in range(P):
            near[k, j] = (b & pows[k]) != zero
    return shared, near


def _surface_check(lab, S, Lm, win):
    """In place: an in-plane pixel whose in-plane neighbours (a ``win`` x ``win`` square) lie
    on average farther than ``Lm`` from the plane refitted to the in-plane pixels' distances
    (not from the detected plane, whose fit may be tilted) becomes UNKNOWN. Single pixels of a plane
    scatter around it by the camera's noise (their mean within a fraction of it); the side
    face of a panel seen around its edge (a door's 19 mm edge) lies within L of the panel's
    face too, but wholly behind it, and would otherwise widen the front by up to
    thickness x tan(incidence) (measured: 2 cm at 69 deg)."""
    m8 = cv2.compare(lab, IN_PLANE, cv2.CMP_EQ)
    x, y, w, h = cv2.boundingRect(m8)  # work on the in-plane pixels' bounding box only
    if w == 0 or h == 0:
        return
    r = win // 2
    y0, y1, x0, x1 = max(0, y - r), min(lab.shape[0], y + h + r), max(0, x - r), min(
        lab.shape[1], x + w + r)
    m8b = m8[y0:y1, x0:x1]
    # relative to the plane refitted to the in-plane pixels' distances (an affine function
    # of the pixel, least squares), not to the fitted plane: a plane 1-2 deg off (a sliding
    # panel 4.6 cm in front of its cabinet's face) departs from one side of a 0.5 m panel by
    # more than the surface distance and the check removed that half with its handle
    # (handle regression: 0.154 m)
    Sb = S[y0:y1, x0:x1]
    coef = np.empty(3)
    state = _ramp_fit(Sb, m8b, Lm[y0:y1, x0:x1], coef)
    if state < 0:  # (points on one line: the least-squares solution of the general case)
        coef = _ramp_fit_lstsq(Sb, m8b > 0, Lm[y0:y1, x0:x1])
        state = 0 if coef is None else 1
    if state > 0:
        ramp = (np.float32(coef[0]), np.float32(coef[1]), np.float32(coef[2]), True)
    else:
        ramp = (np.float32(0.0), np.float32(0.0), np.float32(0.0), False)
    # (the kernels read the whole contiguous images at the box's offset: the compiler makes
    # vector operations of contiguous rows, not of a strided box view)
    S = np.ascontiguousarray(S)
    Lm = np.ascontiguousarray(Lm)
    if win == BOX and min(y1 - y0, x1 - x0) >= 3:
        # the deviations, both window sums and the marks in one pass (boxsum.py: OpenCV's
        # box filter's values)
        surface_marks(S, m8, Lm, y0, y1, x0, x1, *ramp, lab)
        return
    # in-plane neighbours of each pixel (exact integers, from the 0/1 bytes)
    den = cv2.boxFilter((m8b > 0).view(np.uint8), cv2.CV_32F, (win, win), normalize=False)
    # (Sb - ramp) on the in-plane pixels, 0 elsewhere; the ramp is (a x + b y) + c, float32
    dev = np.empty(Sb.shape, np.float32)
    _surface_deviation(S, m8, y0, x0, *ramp, dev)
    num = cv2.boxFilter(dev, -1, (win, win), normalize=False)
    # den >= 1 at every in-plane pixel (its own): max(den, 1) = den where it matters
    _mark_off_surface(num, den, Lm, m8, y0, x0, lab)


@numba.njit(cache=True, nogil=True)
def _surface_deviation(S, m8, y0, x0, a, b, c, with_ramp, dev):
    """``dev`` = (Sb - ((a x + b y) + c)) m (float32, the array expression's operations in
    its order; without ``with_ramp`` Sb m) on the box of ``dev``'s shape at (``y0``, ``x0``)
    of the image ``S`` (x, y counted from the box's corner), m = 1 where ``m8`` is set, else
    0. Rows without a test per pixel (a select), so the compiler makes vector operations."""
    h, w = dev.shape
    one, zero = np.float32(1.0), np.float32(0.0)
    xf = np.arange(w).astype(np.float32)  # (x as float32, read rather than converted)
    for r in range(h):
        # (rows sliced from the box's first column: contiguous, indexed from 0)
        Sr, mr, dr = S[y0 + r, x0:x0 + w], m8[y0 + r, x0:x0 + w], dev[r]
        if with_ramp:
            by = b * np.float32(r)
            for x in range(w):
                v = Sr[x] - ((a * xf[x] + by) + c)
                dr[x] = v * (one if mr[x] != 0 else zero)
        else:
            for x in range(w):
                dr[x] = Sr[x] * (one if mr[x] != 0 else zero)


@numba.njit(cache=True, nogil=True)
def _mark_off_surface(num, den, Lm, m8, y0, x0, lab):
    """In place: OFF_SURFACE or-ed into ``lab`` where ``m8`` is set and |num| > den Lm
    (float32) on the box of ``num``'s shape at (``y0``, ``x0``) of the images ``Lm``, ``m8``
    and ``lab`` (every pixel of the box written, unchanged where not marked)."""
    h, w = num.shape
    flag = np.uint8(OFF_SURFACE)
    for r in range(h):
        nr, dr = num[r], den[r]
        Lr, mr, lr = Lm[y0 + r, x0:x0 + w], m8[y0 + r, x0:x0 + w], lab[y0 + r, x0:x0 + w]
        for x in range(w):
            hit = (mr[x] != 0) & (abs(nr[x]) > dr[x] * Lr[x])
            lr[x] = lr[x] | (flag if hit else np.uint8(0))


def _ramp_fit_lstsq(Sb, inpb, Lmb):
    """The ramp of :func:`_surface_check` by ``np.linalg.lstsq`` where needed (the points of
    every 4th pixel on one line): coefficients (3,), or None with fewer than 3 points."""
    vv, uu = np.nonzero(inpb[::4, ::4])  # every 4th pixel: enough for 3 numbers
    if len(vv) < 3:
        return None
    A = np.column_stack([4.0 * uu, 4.0 * vv, np.ones(len(uu))])
    b = Sb[4 * vv, 4 * uu].astype(np.float64)
    lim = 2.0 * Lmb[4 * vv, 4 * uu].astype(np.float64)
    coef = _affine_lstsq(A, b)
    for _ in range(2):
        keep = np.abs(A @ coef - b) <= lim
        if np.count_nonzero(keep) < 3:
            break
        coef = _affine_lstsq(np.compress(keep, A, axis=0), b[keep])
    return coef


@numba.njit(cache=True, nogil=True)
def _ramp_fit(Sb, m8, Lmb, coef):
    """The ramp of :func:`_surface_check` in one compiled pass: the affine function
    (a x + b y + c, ``coef``) of the pixel fitted by least squares to ``Sb`` on every 4th
    in-plane pixel (``m8`` set) in rows and columns, then twice on those within 2 ``Lmb`` of
    the last fit (a refit needs 3 points). Returns 1 (fitted), 0 (fewer than 3 points) or -1
    (the points on one line: :func:`_ramp_fit_lstsq` decides)."""
    H, W = Sb.shape
    n = ((H + 3) // 4) * ((W + 3) // 4)
    u = np.empty(n)
    v = np.empty(n)
    b = np.empty(n)
    lim = np.empty(n)
    k = 0
    for y in range(0, H, 4):
        for x in range(0, W, 4):
            if m8[y, x]:
                u[k], v[k], b[k] = x, y, Sb[y, x]
                lim[k] = 2.0 * np.float64(Lmb[y, x])
                k += 1
    if k < 3:
        return 0
    keep = np.ones(k, np.bool_)
    for it in range(3):
        if it > 0:
            m = 0
            for i in range(k):
                keep[i] = abs((u[i] * coef[0] + v[i] * coef[1]) + coef[2] - b[i]) <= lim[i]
                m += keep[i]
            if m < 3:
                break
        # the normal equations of the centred columns (:func:`_affine_lstsq`)
        m = 0
        su = sv = sb = 0.0
        for i in range(k):
            if keep[i]:
                su += u[i]
                sv += v[i]
                sb += b[i]
                m += 1
        mu, mv, mb = su / m, sv / m, sb / m
        suu = svv = suv = sub = svb = 0.0
        for i in range(k):
            if keep[i]:
                du, dv, db = u[i] - mu, v[i] - mv, b[i] - mb
                suu += du * du
                svv += dv * dv
                suv += du * dv
                sub += du * db
                svb += dv * db
        det = suu * svv - suv * suv
        if not det > 1e-9 * suu * svv:
            return -1
        a = (svv * sub - suv * svb) / det
        c = (suu * svb - suv * sub) / det
        coef[0], coef[1], coef[2] = a, c, mb - a * mu - c * mv
    return 1


def _affine_lstsq(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least-squares coefficients of ``A`` (k, 3) = [u, v, 1] for ``b`` (k,): the normal
    equations of the centred columns (2 x 2, closed form; 10-50x faster than
    ``np.linalg.lstsq``'s SVD, the same coefficients up to rounding ~1e-15); ``lstsq`` when
    the points are (nearly) on one line."""
    u, v = A[:, 0], A[:, 1]
    k = len(b)
    mu, mv, mb = u.sum() / k, v.sum() / k, b.sum() / k
    du, dv, db = u - mu, v - mv, b - mb
    suu, svv, suv = du @ du, dv @ dv, du @ dv
    det = suu * svv - suv * suv
    if not det > 1e-9 * suu * svv:
        return np.linalg.lstsq(A, b, rcond=None)[0]
    sub, svb = du @ db, dv @ db
    a = (svv * sub - suv * svb) / det
    c = (suu * svb - suv * sub) / det
    return np.array([a, c, mb - a * mu - c * mv])


def _refit_on_own_pixels(planes, labels, Pc, Lmap, min_change_deg, crossing_angle_deg,
                         rounds=3, max_points=40000, max_change_deg=5.0, min_support=100):
    """Planes that cross another plane at a shallow angle (between ``crossing_angle_deg`` and
    30 deg) refitted on their own pixels: those in-plane for them after the crossings
    (:func:`_crossings`), within L / 2 of them (as the second round of
    :func:`refine_plane_fullres`) and nearer to them than to any such crossing plane within L
    of the pixel; ``rounds`` times (the nearer plane is decided with the refitted planes;
    planes that are parallel within ``crossing_angle_deg``, e.g. the flush closed fronts of
    one cabinet, are left alone: their pixels lie within noise of both). None if
    no plane's normal turns by ``min_change_deg`` (deg) or more (and less than
    ``max_change_deg``); else the list with every such plane replaced. Planes of fewer than
    ``min_support`` RANSAC samples (a few rows of the sample grid) are left alone: their own
    pixels are too few for a refit that is not mostly noise (such a refit turns a small
    plane by its noise and can lose the front on it).

    Why: RANSAC and :func:`refine_plane_fullres` count every pixel within L (then L / 2) of a
    plane. A door opened by a few degrees crosses the cabinet's face at that angle, so the
    face beside its hinge lies within L of the door's plane over L / sin(angle) (7 cm at
    8 deg) and tilts the fitted plane towards it (by 2.1 deg at 8 deg, seen from 0.8 m,
    measured on a noise-free render); the door's own surface by the hinge then lies 8 mm off
    its plane, nearer the face's plane, and the crossing gave a 5 cm strip of the door to the
    face (the door's hinge side 46-53 mm short at 5-8 deg). Refitted on the pixels nearer to
    it, the plane is the door's own; the labels are then made again.
    """
    if len(planes) < 2:
        return None
    N0 = np.array([pl.n for pl in planes])
    cosang = np.abs(N0 @ N0.T)
    partners = ((cosang < math.cos(math.radians(crossing_angle_deg)))
                & (cosang > math.cos(math.radians(30.0))))
    if not partners.any():  # (before the pixels are gathered: nothing to refit)
        return None
    H, W = labels[0].shape
    step = max(1, int(math.ceil(math.sqrt(H * W / max_points))))
    own0 = np.array([lab[::step, ::step].reshape(-1) == IN_PLANE for lab in labels])
    # the sampled pixels with a measurement that are in-plane for some plane: their points
    # (float64), L and own0 columns, in one compiled pass
    P, L, own0 = _sampled_own(Pc, Lmap, own0, step)
    cur = list(planes)
    cos10 = math.cos(math.radians(10.0))
    # the distances are needed to the refitted planes and their partners only: those rows of
    # the (planes, pixels) distances (the same products; rows of pixels run fast)
    refit = [k for k, pl in enumerate(planes) if partners[k].any() and pl.support >= min_support]
    rows = sorted(set(refit) | set(np.flatnonzero(partners[refit].any(axis=0)).tolist()))
    row_of = {k: i for i, k in enumerate(rows)}
    if not refit:
        return None
    halfL = 0.5 * L
    refit_rows = np.array([row_of[k] for k in refit], np.int64)
    refit_idx = np.array(refit, np.int64)
    part = [[row_of[j] for j in np.flatnonzero(partners[k])] for k in refit]
    part_ptr = np.cumsum([0] + [len(q) for q in part]).astype(np.int64)
    part_rows = np.array([j for q in part for j in q], np.int64)
    for _ in range(rounds):
        N = np.array([pl.n for pl in cur])
        D = np.array([pl.d for pl in cur])
        A = N[rows] @ P.T                            # (planes, pixels) distances, m
        A += D[rows, None]
        np.abs(A, out=A)
        # each refitted plane's own pixels, all in one compiled pass
        sel_all = np.empty((len(refit), A.shape[1]), bool)
        n_sel = _own_pixels(A, L, halfL, own0, refit_rows, refit_idx, part_ptr, part_rows,
                            sel_all)
        nxt = list(cur)
        for t, k in enumerate(refit):
            sel = sel_all[t]
            if n_sel[t] < 10:
                continue
            n, d = _fit_plane_many(np.compress(sel, P, axis=0))
            if n @ planes[k].n < cos10:
                continue
            pl = cur[k]
            nxt[k] = Plane(n=n, d=d, support=pl.support, bbox=pl.bbox)
        cur = nxt
    # a turn beyond max_change_deg is no correction of a tilt but a different surface (a
    # small plane of a few rows whose own pixels fit another plane): kept as it was
    cmin, cmax = (math.cos(math.radians(a)) for a in (min_change_deg, max_change_deg))
    keep = [b if cmax <= float(a.n @ b.n) < cmin else a for a, b in zip(planes, cur)]
    return None if all(a is b for a, b in zip(planes, keep)) else keep


@numba.njit(cache=True, nogil=True)
def _own_pixels(A, L, halfL, own0, refit_rows, refit_idx, part_ptr, part_rows, sel):
    """:func:`_refit_on_own_pixels`' pixels of each refitted plane t (``sel[t]``): those
    in-plane for it (``own0[refit_idx[t]]``), within ``halfL`` of it (its distances: row
    ``refit_rows[t]`` of ``A``) and no farther from it than from any partner plane within
    ``L`` of the pixel (rows ``part_rows[part_ptr[t]:part_ptr[t + 1]]``). Returns their
    counts."""
    n_t = refit_rows.shape[0]
    n = A.shape[1]
    counts = np.zeros(n_t, np.int64)
    near = np.empty(n)
    for t in range(n_t):
        ak_row = A[refit_rows[t]]
        own = own0[refit_idx[t]]
        out = sel[t]
        # the least distance to a partner within L, partner after partner over all pixels
        # (selects without jumps: vector operations; a least value in any order)
        for i in range(n):
            near[i] = np.inf
        for q in range(part_ptr[t], part_ptr[t + 1]):
            row = A[part_rows[q]]
            for i in range(n):
                a, m = row[i], near[i]
                near[i] = a if (a <= L[i]) & (a < m) else m
        c = 0
        for i in range(n):
            ak = ak_row[i]
            v = own[i] & (ak <= halfL[i]) & (ak <= near[i])
            out[i] = v
            c += v
        counts[t] = c
    return counts


@numba.njit(cache=True, nogil=True)
def _sampled_own(Pc, Lmap, own0, step):
    """The pixels of every ``step``-th row and column (row-major) whose point is measured and
    that are in-plane for some plane (a column of ``own0`` (planes, sampled pixels) set):
    their points (k, 3) float64, ``Lmap`` (k,) float64 and ``own0`` columns (planes, k)."""
    nP, n = own0.shape
    Ws = (Pc.shape[1] + step - 1) // step
    keep = np.zeros(n, np.bool_)
    k = 0
    for i in range(n):
        r, c = (i // Ws) * step, (i % Ws) * step
        if np.isfinite(Pc[r, c, 2]):
            for q in range(nP):
                if own0[q, i]:
                    keep[i] = True
                    k += 1
                    break
    P = np.empty((k, 3))
    L = np.empty(k)
    own = np.empty((nP, k), np.bool_)
    j = 0
    for i in range(n):
        if keep[i]:
            r, c = (i // Ws) * step, (i % Ws) * step
            P[j, 0], P[j, 1], P[j, 2] = Pc[r, c, 0], Pc[r, c, 1], Pc[r, c, 2]
            L[j] = Lmap[r, c]
            for q in range(nP):
                own[q, j] = own0[q, i]
            j += 1
    return P, L, own
