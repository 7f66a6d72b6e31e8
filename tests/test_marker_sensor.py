import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mmlearn.diagrams import MakeSceneDiagram, SceneConfig
from mmlearn.systems import CameraConfig, MarkerSensorConfig


def _scene(sensor: MarkerSensorConfig, *, arm="7dof", q=None, **kw):
    scene = MakeSceneDiagram(SceneConfig(arm=arm, sensor=sensor, **kw))
    ctx = scene.diagram.CreateDefaultContext()
    if q is not None:
        scene.set_joint_positions(ctx, q)
    return scene, ctx, scene.sensor.GetMyContextFromRoot(ctx)


def _true(scene, ctx):
    plant = scene.plant
    pctx = plant.GetMyContextFromRoot(ctx)
    return [plant.GetFrameByName(m + "_marker", scene.robot).CalcPoseInWorld(pctx)
            for m in scene.sensor.marker_ids]


def test_noise_free_sensor_returns_true_marker_poses():
    q = [0.3, -0.4, 0.2, 0.5, -0.1, 0.3, 0.02]
    scene, ctx, sctx = _scene(MarkerSensorConfig(cameras=[]), q=q, cabinet=False)
    obs = scene.sensor.observe(sctx)
    assert obs.marker_ids == [f"x{i}" for i in range(1, 11)]
    assert obs.visible.all()
    for X_obs, X_true in zip(obs.poses, _true(scene, ctx)):
        np.testing.assert_allclose(X_obs.GetAsMatrix4(), X_true.GetAsMatrix4(), atol=1e-12)
    arr = obs.as_array()
    assert arr.shape == (10, 7) and np.all(np.isfinite(arr))


def test_noise_statistics_match_sigma():
    sp, so = 0.05, math.radians(10)
    scene, ctx, sctx = _scene(MarkerSensorConfig(cameras=[], sigma_pos=sp, sigma_orient=so),
                              cabinet=False)
    true = _true(scene, ctx)
    dp, dr = [], []
    for k in range(300):
        obs = scene.sensor.observe(sctx, frame=k)
        for X, T in zip(obs.poses, true):
            dp.append(X.translation() - T.translation())
            R = T.rotation().matrix().T @ X.rotation().matrix()
            dr.append(Rotation.from_matrix(R).as_rotvec())
    dp, dr = np.array(dp), np.array(dr)
    assert np.abs(dp.mean(axis=0)).max() < 0.01
    np.testing.assert_allclose(dp.std(axis=0), sp, rtol=0.08)
    np.testing.assert_allclose(dr.std(axis=0), so, rtol=0.08)


def test_outliers_appear_at_the_configured_rate_inside_the_workspace():
    gamma = 0.3
    cfg = MarkerSensorConfig(cameras=[], gamma=gamma, workspace_min=[-1, -1, 0],
                             workspace_max=[1, 1, 2])
    scene, ctx, sctx = _scene(cfg, cabinet=False)
    flags = []
    true = _true(scene, ctx)
    for k in range(200):
        obs = scene.sensor.observe(sctx, frame=k)
        flags.extend(obs.outlier)
        for X, T, o in zip(obs.poses, true, obs.outlier):
            p = X.translation()
            if o:
                assert np.all(p >= [-1, -1, 0]) and np.all(p <= [1, 1, 2])
            else:
                assert np.linalg.norm(p - T.translation()) < 1e-9
    rate = np.mean(flags)
    n = len(flags)
    assert abs(rate - gamma) < 3 * math.sqrt(gamma * (1 - gamma) / n)


def test_dropout_rate():
    scene, ctx, sctx = _scene(MarkerSensorConfig(cameras=[], dropout=0.25), cabinet=False)
    vis = np.concatenate([scene.sensor.observe(sctx, frame=k).visible for k in range(200)])
    assert abs((1 - vis.mean()) - 0.25) < 0.04


def test_markers_facing_away_are_invisible():
    cam = CameraConfig(position=[2.5, 0, 0.8], look_at=[0, 0, 0.7])
    scene, ctx, sctx = _scene(MarkerSensorConfig(cameras=[cam], check_occlusion=False),
                              cabinet=False)
    assert scene.sensor.observe(sctx).visible.all()  # all markers on the +x side
    # turn the arm around (q1 = pi): the markers of x3 .. x10 now face away
    q = [math.pi, 0, 0, 0, 0, 0, 0]
    scene, ctx, sctx = _scene(MarkerSensorConfig(cameras=[cam], check_occlusion=False),
                              q=q, cabinet=False)
    vis = scene.sensor.observe(sctx).visible
    assert vis[:2].all() and not vis[2:].any()


def test_markers_outside_the_field_of_view_are_invisible():
    cam = CameraConfig(position=[2.5, 0, 1.5], look_at=[0, 0, 1.5], fov_x_deg=30,
                       fov_y_deg=20)
    scene, ctx, sctx = _scene(MarkerSensorConfig(cameras=[cam], check_occlusion=False),
                              cabinet=False)
    obs = scene.sensor.observe(sctx)
    z = np.array([X.translation()[2] for X in _true(scene, ctx)])
    # vertical half-angle 10 deg at 2.5 m: only markers above ~1.06 m are in view
    np.testing.assert_array_equal(obs.visible, z > 1.5 - 2.5 * math.tan(math.radians(10)))
    assert obs.visible.any() and not obs.visible.all()


def test_markers_occluded_by_geometry_are_invisible():
    # the cabinet (0.9 m high, 0.45 m deep, front at x = 2.0) stands between a low camera
    # and the arm
    cx, cz = 5.0, 0.7
    cam = CameraConfig(position=[cx, 0, cz], look_at=[0, 0, cz], fov_x_deg=90, fov_y_deg=90)
    kw = dict(cabinet=True, cabinet_pose=[2.0, 0.0, 0.0])
    scene, ctx, sctx = _scene(MarkerSensorConfig(cameras=[cam], check_occlusion=False), **kw)
    assert scene.sensor.observe(sctx).visible.all()
    scene, ctx, sctx = _scene(MarkerSensorConfig(cameras=[cam], check_occlusion=True), **kw)
    vis = scene.sensor.observe(sctx).visible
    P = np.array([X.translation() for X in _true(scene, ctx)])
    # the line of sight descends towards the camera, so it passes lowest over the
    # cabinet's front (doors at x ~ 2.03): hidden when it is below the 0.9 m top there
    h = cz + (P[:, 2] - cz) * (cx - 2.03) / (cx - P[:, 0])
    hidden, clear = h < 0.9 - 0.01, h > 0.9 + 0.01
    clear[-1] = False  # x10's marker sits between the fingers, behind x9: never in sight
    assert hidden.sum() >= 5 and clear.sum() >= 3
    assert not vis[hidden].any()
    assert vis[clear].all()


def test_same_seed_same_noise_other_seed_other_noise():
    def draw(seed):
        cfg = MarkerSensorConfig(cameras=[], sigma_pos=0.01, gamma=0.2, seed=seed)
        scene, ctx, sctx = _scene(cfg, arm="2dof", cabinet=False)
        return scene.sensor.observe(sctx, frame=3).as_array()

    np.testing.assert_array_equal(draw(1), draw(1))
    assert not np.allclose(draw(1), draw(2))


@pytest.mark.parametrize("kw,msg", [
    (dict(sigma_pos=-0.1), "sigma_pos"),
    (dict(sigma_orient=-1.0), "sigma_orient"),
    (dict(gamma=1.0), "gamma"),
    (dict(gamma=-0.1), "gamma"),
    (dict(rate_hz=0.0), "rate_hz"),
    (dict(dropout=1.5), "dropout"),
    (dict(bodies=["x1", "elbow"]), "unknown body 'elbow'"),
    (dict(sigma_pos=float("nan")), "sigma_pos must be finite"),
])
def test_invalid_configs_raise_clear_errors(kw, msg):
    with pytest.raises(ValueError, match=msg):
        MakeSceneDiagram(SceneConfig(arm="2dof", cabinet=False,
                                     sensor=MarkerSensorConfig(**kw)))


def test_misspelled_yaml_key_is_rejected(tmp_path):
    from mmlearn.apps.common.cli import load_config

    f = tmp_path / "scene.yaml"
    f.write_text("arm: 2dof\nsensor:\n  sigma_poss: 0.1\n")
    with pytest.raises(ValueError, match="sigma_poss"):
        load_config(f, SceneConfig)
    f.write_text("arm: 2dof\nsensor:\n  sigma_pos: 0.1\n")
    assert load_config(f, SceneConfig).sensor.sigma_pos == 0.1
