"""The robot looks at the cabinet before opening it: a depth camera on its head, the
FrontDetector, and the handle derived from the detected front.

:func:`LookAtFront` builds the opening scene (:func:`~mmlearn.diagrams.common.scene.MakeSceneDiagram`:
the mobile robot with its hook arm and the mechanism) with an ``RgbdSensor`` mounted on the
robot's ``mobile_base`` body (:func:`~mmlearn.diagrams.perception.diagram.AddDepthCamera`, with
:class:`~mmlearn.systems.DepthNoise`) and a :class:`~mmlearn.systems.FrontDetector` on the
noisy depth image, puts the robot at its start, and evaluates ``frames`` camera frames (the
noise differs per frame). In each frame the front is chosen
(:func:`mmlearn.models.perception.handle.select_front`) and its handle derived
(:func:`~mmlearn.models.perception.handle.handle_from_front`); the estimate is the per-coordinate
median over the frames that found the front (frames whose handle came from the bar's points
outvote those that placed it by the kind's convention). When no frame found the front, the
robot looks ``frames`` more frames with ``retry_detector`` (L = 0.01 m).

The arm is turned aside while the robot looks (``LookConfig.arm_pose``): at the trial's
start pose it stands between the head and the cabinet and hid the front's middle or free
edge in 4 of 15 views tried (the move back to the start pose is not simulated).

The head: the camera sits at ``mount_position`` in the base frame (x forward, z up; behind
and above the arm, which would otherwise hide the front's free edge) and is panned and tilted
to look at the point the robot was sent to. Its pose relative to the base is therefore known
exactly; the robot's belief of the base pose carries the localisation error, which the
caller applies to the estimate (``believed_from_true``), as it does to a click.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pydrake.systems.framework import DiagramBuilder

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.depth_noise import DepthNoiseConfig
from mmlearn.models.perception.detection import FrontDetectorConfig
from mmlearn.models.perception.handle import (HandleEstimate, HandleFromFrontConfig,
                                              handle_from_front, select_front)
from mmlearn.sdf.mechanisms import MechanismSpec
from mmlearn.systems import MarkerSensorConfig
from mmlearn.systems.perception.front_detector import FrontDetector

from mmlearn.diagrams.perception.diagram import AddDepthCamera, DepthCameraConfig, camera_pose_looking_at
from mmlearn.diagrams.common.scene import MakeSceneDiagram, SceneConfig

__all__ = ["LookConfig", "LookResult", "LookAtFront", "NoFrontDetected", "front_centre"]


class NoFrontDetected(RuntimeError):
    """The robot looked and found no front it could open (``look``: the
    :class:`LookResult`)."""

    def __init__(self, look):
        super().__init__(f"no front detected ({look.frames_found} of {look.frames} frames; "
                         f"rectangles per frame {look.rectangles})")
        self.look = look


@dataclass
class LookConfig:
    """How the robot looks for the front.

    Attributes:
        mount_position: the camera's optical centre in the base frame (x forward, y left,
            z up from the floor), m.
        arm_pose: the arm's joint commands (rad) while the robot looks: the arm turned aside
            so that it does not hide the front (the move from there to the trial's start
            pose is not simulated); None = the start pose's.
        frames: camera frames to detect in (>= 1); frames are 1 / camera.rate_hz apart.
        min_frames: the front must be found in at least this many frames.
        sent_error: the point the robot is sent to (its rough idea of the front's centre)
            lies within this distance of the true closed front's centre, m.
        camera: the depth camera (its distance / angle fields are not used).
        noise: the depth noise (its ``seed`` is replaced by the trial's).
        detector: the FrontDetector's parameters (default: its defaults with the inlier
            distance L = 0.015 m and 12 starts per plane: a drawer's front stands only
            0.024 m off the carcass face around it, and with L = 0.02 m that face's plane
            swallowed the drawer's front in some frames). Offset layers are off
            (``layer_planes=0``): they serve fronts seen while they open; here the robot
            looks at the closed front, and on this overlay drawer front (2.4 cm proud of
            its carcass, split by its handle) they made two partial layers, and the
            handle came out centimetres off (tests/test_operate_perception.py).
        retry_detector: when no frame found the front, the robot looks ``frames`` more
            frames with this detector configuration (default: L = 0.01 m, the original
            detector's, layers off as above; None = no second look).
        handle: choosing the front and deriving the handle.
    """

    mount_position: list[float] = param([-0.25, 0.0, 1.6], unit="m", length=3, elements=True,
                                        factory=True)
    arm_pose: list[float] | None = param([1.5, 0.3, 0.0, 1.2, 0.0, 0.0], unit="rad",
                                         optional=True, elements=True, factory=True)
    frames: int = param(5, integer=True, ge=1)
    min_frames: int = param(1, integer=True, ge=1)
    sent_error: float = param(0.10, unit="m", ge=0)
    camera: DepthCameraConfig = param(default_factory=DepthCameraConfig, nested=DepthCameraConfig)
    noise: DepthNoiseConfig = param(default_factory=DepthNoiseConfig, nested=DepthNoiseConfig)
    detector: FrontDetectorConfig = param(
        default_factory=lambda: FrontDetectorConfig(inlier_distance=0.015,
                                                    starts_per_plane=12, layer_planes=0),
        nested=FrontDetectorConfig)
    retry_detector: FrontDetectorConfig | None = param(
        default_factory=lambda: FrontDetectorConfig(inlier_distance=0.01, starts_per_plane=12,
                                                    layer_planes=0),
        optional=True, nested=FrontDetectorConfig)
    handle: HandleFromFrontConfig = param(default_factory=HandleFromFrontConfig,
                                          nested=HandleFromFrontConfig)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first bad field."""
        validate_fields(self)
        if not self.min_frames <= self.frames:
            raise ValueError(f"LookConfig: min_frames must be an integer in [1, frames = "
                             f"{self.frames}], got {self.min_frames!r}")


@dataclass
class LookResult:
    """What the robot saw (true world frame).

    Attributes:
        found: whether the front was found in at least ``min_frames`` frames.
        estimate: the handle estimate of the first successful frame with ``handle`` replaced
            by the median over the successful frames (None when not found).
        frames_found: frames in which the front was found.
        frames: frames evaluated (``2 * frames`` after a second look).
        target: the point the robot was sent to, m.
        X_WC: (4, 4) the camera's true pose.
        per_frame: handle estimates of the successful frames, (k, 3), m.
        rectangles: number of rectangles detected per frame.
        last_depth: the last frame's noisy depth image, (H, W) m (NaN = none).
        last_rectangles: the rectangles detected in the last frame.
    """

    found: bool
    estimate: HandleEstimate | None
    frames_found: int
    frames: int
    target: np.ndarray
    X_WC: np.ndarray
    per_frame: np.ndarray
    rectangles: list
    last_depth: np.ndarray | None = None
    last_rectangles: list = field(default_factory=list)


def front_centre(spec: MechanismSpec) -> np.ndarray:
    """Centre of the closed front's outer face, world, m."""
    if hasattr(spec, "front_centre"):  # a user's model
        return spec.front_centre()
    T = spec.X_WF()
    # the panel's centre in the moving body's frame (sdf/mechanisms.py, mechanism_sdf)
    y = {"left_door": spec.width / 2, "right_door": -spec.width / 2,
         "sliding_door": spec.width / 2}.get(spec.kind, 0.0)
    p_F = spec.front_origin_F() + np.array([0.01, y, spec.height / 2])
    return T[:3, :3] @ p_F + T[:3, 3]


def LookAtFront(spec: MechanismSpec, start_command, *, config: LookConfig | None = None,
                seed: int = 0) -> LookResult:
    """Put the robot at ``start_command`` (base x, y, yaw, then the arm's joints) in front of
    the mechanism ``spec``, look at it and derive its handle (see the module docstring).
    ``seed`` draws the point the robot is sent to, the depth noise and the detector's
    random draws."""
    cfg = config or LookConfig()
    cfg.validate()
    start = np.asarray(start_command, float).ravel()
    rng = np.random.default_rng([int(seed), 7919])
    err = rng.normal(size=3)
    err *= rng.uniform(0.0, cfg.sent_error) / max(np.linalg.norm(err), 1e-12)
    target = front_centre(spec) + err
    scene = MakeSceneDiagram(SceneConfig(
        arm="7dof", tool="hook", mobile_base=True, cabinet=False, mechanism=spec,
        sensor=MarkerSensorConfig(rate_hz=5.0, cameras=[], seed=int(seed))))
    plant = scene.plant
    builder = DiagramBuilder()
    sd = builder.AddNamedSystem("scene", scene.diagram)
    # the head looks at the target: its direction in the base frame
    x, y, yaw = start[:3]
    c, s = math.cos(yaw), math.sin(yaw)
    R_WB = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    target_B = R_WB.T @ (target - np.array([x, y, 0.0]))
    X_BC = camera_pose_looking_at(np.asarray(cfg.mount_position, float), target_B)
    base = plant.GetBodyByName("mobile_base", scene.robot)
    noise_cfg = DepthNoiseConfig(**{**cfg.noise.__dict__, "seed": int(seed)})
    sensor, noise = AddDepthCamera(builder, scene.scene_graph, camera=cfg.camera, X_WC=X_BC,
                                   noise=noise_cfg,
                                   parent_frame_id=plant.GetBodyFrameIdOrThrow(base.index()),
                                   query_object_port=sd.GetOutputPort("query_object"))
    K = cfg.camera.intrinsics()
    det = builder.AddNamedSystem("front_detector", FrontDetector(
        intrinsics=K, config=cfg.detector, seed=int(seed)))
    builder.Connect(noise.get_depth_image_output_port(), det.get_depth_image_input_port())
    builder.Connect(sensor.body_pose_in_world_output_port(), det.get_X_WC_input_port())
    detectors = [det]
    if cfg.retry_detector is not None:
        det2 = builder.AddNamedSystem("front_detector_retry", FrontDetector(
            intrinsics=K, config=cfg.retry_detector, seed=int(seed)))
        builder.Connect(noise.get_depth_image_output_port(), det2.get_depth_image_input_port())
        builder.Connect(sensor.body_pose_in_world_output_port(), det2.get_X_WC_input_port())
        detectors.append(det2)
    diagram = builder.Build()
    ctx = diagram.CreateDefaultContext()
    look = start.copy()
    if cfg.arm_pose is not None:
        if len(cfg.arm_pose) != start.size - 3:
            raise ValueError(f"LookConfig.arm_pose needs {start.size - 3} values (the arm's "
                             f"joints), got {len(cfg.arm_pose)}")
        look[3:] = cfg.arm_pose
    scene.set_joint_positions(ctx, look)
    X_WC = sensor.body_pose_in_world_output_port().Eval(
        sensor.GetMyContextFromRoot(ctx)).GetAsMatrix4()
    estimates, counts = [], []
    for k in range(cfg.frames * len(detectors)):
        if k == cfg.frames and estimates:
            break  # found in the first look: no second one
        dk = detectors[k // cfg.frames]
        ctx.SetTime(k / cfg.camera.rate_hz)
        rects = dk.get_rectangles_output_port().Eval(dk.GetMyContextFromRoot(ctx))
        counts.append(len(rects))
        front = select_front(rects, X_WC[:3, 3], target, cfg.handle)
        depth = np.asarray(noise.get_depth_image_output_port().Eval(
            noise.GetMyContextFromRoot(ctx)).data, float)[..., 0]
        if front is None:
            continue
        estimates.append(handle_from_front(spec.kind, front, depth, K, X_WC, cfg.handle))
    n_found = len(estimates)
    found = n_found >= cfg.min_frames
    # frames that saw the bar outvote those that placed the handle by the kind's convention
    if any(e.source == "bar" for e in estimates):
        estimates = [e for e in estimates if e.source == "bar"]
    per_frame = np.array([e.handle for e in estimates]).reshape(-1, 3)
    est = None
    if found:
        e0 = estimates[0]
        est = HandleEstimate(handle=np.median(per_frame, axis=0), normal=e0.normal, bar=e0.bar,
                             e_y=e0.e_y, front=e0.front, source=e0.source,
                             bar_points=e0.bar_points)
    return LookResult(found=found, estimate=est, frames_found=n_found,
                      frames=len(counts), target=target, X_WC=X_WC, per_frame=per_frame,
                      rectangles=counts, last_depth=depth, last_rectangles=list(rects))
