"""The front detector's rectified grids: the hand-written 3-vector cross product is
np.cross's; the plane axes are right-handed with e2 down; a cost image rectified onto a plane grid is the cost table applied to
the rectified labels (cells outside the image and behind the camera included); the rotation
polish's returned tables are those of its best window made from scratch."""

import math

import cv2
import numpy as np

from mmlearn.models.perception.detection import FrontDetectorConfig
from mmlearn.models.perception.detection.grid import (_cross3, _make_grid, _plane_axes, _sats,
                                                       _warp_labels)
from mmlearn.models.perception.detection.labels import (FREE, GAP, IN_PLANE, OCCLUDED, OUTSIDE,
                                                         UNKNOWN)
from mmlearn.models.perception.detection.search import _greedy, _objective, _polish_rotations
from mmlearn.models.common.camera import PinholeIntrinsics


def _lut(cfg):
    lut = np.zeros(256, np.uint8)
    lut[:7] = np.round(255.0 * np.array([cfg.cost_in_plane, cfg.cost_free, cfg.cost_occluded,
                                         cfg.cost_unknown, cfg.cost_free, cfg.cost_unknown,
                                         cfg.cost_free]))
    return lut


def test_cross3_is_np_cross_bit_for_bit():
    rng = np.random.default_rng(0)
    for scale in (1e-8, 1.0, 1e6):
        a = rng.normal(size=(500, 3)) * scale
        b = rng.normal(size=(500, 3))
        for x, y in zip(a, b):
            assert np.array_equal(_cross3(x, y), np.cross(x, y))
    # parallel vectors: exactly zero
    assert np.array_equal(_cross3(np.array([1.0, 2, 3]), np.array([2.0, 4, 6])), np.zeros(3))


def test_plane_axes_right_handed_and_down():
    """e1 x e2 = n, unit axes, e2 along gravity projected onto the plane (or e1 along the
    camera x axis for a horizontal plane / unknown gravity)."""
    rng = np.random.default_rng(1)
    down = np.array([0.0, 1.0, 0.0])
    for _ in range(200):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        for d in (down, None):
            e1, e2 = _plane_axes(n, d)
            assert abs(np.linalg.norm(e1) - 1) < 1e-12 and abs(np.linalg.norm(e2) - 1) < 1e-12
            assert np.allclose(np.cross(e1, e2), n, atol=1e-12)
            g = None if d is None else d - (d @ n) * n
            if g is not None and np.linalg.norm(g) > 0.5:
                assert np.allclose(e2, g / np.linalg.norm(g), atol=1e-12)
            else:
                assert e1 @ np.array([1.0, 0, 0]) >= 0 or abs(n[0]) > 1 - 1e-6
    # the camera looking straight at a wall (normal towards the camera): e2 = down, e1 = e2 x n
    # = the camera's -x
    e1, e2 = _plane_axes(np.array([0.0, 0.0, -1.0]), down)
    assert np.allclose(e1, [-1, 0, 0]) and np.allclose(e2, [0, 1, 0])


def test_cost_image_warp_is_lut_of_label_warp():
    """Nearest-neighbour rectification only selects pixels: warping lut[labels] (with
    ``outside`` = lut[OUTSIDE]) equals lut[warped labels], on grids reaching outside the image
    and behind the camera."""
    K = PinholeIntrinsics.from_fov(640, 480, 58.0)
    rng = np.random.default_rng(3)
    labels = rng.choice(np.array([IN_PLANE, FREE, OCCLUDED, UNKNOWN, GAP], np.uint8),
                        size=(K.height, K.width))
    lut = _lut(FrontDetectorConfig())
    cost_img = lut[labels]
    # a plane through (0, 0, 2) tilted 70 deg about the camera x axis: its far half leaves
    # the image, its near half passes behind the camera
    a = math.radians(70.0)
    o = np.array([0.0, 0.0, 2.0])
    e1 = np.array([1.0, 0.0, 0.0])
    e2 = np.array([0.0, math.cos(a), -math.sin(a)])
    for (u0, v0, c, shape) in ((-1.0, -1.0, 0.01, (200, 200)), (-3.0, -4.0, 0.02, (400, 300)),
                               (-0.2, -0.1, 0.002, (100, 150))):
        lab = _warp_labels(labels, K, o, e1, e2, u0, v0, c, shape)
        cost = _warp_labels(cost_img, K, o, e1, e2, u0, v0, c, shape, outside=lut[OUTSIDE])
        assert np.array_equal(cost, lut[lab])
    # the test reaches both special cases
    lab = _warp_labels(labels, K, o, e1, e2, -3.0, -4.0, 0.02, (400, 300))
    vv = -4.0 + (np.arange(400) + 0.5) * 0.02
    z = o[2] + vv * e2[2]
    assert (lab[z < 0.05] == OUTSIDE).all() and (z < 0.05).any()
    assert (lab[z >= 0.05] == OUTSIDE).any() and (lab != OUTSIDE).any()


def test_polish_tables_are_its_best_window_made_again():
    """The rotation polish keeps only each window's objective and rectangle; the labels and
    tables it returns are those of the best window made from scratch, and the returned
    objective is that rectangle's on them (a tilted front: the rectangle turns)."""
    import cv2

    cfg = FrontDetectorConfig()
    lut = _lut(cfg)
    K = PinholeIntrinsics.from_fov(640, 480, 58.0)
    lab = np.full((K.height, K.width), FREE, np.uint8)
    box = cv2.boxPoints(((320, 240), (260, 160), 6.0)).astype(np.int32)
    cv2.fillConvexPoly(lab, box, IN_PLANE)
    z = 2.0
    vv, uu = np.mgrid[4:K.height:8, 4:K.width:8]
    pts = np.column_stack([((uu - K.cx) / K.fx * z).ravel(), ((vv - K.cy) / K.fy * z).ravel(),
                           np.full(uu.size, z)])
    from mmlearn.models.perception.detection import Plane

    plane = Plane(n=np.array([0.0, 0.0, -1.0]), d=z, support=len(pts),
                  bbox=(0, K.height // 8 - 1, 0, K.width // 8 - 1))
    g = _make_grid(0, plane, lab, pts, K, np.array([0.0, 1.0, 0.0]), cfg, lut)
    p = np.array([0.0, 0.0, z]) - g.o
    j, i = int((p @ g.e1 - g.u0) / g.c), int((p @ g.e2 - g.v0) / g.c)
    R, _, _ = _greedy(g.sat_cost[None], np.array([g.shape]), np.zeros(1, np.int64),
                      np.array([[j - 8, j + 8, i - 8, i + 8]], np.int64),
                      np.array([[1, 2, 4, 8]]), np.array([6]), cfg.alpha, cfg.max_iterations)
    (score, best), = _polish_rotations([(g, R[0], lab)], K, cfg, lut)
    e1, e2, u0, v0, Rf, labels, sat_cost, sat_in, c = best
    again = _warp_labels(lab, K, g.o, e1, e2, u0, v0, c, labels.shape)
    assert np.array_equal(labels, again)
    sc, si = _sats(again, lut)
    assert np.array_equal(sat_cost, sc) and np.array_equal(sat_in, si)
    assert score == float(_objective(sc[None], 0, Rf, cfg.alpha))
    assert abs(float(e1 @ g.e1)) < math.cos(math.radians(0.25))  # it turned


def _edge_angle_reference(inplane):
    """The edge angle by the array code: float32 Sobel gradients, their magnitudes and
    angles, the weighted sum of exp(4 i phi)."""
    f = inplane.astype(np.float32)
    gx = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=3)
    sel = (gx != 0) | (gy != 0)
    if np.count_nonzero(sel) < 8:
        return 0.0
    mag = np.hypot(gx[sel], gy[sel])
    z = np.sum(mag * np.exp(4j * np.arctan2(gy[sel], gx[sel])))
    if abs(z) < 1e-6 * mag.sum():
        return 0.0
    return float(np.angle(z) / 4.0)


def test_edge_angle_by_table_equals_the_array_code():
    """Rotated rectangles, random blobs, a grid without edges: the looked-up gradients give
    the array code's angle exactly."""
    from mmlearn.models.perception.detection.grid import _edge_angle

    rng = np.random.default_rng(11)
    grids = [np.zeros((30, 40), bool), np.ones((30, 40), bool)]
    for deg in (0.0, 7.0, 20.0, -33.0):
        img = np.zeros((120, 160), np.uint8)
        box = cv2.boxPoints(((80, 60), (90, 50), deg))
        cv2.fillPoly(img, [np.round(box).astype(np.int32)], 1)
        grids.append(img.astype(bool))
    for _ in range(40):
        a = np.zeros((int(rng.integers(3, 90)), int(rng.integers(3, 90))), bool)
        for _ in range(3):
            r0, c0 = rng.integers(0, a.shape[0]), rng.integers(0, a.shape[1])
            a[r0:r0 + int(rng.integers(1, 40)), c0:c0 + int(rng.integers(1, 40))] = True
        grids.append(a)
    got = [_edge_angle(g) for g in grids]
    assert got == [_edge_angle_reference(g) for g in grids]
    assert got[0] == 0.0 and 2.0 < abs(math.degrees(got[3])) < 10.0  # (7 deg, rasterised)


def test_edge_codes_are_opencv_s_sobel_gradients():
    """The edge cells' codes (gx + 4) 9 + (gy + 4) in raster order: those of OpenCV's 3 x 3
    Sobel gradients with its default border, thin and tiny grids included."""
    from mmlearn.models.perception.detection.grid import _edge_codes

    rng = np.random.default_rng(12)
    for shape in [(1, 1), (1, 6), (5, 1), (2, 2), (2, 7), (3, 3), (17, 23), (40, 31)]:
        for p in (0.2, 0.5):
            u8 = (rng.random(shape) < p).astype(np.uint8)
            gx = cv2.Sobel(u8, cv2.CV_16S, 1, 0, ksize=3).astype(np.int64)
            gy = cv2.Sobel(u8, cv2.CV_16S, 0, 1, ksize=3).astype(np.int64)
            want = ((gx + 4) * 9 + gy + 4).reshape(-1)[((gx != 0) | (gy != 0)).reshape(-1)]
            code = np.empty(u8.size, np.int64)
            n = _edge_codes(u8, code)
            assert n == len(want) and np.array_equal(code[:n], want)
