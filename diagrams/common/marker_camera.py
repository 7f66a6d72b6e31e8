"""Wiring of the camera marker sensor: ArUco textures on the marker squares, RGB cameras
(Drake ``RgbdSensor`` with RenderEngineVtk) and a :class:`CameraMarkerSensor`.

Two steps, because textures are geometry and must be registered before the plant is
finalized::

    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=...)
    ... parse models ...
    markers = AddArucoMarkers(plant, config=cfg, model_instance=robot)   # before Finalize
    plant.Finalize()
    sensor, cameras = AddCameraMarkerSensor(builder, scene_graph, markers=markers,
                                            config=cfg)
"""

from __future__ import annotations

import dataclasses

import numpy as np

from pydrake.geometry import (ClippingRange, ColorRenderCamera, DepthRange, DepthRenderCamera,
                              GeometryInstance, IllustrationProperties, MakeRenderEngineVtk,
                              Mesh, PerceptionProperties, RenderCameraCore,
                              RenderEngineVtkParams, Rgba)
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraInfo, RgbdSensor

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.sdf.aruco import marker_texture, quad_mesh
from mmlearn.systems.common.camera_marker_sensor import (CameraMarkerSensor,
                                                         CameraMarkerSensorConfig, CameraView)
from mmlearn.systems.common.depth_noise import DepthNoise

__all__ = ["AddArucoMarkers", "AddMarkerCameras", "AddCameraMarkerSensor", "MarkerRig",
           "camera_views", "marker_bodies", "RENDERER"]

#: Name of the RenderEngineVtk the marker cameras use.
RENDERER = "mmlearn_marker_vtk"


def marker_bodies(plant, model_instance, bodies=()) -> list[str]:
    """Names of the bodies whose ``<body>_marker`` frames are textured: ``bodies`` if given
    (each must have a marker frame), else every body of ``model_instance`` with one."""
    have = [plant.get_body(b).name() for b in plant.GetBodyIndices(model_instance)
            if plant.HasFrameNamed(plant.get_body(b).name() + "_marker", model_instance)]
    if not bodies:
        if not have:
            raise ValueError("the model instance has no <body>_marker frames")
        return have
    unknown = [b for b in bodies if b not in have]
    if unknown:
        raise ValueError(f"no <body>_marker frame for {unknown}; bodies with markers: {have}")
    return list(bodies)


def AddArucoMarkers(plant, *, config: CameraMarkerSensorConfig, model_instance,
                    bodies=None, mounts: dict | None = None) -> dict[str, int]:
    """Put an ArUco-textured square on the marker frame of every observed body of
    ``model_instance`` (``bodies``, default ``config.bodies``, empty = all with a
    ``<body>_marker`` frame). Call before ``plant.Finalize()``.

    The square (``config.aruco.plate_size`` m, marker in the middle) lies in the marker
    frame's xy plane, ``config.aruco.surface_offset`` m above it and turned by
    ``config.aruco.in_plane_angle_deg`` about its normal; its perception properties
    carry the texture (Meshcat shows it as a plain white square: illustration ignores
    ``diffuse_map``). Marker k gets ArUco id ``config.aruco.first_id + k``. ``mounts``
    ({body: X_MS}, optional) puts a body's square at pose X_MS in its marker frame M
    instead of on M (where the part's geometry would hide part of a square on M); the
    sensor then reports the square's frame S, and the caller maps it back with X_MS.

    Returns:
        {body name: ArUco id}, in the order of the bodies.
    """
    if plant.is_finalized():
        raise RuntimeError("AddArucoMarkers must be called before plant.Finalize()")
    cfg = config
    cfg.validate()
    names = marker_bodies(plant, model_instance, bodies if bodies is not None else cfg.bodies)
    ids = cfg.aruco.ids(len(names))
    mesh = Mesh(str(quad_mesh()), cfg.aruco.plate_size)
    X_MQ = cfg.aruco.X_MQ()
    out = {}
    for name, aid in zip(names, ids):
        frame = plant.GetFrameByName(name + "_marker", model_instance)
        X_BM = frame.GetFixedPoseInBodyFrame()
        if mounts and name in mounts:
            X_BM = X_BM @ mounts[name]
        gi = GeometryInstance(X_BM @ X_MQ, mesh, f"{name}_aruco_{aid}")
        illus = IllustrationProperties()
        illus.AddProperty("phong", "diffuse", Rgba(1.0, 1.0, 1.0, 1.0))
        gi.set_illustration_properties(illus)
        perc = PerceptionProperties()
        perc.AddProperty("phong", "diffuse", Rgba(1.0, 1.0, 1.0, 1.0))
        perc.AddProperty("phong", "diffuse_map", str(marker_texture(cfg.aruco, aid)))
        gi.set_perception_properties(perc)
        plant.RegisterVisualGeometry(frame.body(), gi)
        out[name] = aid
    return out


def AddMarkerCameras(builder, scene_graph, *, config: CameraMarkerSensorConfig,
                     name_prefix: str = "marker_camera") -> list:
    """Add one ``RgbdSensor`` per camera of ``config`` (fixed in the world, ``width`` x
    ``height``, vertical field of view ``fov_y_deg``) rendering with RenderEngineVtk
    (:data:`RENDERER`, added to ``scene_graph`` if missing) and connect their geometry
    queries. Returns the sensors (named ``<name_prefix>_<i>``)."""
    cfg = config
    cfg.validate()
    if not scene_graph.HasRenderer(RENDERER):
        scene_graph.AddRenderer(RENDERER, MakeRenderEngineVtk(RenderEngineVtkParams()))
    out = []
    for i, cam in enumerate(cfg.cameras):
        core = RenderCameraCore(RENDERER, CameraInfo(cfg.width, cfg.height,
                                                     np.radians(cam.fov_y_deg)),
                                ClippingRange(cfg.near, cam.max_range), RigidTransform())
        depth = DepthRenderCamera(core, DepthRange(cfg.near * 1.01, cam.max_range * 0.99))
        rgbd = builder.AddNamedSystem(f"{name_prefix}_{i}", RgbdSensor(
            scene_graph.world_frame_id(), cam.pose(), ColorRenderCamera(core, False), depth))
        builder.Connect(scene_graph.get_query_output_port(), rgbd.query_object_input_port())
        out.append(rgbd)
    return out


def camera_views(rgbd_sensors, config: CameraMarkerSensorConfig) -> list[CameraView]:
    """The :class:`CameraView` (pose and intrinsics) of each world-fixed RgbdSensor; the
    principal point is shifted by ``config.principal_point_shift_px`` (the calibration of
    the rendered images, see :class:`CameraMarkerSensorConfig`)."""
    views = []
    for s, cam in zip(rgbd_sensors, config.cameras):
        info = s.default_color_render_camera().core().intrinsics()
        K = np.array(info.intrinsic_matrix(), float)
        K[0, 2] += config.principal_point_shift_px[0]
        K[1, 2] += config.principal_point_shift_px[1]
        views.append(CameraView(X_WC=cam.pose(), K=K, width=info.width(),
                                height=info.height()))
    return views


def AddCameraMarkerSensor(builder, scene_graph, *, markers: dict[str, int],
                          config: CameraMarkerSensorConfig,
                          name: str = "marker_sensor"):
    """Add the cameras of ``config`` and a :class:`CameraMarkerSensor` reading the markers
    ``markers`` ({body: ArUco id}, from :func:`AddArucoMarkers`), with every camera's colour
    image (and with ``config.use_depth`` its depth image, through a ``DepthNoise`` system
    named ``<name>_depth_noise_<i>`` when ``config.depth_noise`` is set) connected. Returns
    ``(sensor, rgbd_sensors)``."""
    rgbd = AddMarkerCameras(builder, scene_graph, config=config)
    sensor = builder.AddNamedSystem(name, CameraMarkerSensor(
        marker_ids=list(markers), aruco_ids=list(markers.values()),
        cameras=camera_views(rgbd, config), config=config))
    for i, s in enumerate(rgbd):
        builder.Connect(s.color_image_output_port(), sensor.get_color_image_input_port(i))
        if config.use_depth:
            depth_port = s.depth_image_32F_output_port()
            if config.depth_noise is not None:
                noise = builder.AddNamedSystem(f"{name}_depth_noise_{i}", DepthNoise(
                    intrinsics=PinholeIntrinsics.from_camera_info(
                        s.default_depth_render_camera().core().intrinsics()),
                    config=dataclasses.replace(config.depth_noise,
                                               seed=int(config.depth_noise.seed) + i),
                    rate_hz=config.rate_hz))
                builder.Connect(depth_port, noise.get_clean_depth_input_port())
                depth_port = noise.get_depth_image_output_port()
            builder.Connect(depth_port, sensor.get_depth_image_input_port(i))
    return sensor, rgbd


class MarkerRig:
    """A bench for the camera marker sensor (tests and benchmarks): free-floating marker
    carriers (a 0.10 x 0.10 x 0.01 m grey box with the marker on its +z face) in front of a
    grey backdrop, seen by the cameras of ``config``.

    Attributes:
        diagram, plant, sensor, rgbd: the built parts.
        bodies: the carriers' bodies, marker ``m<k>`` on body k.
    """

    def __init__(self, config: CameraMarkerSensorConfig, *, n_markers: int = 1,
                 backdrop_distance: float | None = 6.0):
        from pydrake.geometry import Box
        from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
        from pydrake.multibody.tree import SpatialInertia
        from pydrake.systems.framework import DiagramBuilder

        builder = DiagramBuilder()
        plant, sg = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        inst = plant.AddModelInstance("markers")
        self.bodies = []
        for k in range(n_markers):
            b = plant.AddRigidBody(f"m{k}", inst,
                                   SpatialInertia.SolidBoxWithMass(0.1, 0.1, 0.1, 0.01))
            plant.RegisterVisualGeometry(b, RigidTransform([0, 0, -0.006]),
                                         Box(0.10, 0.10, 0.01), f"m{k}_carrier",
                                         np.array([0.6, 0.6, 0.6, 1.0]))
            plant.AddFrame(_fixed_frame(f"m{k}_marker", b))
            self.bodies.append(b)
        if backdrop_distance is not None:
            cam = config.cameras[0]
            X_WC = cam.pose()
            X_WB = X_WC @ RigidTransform([0, 0, backdrop_distance])
            plant.RegisterVisualGeometry(plant.world_body(), X_WB, Box(20.0, 20.0, 0.01),
                                         "backdrop", np.array([0.45, 0.45, 0.45, 1.0]))
        markers = AddArucoMarkers(plant, config=config, model_instance=inst)
        plant.set_gravity_enabled(inst, False)
        plant.Finalize()
        self.sensor, self.rgbd = AddCameraMarkerSensor(builder, sg, markers=markers,
                                                       config=config)
        self.diagram = builder.Build()
        self.plant = plant
        self.markers = markers

    def set_poses(self, context, X_WM: list) -> None:
        """Put marker k at world pose ``X_WM[k]`` (RigidTransform) in the root context."""
        pc = self.plant.GetMyMutableContextFromRoot(context)
        for b, X in zip(self.bodies, X_WM):
            self.plant.SetFreeBodyPose(pc, b, X)

    def observe(self, context):
        return self.sensor.observe(self.sensor.GetMyContextFromRoot(context))


def _fixed_frame(name, body):
    from pydrake.multibody.tree import FixedOffsetFrame

    return FixedOffsetFrame(name, body.body_frame(), RigidTransform())
