"""Systems shared by several capabilities (SE(3) geometry, GP, file formats, cameras, marker sensing)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "camera_marker_sensor": ["CameraMarkerSensor", "CameraMarkerSensorConfig", "CameraView", "default_marker_cameras", "marker_normal_from_depth"],
    "depth_noise": ["DepthNoise"],
    "meshcat_view": ["LEGEND_PATH", "LEGEND_KINDS", "draw_legend", "frame_camera"],
    "marker_sensor": ["CameraConfig", "MarkerSensorConfig", "MarkerSensor"],
    "observations": ["MarkerObservations"],
    "plant_helpers": ["GravityCompensation", "StateForceSystem", "JointFriction"],
    "wrist_force_sensor": ["WristForceSensor"],
}

__all__ = [
    "CameraConfig",
    "CameraMarkerSensor",
    "CameraMarkerSensorConfig",
    "CameraView",
    "default_marker_cameras",
    "DepthNoise",
    "draw_legend",
    "frame_camera",
    "GravityCompensation",
    "JointFriction",
    "LEGEND_KINDS",
    "LEGEND_PATH",
    "marker_normal_from_depth",
    "MarkerObservations",
    "MarkerSensor",
    "MarkerSensorConfig",
    "StateForceSystem",
    "WristForceSensor",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
