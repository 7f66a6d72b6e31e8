"""Diagrams shared by several capabilities (SE(3) geometry, GP, file formats, cameras, marker sensing)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "marker_camera": ["AddArucoMarkers", "AddMarkerCameras", "AddCameraMarkerSensor", "MarkerRig", "camera_views", "marker_bodies", "RENDERER"],
    "object_tracks": ["ObjectTrack", "ObjectKinematics", "cabinet_scenario", "cabinet_together_scenario", "yardstick_scenario", "table_scenario", "table_phases", "car_door_scenario", "garage_door_scenario", "SCENARIOS"],
    "scene": ["SceneConfig", "Scene", "MakeSceneDiagram"],
}

__all__ = [
    "AddArucoMarkers",
    "AddCameraMarkerSensor",
    "AddMarkerCameras",
    "cabinet_scenario",
    "camera_views",
    "car_door_scenario",
    "garage_door_scenario",
    "MakeSceneDiagram",
    "marker_bodies",
    "MarkerRig",
    "ObjectKinematics",
    "ObjectTrack",
    "RENDERER",
    "SCENARIOS",
    "Scene",
    "SceneConfig",
    "table_phases",
    "table_scenario",
    "yardstick_scenario",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
