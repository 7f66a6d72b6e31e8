"""The camera marker sensor's mirror test on exact and noisy depth, the depth_noise option,
and --sensor camera / --camera-depth on the apps (synthetic planes and short renders)."""

import math

import cv2
import numpy as np
import pytest

from pydrake.math import RigidTransform, RotationMatrix, RollPitchYaw

from mmlearn.diagrams.common.marker_camera import MarkerRig
from mmlearn.models.common.depth_noise import DepthNoiseConfig, apply_depth_noise
from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.common.marker_detection import DetectorConfig, mirror_test_from_depth
from mmlearn.systems.common.camera_marker_sensor import (CameraMarkerSensorConfig,
                                                         marker_normal_from_depth)
from mmlearn.systems.common.marker_sensor import CameraConfig

# 320 x 240 crop with the focal length of the 1920 x 1440 marker cameras (fov_y 55 deg)
F = 0.5 * 1440 / math.tan(math.radians(27.5))
W, H = 320, 240
K = np.array([[F, 0, W / 2 - 0.5], [0, F, H / 2 - 0.5], [0, 0, 1]])
PK = PinholeIntrinsics(W, H, F, F, W / 2 - 0.5, H / 2 - 0.5)
S = 0.02
OBJ = np.array([[-S, S, 0], [S, S, 0], [S, -S, 0], [-S, -S, 0]])


def _scene(rng, dist, tilt_deg, corner_noise_px=0.1):
    """A 0.04 m marker ``dist`` m ahead tilted by ``tilt_deg`` about a random in-plane
    axis, on an infinite plane (its carrier): (exact depth, corners, [T_a, T_b], index of
    the right solution, angle between the solutions in degrees)."""
    p = np.array([rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), dist])
    z = -p / np.linalg.norm(p)
    x = np.cross([0.0, -1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R0 = np.column_stack([x, np.cross(z, x), z])
    phi = rng.uniform(0, 2 * np.pi)
    tilt = cv2.Rodrigues(math.radians(tilt_deg) * np.array([np.cos(phi), np.sin(phi), 0]))[0]
    spin = cv2.Rodrigues(np.array([0, 0, rng.uniform(0, 2 * np.pi)]))[0]
    R = R0 @ tilt @ spin
    n = R[:, 2]
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    ray = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones((H, W))], -1)
    depth = ((n @ p) / (ray @ n)).astype(np.float32)
    uv = (K @ ((R @ OBJ.T).T + p).T).T
    uv = uv[:, :2] / uv[:, 2:] + rng.normal(0, corner_noise_px, (4, 2))
    k, rv, tv, _ = cv2.solvePnPGeneric(OBJ, uv, K, None, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    Ts = []
    for i in range(k):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = cv2.Rodrigues(rv[i])[0], tv[i].ravel()
        Ts.append(T)
    ang = [math.degrees(math.acos(np.clip(T[:3, 2] @ n, -1, 1))) for T in Ts]
    between = math.degrees(math.acos(np.clip(Ts[0][:3, 2] @ Ts[1][:3, 2], -1, 1)))
    return depth, uv, Ts, int(np.argmin(ang)), between


RULE = dict(min_log_ratio=3.0, max_angle_deg=15.0, max_excess_chi2=13.8)


def test_mirror_test_on_noisy_depth_picks_the_right_solution():
    """A 0.04 m marker 2 m away tilted 30 deg, the depth through the structured-light noise
    model (6.4 mm at 2 m, 1/8 px disparity steps): the residual test picks the right one of
    the two mirror solutions in every draw; the first rule (fitted normal within 15 deg)
    drops or confuses most of the same detections."""
    rng = np.random.default_rng(5)
    new = {"right": 0, "wrong": 0, "other": 0}
    old_right = 0
    n = 0
    while n < 12:
        depth, uv, Ts, right, between = _scene(rng, 2.0, 30.0)
        if between < 20:  # the solutions nearly coincide: nothing to resolve
            continue
        n += 1
        noisy = apply_depth_noise(depth, PK, DepthNoiseConfig(seed=n), frame=0)
        t = mirror_test_from_depth(noisy, uv, K, Ts[0], Ts[1])
        assert t is not None and 30 <= t.n_points
        assert 0.002 < t.sigma_depth_m < 0.02  # ~6.4 mm at 2 m, estimated from the pixels
        c = t.choice(**RULE)
        new["right" if c == right else "wrong" if c in (0, 1) else "other"] += 1
        nrm = marker_normal_from_depth(noisy, uv, K)
        e = [math.degrees(math.acos(np.clip(nrm @ T[:3, 2], -1, 1))) for T in Ts]
        old_right += int(min(e) <= 15 and int(np.argmin(e)) == right)
    assert new["wrong"] == 0 and new["right"] >= 11
    assert old_right <= 6


def test_mirror_test_on_exact_depth_and_its_gates():
    rng = np.random.default_rng(2)
    while True:
        depth, uv, Ts, right, between = _scene(rng, 1.5, 40.0)
        if between > 30:
            break
    t = mirror_test_from_depth(depth, uv, K, Ts[0], Ts[1])
    assert t.choice(**RULE) == right and abs(t.log_ratio) > 100
    assert t.sigma_depth_m == pytest.approx(2e-4)  # exact depth: the floor
    assert t.angle_deg[right] < 3 and t.angle_deg[1 - right] > 25
    # the same solution twice: the depth cannot tell
    same = mirror_test_from_depth(depth, uv, K, Ts[right], Ts[right])
    assert same.log_ratio == 0 and same.choice(**RULE) is None
    # two solutions that both miss the seen plane by 40 deg: neither
    wrong = [T.copy() for T in Ts]
    for k, ax in enumerate(([1.0, 0.0, 0.0], [0.0, 1.0, 0.0])):
        wrong[k][:3, :3] = Ts[right][:3, :3] @ cv2.Rodrigues(np.radians(40) * np.array(ax))[0]
    assert mirror_test_from_depth(depth, uv, K, *wrong).choice(**RULE) == -1
    # no usable pixels
    assert mirror_test_from_depth(np.full((H, W), np.nan), uv, K, *Ts) is None
    assert mirror_test_from_depth(depth, uv + 1000, K, *Ts) is None
    assert mirror_test_from_depth(depth, np.full((4, 2), np.nan), K, *Ts) is None
    with pytest.raises(ValueError, match="depth"):
        mirror_test_from_depth(np.zeros(5), uv, K, *Ts)


CAM = CameraConfig(position=[0.0, 0.0, 1.0], look_at=[1.0, 0.0, 1.0], fov_y_deg=55.0,
                   max_range=10.0)


def _facing(p_W, tilt):
    R = RotationMatrix(np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]]))
    return RigidTransform(R @ RotationMatrix(RollPitchYaw(*tilt)), p_W)


def test_rendered_marker_with_noisy_depth_is_resolved():
    """``depth_noise`` puts a DepthNoise system between the camera and the sensor; a tilted
    marker whose detection is ambiguous by reprojection (threshold set above its ratio) is
    resolved right from the noisy depth; ``observe_images`` on the same images agrees with
    ``observe``."""
    X = _facing([0.9, 0.05, 1.0], (0.0, 0.5, 0.3))
    cfg = CameraMarkerSensorConfig(cameras=[CAM], width=640, height=480,
                                   depth_noise=DepthNoiseConfig(seed=4),
                                   min_unambiguous_ratio=1e6,
                                   detector=DetectorConfig(min_side_px=12.0,
                                                           ambiguity_angle_deg=0.0))
    r = MarkerRig(cfg)
    assert r.diagram.HasSubsystemNamed("marker_sensor_depth_noise_0")
    ctx = r.diagram.CreateDefaultContext()
    r.set_poses(ctx, [X])
    obs = r.observe(ctx)
    assert obs.visible[0]
    dp = np.linalg.norm(obs.poses[0].translation() - X.translation())
    da = math.degrees((X.rotation().inverse() @ obs.poses[0].rotation()).ToAngleAxis().angle())
    assert dp < 0.006 and da < 3.0
    noise = r.diagram.GetSubsystemByName("marker_sensor_depth_noise_0")
    depth = noise.get_depth_image_output_port().Eval(noise.GetMyContextFromRoot(ctx)).data
    assert np.isnan(depth).any()  # the noisy image has missing pixels (the far backdrop)
    cam = r.rgbd[0]
    img = cam.color_image_output_port().Eval(cam.GetMyContextFromRoot(ctx)).data
    obs2, track = r.sensor.observe_images(0.0, [img], [depth])
    assert obs2.visible[0] and track[0, 0] == 0.0
    assert np.allclose(obs2.poses[0].GetAsMatrix4(), obs.poses[0].GetAsMatrix4())
    # no image, a wrongly sized depth image: nothing / the fallback, never an exception
    assert not r.sensor.observe_images(0.0, [None], [None])[0].visible[0]
    assert not r.sensor.observe_images(0.0, [img], [np.zeros((3, 3))])[0].visible[0]


def test_config_depth_fields(tmp_path):
    from pydrake.common.yaml import yaml_load_typed

    with pytest.raises(ValueError, match="depth_test"):
        CameraMarkerSensorConfig(depth_test="plane").validate()
    with pytest.raises(ValueError, match="depth_min_log_ratio"):
        CameraMarkerSensorConfig(depth_min_log_ratio=float("nan")).validate()
    with pytest.raises(ValueError, match="sigma_z_at_1m"):
        CameraMarkerSensorConfig(depth_noise=DepthNoiseConfig(sigma_z_at_1m=-1)).validate()
    f = tmp_path / "cam.yaml"
    f.write_text("depth_test: normal\ndepth_noise: {sigma_z_at_1m: 0.003, seed: 2}\n")
    cfg = yaml_load_typed(schema=CameraMarkerSensorConfig, filename=str(f))
    cfg.validate()
    assert cfg.depth_test == "normal" and cfg.depth_noise.sigma_z_at_1m == 0.003


def test_learn_body_schema_camera_depth_configs():
    """(The flag itself: test_camera_marker_sensor.test_apps_take_the_sensor_flag.)"""
    from mmlearn.diagrams.body_schema.trials import camera_config

    assert camera_config("noisy", 3).depth_noise.seed == 3
    assert camera_config("exact").depth_noise is None and camera_config("exact").use_depth
    assert not camera_config("none").use_depth
    with pytest.raises(ValueError, match="camera_depth"):
        camera_config("lidar")


@pytest.mark.slow
def test_structure_experiments_camera_sensor_and_cabinet_through_the_camera():
    """``--sensor camera`` (the flag: test_camera_marker_sensor.test_apps_take_the_sensor_flag):
    one results file per sensor, and the two-drawer
    cabinet seen by its automatic camera: all three markers read (the cabinet's square on
    its holder above the drawers), mapped back to the parts' marker frames."""
    from mmlearn.diagrams.articulation.trials import observe
    from mmlearn.models.articulation.evaluation import sensor_stats
    from mmlearn.models.articulation.evaluation import structure_report as report
    from mmlearn.diagrams.common.object_tracks import (CAMERA_ELEVATION_DEG, auto_cameras,
                                                       cabinet_scenario)

    line = lambda sensor: {"spec": {"params": {"experiment": "garage", "quick": True,  # noqa: E731
                                               **({"sensor": sensor} if sensor else {})}},
                           "record": {"experiment": "garage", "result": {}, "lines": []},
                           "error": None}
    with pytest.raises(ValueError, match="sensor"):
        report([line(None), line("camera")])
    with pytest.raises(ValueError, match="sensor"):
        observe(cabinet_scenario(2, 2, rng=0), "kinect")

    tr = cabinet_scenario(2, 3, rng=1)
    cams = auto_cameras(tr.poses_true, elevation_deg=CAMERA_ELEVATION_DEG[tr.name])
    ct = observe(tr, "camera", CameraMarkerSensorConfig(cameras=cams, width=960, height=720))
    assert ct.poses.shape == tr.poses.shape
    st = sensor_stats(ct)
    assert st["cabinet"]["seen"] == 1.0 and st["upper_drawer"]["seen"] == 1.0
    assert st["lower_drawer"]["seen"] >= 0.6
    for p in st.values():
        assert p["pos_median_m"] < 0.01 and p["flipped"] == 0.0
