"""The kitchen scene, the moving front, the depth camera and the perception diagram
(short renders with RenderEngineVtk, headless)."""

import json
import math

import numpy as np
import pytest
from pydrake.common.yaml import yaml_load_typed
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mmlearn.diagrams.perception.diagram import (DepthCameraConfig, FrontPerceptionConfig,
                                                 MakeFrontPerceptionDiagram)
from mmlearn.models.perception.motion import FrontMotionConfig, stepped_profile
from mmlearn.sdf.kitchen import KitchenSpec, kitchen_sdf


def _build(front, **camera):
    cfg = FrontPerceptionConfig(front=front)
    for k, v in camera.items():
        setattr(cfg.camera, k, v)
    cfg.motion = FrontMotionConfig(steps=3, step_time=1.0, hold_time=0.5)
    return MakeFrontPerceptionDiagram(cfg)


@pytest.fixture(scope="module")
def door():
    return _build("door", distance=1.5, angle_deg=-20.0)


@pytest.fixture(scope="module")
def drawer():
    return _build("drawer", distance=1.8)


def _eval(P, ctx, name):
    v = P.diagram.GetOutputPort(name).Eval(ctx)
    if isinstance(v, np.ndarray):
        return v.copy()
    if hasattr(v, "data"):
        return np.array(v.data)[..., 0]
    if hasattr(v, "GetAsMatrix4"):
        return v.GetAsMatrix4()
    return v


def _pixel(P, p_W):
    """Pixel (u, v) and camera-frame depth of a world point."""
    X_CW = np.linalg.inv(P.X_WC)
    p = X_CW[:3, :3] @ p_W + X_CW[:3, 3]
    K = P.intrinsics
    return K.fx * p[0] / p[2] + K.cx, K.fy * p[1] / p[2] + K.cy, p[2]


def _face_points(X_WR, w, h, n=5):
    """Points on the front's outer face (inside its outline by 20 %)."""
    s = np.linspace(-0.3, 0.3, n)
    a, b = np.meshgrid(s * w, s * h)
    return (X_WR[:3, :3] @ np.stack([a.ravel(), b.ravel(), np.zeros(a.size)])).T + X_WR[:3, 3]


@pytest.mark.parametrize("which", ["door", "drawer"])
def test_camera_pose(which, door, drawer):
    P = door if which == "door" else drawer
    cam = P.X_WC
    target = P.kinematics.X_WR0[:3, 3]
    d = target - cam[:3, 3]
    dist = 1.5 if which == "door" else 1.8
    assert np.linalg.norm(d) == pytest.approx(dist, abs=1e-9)
    np.testing.assert_allclose(cam[:3, 2], d / np.linalg.norm(d), atol=1e-12)  # looks at it
    assert abs(cam[2, 0]) < 1e-12  # no roll: image rows stay horizontal
    n = P.kinematics.X_WR0[:3, 2]
    horiz = -d.copy()
    horiz[2] = 0
    ang = math.degrees(math.atan2(np.cross(n, horiz)[2], n @ horiz))
    assert ang == pytest.approx(-20.0 if which == "door" else 0.0, abs=1e-9)
    elev = math.degrees(math.asin(-d[2] / np.linalg.norm(d)))
    assert elev == pytest.approx(25.0, abs=1e-9)
    # the exported X_WC is the same pose
    ctx = P.diagram.CreateDefaultContext()
    np.testing.assert_allclose(_eval(P, ctx, "X_WC"), cam, atol=1e-12)


@pytest.mark.parametrize("which", ["door", "drawer"])
def test_true_pose_follows_the_plant_and_the_render(which, door, drawer):
    """At several joint values the X_WR output equals the plant's ``<front>_face`` frame, and
    the clean render sees the face there: the depth at the pixels of points on the face is
    their camera-frame depth (within 2 mm), and their label is the front's."""
    P = door if which == "door" else drawer
    plant = P.plant
    pctx = plant.CreateDefaultContext()
    face = plant.GetFrameByName(f"{which}_face")
    ctx = P.diagram.CreateDefaultContext()
    motion = FrontMotionConfig(steps=3, step_time=1.0, hold_time=0.5)
    t_knots, q_knots = stepped_profile(motion.opening(which), motion)
    checked = 0
    for t in (0.0, 1.0, 2.25, 4.5):
        ctx.SetTime(t)
        q = _eval(P, ctx, "positions")
        plant.SetPositions(pctx, q)
        X = _eval(P, ctx, "X_WR")
        np.testing.assert_allclose(X, face.CalcPoseInWorld(pctx).GetAsMatrix4(), atol=1e-9)
        qj = float(_eval(P, ctx, "front_joint")[0])
        assert qj == pytest.approx(np.interp(t, t_knots, q_knots), abs=1e-12)
        rect = P.diagram.GetOutputPort("front").Eval(ctx)
        np.testing.assert_allclose(rect.X_WR, X, atol=1e-12)
        assert (rect.width, rect.height) == ((0.395, 0.58) if which == "door"
                                             else (0.395, 0.125))
        depth = _eval(P, ctx, "clean_depth")
        label = _eval(P, ctx, "label_image")
        to_cam = P.X_WC[:3, 3] - X[:3, 3]
        if X[:3, 2] @ to_cam / np.linalg.norm(to_cam) < 0.3:
            continue  # seen at a grazing angle or from behind
        X_CW = np.linalg.inv(P.X_WC)
        n_C = X_CW[:3, :3] @ X[:3, 2]
        p_C = X_CW[:3, :3] @ X[:3, 3] + X_CW[:3, 3]
        K = P.intrinsics
        for p in _face_points(X, P.kinematics.width, P.kinematics.height):
            u, v, z = _pixel(P, p)
            ui, vi = int(round(u)), int(round(v))
            # the face's depth along the ray through that pixel's centre
            r = np.array([(ui - K.cx) / K.fx, (vi - K.cy) / K.fy, 1.0])
            z_face = (n_C @ p_C) / (n_C @ r)
            assert abs(z_face - z) < 0.02
            assert depth[vi, ui] == pytest.approx(z_face, abs=0.002), (t, p)
            assert label[vi, ui] in P.front_labels
            checked += 1
    assert checked >= 50
    # the motion: the door turns about its vertical hinge, the drawer slides out along its
    # normal; the end of the profile is the configured opening
    ctx.SetTime(P.duration)
    X = _eval(P, ctx, "X_WR")
    X0 = P.kinematics.X_WR0
    if which == "door":
        cos = X[:3, 2] @ X0[:3, 2]
        assert math.degrees(math.acos(np.clip(cos, -1, 1))) == pytest.approx(90.0, abs=1e-6)
        assert X[2, 3] == pytest.approx(X0[2, 3], abs=1e-12)
        # it opens outwards: the hinge line is on the front's outer face (a concealed
        # hinge's pivot), so at 90 deg the face centre comes out by half the width (hinge on
        # the left, seen from the robot: the normal turns to the kitchen's -y)
        out = (X[:3, 3] - X0[:3, 3]) @ X0[:3, 2]
        assert out == pytest.approx(0.395 / 2, abs=1e-9)
        assert X[1, 2] == pytest.approx(-1.0, abs=1e-9)
    else:
        np.testing.assert_allclose(X[:3, 3] - X0[:3, 3], 0.30 * X0[:3, 2], atol=1e-9)
        np.testing.assert_allclose(X[:3, :3], X0[:3, :3], atol=1e-9)


def test_closed_fronts_ground_truth(door):
    """Every closed front's true rectangle is where the render sees it, with its own label."""
    P = door
    assert set(P.closed_fronts) == {"left_drawer0", "left_drawer1", "left_drawer2",
                                    "right_door", "right_drawer", "drawer"}
    ctx = P.diagram.CreateDefaultContext()
    depth = _eval(P, ctx, "clean_depth")
    label = _eval(P, ctx, "label_image")
    all_labels = [tuple(v) for v in P.closed_front_labels.values()] + [tuple(P.front_labels)]
    assert len(set(all_labels)) == len(all_labels)  # a body (label) per front
    K = P.intrinsics
    X_CW = np.linalg.inv(P.X_WC)
    for name, rect in P.closed_fronts.items():
        n_C = X_CW[:3, :3] @ rect.normal
        p_C = X_CW[:3, :3] @ rect.center + X_CW[:3, 3]
        for p in _face_points(rect.X_WR, rect.width, rect.height, n=3):
            u, v, _ = _pixel(P, p)
            if not (0 <= u < K.width - 0.5 and 0 <= v < K.height - 0.5):
                continue
            ui, vi = int(round(u)), int(round(v))
            r = np.array([(ui - K.cx) / K.fx, (vi - K.cy) / K.fy, 1.0])
            assert depth[vi, ui] == pytest.approx((n_C @ p_C) / (n_C @ r), abs=0.002), name
            assert label[vi, ui] in P.closed_front_labels[name], name


def test_front_at_the_expected_depth_and_noise(drawer):
    """The closed drawer's centre is the target 1.8 m away; the noisy image there has the
    noise of the model (std over the front's inner pixels close to the prediction)."""
    from mmlearn.models.common.depth_noise import predicted_depth_std

    P = drawer
    ctx = P.diagram.CreateDefaultContext()
    clean = _eval(P, ctx, "clean_depth")
    noisy = _eval(P, ctx, "depth_image")
    u, v, z = _pixel(P, P.kinematics.X_WR0[:3, 3])
    assert (u, v) == pytest.approx(((P.intrinsics.width - 1) / 2, (P.intrinsics.height - 1) / 2))
    assert z == pytest.approx(1.8 * math.cos(0.0), abs=1e-9)
    c = clean[int(v) - 2:int(v) + 3, int(u) - 20:int(u) + 21]
    assert np.all(np.abs(c - 1.8) < 0.01)
    n = noisy[int(v) - 2:int(v) + 3, int(u) - 20:int(u) + 21]
    resid = (n - c)[np.isfinite(n)]
    assert resid.size > 150
    sd = float(predicted_depth_std(1.8, P.intrinsics, P.noise.config))
    assert np.std(resid) == pytest.approx(sd, rel=0.35)
    assert np.isnan(noisy).mean() < 0.2


def test_kitchen_spec_checks():
    with pytest.raises(ValueError, match="door_hinge"):
        KitchenSpec(door_hinge="top")
    with pytest.raises(ValueError, match="door_width"):
        KitchenSpec(door_width=-0.3)
    with pytest.raises(ValueError, match="table_y"):
        kitchen_sdf(KitchenSpec(table_y=0.3))
    right = kitchen_sdf(KitchenSpec(door_hinge="right"))
    assert "<xyz>0 0 1</xyz>" in right  # hinge on +y turns about +z to open
    assert "<xyz>0 0 -1</xyz>" in kitchen_sdf(KitchenSpec())


@pytest.mark.parametrize("text, needle", [
    ("front: window\n", "front"),
    ("camera: {distance: -1.0}\n", "distance"),
    ("camera: {angle_deg: 95.0}\n", "angle_deg"),
    ("camera: {height: 2.0, distance: 1.0}\nfront: door\n", "height"),
    ("motion: {door_opening_deg: 150.0}\nfront: door\n", "joint limit"),
    ("motion: {steps: 0}\n", "steps"),
    ("noise: {dropout: 1.5}\n", "dropout"),
    ("point_cloud_stride: 0\n", "point_cloud_stride"),
])
def test_bad_configs(text, needle):
    cfg = yaml_load_typed(schema=FrontPerceptionConfig, data=text)
    with pytest.raises(ValueError, match=needle):
        MakeFrontPerceptionDiagram(cfg)


def test_misspelled_config_key():
    with pytest.raises(RuntimeError, match="distanse"):
        yaml_load_typed(schema=FrontPerceptionConfig, data="camera: {distanse: 2.0}\n")
    cfg = yaml_load_typed(schema=FrontPerceptionConfig,
                          data="front: door\ncamera: {distance: 2.2, height: 1.3}\n")
    assert cfg.front == "door" and cfg.camera.height == 1.3


class _CountMissing(LeafSystem):
    """A stand-in for the detector: counts frames and missing pixels of the depth image."""

    def __init__(self, W, H):
        super().__init__()
        from pydrake.common.value import AbstractValue
        from pydrake.systems.sensors import ImageDepth32F

        self.DeclareAbstractInputPort("depth", AbstractValue.Make(ImageDepth32F(W, H)))
        self._s = self.DeclareDiscreteState(2)
        self.DeclarePeriodicDiscreteUpdateEvent(0.5, 0.0, self._update)
        self.DeclareStateOutputPort("counts", self._s)

    def _update(self, context, state):
        d = np.asarray(self.get_input_port(0).Eval(context).data)
        x = context.get_discrete_state(self._s).get_value()
        state.get_mutable_vector(self._s).set_value(x + [1.0, float(np.isnan(d).sum())])


def test_add_systems_hook():
    def add(builder, parts):
        K = parts.intrinsics
        c = builder.AddNamedSystem("counter", _CountMissing(K.width, K.height))
        builder.Connect(parts.ports["depth_image"], c.get_input_port(0))
        builder.ExportOutput(c.get_output_port(0), "counts")

    cfg = FrontPerceptionConfig()
    cfg.camera.width, cfg.camera.height_px = 160, 120
    P = MakeFrontPerceptionDiagram(cfg, add_systems=add)
    sim = Simulator(P.diagram)
    sim.AdvanceTo(1.2)
    counts = P.diagram.GetOutputPort("counts").Eval(sim.get_context())
    assert counts[0] == 3 and 0 < counts[1] < 3 * 160 * 120


def test_meshcat_scene_and_cloud():
    from pydrake.geometry import StartMeshcat

    meshcat = StartMeshcat()
    cfg = FrontPerceptionConfig()
    cfg.camera.width, cfg.camera.height_px = 160, 120
    P = MakeFrontPerceptionDiagram(cfg, meshcat=meshcat)
    sim = Simulator(P.diagram)
    sim.AdvanceTo(0.5)
    fin = P.diagram.GetSubsystemByName("finite_cloud")
    cloud = fin.get_cloud_output_port().Eval(fin.GetMyContextFromRoot(sim.get_context()))
    assert cloud.size() > 1000 and np.isfinite(cloud.xyzs()).all()
    # Drake's DepthImageToPointCloud and models/fronts.depth_to_points agree on the pixels
    from mmlearn.models.common.camera import depth_to_points

    depth = np.array(P.diagram.GetOutputPort("depth_image").Eval(sim.get_context()).data)
    p_C = depth_to_points(depth, P.intrinsics).reshape(-1, 3)
    p_C = p_C[np.isfinite(p_C).all(axis=1)][::cfg.point_cloud_stride]
    p_W = p_C @ P.X_WC[:3, :3].T + P.X_WC[:3, 3]
    np.testing.assert_allclose(cloud.xyzs().T, p_W, atol=1e-5)
    assert meshcat.HasPath("depth_cloud") and meshcat.HasPath("depth_camera")


def test_render_fronts_help():
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "mmlearn.apps.render_fronts", "--help"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "--distance" in r.stdout and "--html-out" in r.stdout


def test_render_fronts_app(tmp_path, capsys):
    from mmlearn.apps.render_fronts import main

    rc = main(["--front", "drawer", "--distance", "1.2", "--frames", "2", "--out-dir",
               str(tmp_path / "f"), "--json"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    assert res["frames"] == 2
    files = sorted(p.name for p in (tmp_path / "f").iterdir())
    assert len(files) == 8
    meta = json.loads((tmp_path / "f" / [f for f in files if f.endswith(".json")][-1]).read_text())
    assert meta["joint_value"] == pytest.approx(0.30)
    depth = np.load(tmp_path / "f" / files[0].replace(".json", "_depth.npy")
                    if files[0].endswith(".json") else tmp_path / "f" / files[1])
    assert depth.dtype == np.float32 and depth.shape == (480, 640)
    # a YAML FrontPerceptionConfig: no noise, a smaller image
    yml = tmp_path / "scene.yaml"
    yml.write_text("add_noise: false\ncamera: {width: 64, height_px: 48}\n")
    rc = main(["--front", "door", "--distance", "1.5", "--frames", "1", "--config", str(yml),
               "--out-dir", str(tmp_path / "g"), "--json"])
    assert rc == 0
    capsys.readouterr()
    d = np.load(next((tmp_path / "g").glob("*_depth.npy")))
    c = np.load(next((tmp_path / "g").glob("*_clean.npy")))
    assert d.shape == (48, 64) and np.array_equal(d, c)
    yml.write_text("camera: {distanse: 2.0}\n")
    assert main(["--config", str(yml)]) == 2
    assert "distanse" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["--front", "window"])
    assert e.value.code == 2
    assert "window" in capsys.readouterr().err


def test_add_depth_camera_to_another_scene():
    """The camera and its noise on a plant of one's own: looking straight at the floor from
    1.5 m (slightly tilted), the clean render is the plane's depth at every pixel."""
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph

    from mmlearn.diagrams.perception.diagram import AddDepthCamera, camera_pose_looking_at
    from mmlearn.models.common.depth_noise import DepthNoiseConfig
    from mmlearn.sdf.builders import floor_sdf

    builder = DiagramBuilder()
    plant, sg = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
    Parser(plant).AddModelsFromString(floor_sdf(), "sdf")
    plant.Finalize()
    cam = DepthCameraConfig(width=200, height_px=150)
    X_WC = camera_pose_looking_at([0.3, 0.0, 1.5], [0.0, 0.0, 0.0])
    sensor, noise = AddDepthCamera(builder, sg, camera=cam, X_WC=X_WC, noise=DepthNoiseConfig())
    builder.ExportOutput(sensor.depth_image_32F_output_port(), "clean")
    builder.ExportOutput(noise.get_depth_image_output_port(), "noisy")
    diagram = builder.Build()
    ctx = diagram.CreateDefaultContext()
    clean = np.array(diagram.GetOutputPort("clean").Eval(ctx).data)[..., 0]
    K = cam.intrinsics()
    u, v = np.meshgrid(np.arange(K.width), np.arange(K.height))
    r_W = X_WC[:3, :3] @ np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones(u.shape)]
                                   ).reshape(3, -1)
    z_expected = (-X_WC[2, 3] / r_W[2]).reshape(u.shape)  # ray hits z = 0 at depth t
    np.testing.assert_allclose(clean, z_expected, atol=1e-4)
    noisy = np.array(diagram.GetOutputPort("noisy").Eval(ctx).data)[..., 0]
    assert 0.9 < np.isfinite(noisy).mean() < 1.0


def test_without_noise_the_depth_image_is_the_render():
    cfg = FrontPerceptionConfig(add_noise=False)
    cfg.camera.width, cfg.camera.height_px = 160, 120
    P = MakeFrontPerceptionDiagram(cfg)
    assert P.noise is None
    ctx = P.diagram.CreateDefaultContext()
    ctx.SetTime(2.0)
    np.testing.assert_array_equal(_eval(P, ctx, "depth_image"), _eval(P, ctx, "clean_depth"))
