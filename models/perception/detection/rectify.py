"""Stage ``masks``, rectified views: the reveal tests on a virtual camera at the same centre
looking along a plane's normal (:func:`_rectified_view`), so that the sides of a front seen
obliquely run along the view's rows and columns; the result is mapped back to the image
(:func:`_gap_mask_rectified`)."""

import math

import cv2
import numba
import numpy as np

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.detection.gaps import _gap_mask
from mmlearn.models.perception.detection.grid import _plane_axes
from mmlearn.models.perception.detection.planes import Plane


def _rectified_view(K: PinholeIntrinsics, pl: Plane, down_C, cfg, stride: int, off: int):
    """A plane's rectified view for :func:`_gap_mask_rectified`: (H, R, f, width, height)
    (H the image -> view homography, R the view's axes in the camera frame, f its focal
    length, px), or None when the plane's in-plane axes (e1 along its horizontal, e2 down the plane, :func:`_plane_axes`)
    are seen within ``gap_rectify_deg`` of the image rows and columns at its region's centre
    (then the image lines follow its edges already).

    Off the front's normal a front's horizontal sides are slanted in the image, and the line
    means along image rows cross the reveal instead of following it. A virtual camera at the
    same centre, rotated to look along the plane's normal with its x and y axes along e1 and
    e2 (a pure rotation: the homography K' R^T K^-1, the same rays, so the same depth samples),
    sees the plane's sides along its rows and columns and the plane at constant depth z'
    (z' = d (r3 . ray)); the reveals are found there on z' with the same tests, and mapped back
    (nearest pixel). The view covers the plane's region (``Plane.bbox``), with its focal
    length reduced so that it is at most ``gap_rectify_max_scale`` times the image's size
    and holds at most ``gap_rectify_max_upsample`` view pixels per image pixel of the region
    (0: no such limit)."""
    n = np.asarray(pl.n, float)
    if down_C is not None and abs(float(n @ down_C)) > math.sin(
            math.radians(cfg.gap_rectify_max_tilt_deg)):
        return None  # not a vertical plane (floor, countertop): no front
    e1, e2 = _plane_axes(n, down_C)
    r0, r1, c0, c1 = pl.bbox
    uc = off + stride * 0.5 * (c0 + c1)
    vc = off + stride * 0.5 * (r0 + r1)
    ray_c = np.array([(uc - K.cx) / K.fx, (vc - K.cy) / K.fy, 1.0])
    den = n @ ray_c
    if not den < -1e-6:
        return None
    pc = ray_c * (-pl.d / den)

    def img_dir(e):
        q0, q1 = pc, pc + 0.05 * e
        a = np.array([K.fx * q0[0] / q0[2], K.fy * q0[1] / q0[2]])
        b = np.array([K.fx * q1[0] / q1[2], K.fy * q1[1] / q1[2]])
        return b - a
    d1, d2 = img_dir(e1), img_dir(e2)
    slant1 = math.degrees(math.atan2(abs(d1[1]), abs(d1[0]) + 1e-12))
    slant2 = math.degrees(math.atan2(abs(d2[0]), abs(d2[1]) + 1e-12))
    if max(slant1, slant2) < cfg.gap_rectify_deg:
        return None
    # virtual axes in camera coordinates: z' into the plane (away from the camera)
    R = np.column_stack([-e1, e2, -n])  # (-e1) x e2 = -n: right-handed
    # the region's corners (on the plane) in the virtual view
    us = off + stride * np.array([c0, c1 + 1, c1 + 1, c0], float)
    vs = off + stride * np.array([r0, r0, r1 + 1, r1 + 1], float)
    rays = np.column_stack([(us - K.cx) / K.fx, (vs - K.cy) / K.fy, np.ones(4)])
    q = rays @ R  # R^T ray, rows
    if not (q[:, 2] > 1e-3).all():
        return None
    uv = K.fx * q[:, :2] / q[:, 2:3]
    size = uv.max(axis=0) - uv.min(axis=0)
    smax = cfg.gap_rectify_max_scale * np.array([K.width, K.height], float)
    # a coarser virtual focal length when the region would be larger than that (seen
    # obliquely, its far side is stretched in the rotated view)
    scale = min(1.0, float(np.min(smax / np.maximum(size, 1.0))))
    if cfg.gap_rectify_max_upsample > 0:
        # and when the view would hold more than gap_rectify_max_upsample pixels per image
        # pixel of the region (a small plane seen at grazing incidence: a strip of 20-40
        # image columns became a view larger than the image, whose line tests cost as
        # much as the image's twice)
        region_px = (stride * (c1 + 1 - c0)) * (stride * (r1 + 1 - r0))
        scale = min(scale, math.sqrt(cfg.gap_rectify_max_upsample * region_px
                                     / max(float(size[0] * size[1]), 1.0)))
    f = K.fx * scale
    uv = f * q[:, :2] / q[:, 2:3]
    lo, hi = uv.min(axis=0) - 8.0, uv.max(axis=0) + 8.0
    size = hi - lo
    Wv, Hv = int(math.ceil(size[0])), int(math.ceil(size[1]))
    if Wv < 16 or Hv < 16:
        return None
    Kv = np.array([[f, 0.0, -lo[0]], [0.0, f, -lo[1]], [0.0, 0.0, 1.0]])
    Kinv = np.array([[1.0 / K.fx, 0.0, -K.cx / K.fx], [0.0, 1.0 / K.fy, -K.cy / K.fy],
                     [0.0, 0.0, 1.0]])
    Hm = Kv @ R.T @ Kinv  # image pixel -> virtual pixel
    return Hm, R, f, Wv, Hv


def _view_footprint(Hm, Wv: int, Hv: int, shape, pad: int = 2):
    """The image pixels a rectified view reads: (y0, y1, x0, x1), the bounding box (padded by
    ``pad`` px for the bilinear neighbours, clipped to the image of ``shape`` = (H, W)) of the
    view's corners mapped to the image by the inverse of the image -> view homography ``Hm``
    (a view of ``Wv`` x ``Hv`` px); the whole image when a corner does not map in front of the
    camera (the quadrilateral is then not the image of the view)."""
    H, W = shape
    q = np.linalg.inv(Hm) @ np.array([[0.0, Wv, Wv, 0.0], [0.0, 0.0, Hv, Hv], [1.0] * 4])
    if not (q[2] > 1e-9).all():
        return 0, H, 0, W
    u, v = q[0] / q[2], q[1] / q[2]
    if not (np.isfinite(u).all() and np.isfinite(v).all()):
        return 0, H, 0, W
    x0 = int(min(W, max(0, math.floor(u.min()) - pad)))
    x1 = int(min(W, max(0, math.ceil(u.max()) + pad + 1)))
    y0 = int(min(H, max(0, math.floor(v.min()) - pad)))
    y1 = int(min(H, max(0, math.ceil(v.max()) + pad + 1)))
    return y0, y1, x0, x1


@numba.njit(cache=True, nogil=True)
def _view_depth(xs, ys, dzero, a, b, c, y0, y1, x0, x1, zv):
    """``zv`` = ((a x + c) + b y) dzero on rows y0:y1, columns x0:x1 (float32, the array
    expression's operations in its order)."""
    xr = xs[x0:x1]
    for r in range(y0, y1):
        by = b * ys[r]
        # (row slices indexed from 0: vector operations)
        zr, dr = zv[r, x0:x1], dzero[r, x0:x1]
        for col in range(x1 - x0):
            zr[col] = ((a * xr[col] + c) + by) * dr[col]


@numba.njit(cache=True, nogil=True)
def _normalise_view(zw, ww, vw):
    """In place: the warped depth ``zw`` over the warped measured share ``ww`` (at least
    1e-6), 0 where the share is under 1/2; ``vw`` = share >= 1/2 (float32, as the array
    expression)."""
    half = np.float32(0.5)
    eps = np.float32(1e-6)
    for r in range(zw.shape[0]):
        for col in range(zw.shape[1]):
            w = ww[r, col]
            ok = w >= half
            vw[r, col] = ok
            zw[r, col] = zw[r, col] / max(w, eps) if ok else np.float32(0.0)


def _gap_mask_rectified(dzero, valid, K: PinholeIntrinsics, xs, ys, view, cfg, long_pass=True,
                        valid_f=None):
    """:func:`_gap_mask` (short and long windows, the long one's whole threshold scaled) on
    the rectified view ``view`` of a plane
    (:func:`_rectified_view`): (wide, thin) in the image, or None when nothing is found.
    ``long_pass=False``: the short windows only. ``valid_f``: ``valid`` as float32 0 / 1 if
    at hand (shared by a frame's views)."""
    Hm, R, f, Wv, Hv = view
    r3 = R[:, 2].astype(np.float32)
    # z' = d (r3 . ray) only on the image pixels the view reads (its footprint's bounding
    # box; 0 elsewhere, never read): the same float32 values where the warp reads them
    y0, y1, x0, x1 = _view_footprint(Hm, Wv, Hv, dzero.shape)
    zv = np.zeros(dzero.shape, np.float32)
    _view_depth(xs[0], ys[:, 0], dzero, np.float32(r3[0]), np.float32(r3[1]),
                np.float32(r3[2]), y0, y1, x0, x1, zv)  # 0 where not measured
    if valid_f is None:
        valid_f = valid.view(np.uint8).astype(np.float32)
    # bilinear on z' and on the measured share, normalised (unmeasured pixels do not pull
    # the depth towards 0); a pixel at least half measured is measured
    zw = cv2.warpPerspective(zv, Hm, (Wv, Hv), flags=cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    ww = cv2.warpPerspective(valid_f, Hm, (Wv, Hv),
                             flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                             borderValue=0.0)
    vw = np.empty(zw.shape, bool)
    _normalise_view(zw, ww, vw)
    # the long pass here with its whole threshold scaled (gap_depth too: a vertical reveal
    # seen 45 deg off the normal dips 1.6-3.7 mm at 1.5 m, where both passes' thresholds
    # are the 2.5 mm floor; on the whole image a scaled floor labelled false rows on the wall
    # and countertop at 2.2 m)
    gw, gt = _gap_mask(zw, vw, f, cfg, zw, long_pass=long_pass, scale_floor=True,
                       to_image=np.linalg.inv(Hm))
    if not gt.any():
        return None
    # both masks back to the image in one nearest-neighbour warp (bit 0 wide, bit 1 thin:
    # nearest neighbour copies each view pixel's byte whole)
    packed = np.left_shift(gt.view(np.uint8), np.uint8(1))
    packed |= gw.view(np.uint8)
    back = cv2.warpPerspective(packed, Hm, (K.width, K.height),
                               flags=cv2.WARP_INVERSE_MAP | cv2.INTER_NEAREST,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    wide = np.bitwise_and(back, np.uint8(1)).view(bool)
    thin = np.right_shift(back, np.uint8(1)).view(bool)
    return wide, thin
