"""Diagrams marker-less perception of cabinet fronts in depth images (thesis ch. 5)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "diagram": ["DepthCameraConfig", "FrontPerceptionConfig", "FrontPerception", "FrontPerceptionDiagram", "AddDepthCamera", "AddFrontPerception", "MakeFrontPerceptionDiagram", "camera_pose_looking_at"],
}

__all__ = [
    "AddDepthCamera",
    "AddFrontPerception",
    "camera_pose_looking_at",
    "DepthCameraConfig",
    "FrontPerception",
    "FrontPerceptionConfig",
    "FrontPerceptionDiagram",
    "MakeFrontPerceptionDiagram",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
