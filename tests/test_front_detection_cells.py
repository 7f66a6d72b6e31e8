"""The plane stage on the organised image's cell grid (``plane_method = "cells"``): the cell
sums, the closed-form eigenvector, the planes of a wall with a proud front and of a floor,
and the detector run with it."""

import math

import numpy as np
import pytest

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.detection import FrontDetectorConfig, detect_fronts
from mmlearn.models.perception.detection.cells import (
    _cell_sums, _sym_least_eig, find_cell_planes)
from mmlearn.models.perception.synth import (
    DRAWER_SIZE, add_depth_noise, front_pose, kitchen_scene, look_at, render_depth)

K = PinholeIntrinsics.from_fov(640, 480, 58.0)


def _points(depth):
    """Camera-frame points (H, W, 3) float32 of a depth image, NaN where not measured."""
    u = (np.arange(K.width) - K.cx) / K.fx
    v = (np.arange(K.height) - K.cy) / K.fy
    z = np.where(np.isfinite(depth) & (depth > 0), depth, np.nan)
    return np.stack([u[None, :] * z, v[:, None] * z, z], axis=-1).astype(np.float32)


def _wall_with_front(rng, z_face, proud, noise_at_1m=0.0015):
    """A wall at depth ``z_face`` facing the camera with a 0.4 x 0.2 m front ``proud`` in
    front of it, and the floor 0.4 m below the camera (points, m)."""
    u = (np.arange(K.width) - K.cx) / K.fx
    v = (np.arange(K.height) - K.cy) / K.fy
    x, y = u[None, :] * z_face, v[:, None] * z_face
    z = np.full((K.height, K.width), z_face)
    z[(np.abs(x) < 0.2) & (np.abs(y) < 0.1)] = z_face - proud
    with np.errstate(divide="ignore"):
        z_floor = np.where(v[:, None] > 0, 0.4 / v[:, None], np.inf) * np.ones_like(z)
    z = np.minimum(z, z_floor)
    z = z + rng.standard_normal(z.shape) * noise_at_1m * z ** 2
    return _points(z)


def test_cell_sums_are_the_sums_of_each_cells_points():
    rng = np.random.default_rng(0)
    Pc = _wall_with_front(rng, 2.0, 0.1)
    Pc[5, 7] = np.nan
    S = _cell_sums(Pc, 5.0, 8, 60, 80, 1)
    cell = Pc[0:8, 0:8].reshape(-1, 3).astype(np.float64)
    cell = cell[np.isfinite(cell[:, 2])]
    x, y, z = cell.T
    want = [len(cell), x.sum(), y.sum(), z.sum(), x @ x, x @ y, x @ z, y @ y, y @ z, z @ z]
    assert np.allclose(S[0, 0], want, rtol=1e-12)
    assert _cell_sums(Pc, 5.0, 8, 60, 80, 2)[0, 0, 0] == 16  # (5, 7) is not on every 2nd


@pytest.mark.parametrize("seed", range(5))
def test_closed_form_least_eigenvector_agrees_with_eigh(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3, 3))
    A = A @ A.T + np.diag([0.0, 0.0, 1e-3 * seed])
    lam, *v = _sym_least_eig(A[0, 0], A[0, 1], A[0, 2], A[1, 1], A[1, 2], A[2, 2])
    w, V = np.linalg.eigh(A)
    assert lam == pytest.approx(w[0], abs=1e-9)
    assert abs(abs(np.dot(v, V[:, 0])) - 1.0) < 1e-8


@pytest.mark.parametrize("z_face", [1.2, 2.5])
def test_front_proud_of_its_wall_the_wall_and_the_floor_are_planes(z_face):
    """The wall, the front 3 cm proud of it (within L of the wall: its cells' centroids are
    not) and the floor are three planes; support and bbox are on the sample grid."""
    rng = np.random.default_rng(1)
    cfg = FrontDetectorConfig(plane_method="cells")
    planes, _ = find_cell_planes(_wall_with_front(rng, z_face, 0.03), 8, cfg)
    facing = sorted(-p.d / p.n[2] for p in planes if abs(p.n[2]) > 0.995)
    assert any(abs(o - z_face) < 0.01 for o in facing), facing
    assert any(abs(o - (z_face - 0.03)) < 0.01 for o in facing), facing
    floor = [p for p in planes if abs(p.n[1]) > 0.995]
    assert floor and abs(abs(floor[0].d) - 0.4) < 0.01
    front = min(planes, key=lambda p: abs(-p.d / p.n[2] - (z_face - 0.03)))
    r0, r1, c0, c1 = front.bbox
    assert 0 <= r0 < r1 <= 60 and 0 <= c0 < c1 <= 80
    # the front spans 0.4 x 0.2 m: its share of the 8 px grid
    cells = 0.4 * K.fx / z_face / 8 * 0.2 * K.fy / z_face / 8
    assert 0.7 * cells < front.support < 1.3 * cells


def test_detector_with_the_cell_plane_stage_finds_a_drawer():
    rng = np.random.default_rng(3)
    X = front_pose(0.8, 0.1, 0.75)
    cam = X[:3, 3] + 1.8 * np.array([math.cos(0.2), math.sin(0.2), 0.0])
    cam[2] = X[2, 3] + 0.6
    X_WC = look_at(cam, X[:3, 3])
    depth = add_depth_noise(render_depth(kitchen_scene([(DRAWER_SIZE, X, 0.02)]), K, X_WC), rng)
    rects, _ = detect_fronts(depth.astype(np.float32), K, X_WC,
                             FrontDetectorConfig(plane_method="cells"), rng=0)
    err = min(np.linalg.norm(r.center - X[:3, 3]) for r in rects)
    assert err < 0.02
    best = min(rects, key=lambda r: np.linalg.norm(r.center - X[:3, 3]))
    assert abs(best.width - DRAWER_SIZE[0]) < 0.02 and abs(best.height - DRAWER_SIZE[1]) < 0.02


def test_plane_method_is_validated():
    with pytest.raises(ValueError, match="plane_method"):
        FrontDetectorConfig(plane_method="octree").validate()
    with pytest.raises(ValueError, match="cell_pixel_step"):
        FrontDetectorConfig(cell_pixel_step=0).validate()


def test_benchmark_set_overrides_the_config_and_names_a_bad_field(monkeypatch):
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_front_detector.py"
    monkeypatch.syspath_prepend(str(path.parent))
    spec = importlib.util.spec_from_file_location("_bench_front_detector", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    cfg = bench._config(["plane_method=cells", "cell_distance=0.25"])
    assert cfg.plane_method == "cells" and cfg.cell_distance == 0.25
    with pytest.raises(ValueError, match="nofield"):
        bench._config(["nofield=1"])
    with pytest.raises(ValueError, match="plane_method"):
        bench._config(["plane_method=octree"])


def test_cell_regions_are_scipy_8_connected_labels_in_raster_order():
    from scipy import ndimage

    from mmlearn.models.perception.detection import cells

    rng = np.random.default_rng(3)
    for _ in range(50):
        H, W = (int(v) for v in rng.integers(1, 25, 2))
        rr, cc = np.nonzero(rng.random((H, W)) < 0.7)
        img = np.full((H, W), -1, np.int64)
        img[rr, cc] = np.arange(len(rr))
        mask = rng.random(len(rr)) < 0.6
        lab, n = cells._regions_of(mask, img, rr.astype(np.int64), cc.astype(np.int64))
        grid = np.zeros((H, W), bool)
        grid[rr[mask], cc[mask]] = True
        ref, n_ref = ndimage.label(grid, structure=np.ones((3, 3)))
        got = np.zeros((H, W), np.int64)
        got[rr, cc] = lab
        assert n == n_ref and np.array_equal(got, ref)
