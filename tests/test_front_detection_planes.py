"""Sequential RANSAC (thesis 5.1.1): a front standing proud of a larger parallel plane is a
plane of its own, and rounds that only clear fragments from the pool do not take a plane's
turn."""

import numpy as np
import pytest

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.detection import FrontDetectorConfig
from mmlearn.models.perception.detection.planes import find_planes

K = PinholeIntrinsics.from_fov(640, 480, 58.0)


def _plane_points(rng, z_face=1.0, proud=0.018, noise=0.001):
    """Sample-grid points (every 8th pixel of a 640 x 480 camera) of a wall at z_face with a
    0.16 x 0.16 m panel standing ``proud`` in front of it (camera frame, m)."""
    rows, cols = np.mgrid[0:60, 0:80]
    u, v = cols.ravel() * 8 + 4.0, rows.ravel() * 8 + 4.0
    x, y = (u - K.cx) / K.fx * z_face, (v - K.cy) / K.fy * z_face
    panel = (np.abs(x) < 0.08) & (np.abs(y) < 0.08)
    z = np.where(panel, z_face - proud, z_face) + rng.normal(0, noise, x.shape)
    pts = np.column_stack([(u - K.cx) / K.fx * z, (v - K.cy) / K.fy * z, z])
    return pts, np.column_stack([rows.ravel(), cols.ravel()]), panel


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_front_standing_proud_of_a_larger_parallel_plane_is_its_own_plane(seed):
    """A front 1.8 cm proud of its carcass with L = 0.01 m: after the carcass' plane, the
    front's points stay in the pool (the removal band is L plus the noise part, not 2 L) and
    its plane is not taken for a copy of the carcass' (centroid farther than L)."""
    rng = np.random.default_rng(seed)
    pts, rc, panel = _plane_points(rng)
    cfg = FrontDetectorConfig(inlier_distance=0.01)
    planes = find_planes(pts, rc, (60, 80), cfg, np.random.default_rng(seed))
    offsets = sorted(round(-p.d / p.n[2], 3) for p in planes if abs(p.n[2]) > 0.99)
    assert any(abs(o - 0.982) < 0.003 for o in offsets), offsets
    assert any(abs(o - 1.0) < 0.003 for o in offsets), offsets


def test_rounds_spent_on_fragments_do_not_take_a_planes_turn():
    """Sequential RANSAC keeps up to max_planes planes: rounds that only clear the pool (the
    largest region of the best hypothesis' inliers below min_plane_points: here 12 coplanar
    4 x 4 fragments, e.g. a far wall seen through clutter) do not use up a plane's turn. With
    the rounds counted against max_planes (8) the front behind them (42 samples, smaller than
    the fragments' 192) was never reached (a drawer 45 deg off the normal on a filtered image
    lost its plane this way)."""
    rc, pts = [], []

    def patch(r0, c0, nr, nc, z):
        for r in range(r0, r0 + nr):
            for c in range(c0, c0 + nc):
                rc.append((r, c))
                pts.append(((c - 40) * 0.01 * z, (r - 30) * 0.01 * z, z))

    for r0 in (5, 15, 25):
        for c0 in (5, 15, 25, 35):
            patch(r0, c0, 4, 4, 2.0)  # 16 samples each, min_plane_points 20
    patch(40, 60, 6, 7, 1.0)
    cfg = FrontDetectorConfig()
    assert cfg.max_planes == 8 and cfg.min_plane_points == 20
    planes = find_planes(np.array(pts, float), np.array(rc), (60, 80), cfg,
                         np.random.default_rng(0))
    assert len(planes) == 1
    assert abs(planes[0].n[2]) > 0.999 and abs(abs(planes[0].d) - 1.0) < 1e-6
    assert planes[0].support == 42
