"""CameraMarkerSensor: ArUco textures rendered by an RgbdSensor, detected and located
(short 640x480 renders)."""

import math

import numpy as np
import pytest

from pydrake.math import RigidTransform, RotationMatrix, RollPitchYaw

from mmlearn.diagrams.common.marker_camera import MarkerRig
from mmlearn.models.common.marker_detection import (DetectorConfig, detect_marker_poses,
                                                    make_detector)
from mmlearn.sdf.aruco import ArucoSpec, marker_image
from mmlearn.systems.common.camera_marker_sensor import CameraMarkerSensorConfig
from mmlearn.systems.common.marker_sensor import CameraConfig

# camera at (0, 0, 1) looking along +x: camera x = -world y, camera y = -world z
CAM = CameraConfig(position=[0.0, 0.0, 1.0], look_at=[1.0, 0.0, 1.0], fov_y_deg=55.0,
                   max_range=10.0)


def _config(**kw):
    return CameraMarkerSensorConfig(cameras=[CAM], width=640, height=480, **kw)


@pytest.fixture(scope="module")
def rig():
    r = MarkerRig(_config(), n_markers=2)
    return r, r.diagram.CreateDefaultContext()


def _facing(p_W, tilt=(0.0, 0.0, 0.0)):
    """A marker at p_W whose normal points back at the camera (-x), tilted by rpy."""
    R = RotationMatrix(np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]]))
    return RigidTransform(R @ RotationMatrix(RollPitchYaw(*tilt)), p_W)


def _errors(X, X_true):
    dp = float(np.linalg.norm(X.translation() - X_true.translation()))
    da = math.degrees((X_true.rotation().inverse() @ X.rotation()).ToAngleAxis().angle())
    return dp, da


FAR = _facing([-5.0, 0.0, 1.0])  # behind the camera: out of view


def test_texture_decodes_and_pose_of_a_synthetic_image():
    """The generated texture is a valid marker of its id (no rendering): pasted face-on into
    an image, the pose is recovered at the depth that K and its size imply."""
    spec = ArucoSpec()
    img = marker_image(spec, 7)
    canvas = np.full((480, 640), 128, np.uint8)
    h = img.shape[0]
    canvas[100:100 + h, 200:200 + h] = img
    marker_px = h * spec.marker_size / spec.plate_size
    f = 500.0
    K = np.array([[f, 0, 319.5], [0, f, 239.5], [0, 0, 1]])
    det = detect_marker_poses(canvas, K, marker_size=spec.marker_size,
                              detector=make_detector(spec.dictionary), ids={7})
    assert det.ids.tolist() == [7]
    z = det.T_CM[0, 2, 3]
    assert z == pytest.approx(f * spec.marker_size / marker_px, rel=0.01)
    assert abs(det.side_px[0] - marker_px) < 0.3
    # an id we do not look for is not reported
    det = detect_marker_poses(canvas, K, marker_size=spec.marker_size,
                              detector=make_detector(spec.dictionary), ids={3})
    assert len(det) == 0


def test_marker_detected_at_known_pose(rig):
    r, ctx = rig
    for p, tilt in (([0.6, 0.05, 1.02], (0.3, 0.0, 0.4)), ([0.8, -0.1, 0.95], (0.0, -0.5, 1.2))):
        X = _facing(p, tilt)
        r.set_poses(ctx, [X, FAR])
        obs = r.observe(ctx)
        assert obs.marker_ids == ["m0", "m1"]
        assert obs.visible.tolist() == [True, False]
        dp, da = _errors(obs.poses[0], X)
        assert dp < 0.006, dp
        assert da < 3.0, da


def test_no_marker_in_view_gives_an_empty_frame(rig):
    r, ctx = rig
    # one behind the camera, one in view but turned away (its back faces the camera)
    away = RigidTransform(RotationMatrix.MakeYRotation(math.pi / 2), [0.7, 0.0, 1.0])
    r.set_poses(ctx, [FAR, away])
    obs = r.observe(ctx)
    assert not obs.visible.any()
    assert obs.as_array().shape == (2, 7) and np.isnan(obs.as_array()).all()


def test_marker_partly_outside_the_image_is_not_reported(rig):
    r, ctx = rig
    # 0.6 m away the half-width of the view is 0.6 * tan(fov_x / 2) = 0.41 m; the plate
    # centred on the image's left border is cut in half
    half_w = 0.6 * math.tan(math.radians(55.0) / 2) * 640 / 480
    X = _facing([0.6, half_w, 1.0])
    r.set_poses(ctx, [X, FAR])
    assert not r.observe(ctx).visible[0]
    # fully inside near the border: reported, and right
    X = _facing([0.6, half_w - 0.06, 1.0])
    r.set_poses(ctx, [X, FAR])
    obs = r.observe(ctx)
    assert obs.visible[0]
    assert _errors(obs.poses[0], X)[0] < 0.006


def test_occluded_marker_is_not_reported_or_reported_right(rig):
    r, ctx = rig
    X = _facing([0.8, 0.0, 1.0])
    # the second carrier (0.10 m box) 0.2 m in front, shifted sideways by s: covers part
    for s, must_hide in ((0.0, True), (0.05, None), (0.075, None), (0.2, False)):
        occluder = _facing([0.6, s * 0.6 / 0.8 + 0.0, 1.0], (0.0, math.pi, 0.0))
        r.set_poses(ctx, [X, occluder])
        obs = r.observe(ctx)
        if must_hide:
            assert not obs.visible[0]
        if must_hide is False:
            assert obs.visible[0]
        if obs.visible[0]:
            assert _errors(obs.poses[0], X)[0] < 0.01


def test_bad_images_never_raise(rig):
    """A wrongly sized or blank image is no detection; the frame still happens."""
    from pydrake.common.value import AbstractValue
    from pydrake.systems.sensors import ImageRgba8U

    r, _ = rig
    sensor = r.sensor
    ctx = sensor.CreateDefaultContext()
    sensor.get_color_image_input_port(0).FixValue(ctx, AbstractValue.Make(ImageRgba8U(10, 7)))
    obs = sensor.observe(ctx)
    assert len(obs) == 2 and not obs.visible.any()
    sensor.get_color_image_input_port(0).FixValue(
        ctx, AbstractValue.Make(ImageRgba8U(640, 480)))
    assert not sensor.observe(ctx).visible.any()
    with pytest.raises(ValueError, match="shape"):
        detect_marker_poses(np.zeros((4, 4, 2), np.uint8), np.eye(3), marker_size=0.04,
                            detector=make_detector("DICT_4X4_50"))
    with pytest.raises(ValueError, match="uint8"):
        detect_marker_poses(np.full((40, 40), np.nan), np.eye(3), marker_size=0.04,
                            detector=make_detector("DICT_4X4_50"))


def test_config_errors_name_the_field(tmp_path):
    from pydrake.common.yaml import yaml_load_typed

    with pytest.raises(ValueError, match="width"):
        CameraMarkerSensorConfig(width=0).validate()
    with pytest.raises(ValueError, match="marker_size"):
        CameraMarkerSensorConfig(aruco=ArucoSpec(marker_size=float("nan"))).validate()
    with pytest.raises(ValueError, match="dictionary"):
        CameraMarkerSensorConfig(aruco=ArucoSpec(dictionary="DICT_9X9")).validate()
    with pytest.raises(ValueError, match="corner_refinement"):
        DetectorConfig(corner_refinement="magic").validate()
    with pytest.raises(ValueError, match="cameras"):
        CameraMarkerSensorConfig(cameras=[]).validate()
    f = tmp_path / "c.yaml"
    f.write_text("widht: 640\n")
    with pytest.raises(RuntimeError, match="widht"):
        yaml_load_typed(schema=CameraMarkerSensorConfig, filename=str(f))
    f.write_text("width: 800\nheight: 600\naruco: {marker_size: 0.05}\n")
    cfg = yaml_load_typed(schema=CameraMarkerSensorConfig, filename=str(f))
    cfg.validate()
    assert (cfg.width, cfg.aruco.marker_size) == (800, 0.05)


@pytest.mark.slow
def test_body_schema_diagram_with_camera_sensor_runs():
    """The body-schema diagram with the camera sensor (one 640x480 camera, closer): the
    learner's observations come from it, a few steps simulate, the base's marker is seen
    where the plant has it."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram

    cam = CameraMarkerSensorConfig(
        cameras=[CameraConfig(position=[1.0, 0.0, 0.6], look_at=[0.0, 0.0, 0.4],
                              fov_y_deg=55.0, max_range=5.0)], width=640, height=480,
        detector=DetectorConfig(min_side_px=12.0, min_ambiguity_ratio=1.0),
        min_unambiguous_ratio=1.0)  # the wiring only: x1 is ambiguous in this close view
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm="2dof", sensor="camera",
                                                       camera=cam))
    assert type(bs.scene.sensor).__name__ == "CameraMarkerSensor"
    sim = Simulator(bs.diagram)
    root = sim.get_mutable_context()
    bs.prepare(root)
    sim.AdvanceTo(0.25)
    obs = bs.diagram.GetOutputPort("observations").Eval(root)
    assert obs.marker_ids == bs.parts
    assert obs.time == pytest.approx(0.2)
    stats = bs.diagram.GetOutputPort("marker_stats").Eval(root)
    assert stats[0] == 3  # frames at t = 0, 0.1, 0.2
    assert stats[2] >= 3  # the base x1 at least, in every frame
    plant = bs.scene.plant
    X_true = plant.GetFrameByName("x1_marker", bs.scene.robot).CalcPoseInWorld(
        plant.GetMyContextFromRoot(root))
    assert obs.visible[bs.parts.index("x1")]
    dp, da = _errors(obs.poses[bs.parts.index("x1")], X_true)
    assert dp < 0.01 and da < 5.0
    with pytest.raises(ValueError, match="sensor"):
        MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm="2dof", sensor="laser"))


def test_object_track_through_the_camera():
    """A short open-yardstick track observed by a camera placed by auto_cameras: the seen
    markers are where the plant has them, unseen ones are NaN rows, the truth is kept."""
    from mmlearn.diagrams.common.object_tracks import auto_cameras, camera_track, yardstick_scenario

    tr = yardstick_scenario(False, 4, rng=3)
    cams = auto_cameras(tr.poses_true)
    assert np.all(np.isfinite(cams[0].position))
    ct = camera_track(tr, CameraMarkerSensorConfig(
        cameras=cams, width=960, height=720,
        detector=DetectorConfig(min_side_px=12.0, min_ambiguity_ratio=1.0)))
    assert ct.poses.shape == tr.poses.shape and np.array_equal(ct.poses_true, tr.poses_true)
    seen = ~np.isnan(ct.poses[..., 0])
    assert seen.mean() >= 0.75
    assert np.all(np.isnan(ct.poses[~seen]))
    err = np.linalg.norm(ct.poses[seen][:, :3] - tr.poses_true[seen][:, :3], axis=1)
    assert np.median(err) < 0.005 and err.max() < 0.03
    dot = np.abs(np.sum(ct.poses[seen][:, 3:] * tr.poses_true[seen][:, 3:], axis=1))
    # no mirror flip: the static part's better IPPE solution is the mirror one here (43 deg
    # off); the depth image's plane picks the right one (16/16 seen, max 5.6 deg)
    assert np.degrees(2 * np.arccos(np.clip(dot, 0, 1))).max() < 10


@pytest.mark.parametrize("mod,flag,choices,bad", [
    ("learn_body_schema", "--sensor", "{ideal,camera}", "kinect"),
    ("structure_experiments", "--sensor", "{ideal,camera}", "kinect"),
    ("learn_body_schema", "--camera-depth", "{exact,noisy,none}", "lidar")])
def test_apps_take_the_sensor_flag(mod, flag, choices, bad, capsys):
    import importlib

    main = importlib.import_module(f"mmlearn.apps.{mod}").main
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    assert f"{flag} {choices}" in capsys.readouterr().out
    with pytest.raises(SystemExit) as e:
        main([flag, bad])
    assert e.value.code == 2
    assert f"invalid choice: '{bad}'" in capsys.readouterr().err


def test_cameras_that_disagree_are_resolved_by_the_mirror_solutions(rig):
    """Two cameras: camera A's better solution is the mirror-flipped one, its other
    solution agrees with camera B -> the agreeing pose is reported; when no choice agrees
    within max_disagreement_deg, the marker is not reported."""
    r, _ = rig
    true = RigidTransform(RollPitchYaw(0.1, 0.2, 0.3), [1.0, 0.0, 1.0])
    flip = RigidTransform(RollPitchYaw(0.1, -0.5, 0.3), [1.01, 0.0, 1.0])
    near = RigidTransform(RollPitchYaw(0.1, 0.22, 0.3), [1.002, 0.0, 1.0])
    other = RigidTransform(RollPitchYaw(0.6, 0.2, 0.3), [1.0, 0.0, 1.0])
    # (side px, ambiguity ratio, [better solution, mirror solution])
    X = r.sensor._fuse([(30.0, 1.2, [flip, near]), (20.0, 1.2, [true, other])])
    assert X is not None and _errors(X, near)[1] < 1e-6
    assert r.sensor._fuse([(30.0, 9.0, [flip, flip]), (20.0, 9.0, [true, true])]) is None
    assert _errors(r.sensor._fuse([(30.0, 9.0, [flip, near])]), flip)[1] < 1e-6
    assert r.sensor._fuse([]) is None


def test_one_camera_ambiguous_detection_is_resolved_by_the_last_report_or_dropped(rig):
    """One camera: a clear detection (mirror solution reprojects >= min_unambiguous_ratio
    times worse) is kept as it is; an ambiguous one is dropped unless the last report of the
    marker picks one of its solutions (within track_max_angle_deg); two solutions that
    nearly coincide are not ambiguous."""
    r, _ = rig
    s = r.sensor
    assert s.config.min_unambiguous_ratio == 2.5 and s.config.track_max_angle_deg == 20.0
    true = RigidTransform(RollPitchYaw(0.1, 0.2, 0.3), [1.0, 0.0, 1.0])
    flip = RigidTransform(RollPitchYaw(0.1, -0.5, 0.3), [1.01, 0.0, 1.0])
    R = lambda X: np.asarray(X.rotation().matrix())  # noqa: E731
    # clear: the better solution, whatever the last report says
    assert _errors(s._fuse([(25.0, 4.0, [true, flip])]), true)[1] < 1e-9
    assert _errors(s._fuse([(25.0, 4.0, [flip, true])], R(true)), flip)[1] < 1e-9
    # ambiguous, nothing to compare with: not reported
    assert s._fuse([(25.0, 1.3, [flip, true])]) is None
    # ambiguous, the last report 5 degrees from the true pose: the mirror-free solution
    last = R(true) @ np.asarray(RotationMatrix(RollPitchYaw(0.0, 0.0, 0.09)).matrix())
    assert _errors(s._fuse([(25.0, 1.3, [flip, true])], last), true)[1] < 1e-9
    # ambiguous and the last report far from both solutions: not reported
    far = np.asarray(RotationMatrix(RollPitchYaw(1.5, 1.0, -1.0)).matrix())
    assert s._fuse([(25.0, 1.3, [flip, true])], far) is None
    # two solutions 3 degrees apart: either is right
    near = RigidTransform(RollPitchYaw(0.1, 0.25, 0.3), [1.0, 0.0, 1.0])
    assert _errors(s._fuse([(25.0, 1.0, [true, near])]), true)[1] < 1e-9


def test_rendered_ambiguous_marker_needs_depth_or_a_recent_report():
    """Rendered: a tilted marker whose detection is ambiguous under the threshold is
    resolved by the depth image's plane; without depth it is not reported on its own; after a report of it 0.1 s earlier it is reported, and right;
    a report older than track_max_age_s does not count."""
    probe = MarkerRig(_config())
    ctx = probe.diagram.CreateDefaultContext()
    X = _facing([0.9, 0.05, 1.0], (0.0, 0.5, 0.3))
    probe.set_poses(ctx, [X])
    cam = probe.rgbd[0]
    det = probe.sensor.detect(cam.color_image_output_port().Eval(
        cam.GetMyContextFromRoot(ctx)).data, 0)
    assert len(det) == 1
    amb = float(det.ambiguity[0])
    cfg = dict(min_unambiguous_ratio=max(1.0, amb * 1.01),
               detector=DetectorConfig(min_side_px=12.0, ambiguity_angle_deg=0.0))
    # with the depth image the plane's normal picks the right solution at once
    r = MarkerRig(_config(**cfg))
    ctx = r.diagram.CreateDefaultContext()
    r.set_poses(ctx, [X])
    obs = r.observe(ctx)
    assert obs.visible[0]
    dp, da = _errors(obs.poses[0], X)
    assert dp < 0.006 and da < 3.0
    # without it, a recent report is needed
    r = MarkerRig(_config(use_depth=False, **cfg))
    ctx = r.diagram.CreateDefaultContext()
    r.set_poses(ctx, [X])
    sctx = r.sensor.GetMyMutableContextFromRoot(ctx)
    assert not r.sensor.observe(sctx).visible[0]
    # a report of the true pose at t = 0 (as the periodic update stores it), then t = 0.1
    row = np.concatenate([[0.0], np.asarray(X.rotation().matrix()).ravel(), X.translation()])
    sctx.get_mutable_discrete_state(r.sensor._track_index).set_value(row)
    ctx.SetTime(0.1)
    obs = r.sensor.observe_and_remember(sctx)
    assert obs.visible[0]
    dp, da = _errors(obs.poses[0], X)
    assert dp < 0.006 and da < 3.0
    stored = sctx.get_discrete_state(r.sensor._track_index).get_value()
    assert stored[0] == pytest.approx(0.1)
    ctx.SetTime(0.1 + r.sensor.config.track_max_age_s + 0.05)  # the report is too old
    assert not r.sensor.observe(sctx).visible[0]


def test_ambiguous_detections_can_be_dropped():
    """The two pose solutions of a marker are returned; with min_ambiguity_ratio above the
    detection's ratio (and no angle allowance) it is dropped."""
    r = MarkerRig(_config(detector=DetectorConfig(min_ambiguity_ratio=1.0)))
    ctx = r.diagram.CreateDefaultContext()
    X = _facing([0.9, 0.05, 1.0], (0.0, 0.5, 0.3))
    r.set_poses(ctx, [X])
    cam = r.rgbd[0]
    img = cam.color_image_output_port().Eval(cam.GetMyContextFromRoot(ctx)).data
    det = r.sensor.detect(img, 0)
    assert len(det) == 1 and det.T_CM_other.shape == (1, 4, 4)
    amb = float(det.ambiguity[0])
    assert amb > 1.0
    strict = detect_marker_poses(img, r.sensor.cameras[0].K, marker_size=0.04,
                                 detector=make_detector("DICT_4X4_50"),
                                 config=DetectorConfig(min_ambiguity_ratio=amb * 1.01,
                                                       ambiguity_angle_deg=0.0))
    assert len(strict) == 0
    loose = detect_marker_poses(img, r.sensor.cameras[0].K, marker_size=0.04,
                                detector=make_detector("DICT_4X4_50"),
                                config=DetectorConfig(min_ambiguity_ratio=amb * 0.99,
                                                      ambiguity_angle_deg=0.0))
    assert len(loose) == 1


def test_marker_normal_from_depth_picks_the_plane_and_ignores_holes():
    """The plane through the depth pixels inside the quad: a synthetic tilted plane gives its
    normal (towards the camera); NaN / zero pixels are skipped; too few pixels -> None."""
    from mmlearn.systems.common.camera_marker_sensor import marker_normal_from_depth

    f, h, w = 500.0, 120, 160
    K = np.array([[f, 0, 79.5], [0, f, 59.5], [0, 0, 1]])
    n_true = np.array([0.3, -0.2, -1.0])
    n_true /= np.linalg.norm(n_true)
    p0 = np.array([0.0, 0.0, 1.5])
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    ray = np.stack([(u - K[0, 2]) / f, (v - K[1, 2]) / f, np.ones_like(u, float)], -1)
    depth = (n_true @ p0) / (ray @ n_true)  # z of the ray's hit on the plane
    corners = np.array([[60, 40], [100, 40], [100, 80], [60, 80]], float)
    n = marker_normal_from_depth(depth, corners, K)
    assert math.degrees(math.acos(min(1.0, n @ n_true))) < 0.01
    holes = depth.copy()
    holes[45:60, :] = np.nan
    holes[60:65, :] = 0.0
    n = marker_normal_from_depth(holes, corners, K)
    assert math.degrees(math.acos(min(1.0, n @ n_true))) < 0.01
    assert marker_normal_from_depth(np.full((h, w), np.nan), corners, K) is None
    assert marker_normal_from_depth(depth, corners + 1000, K) is None
