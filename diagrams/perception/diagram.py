"""A depth camera looking at a kitchen cabinet whose door or drawer opens (thesis ch. 5).

:func:`MakeFrontPerceptionDiagram` wires

* a kinematic-only ``MultibodyPlant`` of the kitchen (:mod:`mmlearn.sdf.kitchen`) and the
  floor, registered with a ``SceneGraph``; the plant is not simulated: a ``TrajectorySource``
  plays the moving front's stepped joint profile
  (:func:`mmlearn.models.perception.motion.stepped_profile`) into Drake's
  ``MultibodyPositionToGeometryPose``, which poses the geometry;
* an ``RgbdSensor`` (``RenderEngineVtk``, 640 x 480, 58 deg horizontal field of view by
  default) fixed in the world on a "robot head" pose looking at the moving front
  (:class:`DepthCameraConfig`: distance, angle off the front's normal, elevation or height);
* :class:`~mmlearn.systems.DepthNoise` on the rendered depth;
* :class:`~mmlearn.systems.TrueFrontPose` (the ground truth);
* with Meshcat: the scene (``MeshcatVisualizer``, illustration role) and the noisy point
  cloud in the world (``DepthImageToPointCloud`` + ``MeshcatPointCloudVisualizer``).

Exported ports: ``depth_image`` (noisy ``ImageDepth32F``, m, NaN = missing),
``clean_depth`` (the render), ``label_image`` (``ImageLabel16I``: render label of each pixel),
``X_WC`` (camera pose, ``RigidTransform``), ``X_WR`` (true front pose), ``front`` (true
``FrontRectangle``), ``front_joint`` (joint value, rad or m), ``positions`` (plant positions),
``query_object``.

:func:`AddDepthCamera` adds the camera and its noise to any diagram with a SceneGraph (e.g.
the arm scenes, to look at the cabinet while operating it).

Hook for the detector and the tracker: :func:`AddFrontPerception` adds all of the above to
a caller's ``DiagramBuilder`` and returns the parts (ports included) without building, and
:func:`MakeFrontPerceptionDiagram` takes ``add_systems(builder, parts)``, called before
``Build``, to add and connect further systems (and export their ports).
"""


import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from pydrake.geometry import (ClippingRange, DepthRange, DepthRenderCamera, MakeRenderEngineVtk,
                              MeshcatPointCloudVisualizer, MeshcatVisualizer,
                              MeshcatVisualizerParams, RenderCameraCore, RenderEngineVtkParams,
                              Role, SceneGraph)
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.perception import BaseField, DepthImageToPointCloud
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.systems.rendering import MultibodyPositionToGeometryPose
from pydrake.systems.sensors import CameraInfo, PixelType, RgbdSensor
from pydrake.trajectories import PiecewisePolynomial

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.depth_noise import DepthNoiseConfig
from mmlearn.models.perception.motion import FrontJointKinematics, FrontMotionConfig, stepped_profile
from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.fronts import FrontRectangle
from mmlearn.sdf import add_package
from mmlearn.sdf.builders import floor_sdf
from mmlearn.sdf.kitchen import KitchenSpec, kitchen_sdf
from mmlearn.models.perception.depth_filter import DepthFilterConfig
from mmlearn.systems.common.depth_noise import DepthNoise
from mmlearn.systems.perception.depth_temporal_filter import DepthTemporalFilter
from mmlearn.systems.perception.front_detector import FrontDetector
from mmlearn.systems.perception.front_tracker import FrontTracker
from mmlearn.systems.perception.front_pose import TrueFrontPose
from mmlearn.systems.perception.point_cloud_filter import FinitePointCloud

__all__ = ["DepthCameraConfig", "FrontPerceptionConfig", "FrontPerception",
           "FrontPerceptionDiagram", "AddDepthCamera", "AddFrontPerception",
           "MakeFrontPerceptionDiagram",
           "camera_pose_looking_at"]

FRONTS = ("door", "drawer")
_RENDERER = "vtk"


@dataclass
class DepthCameraConfig:
    """The depth camera on the robot's head (load with ``yaml_load_typed``).

    The camera looks at the *target*: the centre of the moving front's outer face when
    closed, plus ``look_at_offset``. Its optical centre is ``distance`` from the target,
    turned ``angle_deg`` about the vertical away from the front's normal (positive towards
    the kitchen's +y, the robot's right), and either ``elevation_deg`` above the target's
    horizontal plane or, when ``height`` is given, at that height above the floor.

    Attributes:
        width, height_px: image size, pixels.
        fov_x_deg: horizontal field of view, deg (the Kinect's: 58).
        distance: camera centre to target, m (the thesis' experiments: 0.8-2.8).
        angle_deg: azimuth off the front's normal, deg (``|angle| <= 80``).
        elevation_deg: how far above the target the camera is, as an angle, deg (used when
            ``height`` is None).
        height: camera height above the floor, m, or None (then ``elevation_deg`` sets it).
        look_at_offset: added to the target point (kitchen axes: x out of the fronts, y, z
            up), m.
        z_near, z_far: render clipping and depth range, m (the noise model's own range
            then cuts it).
        rate_hz: camera frames per second (the noise's frame index is round(t * rate_hz);
            the Meshcat point cloud is published at this rate).
    """

    width: int = param(640, unit="px", integer=True, ge=8)
    height_px: int = param(480, unit="px", integer=True, ge=8)
    fov_x_deg: float = param(58.0, unit="deg", gt=0, le=170)
    distance: float = param(1.8, unit="m", ge=0.2)
    angle_deg: float = param(0.0, unit="deg", ge=-80, le=80)
    elevation_deg: float = param(25.0, unit="deg", ge=-60, le=80)
    height: float | None = param(None, unit="m", gt=0, optional=True)
    look_at_offset: list[float] = param([0.0, 0.0, 0.0], unit="m", length=3, elements=True,
                                        factory=True)
    z_near: float = param(0.1, unit="m", gt=0)
    z_far: float = param(10.0, unit="m", gt=0)
    rate_hz: float = param(5.0, unit="Hz", gt=0)

    def validate(self) -> "DepthCameraConfig":
        """Raise ``ValueError`` naming the first bad field; return the config."""
        validate_fields(self)
        if not self.z_far > self.z_near:
            raise ValueError(f"DepthCameraConfig: z_far must be > z_near ({self.z_near} m), "
                             f"got {self.z_far}")
        return self

    def intrinsics(self) -> PinholeIntrinsics:
        return PinholeIntrinsics.from_fov(self.width, self.height_px, self.fov_x_deg)

    def fov_y_rad(self) -> float:
        K = self.intrinsics()
        return 2.0 * math.atan(0.5 * K.height / K.fy)

    def X_WC(self, X_WT: np.ndarray) -> np.ndarray:
        """Camera pose (4, 4) for a target pose X_WT (position: the point looked at; its
        z axis: the front's outward normal; world z is up)."""
        self.validate()
        X_WT = np.asarray(X_WT, float)
        n = X_WT[:3, 2].copy()
        n[2] = 0.0
        if np.linalg.norm(n) < 1e-9:
            raise ValueError("DepthCameraConfig: the target's normal is vertical")
        n /= np.linalg.norm(n)
        side = np.cross([0.0, 0.0, 1.0], n)  # horizontal: the kitchen's +y for n = +x
        a = math.radians(self.angle_deg)
        horiz = math.cos(a) * n + math.sin(a) * side  # +angle towards +side
        target = X_WT[:3, 3] + np.asarray(self.look_at_offset, float)
        if self.height is None:
            e = math.radians(self.elevation_deg)
            p = target + self.distance * (math.cos(e) * horiz + math.sin(e) * np.array([0, 0, 1.0]))
        else:
            dz = float(self.height) - target[2]
            if abs(dz) >= self.distance:
                raise ValueError(f"DepthCameraConfig: height {self.height} m is "
                                 f"{abs(dz):.3f} m from the target's height, not less than "
                                 f"distance {self.distance} m")
            p = target + math.sqrt(self.distance**2 - dz**2) * horiz + np.array([0, 0, dz])
        return camera_pose_looking_at(p, target)


def camera_pose_looking_at(position, target) -> np.ndarray:
    """X_WC (4, 4) of a Drake camera (z forward, x right, y down) at ``position`` looking at
    ``target``, image rows along world -z as far as possible (no roll)."""
    p = np.asarray(position, float)
    z = np.asarray(target, float) - p
    if np.linalg.norm(z) < 1e-9:
        raise ValueError("camera_pose_looking_at: target equals position")
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-6:
        raise ValueError("camera_pose_looking_at: looking straight up or down")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    X = np.eye(4)
    X[:3, :3] = np.column_stack([x, y, z])
    X[:3, 3] = p
    return X


@dataclass
class FrontPerceptionConfig:
    """Configuration of :func:`MakeFrontPerceptionDiagram` (load with ``yaml_load_typed``).

    Attributes:
        front: which front moves: "door" (revolute) or "drawer" (prismatic); the other stays
            closed.
        kitchen: the scene's geometry (:class:`KitchenSpec`).
        motion: the moving front's stepped opening (:class:`FrontMotionConfig`).
        camera: the depth camera (:class:`DepthCameraConfig`).
        noise: the depth noise (:class:`DepthNoiseConfig`; its ``seed`` is the run's seed).
        add_noise: False = the ``depth_image`` port is the clean render (Drake's codes: inf
            where nothing is within ``z_far``, 0 nearer than ``z_near``; both count as "no
            measurement" in :func:`mmlearn.models.perception.fronts.valid_depth_mask`).
        point_cloud: with Meshcat, also show the noisy point cloud.
        point_cloud_stride: show every n-th measured point (>= 1; 1 = all, ~300k points per
            frame, heavy in a recording).
        point_cloud_rate_hz: clouds drawn per second, Hz (0 = one per camera frame; a 30 Hz
            camera's clouds would fill a recording, so the apps draw at the detector's rate).
    """

    front: str = param("drawer", choices=FRONTS)
    kitchen: KitchenSpec = field(default_factory=KitchenSpec)
    motion: FrontMotionConfig = field(default_factory=FrontMotionConfig)
    camera: DepthCameraConfig = field(default_factory=DepthCameraConfig)
    noise: DepthNoiseConfig = field(default_factory=DepthNoiseConfig)
    add_noise: bool = True
    point_cloud: bool = True
    point_cloud_stride: int = param(3, integer=True, ge=1)
    point_cloud_rate_hz: float = param(0.0, unit="Hz; 0 = the camera's rate", ge=0)

    def validate(self) -> "FrontPerceptionConfig":
        """Raise ``ValueError`` naming the first bad field; return the config."""
        validate_fields(self)
        self.kitchen.validate()
        self.motion.validate()
        self.camera.validate()
        self.noise.validate()
        self.check_distance(self.camera.distance, "camera.distance")
        limit = self.kitchen.door_limit if self.front == "door" else self.kitchen.drawer_limit
        if self.motion.opening(self.front) > limit + 1e-12:
            raise ValueError(f"FrontPerceptionConfig: the {self.front} opens to "
                             f"{self.motion.opening(self.front):.4g} beyond its joint limit "
                             f"{limit:.4g} (kitchen.{self.front}_limit)")
        return self


    def camera_range(self) -> float:
        """The farthest depth the camera measures, m: its ``z_far`` and, with noise, the
        noise model's ``max_range``."""
        far = float(self.camera.z_far)
        return min(far, float(self.noise.max_range)) if self.add_noise else far

    def check_distance(self, distance: float, name: str = "distance") -> None:
        """Raise ``ValueError`` when a camera ``distance`` (m) to the front leaves the front
        beyond the camera's range (every pixel of it would be missing)."""
        far = self.camera_range()
        if not float(distance) < far:
            what = ("noise.max_range" if self.add_noise and far < self.camera.z_far
                    else "camera.z_far")
            raise ValueError(f"{name} {float(distance):g} m is beyond the camera's range "
                             f"{far:g} m ({what}): the front would not be seen")


@dataclass
class FrontPerception:
    """What :func:`AddFrontPerception` added to a builder (the ports not yet exported).

    Attributes:
        plant: the kinematic-only kitchen plant (finalized; not a system of the diagram:
            keep this object alive as long as the diagram).
        scene_graph: the SceneGraph (in the diagram).
        camera: the RgbdSensor.
        noise: the DepthNoise system, or None with ``add_noise`` False.
        true_pose: the TrueFrontPose system.
        trajectory: the TrajectorySource of the plant's positions.
        intrinsics: the camera's :class:`PinholeIntrinsics`.
        X_WC: (4, 4) camera pose in the world.
        kinematics: the moving front's :class:`FrontJointKinematics`.
        joint_name: the moving front's joint (``door_hinge`` or ``drawer_slide``).
        duration: length of the opening profile, s.
        front_labels: render labels (ints) of the moving front body's geometry in the
            ``label_image`` (its pixels: ``np.isin(label, front_labels)``).
        closed_fronts: the fronts that do not move in this run (the neighbours' and the
            other one of door / drawer), name -> true :class:`FrontRectangle` (world).
        closed_front_labels: their render labels, name -> list of ints.
        ports: output ports by name: ``depth_image``, ``clean_depth``, ``label_image``,
            ``X_WC``, ``X_WR``, ``front``, ``front_joint``, ``positions``, ``query_object``.
        cloud_visualizer: the MeshcatPointCloudVisualizer (None without Meshcat).
    """

    plant: MultibodyPlant
    scene_graph: SceneGraph
    camera: RgbdSensor
    noise: DepthNoise | None
    true_pose: TrueFrontPose
    trajectory: TrajectorySource
    intrinsics: PinholeIntrinsics
    X_WC: np.ndarray
    kinematics: FrontJointKinematics
    joint_name: str
    duration: float
    front_labels: list
    closed_fronts: dict
    closed_front_labels: dict
    ports: dict
    cloud_visualizer: object = None


@dataclass
class FrontPerceptionDiagram(FrontPerception):
    """:class:`FrontPerception` plus the built ``diagram`` (all ``ports`` exported under
    their names) and the scene's MeshcatVisualizer (None without Meshcat)."""

    diagram: object = None
    visualizer: object = None


def _front_kinematics(plant, front: str, spec: KitchenSpec) -> FrontJointKinematics:
    """The moving front's joint in the world, read from the plant at q = 0."""
    ctx = plant.CreateDefaultContext()
    joint = plant.GetJointByName("door_hinge" if front == "door" else "drawer_slide")
    X_WJ = joint.frame_on_parent().CalcPoseInWorld(ctx)
    axis_W = X_WJ.rotation().matrix() @ np.asarray(joint.revolute_axis() if front == "door"
                                                   else joint.translation_axis(), float)
    X_WR0 = plant.GetFrameByName(f"{front}_face").CalcPoseInWorld(ctx).GetAsMatrix4()
    w, h = spec.front_size(front)
    return FrontJointKinematics(kind="revolute" if front == "door" else "prismatic",
                                axis_W=axis_W, point_W=X_WJ.translation(), X_WR0=X_WR0,
                                width=w, height=h)


def _draw_camera(meshcat, X_WC: np.ndarray, K: PinholeIntrinsics, depth: float = 0.25) -> None:
    """A small box and the view frustum's edges (``depth`` m long) at the camera pose."""
    from pydrake.geometry import Box, Rgba

    meshcat.SetObject("depth_camera/body", Box(0.07, 0.03, 0.04), Rgba(0.1, 0.1, 0.1, 1))
    c = np.array([[0.0, 0.0], [K.width - 1.0, 0.0], [K.width - 1.0, K.height - 1.0],
                  [0.0, K.height - 1.0]])
    corners = np.c_[(c[:, 0] - K.cx) / K.fx, (c[:, 1] - K.cy) / K.fy, np.ones(4)] * depth
    start = np.zeros((3, 8))
    end = np.zeros((3, 8))
    for i in range(4):
        end[:, i] = corners[i]
        start[:, 4 + i], end[:, 4 + i] = corners[i], corners[(i + 1) % 4]
    meshcat.SetLineSegments("depth_camera/frustum", start, end, 2.0, Rgba(0.1, 0.1, 0.8, 1))
    meshcat.SetTransform("depth_camera", RigidTransform(X_WC))


def _closed_fronts(plant, spec: KitchenSpec, moving: str) -> dict:
    """True rectangles (world) of the fronts that stay closed in this run."""
    ctx = plant.CreateDefaultContext()
    sizes = {name: (w, h) for name, _, _, w, h in spec.closed_fronts()}
    other = "drawer" if moving == "door" else "door"
    sizes[other] = spec.front_size(other)
    return {name: FrontRectangle(plant.GetFrameByName(f"{name}_face").CalcPoseInWorld(ctx)
                                 .GetAsMatrix4(), w, h) for name, (w, h) in sizes.items()}


def _body_labels(plant, scene_graph, body_name: str) -> list[int]:
    """Render labels of the perception geometry of a body."""
    inspector = scene_graph.model_inspector()
    body = plant.GetBodyByName(body_name)
    fid = plant.GetBodyFrameIdOrThrow(body.index())
    labels = set()
    for gid in inspector.GetGeometries(fid, Role.kPerception):
        props = inspector.GetPerceptionProperties(gid)
        labels.add(int(props.GetProperty("label", "id")))
    return sorted(labels)


def AddDepthCamera(builder: DiagramBuilder, scene_graph: SceneGraph, *,
                   camera: DepthCameraConfig, X_WC: np.ndarray,
                   noise: DepthNoiseConfig | None = None, name: str = "depth_camera",
                   parent_frame_id=None, query_object_port=None):
    """Add a depth camera fixed in the world (an ``RgbdSensor`` rendering with
    ``RenderEngineVtk``; the renderer is added to ``scene_graph`` when it has none of that
    name) and, unless ``noise`` is None, a :class:`DepthNoise` on its depth image, to any
    diagram with a SceneGraph (e.g. the operate scene). ``X_WC`` (4, 4) is the camera pose
    (Drake camera frame: x right, y down, z forward); ``camera`` gives the image size, field
    of view, clipping range and frame rate (its distance / angle fields are not used).
    ``parent_frame_id``: a SceneGraph ``FrameId`` (e.g. a robot body's, from
    ``plant.GetBodyFrameIdOrThrow``) to mount the camera on; ``X_WC`` is then the camera
    pose relative to that frame (None = the world frame). ``query_object_port``: the port
    to read the scene's QueryObject from when ``scene_graph`` sits inside a sub-diagram
    that exports it (None = ``scene_graph``'s own port, which must be in ``builder``).

    Returns ``(sensor, noise_system or None)``; the camera's intrinsics are
    ``camera.intrinsics()`` (use these, not the sensor's own CameraInfo, see below).
    """
    camera.validate()
    if not scene_graph.HasRenderer(_RENDERER):
        scene_graph.AddRenderer(_RENDERER, MakeRenderEngineVtk(RenderEngineVtkParams()))
    K = camera.intrinsics()
    # RenderEngineVtk renders pixel (u, v) along the ray through (u + 0.5, v + 0.5) of the
    # CameraInfo it is given (measured: tests/test_front_perception.py), while Drake's
    # CameraInfo documentation, DepthImageToPointCloud and models/perception/fronts.py put pixel u's
    # centre at u. Rendering with the principal point moved by half a pixel makes the image
    # agree with K.
    core = RenderCameraCore(_RENDERER, CameraInfo(K.width, K.height, K.fx, K.fy, K.cx + 0.5,
                                                  K.cy + 0.5),
                            ClippingRange(camera.z_near, camera.z_far), RigidTransform())
    depth_cam = DepthRenderCamera(core, DepthRange(camera.z_near * 1.0001,
                                                   camera.z_far * 0.9999))
    sensor = builder.AddNamedSystem(name, RgbdSensor(
        scene_graph.world_frame_id() if parent_frame_id is None else parent_frame_id,
        RigidTransform(np.asarray(X_WC, float)), depth_cam))
    builder.Connect(scene_graph.get_query_output_port() if query_object_port is None
                    else query_object_port, sensor.query_object_input_port())
    noise_sys = None
    if noise is not None:
        noise_sys = builder.AddNamedSystem(f"{name}_noise", DepthNoise(
            intrinsics=K, config=noise, rate_hz=camera.rate_hz))
        builder.Connect(sensor.depth_image_32F_output_port(),
                        noise_sys.get_clean_depth_input_port())
    return sensor, noise_sys


def AddFrontPerception(builder: DiagramBuilder, config: FrontPerceptionConfig | None = None,
                       *, meshcat=None) -> FrontPerception:
    """Add the kitchen, the moving front, the camera and the noise to ``builder`` (see the
    module docstring); returns the parts, nothing exported."""
    cfg = config or FrontPerceptionConfig()
    cfg.validate()
    scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
    plant = MultibodyPlant(time_step=0.0)
    plant.set_name("kitchen_plant")
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    parser = Parser(plant)
    add_package(parser)
    parser.AddModelsFromString(floor_sdf(), "sdf")
    parser.AddModelsFromString(kitchen_sdf(cfg.kitchen), "sdf")
    plant.Finalize()

    # the stepped joint profile of the moving front -> all plant positions -> geometry poses
    front = cfg.front
    joint_name = "door_hinge" if front == "door" else "drawer_slide"
    j = plant.GetJointByName(joint_name).position_start()
    t, qf = stepped_profile(cfg.motion.opening(front), cfg.motion)
    Q = np.zeros((plant.num_positions(), t.size))
    Q[j] = qf
    traj = builder.AddNamedSystem("front_trajectory",
                                  TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, Q)))
    to_pose = builder.AddNamedSystem("positions_to_poses", MultibodyPositionToGeometryPose(plant))
    builder.Connect(traj.get_output_port(), to_pose.get_input_port())
    builder.Connect(to_pose.get_output_port(),
                    scene_graph.get_source_pose_port(plant.get_source_id()))

    kin = _front_kinematics(plant, front, cfg.kitchen)
    closed = _closed_fronts(plant, cfg.kitchen, front)
    true_pose = builder.AddNamedSystem("true_front_pose", TrueFrontPose(
        kinematics=kin, position_index=j, num_positions=plant.num_positions()))
    builder.Connect(traj.get_output_port(), true_pose.get_positions_input_port())

    # the camera, fixed in the world, looking at the closed front
    cam = cfg.camera
    K = cam.intrinsics()
    X_WC = cam.X_WC(kin.X_WR0)
    sensor, noise = AddDepthCamera(builder, scene_graph, camera=cam, X_WC=X_WC,
                                   noise=cfg.noise if cfg.add_noise else None)
    depth_port = (noise.get_depth_image_output_port() if noise is not None
                  else sensor.depth_image_32F_output_port())

    ports = {"depth_image": depth_port,
             "clean_depth": sensor.depth_image_32F_output_port(),
             "label_image": sensor.label_image_output_port(),
             "X_WC": sensor.body_pose_in_world_output_port(),
             "X_WR": true_pose.get_X_WR_output_port(),
             "front": true_pose.get_front_output_port(),
             "front_joint": true_pose.get_joint_value_output_port(),
             "positions": traj.get_output_port(),
             "query_object": scene_graph.get_query_output_port()}

    cloud_vis = None
    if meshcat is not None:
        # Meshcat's view: from behind and beside the depth camera, onto the target
        target = kin.X_WR0[:3, 3]
        back = X_WC[:3, 3] - target
        eye = target + 1.3 * back + np.array([0.0, 0.0, 0.35]) + 0.3 * X_WC[:3, 0]
        meshcat.SetCameraPose(eye, target)
        _draw_camera(meshcat, X_WC, K)
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat,
                                       MeshcatVisualizerParams(role=Role.kIllustration))
        if cfg.point_cloud:
            to_cloud = builder.AddNamedSystem("depth_to_cloud", DepthImageToPointCloud(
                CameraInfo(K.width, K.height, K.fx, K.fy, K.cx, K.cy), PixelType.kDepth32F,
                1.0, BaseField.kXYZs))
            builder.Connect(depth_port, to_cloud.depth_image_input_port())
            builder.Connect(sensor.body_pose_in_world_output_port(),
                            to_cloud.camera_pose_input_port())
            cloud_vis = builder.AddNamedSystem("cloud_visualizer", MeshcatPointCloudVisualizer(
                meshcat, "depth_cloud", 1.0 / (cfg.point_cloud_rate_hz or cam.rate_hz)))
            finite = builder.AddNamedSystem("finite_cloud",
                                            FinitePointCloud(stride=cfg.point_cloud_stride))
            builder.Connect(to_cloud.point_cloud_output_port(), finite.get_cloud_input_port())
            builder.Connect(finite.get_cloud_output_port(), cloud_vis.cloud_input_port())
    return FrontPerception(plant=plant, scene_graph=scene_graph, camera=sensor, noise=noise,
                           true_pose=true_pose, trajectory=traj, intrinsics=K, X_WC=X_WC,
                           kinematics=kin, joint_name=joint_name,
                           duration=cfg.motion.duration(),
                           front_labels=_body_labels(plant, scene_graph, front),
                           closed_fronts=closed, ports=ports,
                           closed_front_labels={n: _body_labels(plant, scene_graph, n)
                                                for n in closed},
                           cloud_visualizer=cloud_vis)


def AddFrontDetectorAndTracker(builder: DiagramBuilder, parts: FrontPerception, *,
                               detector_config=None, tracker_config=None, seed: int = 0,
                               temporal_filter: DepthFilterConfig | None = None,
                               camera_rate_hz: float | None = None):
    """Add a ``FrontDetector`` on the perception's noisy depth image and camera pose and a
    ``FrontTracker`` on its rectangles (named ``front_detector`` / ``front_tracker``), e.g.
    from the ``add_systems`` callback of :func:`MakeFrontPerceptionDiagram`. ``seed``: the
    detector's RANSAC seed. ``temporal_filter``: put a ``DepthTemporalFilter`` (named
    ``depth_temporal_filter``, updated at ``camera_rate_hz``, the camera's frame rate, Hz)
    between the depth image and the detector, its ``noise_scale`` into the detector's.
    Returns ``(detector, tracker)``."""
    det = builder.AddNamedSystem("front_detector", FrontDetector(
        intrinsics=parts.intrinsics, config=detector_config, seed=seed))
    trk = builder.AddNamedSystem("front_tracker", FrontTracker(config=tracker_config))
    if temporal_filter is not None:
        if camera_rate_hz is None:
            raise ValueError("AddFrontDetectorAndTracker: a temporal_filter needs "
                             "camera_rate_hz (the camera's frames per second)")
        filt = builder.AddNamedSystem("depth_temporal_filter", DepthTemporalFilter(
            intrinsics=parts.intrinsics, config=temporal_filter, rate_hz=camera_rate_hz))
        builder.Connect(parts.ports["depth_image"], filt.get_depth_image_input_port())
        builder.Connect(filt.get_depth_image_output_port(), det.get_depth_image_input_port())
        builder.Connect(filt.get_noise_scale_output_port(), det.get_noise_scale_input_port())
    else:
        builder.Connect(parts.ports["depth_image"], det.get_depth_image_input_port())
    builder.Connect(parts.ports["X_WC"], det.get_X_WC_input_port())
    builder.Connect(det.get_rectangles_output_port(), trk.get_rectangles_input_port())
    return det, trk


def MakeFrontPerceptionDiagram(config: FrontPerceptionConfig | None = None, *, meshcat=None,
                               add_systems: Callable[[DiagramBuilder, FrontPerception], None]
                               | None = None) -> FrontPerceptionDiagram:
    """Build the front-perception diagram (see the module docstring).

    Args:
        config: the :class:`FrontPerceptionConfig` (default: the drawer at 1.8 m).
        meshcat: show the scene and the noisy point cloud there.
        add_systems: called as ``add_systems(builder, parts)`` before ``Build``: add the
            detector / tracker, connect them to ``parts.ports`` and export what you need.

    Returns:
        a :class:`FrontPerceptionDiagram`.
    """
    builder = DiagramBuilder()
    parts = AddFrontPerception(builder, config, meshcat=meshcat)
    for name, port in parts.ports.items():
        builder.ExportOutput(port, name)
    if add_systems is not None:
        add_systems(builder, parts)
    diagram = builder.Build()
    diagram.set_name("front_perception")
    vis = None
    if meshcat is not None:
        vis = next((s for s in diagram.GetSystems() if isinstance(s, MeshcatVisualizer)), None)
    return FrontPerceptionDiagram(**{k: getattr(parts, k) for k in parts.__dataclass_fields__},
                                  diagram=diagram, visualizer=vis)
