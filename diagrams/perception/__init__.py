"""Diagrams marker-less perception of cabinet fronts in depth images (thesis ch. 5)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "diagram": ["DepthCameraConfig", "FrontPerceptionConfig", "FrontPerception", "FrontPerceptionDiagram", "AddDepthCamera", "AddFrontPerception", "MakeFrontPerceptionDiagram", "camera_pose_looking_at"],
    "trials": ["EXPECTED_MODEL", "TrackFrontsConfig", "track_fronts", "fronts_trial"],
}

__all__ = [
    "AddDepthCamera",
    "AddFrontPerception",
    "camera_pose_looking_at",
    "DepthCameraConfig",
    "EXPECTED_MODEL",
    "FrontPerception",
    "FrontPerceptionConfig",
    "FrontPerceptionDiagram",
    "fronts_trial",
    "MakeFrontPerceptionDiagram",
    "track_fronts",
    "TrackFrontsConfig",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
