"""Unit tests of the detector's acceptance-check and side-refinement helpers
(models/perception/detection/check.py, edges.py)."""

import numpy as np

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.detection.check import _corners_px, _inside_border
from mmlearn.models.perception.detection.edges import _edge_crossing, _first_run

K = PinholeIntrinsics.from_fov(640, 480, 58.0)
E1, E2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


def test_corners_project_symmetrically_and_the_border_test_agrees_with_them():
    c = np.array([0.0, 0.0, 2.0])
    u, v, z = _corners_px(c, E1, E2, 0.4, 0.6, K)
    assert np.allclose(z, 2.0)
    assert np.allclose(u[[0, 3]] + u[[1, 2]], 2 * K.cx)
    assert np.allclose(v[[0, 1]] + v[[2, 3]], 2 * K.cy)
    assert _inside_border(c, E1, E2, 0.4, 0.6, K, margin=5)
    # a front whose corner leaves the image (or lies behind the camera) fails
    assert not _inside_border(np.array([1.5, 0.0, 2.0]), E1, E2, 0.4, 0.6, K, margin=5)
    assert not _inside_border(np.array([0.0, 0.0, -2.0]), E1, E2, 0.4, 0.6, K, margin=5)
    # the margin counts: a front 3 px inside the border passes at margin 2, fails at 4
    u_edge = K.width - 1 - 3
    x = (u_edge - K.cx) * 2.0 / K.fx - 0.2
    assert _inside_border(np.array([x, 0.0, 2.0]), E1, E2, 0.4, 0.6, K, margin=2)
    assert not _inside_border(np.array([x, 0.0, 2.0]), E1, E2, 0.4, 0.6, K, margin=4)


def test_first_run_finds_the_first_k_trues_in_a_row():
    m = [False, True, False, True, True, True, False]
    assert _first_run(m, 3) == 3
    assert _first_run(m, 1) == 1
    assert _first_run(m, 4) == len(m)  # no run of 4, and the end is not reached by a True
    assert _first_run([False, False, True], 3) == 2  # the end counts as an endless run


def test_edge_crossing_interpolates_where_the_in_plane_share_falls_below_half():
    pos = np.arange(12, dtype=float) * 0.01
    inside = np.array([10.0] * 6 + [0.0] * 6)
    outside = 10.0 - inside
    level = np.zeros(12)
    x = _edge_crossing(inside, outside, level, pos, step=0.01)
    assert x is not None and pos[5] <= x <= pos[6]
    # a profile that starts outside has no side to end
    assert _edge_crossing(outside, inside, level, pos, step=0.01) is None
