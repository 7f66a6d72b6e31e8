"""The front detector's rectified views: a view reads only the image pixels inside :func:`_view_footprint` (z' computed there only
gives the very same warped image), and :func:`_gap_mask_rectified`'s one packed warp back
gives the masks of two separate nearest-neighbour warps."""

import math

import cv2
import numpy as np

from mmlearn.models.perception.detection import FrontDetectorConfig, Plane
from mmlearn.models.perception.detection.gaps import _gap_mask
from mmlearn.models.perception.detection.rectify import (_gap_mask_rectified, _rectified_view,
                                                          _view_footprint)
from mmlearn.models.common.camera import PinholeIntrinsics

K = PinholeIntrinsics(width=640, height=480, fx=577.3, fy=577.3, cx=319.5, cy=239.5)
DOWN = np.array([0.0, 1.0, 0.0])  # a level camera: its y axis is down


def _views():
    """Rectified views of vertical planes turned 30-70 deg about the vertical, their regions
    in different parts of the image."""
    cfg = FrontDetectorConfig()
    out = []
    for ang, bbox in ((50, (0, 20, 10, 70)), (-35, (40, 59, 5, 40)), (70, (0, 25, 0, 40)),
                      (-60, (0, 30, 0, 79))):
        a = math.radians(ang)
        pl = Plane(n=np.array([math.sin(a), 0.0, -math.cos(a)]), d=1.5, support=500, bbox=bbox)
        v = _rectified_view(K, pl, DOWN, cfg, 8, 4)
        assert v is not None, (ang, bbox)
        out.append(v)
    return out


def test_view_footprint_holds_every_pixel_the_warp_reads():
    """Zeroing the image outside the footprint changes no pixel of the bilinear warp, while
    zeroing it inside does (the box is not the whole image for a part-image region)."""
    rng = np.random.default_rng(0)
    img = rng.uniform(0.5, 3.0, (K.height, K.width)).astype(np.float32)
    smaller = 0
    for Hm, _, _, Wv, Hv in _views():
        y0, y1, x0, x1 = _view_footprint(Hm, Wv, Hv, img.shape)
        assert 0 <= y0 < y1 <= K.height and 0 <= x0 < x1 <= K.width
        smaller += (y1 - y0) * (x1 - x0) < K.height * K.width
        crop = np.zeros_like(img)
        crop[y0:y1, x0:x1] = img[y0:y1, x0:x1]
        kw = dict(flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
        full = cv2.warpPerspective(img, Hm, (Wv, Hv), **kw)
        assert np.array_equal(cv2.warpPerspective(crop, Hm, (Wv, Hv), **kw), full)
        # a one-pixel narrower box (no padding) would lose pixels the warp reads
        inner = np.zeros_like(img)
        inner[y0 + 3:y1 - 3, x0 + 3:x1 - 3] = img[y0 + 3:y1 - 3, x0 + 3:x1 - 3]
        assert not np.array_equal(cv2.warpPerspective(inner, Hm, (Wv, Hv), **kw), full)
    assert smaller >= 2


def test_view_footprint_whole_image_when_a_corner_is_behind_the_camera():
    # a homography whose inverse sends a view corner behind the camera (w <= 0)
    Hm = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.01, 0.0, 1.0]])
    Hi = np.linalg.inv(Hm)
    assert (Hi @ np.array([100.0, 0.0, 1.0]))[2] <= 0
    assert _view_footprint(Hm, 300, 200, (480, 640)) == (0, 480, 0, 640)


def test_gap_mask_rectified_packed_warp_back_is_two_warps():
    """The masks come back to the image as two separate nearest-neighbour warps would bring
    them, on a synthetic depth image of a slanted wall with vertical reveals."""
    cfg = FrontDetectorConfig()
    Hm, R, f, Wv, Hv = view = _views()[3]  # the upper half, 60 deg off its normal
    xs = ((np.arange(K.width, dtype=np.float32) - np.float32(K.cx)) / np.float32(K.fx))[None]
    ys = ((np.arange(K.height, dtype=np.float32) - np.float32(K.cy)) / np.float32(K.fy))[:, None]
    a = math.radians(-60)
    n = np.array([math.sin(a), 0.0, -math.cos(a)])
    den = n[0] * xs + n[2] + n[1] * ys  # n . ray
    d = (-1.5 / den).astype(np.float32)
    # reveals: every 0.3 m along the wall, 5 mm wide bands without return
    e1 = np.array([math.cos(a), 0.0, math.sin(a)])
    s = (d * xs * e1[0] + d * e1[2]) % 0.3
    valid = (d > 0) & (s > 0.005)
    dzero = np.where(valid, d, np.float32(0.0))
    res = _gap_mask_rectified(dzero, valid, K, xs, ys, view, cfg)
    assert res is not None
    wide, thin = res
    assert thin.any() and (wide >= thin).all()
    # the same masks from the view's own masks warped back one at a time
    r3 = R[:, 2].astype(np.float32)
    zv = ((np.float32(r3[0]) * xs + np.float32(r3[2])) + np.float32(r3[1]) * ys) * dzero
    kw = dict(flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    zw = cv2.warpPerspective(zv, Hm, (Wv, Hv), **kw)
    ww = cv2.warpPerspective(valid.astype(np.float32), Hm, (Wv, Hv), **kw)
    vw = ww >= 0.5
    zw = zw / np.maximum(ww, np.float32(1e-6))
    zw[~vw] = 0.0
    gw, gt = _gap_mask(zw, vw, f, cfg, zw, scale_floor=True, to_image=np.linalg.inv(Hm))
    back = dict(flags=cv2.WARP_INVERSE_MAP | cv2.INTER_NEAREST,
                borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    size = (K.width, K.height)
    assert np.array_equal(wide, cv2.warpPerspective(gw.view(np.uint8), Hm, size, **back) > 0)
    assert np.array_equal(thin, cv2.warpPerspective(gt.view(np.uint8), Hm, size, **back) > 0)


def test_view_depth_is_the_array_expression_on_its_box():
    """A rectified view's depth z' = ((a x + c) + b y) d on the footprint's box, bit for bit
    the float32 array expression there, and untouched (0) outside it."""
    from mmlearn.models.perception.detection.rectify import _view_depth

    rng = np.random.default_rng(8)
    H, W, y0, y1, x0, x1 = 40, 60, 5, 33, 7, 51
    xs = np.linspace(-0.5, 0.5, W).astype(np.float32)
    ys = np.linspace(-0.4, 0.4, H).astype(np.float32)
    dz = np.where(rng.random((H, W)) < 0.9, rng.uniform(0.5, 3.0, (H, W)), 0.0).astype(np.float32)
    a, b, c = np.float32(0.3), np.float32(-0.2), np.float32(-0.9)
    zv = np.zeros((H, W), np.float32)
    _view_depth(xs, ys, dz, a, b, c, y0, y1, x0, x1, zv)
    want = np.zeros((H, W), np.float32)
    want[y0:y1, x0:x1] = ((a * xs[None, x0:x1] + c) + b * ys[y0:y1, None]) * dz[y0:y1, x0:x1]
    assert np.array_equal(zv, want) and zv[y0:y1, x0:x1].any()


def test_view_upsampling_limit_shrinks_a_grazing_strip_s_view_only():
    """A narrow strip of a plane seen 80 deg off its normal gets a view far larger than its
    image pixels; ``gap_rectify_max_upsample`` k caps the view at about k view pixels per
    region pixel (the same axes, a lower focal length), and leaves the view of a large
    region seen 50 deg off its normal (3.5 view pixels per region pixel) as it was."""
    a = math.radians(80.0)
    strip = Plane(n=np.array([math.sin(a), 0.0, -math.cos(a)]), d=0.4, support=40,
                  bbox=(10, 40, 30, 33))
    region_px = (8 * 4) * (8 * 31)
    free = _rectified_view(K, strip, DOWN, FrontDetectorConfig(gap_rectify_max_upsample=0.0),
                           8, 4)
    capped = _rectified_view(K, strip, DOWN, FrontDetectorConfig(gap_rectify_max_upsample=4.0),
                             8, 4)
    assert free[3] * free[4] > 8 * region_px
    assert capped[3] * capped[4] <= 4 * region_px + 16 * (capped[3] + capped[4]) + 256
    assert capped[2] < free[2]
    np.testing.assert_array_equal(capped[1], free[1])
    b = math.radians(50.0)
    wide = Plane(n=np.array([math.sin(b), 0.0, -math.cos(b)]), d=1.5, support=900,
                 bbox=(0, 20, 10, 70))
    v0, v4 = (_rectified_view(K, wide, DOWN, FrontDetectorConfig(gap_rectify_max_upsample=k),
                              8, 4) for k in (0.0, 4.0))
    assert v0 is not None and v0[2] == v4[2] and (v0[3], v0[4]) == (v4[3], v4[4])
