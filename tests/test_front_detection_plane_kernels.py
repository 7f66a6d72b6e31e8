"""The plane stage's compiled passes against plain array code: the frame arrays and the sample
grid bit for bit, the sample grid's regions against OpenCV's, and whole RANSAC runs against
rounds written with numpy and OpenCV (the same planes, supports and bounding boxes)."""

import math

import cv2
import numpy as np
import pytest
from plane_reference import svd_plane

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.detection import FrontDetectorConfig
from mmlearn.models.perception.detection import pipeline as P
from mmlearn.models.perception.detection.planes import (_components, _hypotheses, _largest_region,
                                                        find_planes)
from mmlearn.models.perception.synth import (DOOR_SIZE, add_depth_noise, front_pose, kitchen_scene,
                                             look_at, render_depth)

K = PinholeIntrinsics.from_fov(160, 120, 58.0)


def _frame_arrays_reference(d, K, cfg):
    """The per-pixel arrays by numpy expressions (float32, in the kernel's operation order)."""
    f32 = np.float32
    xs = ((np.arange(K.width, dtype=f32) - f32(K.cx)) * f32(1.0 / K.fx))[None, :]
    ys = ((np.arange(K.height, dtype=f32) - f32(K.cy)) * f32(1.0 / K.fy))[:, None]
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(d) & (d > 0)
    dz = np.where(valid, d, f32(np.nan))
    Pc = np.dstack([xs * dz, ys * dz, dz]).astype(f32)
    z0 = np.where(valid, d, f32(0.0))
    sq = (lambda a: (f32(a) * z0) * z0)
    Limg = np.maximum(sq(cfg.inlier_distance_per_m2), f32(cfg.inlier_distance))
    surf = np.maximum(sq(cfg.surface_distance_per_m2), f32(cfg.surface_distance))
    band = sq((cfg.removal_factor - 1.0) * cfg.inlier_distance_per_m2)
    Lband = np.maximum(band, f32(0.0)) + Limg
    return valid, z0, xs, ys, Pc, Limg, surf, Lband


def _depth(seed):
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.3, 6.0, (K.height, K.width)).astype(np.float32)
    d[rng.random(d.shape) < 0.05] = np.nan
    d.flat[rng.choice(d.size, 8, replace=False)] = [np.inf, -np.inf, 0.0, -1.0, 1e-30, 5.0,
                                                    np.float32(5.0000005), 4.9999995]
    return d


@pytest.mark.parametrize("seed", [0, 1])
def test_frame_arrays_and_sample_grid_match_the_array_code_bit_for_bit(seed):
    d = _depth(seed)
    cfg = FrontDetectorConfig(max_depth=5.0, ransac_stride_px=3 + seed)
    got = P._frame_arrays(d, K, cfg)
    ref = _frame_arrays_reference(d, K, cfg)
    for g, r in zip(got, ref):
        assert g.shape == r.shape and g.dtype == r.dtype
        assert np.array_equal(g.view(np.uint8), r.view(np.uint8))
    f = P._prepare_frame(d, got, K, np.eye(4), None, cfg)
    st, off = cfg.ransac_stride_px, cfg.ransac_stride_px // 2
    sub = ref[0][off::st, off::st] & (d[off::st, off::st] <= np.float32(cfg.max_depth))
    rr, cc = np.nonzero(sub)
    assert tuple(f.grid_shape) == sub.shape
    assert np.array_equal(f.grid_rc, np.column_stack([rr, cc]))
    assert np.array_equal(f.sample_pts, ref[4][off::st, off::st][rr, cc].astype(np.float64))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_regions_of_points_in_any_order_are_numbered_by_their_first_cell(seed):
    """Points listed in a random order: the same partition as OpenCV's 8-connected
    components, numbered from 1 in the raster order of each region's first cell; the largest
    region, and of equally large ones the first."""
    rng = np.random.default_rng(seed)
    H, W = 25, 33
    cells = np.flatnonzero(rng.random(H * W) < 0.5)
    rc = np.column_stack(np.divmod(rng.permutation(cells), W))
    img = np.zeros((H, W), np.uint8)
    img[rc[:, 0], rc[:, 1]] = 1
    n_ref, ref = cv2.connectedComponents(img, connectivity=8)
    sel = np.flatnonzero(rng.random(len(rc)) < 0.99)
    sel = sel[np.isin(rc[sel, 0] * W + rc[sel, 1], cells)]
    lab = _components(sel, rc, (H, W))
    # numbering: the first (raster) cell of region k comes before that of region k + 1
    flat = rc[sel, 0] * W + rc[sel, 1]
    first = [flat[lab == k].min() for k in range(1, lab.max() + 1)]
    assert first == sorted(first)
    pairs = set(zip(lab.tolist(), ref[rc[sel, 0], rc[sel, 1]].tolist()))
    assert len(pairs) == len(set(lab.tolist()))  # a bijection onto OpenCV's regions
    sizes = np.bincount(lab)
    big = _largest_region(sel, rc, (H, W))
    assert len(big) == sizes.max() and np.all(lab[np.isin(sel, big)] == np.argmax(sizes))
    assert np.array_equal(big, sel[np.isin(sel, big)])  # in the order of sel
    # two equally large regions: the one whose first cell comes first
    two = np.array([[0, 0], [0, 1], [5, 5], [5, 6]])
    assert np.array_equal(_largest_region(np.array([2, 3, 0, 1]), two, (8, 8)), [0, 1])


def _largest_reference(sel, rc, shape):
    img = np.zeros(shape, np.uint8)
    img[rc[sel, 0], rc[sel, 1]] = 1
    _, lab = cv2.connectedComponents(img, connectivity=8, ltype=cv2.CV_32S)
    lab = lab[rc[sel, 0], rc[sel, 1]]
    if len(sel) == 0:
        return sel
    sizes = np.bincount(lab)
    best = [k for k in range(1, len(sizes)) if sizes[k] == sizes.max()]
    flat = rc[sel, 0] * shape[1] + rc[sel, 1]
    k = min(best, key=lambda q: flat[lab == q].min())  # (the first in raster order)
    return sel[lab == k]



def _find_planes_reference(pts, rc, shape, cfg, rng):
    """Sequential RANSAC written with numpy and OpenCV: counts by the float32 matrix product,
    regions by OpenCV's components, least squares by the SVD; the same draws."""
    Lp = np.maximum(cfg.inlier_distance, cfg.inlier_distance_per_m2 * pts[:, 2] ** 2)
    Lr = Lp + (cfg.removal_factor - 1.0) * cfg.inlier_distance_per_m2 * pts[:, 2] ** 2
    m = len(pts)
    r = max(1, int(round(cfg.ransac_local_radius_px / cfg.ransac_stride_px)))
    Wp = shape[1] + 2 * r
    lookup = np.full((shape[0] + 2 * r) * Wp, -1, np.int64)
    flat_rc = (rc[:, 0] + r) * Wp + (rc[:, 1] + r)
    lookup[flat_rc] = np.arange(m)
    active, planes = np.ones(m, bool), []
    for _ in range(2 * cfg.max_planes):
        if len(planes) >= cfg.max_planes:
            break
        idx = np.flatnonzero(active)
        if len(idx) < max(3, cfg.min_plane_points):
            break
        hyp = _hypotheses(pts, idx, lookup, flat_rc, r, Wp, cfg.ransac_hypotheses, rng)
        if hyp is None:
            break
        N32, dd32 = hyp[0].astype(np.float32), hyp[1].astype(np.float32)
        D = np.abs(N32 @ pts[idx].T.astype(np.float32) + dd32[:, None])
        inl_all = D <= Lp[idx].astype(np.float32)
        counts = inl_all.sum(axis=1)
        best = int(np.argmax(counts))
        if counts[best] < cfg.min_plane_points:
            break
        inl = _largest_reference(idx[inl_all[best]], rc, shape)
        n, d = hyp[0][best], hyp[1][best]
        for shrink in (1.0, 0.5, 1.0):
            if len(inl) < 3:
                break
            n, d = svd_plane(pts[inl])
            inl = _largest_reference(idx[np.abs(pts[idx] @ n + d) <= shrink * Lp[idx]], rc,
                                     shape)
        loose = idx[np.abs(pts[idx] @ n + d) <= Lr[idx]]
        img = np.zeros(shape, np.uint8)
        img[rc[loose, 0], rc[loose, 1]] = 1
        _, lab = cv2.connectedComponents(img, connectivity=8, ltype=cv2.CV_32S)
        touched = set(lab[rc[inl, 0], rc[inl, 1]].tolist())
        gone = np.concatenate([loose[np.isin(lab[rc[loose, 0], rc[loose, 1]],
                                             list(touched))], inl])
        active[gone] = False
        lookup[flat_rc[gone]] = -1
        if len(inl) < cfg.min_plane_points:
            continue
        Lq = max(cfg.inlier_distance, cfg.inlier_distance_per_m2 * d * d)
        cen = pts[inl].mean(axis=0)
        if any(abs(q[0] @ n) > math.cos(math.radians(5.0)) and abs(q[0] @ cen + q[1]) < Lq
               for q in planes):
            continue
        planes.append((n, d, len(inl), (rc[inl, 0].min(), rc[inl, 0].max() + 1,
                                        rc[inl, 1].min(), rc[inl, 1].max() + 1)))
    return planes


@pytest.mark.parametrize("seed", [0, 1])
def test_ransac_rounds_match_numpy_and_opencv_rounds(seed):
    """A rendered kitchen frame (wall, floor, cabinet, a door pulled out): the compiled rounds
    find the planes of the array code: the same supports and bounding boxes, normals and
    offsets to rounding."""
    rng = np.random.default_rng(seed)
    Kf = PinholeIntrinsics.from_fov(640, 480, 58.0)
    X = front_pose(0.62 + rng.uniform(0.1, 0.3), rng.uniform(-0.3, 0.3), 0.45)
    cam = X[:3, 3] + 1.8 * np.array([math.cos(0.3), math.sin(0.3), 0.0])
    cam[2] = X[2, 3] + 0.6
    X_WC = look_at(cam, X[:3, 3])
    depth = add_depth_noise(render_depth(kitchen_scene([(DOOR_SIZE, X, 0.02)]), Kf, X_WC), rng)
    cfg = FrontDetectorConfig()
    d, Xc = P._check_inputs(depth, Kf, X_WC)
    f = P._prepare_frame(d, P._frame_arrays(d, Kf, cfg), Kf, Xc, None, cfg)
    got = find_planes(f.sample_pts, f.grid_rc, f.grid_shape, cfg, np.random.default_rng(seed))
    ref = _find_planes_reference(f.sample_pts, f.grid_rc, tuple(f.grid_shape), cfg,
                                 np.random.default_rng(seed))
    assert len(got) == len(ref) >= 3
    for p, (n, dd, support, bbox) in zip(got, ref):
        assert p.support == support and p.bbox == tuple(int(v) for v in bbox)
        assert np.allclose(p.n, n, atol=1e-9) and abs(p.d - dd) < 1e-9


def test_refits_of_many_planes_in_one_call_are_the_refits_one_by_one():
    """A wall with a box in front of part of it: the wall, the box's face, a plane that no
    pixel lies near (stays as it was) and one turned 20 deg from the wall (its refit would
    turn it back by more than 10 deg: stays), refitted together and one by one; the wall's
    refit against the SVD plane of its pixels within L, then L / 2."""
    from mmlearn.models.perception.detection.planes import (Plane, refine_plane_fullres,
                                                            refine_planes_fullres)
    rng = np.random.default_rng(8)
    Kf = PinholeIntrinsics.from_fov(320, 240, 58.0)
    v, u = np.mgrid[0:240, 0:320].astype(np.float64)
    x, y = (u - Kf.cx) / Kf.fx, (v - Kf.cy) / Kf.fy
    n_wall = np.array([0.15, -0.05, -1.0]) / np.linalg.norm([0.15, -0.05, -1.0])
    z = 2.0 / -(n_wall[0] * x + n_wall[1] * y + n_wall[2]) + rng.normal(0, 0.003, x.shape)
    z[60:140, 100:220] -= 0.15
    z[rng.random(z.shape) < 0.02] = np.nan
    Pc = np.dstack([x * z, y * z, z]).astype(np.float32)
    L = np.maximum(0.02, 0.004 * np.nan_to_num(z) ** 2).astype(np.float32)
    a = np.radians(20.0)
    turned = np.array([np.sin(a), 0.0, -np.cos(a)])
    planes = [Plane(n=n_wall, d=2.0, support=900, bbox=(0, 30, 0, 40)),
              Plane(n=n_wall, d=1.85, support=150, bbox=(8, 17, 12, 27)),
              Plane(n=np.array([0.0, 0.0, -1.0]), d=9.0, support=30, bbox=(0, 5, 0, 5)),
              Plane(n=turned, d=2.0, support=40, bbox=(0, 30, 0, 40))]
    together = refine_planes_fullres(planes, Pc, L, 8, 4, max_points=5000)
    for pl, got in zip(planes, together):
        one = refine_plane_fullres(pl, Pc, L, 8, 4, max_points=5000)
        assert np.array_equal(got.n, one.n) and got.d == one.d and got.bbox == pl.bbox
    assert together[2] is planes[2] and together[3] is planes[3]
    assert together[0] is not planes[0] and together[1] is not planes[1]
    step = int(math.ceil(math.sqrt(240 * 320 / 5000)))
    P3 = Pc[::step, ::step].reshape(-1, 3).astype(np.float64)
    Ls = L[::step, ::step].reshape(-1).astype(np.float64)
    P3, Ls = P3[np.isfinite(P3[:, 2])], Ls[np.isfinite(P3[:, 2])]
    n, d = n_wall, 2.0
    for shrink in (1.0, 0.5):
        n, d = svd_plane(P3[np.abs(P3 @ n + d) <= shrink * Ls])
    assert np.allclose(together[0].n, n, atol=1e-9) and abs(together[0].d - d) < 1e-9
    assert refine_planes_fullres([], Pc, L, 8, 4) == []
