"""FrontDetector LeafSystem: ports, determinism, bad frames, a short simulation."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource
from pydrake.systems.sensors import CameraInfo, ImageDepth32F

from mmlearn.models.perception.detection import FrontDetectorConfig
from mmlearn.models.perception.synth import add_depth_noise, look_at, render_depth
from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.systems import FrontDetector
from mmlearn.systems.perception.front_detector import TIMING_NAMES

from test_front_detection import DOOR, _front_pose, _match, kitchen

K = PinholeIntrinsics.from_fov(640, 480, 58.0)


def _image(depth):
    img = ImageDepth32F(depth.shape[1], depth.shape[0])
    img.mutable_data[:, :, 0] = depth
    return img


def _door_frame(seed=0):
    X = _front_pose(0.85, 0.1, 0.6)
    X_WC = look_at([2.4, 0.4, 1.3], X[:3, 3])
    depth = add_depth_noise(render_depth(kitchen([(DOOR, X, 0.02)]), K, X_WC),
                            np.random.default_rng(seed)).astype(np.float32)
    return X, X_WC, depth


def _diagram(depth, X_WC, **kw):
    b = DiagramBuilder()
    det = b.AddSystem(FrontDetector(**kw))
    img = b.AddSystem(ConstantValueSource(AbstractValue.Make(_image(depth))))
    b.Connect(img.get_output_port(), det.get_depth_image_input_port())
    if X_WC is not None:
        pose = b.AddSystem(ConstantValueSource(AbstractValue.Make(RigidTransform(X_WC))))
        b.Connect(pose.get_output_port(), det.get_X_WC_input_port())
    b.ExportOutput(det.get_rectangles_output_port(), "rectangles")
    b.ExportOutput(det.get_timings_output_port(), "timings")
    return b.Build(), det


def test_detects_the_door_in_world_frame_and_reports_timings():
    X, X_WC, depth = _door_frame()
    diagram, _ = _diagram(depth, X_WC, intrinsics=K)
    ctx = diagram.CreateDefaultContext()
    rects = diagram.GetOutputPort("rectangles").Eval(ctx)
    m = _match(rects, X, DOOR)
    assert m is not None and m[1] < 0.01 and m[2] < 2.0, m
    t = diagram.GetOutputPort("timings").Eval(ctx)
    assert len(t) == len(TIMING_NAMES) and np.all(t >= 0) and t[-1] >= t[:-1].max()


def test_camera_info_accepted_and_same_time_same_result_in_two_simulators():
    X, X_WC, depth = _door_frame(1)
    info = CameraInfo(640, 480, K.fx, K.fy, K.cx, K.cy)
    results = []
    for _ in range(2):
        diagram, _ = _diagram(depth, X_WC, intrinsics=info, seed=4)
        sim = Simulator(diagram)
        sim.AdvanceTo(0.2)
        rects = diagram.GetOutputPort("rectangles").Eval(sim.get_context())
        results.append(rects)
    assert len(results[0]) == len(results[1]) > 0
    for a, b in zip(*results):
        np.testing.assert_array_equal(a.X_WR, b.X_WR)


def test_unconnected_pose_means_camera_frame():
    X, X_WC, depth = _door_frame(2)
    diagram, _ = _diagram(depth, None, intrinsics=K)
    rects = diagram.GetOutputPort("rectangles").Eval(diagram.CreateDefaultContext())
    X_CF = np.linalg.inv(X_WC) @ X
    m = _match(rects, X_CF, DOOR)
    assert m is not None and m[1] < 0.01


@pytest.mark.parametrize("depth", [np.full((480, 640), np.nan, np.float32),
                                   np.zeros((480, 640), np.float32),
                                   np.ones((240, 320), np.float32)])
def test_bad_frames_give_empty_lists(depth):
    diagram, _ = _diagram(depth, np.eye(4), intrinsics=K)
    ctx = diagram.CreateDefaultContext()
    assert diagram.GetOutputPort("rectangles").Eval(ctx) == []
    t = diagram.GetOutputPort("timings").Eval(ctx)
    if depth.shape != (480, 640):
        assert np.all(np.isnan(t))  # wrong size: could not be processed


def test_constructor_errors_are_clear():
    with pytest.raises(ValueError, match="intrinsics"):
        FrontDetector(intrinsics="camera")
    with pytest.raises(ValueError, match="seed"):
        FrontDetector(intrinsics=K, seed=-1)
    with pytest.raises(ValueError, match="min_recall"):
        FrontDetector(intrinsics=K, config=FrontDetectorConfig(min_recall=2.0))


@pytest.mark.parametrize("front,distance", [("drawer", 1.5), ("door", 1.2)])
def test_in_the_rendered_kitchen_diagram(front, distance):
    """RgbdSensor (VTK) -> DepthNoise -> FrontDetector in MakeFrontPerceptionDiagram: the
    opened front is found within 1 cm / 2 deg of its true pose (the diagram's ``front``)."""
    from mmlearn.diagrams.perception.diagram import (DepthCameraConfig, FrontPerceptionConfig,
                                                     MakeFrontPerceptionDiagram)
    from mmlearn.models.perception.motion import FrontMotionConfig

    def add(builder, parts):
        det = builder.AddSystem(FrontDetector(intrinsics=parts.intrinsics, seed=1))
        builder.Connect(parts.ports["depth_image"], det.get_depth_image_input_port())
        builder.Connect(parts.ports["X_WC"], det.get_X_WC_input_port())
        builder.ExportOutput(det.get_rectangles_output_port(), "rectangles")

    cfg = FrontPerceptionConfig(
        front=front, camera=DepthCameraConfig(distance=distance),
        motion=FrontMotionConfig(door_opening_deg=30.0, drawer_opening=0.2, steps=1,
                                 step_time=0.5, hold_time=0.2),
        point_cloud=False)
    scene = MakeFrontPerceptionDiagram(cfg, add_systems=add)
    sim = Simulator(scene.diagram)
    sim.AdvanceTo(1.0)  # fully open
    ctx = sim.get_context()
    truth = scene.diagram.GetOutputPort("front").Eval(ctx)
    rects = scene.diagram.GetOutputPort("rectangles").Eval(ctx)
    m = _match(rects, truth.X_WR, (truth.width, truth.height))
    assert m is not None, "no rectangle"
    r, perr, aerr = m
    assert perr < 0.01 and aerr < 2.0, (perr, aerr, r.width, r.height)
