"""Offset layers: a drawer pulled out by its first 1-4 cm stands that far proud of
its cabinet's face, within L (or the removal band) of the face's plane. RANSAC counted its
points to the face, so it had no plane of its own and was missed in its first opening frames
at every distance (seeds 6000-6009: 0.016 / 0.027 m missed in all 60 runs). The detector
splits such layers off the largest planes (``layer_planes``, :func:`_offset_layers`)."""

import dataclasses

import numpy as np
import pytest
from conftest import perception_frame_at

from mmlearn.models.perception.evaluation import match_front
from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig, MakeFrontPerceptionDiagram
from mmlearn.models.perception.detection import FrontDetectorConfig, Plane, detect_fronts
from mmlearn.models.perception.detection.labels import FREE, IN_PLANE, _label_images
from mmlearn.models.perception.detection.layers import _offset_layers
from mmlearn.models.common.camera import PinholeIntrinsics

NO_LAYERS = dataclasses.replace(FrontDetectorConfig(), layer_planes=0)


def _drawer_frame(distance, q_target, seed):
    """Noisy depth, X_WC, the true drawer pose, its size, K and q at the first time the
    drawer's stepped opening reaches ``q_target`` (m)."""
    cfg = FrontPerceptionConfig(front="drawer", add_noise=True)
    cfg.camera.distance = distance
    cfg.noise.seed = seed
    P = MakeFrontPerceptionDiagram(cfg)
    depth, X_WC, X_WR, q = perception_frame_at(P, q_target, depth_port="depth_image", t_end=8.0)
    return depth, X_WC, X_WR, P.kinematics.width, P.kinematics.height, P.intrinsics, q


def _hit(frame, cfg, rng):
    depth, X_WC, X, w, h, K, _ = frame
    rects, _ = detect_fronts(depth, K, X_WC, cfg, rng=rng)
    return match_front(rects, X, w, h, max_size_m=0.1)


@pytest.mark.parametrize("distance,q", [(1.8, 0.02), (2.3, 0.03)])
def test_drawer_a_few_cm_proud_of_the_face_is_found(distance, q):
    """Noisy renders (seed 2001, not a seed the thresholds were set on): the drawer pulled
    out by 2-3 cm is found in most of 4 detector seeds with the layers, in none without."""
    frame = _drawer_frame(distance, q, seed=2001)
    assert 0.01 < frame[-1] < 0.045, frame[-1]
    with_layers = [_hit(frame, FrontDetectorConfig(), rng) for rng in range(4)]
    without = [_hit(frame, NO_LAYERS, rng) for rng in range(4)]
    assert sum(h is not None for h in with_layers) >= 3, with_layers
    assert all(h is None for h in without), without
    for h in with_layers:
        if h is not None:
            assert h["pos_error_m"] < 0.03 and h["orient_error_deg"] < 3.0, h


def _synthetic(proud, strip=False, size=(0.4, 0.13)):
    """Depth of a frontal wall 1.5 m away with a rectangle ``proud`` m in front of it (or a
    1.5 cm tall strip with ``strip``), 1 mm noise; the wall's plane and K."""
    K = PinholeIntrinsics(width=320, height=240, fx=280.0, fy=280.0, cx=160.0, cy=120.0)
    rng = np.random.default_rng(0)
    z = np.full((240, 320), 1.5, np.float32)
    w, h = (size[0], 0.015) if strip else size
    u0, u1 = int(160 - 0.5 * w * 280 / 1.5), int(160 + 0.5 * w * 280 / 1.5)
    v0, v1 = int(120 - 0.5 * h * 280 / 1.5), int(120 + 0.5 * h * 280 / 1.5)
    z[v0:v1, u0:u1] -= proud
    z += rng.normal(0.0, 0.001, z.shape).astype(np.float32)
    wall = Plane(n=np.array([0.0, 0.0, -1.0]), d=1.5, support=1000, bbox=(0, 30, 0, 40))
    return z, K, wall, (v0, v1, u0, u1)


def _layers_of(z, K, wall, cfg=None):
    cfg = cfg or FrontDetectorConfig()
    xs = ((np.arange(K.width, dtype=np.float32) - K.cx) / K.fx)[None, :]
    ys = ((np.arange(K.height, dtype=np.float32) - K.cy) / K.fy)[:, None]
    valid = np.isfinite(z)
    L = np.maximum(np.float32(cfg.inlier_distance), cfg.inlier_distance_per_m2 * z * z)
    Lm = np.maximum(np.float32(cfg.surface_distance), cfg.surface_distance_per_m2 * z * z)
    Lband = L + (cfg.removal_factor - 1.0) * cfg.inlier_distance_per_m2 * z * z
    labels, S = _label_images(z, valid, xs, ys, [wall], L, cfg.crossing_angle_deg, 5,
                              (Lm, 5), None, keep_distances=True)
    Pc = np.stack([xs * z, ys * z, z], axis=-1).astype(np.float32)
    return _offset_layers([wall], labels, S, Pc, L, Lband, K, cfg, 8, 4), (xs, ys, L, Lm)


@pytest.mark.parametrize("proud", [0.012, 0.02, 0.027])
def test_a_rectangle_proud_of_a_wall_is_a_layer_of_it(proud):
    """(At 1.5 m the removal band is 2.9 cm: a front farther out keeps its points in RANSAC's
    pool and gets its own plane there.)"""
    z, K, wall, (v0, v1, u0, u1) = _synthetic(proud)
    layers, (xs, ys, L, Lm) = _layers_of(z, K, wall)
    assert len(layers) == 1
    lay = layers[0]
    assert lay.parent == 0
    assert abs(abs(lay.n @ wall.n) - 1.0) < 1e-3
    # the layer's plane through the rectangle: its offset from the wall is the step
    assert lay.d == pytest.approx(1.5 - proud, abs=0.002)
    # its region holds the rectangle; outside it the layer has no in-plane pixel, and inside
    # the wall keeps its own pixels and the layer the rectangle's (the nearer-plane rule)
    r0, r1, c0, c1 = lay.region
    assert r0 <= v0 and r1 >= v1 and c0 <= u0 and c1 >= u1
    valid = np.isfinite(z)
    wall_lab, lay_lab = _label_images(z, valid, xs, ys, [wall, lay], L, 3.0, 5, (Lm, 5), None)
    outside = np.ones(z.shape, bool)
    outside[r0:r1, c0:c1] = False
    assert not (lay_lab[outside] == IN_PLANE).any()
    inner = (slice(v0 + 3, v1 - 3), slice(u0 + 3, u1 - 3))
    assert (lay_lab[inner] == IN_PLANE).mean() > 0.95
    assert (wall_lab[inner] == IN_PLANE).mean() < 0.05
    ring = np.zeros(z.shape, bool)
    ring[max(r0, v0 - 12):v0 - 3, u0:u1] = True
    assert (lay_lab[ring] == FREE).mean() > 0.95   # the wall behind the layer: seen through it
    assert (wall_lab[ring] == IN_PLANE).mean() > 0.95


def test_flush_surfaces_and_thin_strips_are_no_layers():
    z, K, wall, _ = _synthetic(0.0)
    assert _layers_of(z, K, wall)[0] == []
    z, K, wall, _ = _synthetic(0.02, strip=True)   # a countertop's edge: 1.5 cm tall
    assert _layers_of(z, K, wall)[0] == []
    z, K, wall, _ = _synthetic(0.02)
    assert _layers_of(z, K, wall, dataclasses.replace(FrontDetectorConfig(),
                                                      layer_planes=0))[0] == []


@pytest.mark.parametrize("key,value", [("layer_planes", -1), ("layer_max_layers", 1.5),
                                       ("layer_min_pixels", -3), ("layer_min_size", -0.1),
                                       ("layer_min_size", float("nan"))])
def test_layer_config_errors(key, value):
    with pytest.raises(ValueError, match=key):
        dataclasses.replace(FrontDetectorConfig(), **{key: value}).validate()


def test_a_plane_seen_edge_on_gives_no_huge_opening():
    """A parent plane nearly through the camera's centre (seen edge-on: its own depth on a ray
    is anything) took the opening's size from that depth, 6.5 TiB of kernel (a door at 0.8 m,
    seed 7000); the size now comes from the measured depth and is capped."""
    z, K, _, _ = _synthetic(0.0)
    # the plane x = 0.5 z through the camera's centre: it cuts the wall along column 300,
    # and the ray through its region's centre (column 160) meets it at z = 2e-7 m
    n = np.array([1.0, 0.0, -0.5]) / np.sqrt(1.25)
    edge_on = Plane(n=n, d=1e-7, support=1000, bbox=(0, 30, 0, 40))
    layers, _ = _layers_of(z, K, edge_on)
    assert layers == []


def test_the_polish_cannot_reject_an_accepted_rectangle(monkeypatch):
    """The rotation polish is a refinement: when the rectangle it returns fails precision or
    recall, the accepted rectangle it started from is kept (a drawer opened 0.25 m at 2.2 m:
    the polish cut its height from 0.116 to 0.082 m and its recall fell to 0.689)."""
    import mmlearn.models.perception.detection.pipeline as fd
    z, K, wall, _ = _synthetic(0.05)     # a box 5 cm proud: a front of its own
    z[:, :8] = np.nan                    # (its wall's edges not touching the border)
    X_WC = None                          # (camera frame, gravity unknown: every plane searched)
    base, _ = fd.detect_fronts(z, K, X_WC, rng=0)
    assert any(abs(r.width - 0.4) < 0.03 and abs(r.height - 0.13) < 0.03 for r in base)
    orig = fd._polish_rotations

    def shrink(jobs, K_, cfg, lut):   # a polish that cuts every rectangle to a sliver
        out = orig(jobs, K_, cfg, lut)
        # (each result: (score, (e1, e2, u0, v0, rectangle, labels, tables..., cell)))
        return [(o[0], o[1][:4] + (np.array([o[1][4][0], o[1][4][0] + 2, o[1][4][2],
                                             o[1][4][2] + 2]),) + o[1][5:]) for o in out]

    monkeypatch.setattr(fd, "_polish_rotations", shrink)
    cut, _ = fd.detect_fronts(z, K, X_WC, rng=0)
    assert any(abs(r.width - 0.4) < 0.03 and abs(r.height - 0.13) < 0.03 for r in cut)


def _tilted(plane_tilt_deg):
    """A flat frontal wall 1.5 m away (1 mm noise) and a plane through its centre tilted by
    ``plane_tilt_deg`` about the horizontal axis: a plane fitted across two surfaces, off the
    wall by up to ~2 cm at its top and bottom."""
    z, K, _, _ = _synthetic(0.0)
    a = np.radians(plane_tilt_deg)
    n = np.array([0.0, np.sin(a), -np.cos(a)])
    return z, K, Plane(n=n, d=1.5 * np.cos(a), support=1000, bbox=(0, 30, 0, 40))


def test_a_ramp_under_a_misfitted_plane_is_no_layer(monkeypatch):
    """The parent plane tilted 2 deg against the surface: its lower part lies a few mm to
    2 cm in front of the plane, like a pulled-out front, but the parent's own pixels around
    it continue the "layer" (a ramp, not a step): no layer (an operate-scene door and the
    rail behind it were split like this, operate_trials left_door seed 3). Without the ring
    test the ramp is taken for a layer."""
    import mmlearn.models.perception.detection.layers as fd
    z, K, parent = _tilted(2.0)
    assert _layers_of(z, K, parent)[0] == []
    monkeypatch.setattr(fd, "_LAYER_MAX_RING", 1.0)
    assert len(_layers_of(z, K, parent)[0]) >= 1


def test_a_recess_is_no_layer():
    """Only fronts standing proud of the plane (towards the camera) are layers: a panel 2 cm
    behind the wall (a rail behind a door) is not."""
    z, K, wall, _ = _synthetic(-0.02)
    assert _layers_of(z, K, wall)[0] == []
